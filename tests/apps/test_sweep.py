"""The robustness sweep: a few seeded perturbed starts on the shipped asset all swing up, every run from MuJoCo."""
import numpy as np
import pytest

from cartpole.apps.sweep import SweepError, SweepResult, sweep_starts, swingup_sweep


def test_quick_sweep_succeeds_on_the_shipped_asset():
    seen = []
    r = swingup_sweep(None, n=4, seed=0, progress=seen.append)
    assert isinstance(r, SweepResult)
    assert seen[-1] == pytest.approx(1.0) and len(seen) == 4  # progress after every run
    # starts are the documented seeded box around hanging at rest
    assert np.allclose(r.starts, sweep_starts(4, seed=0))
    assert np.all(np.abs(r.starts - [0, np.pi, 0, 0]) <= [0.3, 0.3, 0.3, 1.0])
    assert r.success_rate == 1.0, r.summary()["failed"]
    assert np.all(r.time_to_upright <= r.duration) and r.t_max < 8.0
    assert np.all(r.cart_clearance > 0.1) and np.all(r.peak_ctrl <= 1.0)
    s = r.summary()
    assert s["successes"] == 4 and s["time_to_upright_median"] == pytest.approx(r.t_median)
    with pytest.raises(Exception):
        r.rho = 1.0
    assert not r.success.flags.writeable and not r.starts.flags.writeable


def test_gain_jitter_is_seeded_and_bounded():
    r = swingup_sweep(None, n=2, seed=5, gain_jitter=0.2, duration=2.0)
    assert len(r.options) == 2 and r.options[0] != r.options[1]
    assert all(0.8 * 15.0 <= o["energy_gain"] <= 1.2 * 15.0 and o["energy_accel"] <= 1.0 for o in r.options)


def test_bad_settings_raise():
    with pytest.raises(SweepError):
        swingup_sweep(None, n=0)
    with pytest.raises(SweepError):
        swingup_sweep(None, n=2, gain_jitter=1.5)
    with pytest.raises(SweepError, match="Unknown sweep method"):
        swingup_sweep(None, method="magic", n=1)
    with pytest.raises(SweepError, match="use --method energy"):
        swingup_sweep(None, method="trajopt", n=1, gain_jitter=0.1)
    with pytest.raises(SweepError, match="workers"):
        swingup_sweep(None, n=1, workers=0)


def test_a_run_that_raises_is_a_failed_row_with_its_sentence(monkeypatch):
    import cartpole.apps.sweep as sweep_mod
    from cartpole.apps.swingup import SwingupError

    real = sweep_mod.run_swingup
    starts = sweep_starts(3, seed=2)

    def flaky(model, **kw):
        if np.allclose(kw["x0"], starts[1]):
            raise SwingupError("No plan from this start; try another.")
        return real(model, **kw)

    monkeypatch.setattr(sweep_mod, "run_swingup", flaky)
    r = swingup_sweep(None, n=3, seed=2, duration=1.0)
    rows = r.rows()
    assert [row["run"] for row in rows] == [0, 1, 2]
    assert rows[1]["success"] is False and rows[1]["error"] == "No plan from this start; try another."
    assert rows[1]["time_to_upright"] is None and rows[0]["error"] is None and rows[0]["replays"] is True


def test_python_m_cartpole_sweep_prints_one_json_summary_per_model():
    import json
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "cartpole.apps.sweep", "--n", "1", "--json"], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    (summary,) = json.loads(r.stdout)
    assert summary["n"] == 1 and summary["successes"] == 1 and summary["mjcf"].endswith("cartpole.xml")


def test_done_runs_are_skipped_and_on_row_sees_each_finished_run():
    full = swingup_sweep(None, n=3, seed=4, duration=2.0)
    seen = []
    row1 = {k: v for k, v in zip(("success", "replays", "time_to_upright", "caught_at", "cart_clearance",
                                  "peak_ctrl", "error"), (bool(full.success[1]), bool(full.replays[1]),
                                                          full.time_to_upright[1], full.caught_at[1],
                                                          full.cart_clearance[1], full.peak_ctrl[1], None))}
    part = swingup_sweep(None, n=3, seed=4, duration=2.0, done={1: row1},
                         on_row=lambda i, x0, row: seen.append((i, tuple(x0))))
    assert [i for i, _ in seen] == [0, 2]  # run 1 was not run again
    assert [x0 for _, x0 in seen] == [tuple(full.starts[0]), tuple(full.starts[2])]
    assert part.rows() == full.rows()


def test_success_map_is_a_labelled_png(tmp_path):
    from cartpole.models import read_params
    from cartpole.viz.sweep_plot import plot_success_map, success_map_figure

    r = swingup_sweep(None, n=3, seed=1, duration=1.0)  # too short to hold: failures drawn as crosses
    params = read_params(None)
    fig = success_map_figure(r, params)
    ax = fig.axes[0]
    assert "[rad]" in ax.get_xlabel() and "[rad/s]" in ax.get_ylabel() and "of 3 starts" in ax.get_title()
    path = plot_success_map(r, params, tmp_path / "figures" / "map.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_trajopt_sweep_reports_the_basin_of_the_hand_over_lqr():
    from cartpole.models import build_model, read_params
    from cartpole.planning.trajopt import handover_catch
    from cartpole.apps.sweep import swingup_sweep
    from cartpole.validation.basin import estimate_basin

    params = read_params()
    res = swingup_sweep(params, method="trajopt", n=1, seed=0)
    direct = estimate_basin(params, handover_catch(params, build_model(params)))  # estimated anew, no cache
    assert res.rho == direct.rho


# ---- sweep descriptions: axes over starts, pushes, model error and controller settings -------------------------

def test_axis_reads_a_fixed_value_a_sample_or_a_grid():
    from cartpole.apps.sweep import Axis, axis

    assert axis("push_time", "0.5") == Axis("push_time", 0.5, 0.5, 1)
    assert axis("push_force", -20, 20) == Axis("push_force", -20.0, 20.0, None) and axis("push_force", -20, 20).random
    g = axis("model_error", 0.8, 1.2, 5)
    assert not g.random and np.allclose(g.values(), [0.8, 0.9, 1.0, 1.1, 1.2])
    for bad in [("a",), (1, 2, 3, 4), (2, 1), (0, 1, 2.5), (0, 1, 0), (np.nan,)]:
        with pytest.raises(SweepError):
            axis("push_force", *bad)


def test_a_grid_sweep_is_the_product_of_its_axes_and_each_run_is_exactly_run_swingup():
    from cartpole.models import build_model, read_params
    from cartpole.apps.sweep import axis
    from cartpole.apps.swingup import run_swingup

    axes = [axis("push_force", -15, 15, 2), axis("model_error", 0.9, 1.1, 2), axis("push_time", 1.0)]
    r = swingup_sweep(None, axes=axes, duration=4.0)
    rows = r.rows()
    assert [(row["push"], row["model_error"]) for row in rows] == [
        ([[1.0, -15.0]], 0.9), ([[1.0, -15.0]], 1.1), ([[1.0, 15.0]], 0.9), ([[1.0, 15.0]], 1.1)]
    assert all(row["start"] == list(build_model().x_hanging) for row in rows)  # no start axis: hanging rest
    np.testing.assert_array_equal(r.axis_values("push_force", read_params()), [-15, -15, 15, 15])
    one = run_swingup(None, method="energy", duration=4.0, push=[(1.0, 15.0)], model_error=0.9)
    assert rows[2]["success"] == one.success
    assert rows[2]["time_to_upright"] == (one.metrics["time_to_upright"] if one.success else None)
    assert rows[2]["peak_ctrl"] == one.metrics["peak_ctrl"] and rows[2]["cart_clearance"] == one.metrics["cart_clearance"]
    assert [a["name"] for a in r.summary()["axes"]] == ["push_force", "model_error", "push_time"]


def test_sampled_axes_are_seeded_and_give_the_same_rows_on_two_workers():
    from cartpole.apps.sweep import axis

    axes = [axis("start:hinge", 2.9, 3.4), axis("start:slider_rate", -0.2, 0.2), axis("setting:energy_gain", 12, 18, 2)]
    one = swingup_sweep(None, axes=axes, n=2, seed=7, duration=2.0)
    assert one.n == 4  # 2 grid points x 2 draws
    starts = np.asarray(one.starts)
    assert np.all((2.9 <= starts[:, 1]) & (starts[:, 1] <= 3.4)) and np.all(starts[:, [0, 3]] == 0)
    assert [row["settings"] for row in one.rows()] == [{"energy_gain": 12.0}] * 2 + [{"energy_gain": 18.0}] * 2
    assert not np.allclose(swingup_sweep(None, axes=axes, n=2, seed=8, duration=2.0).starts, starts)
    two = swingup_sweep(None, axes=axes, n=2, seed=7, duration=2.0, workers=2)
    assert two.rows() == one.rows()  # floats compared exactly


@pytest.mark.parametrize("axes, words", [
    ([("wind", 1.0)], "Unknown sweep axis"), ([("start:elbow", 1.0)], "No joint 'elbow'"),
    ([("setting:horizon", 1.0)], "no setting 'horizon'"), ([("push_time", 1.0)], "without a push force"),
    ([("model_error", 0.0, 1.0, 3)], "scale in"), ([("push_force", 1.0), ("push_force", 2.0)], "twice"),
])
def test_bad_axes_are_refused_before_any_run(axes, words):
    from cartpole.apps.sweep import axis

    with pytest.raises(SweepError, match=words):
        swingup_sweep(None, axes=[axis(name, *v) for name, *v in axes], on_row=lambda *a: pytest.fail("ran"))


def test_a_sweep_finds_its_basins_on_disk_the_second_time(tmp_path, monkeypatch):
    import cartpole.validation.basin as basin_mod
    from cartpole.apps.sweep import axis

    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    axes = [axis("model_error", 0.9, 1.1, 2)]
    first = swingup_sweep(None, axes=axes, duration=0.5)
    assert len(list((tmp_path / "basins").glob("*.npz"))) == 2  # one catch per planning model
    monkeypatch.setattr(basin_mod, "estimate_basin", lambda *a, **k: pytest.fail("estimated again"))
    again = swingup_sweep(None, axes=axes, duration=0.5)
    assert again.rows() == first.rows() and again.rho == first.rho


def test_comparison_figure_puts_two_methods_side_by_side(tmp_path):
    from cartpole.models import read_params
    from cartpole.apps.sweep import axis
    from cartpole.viz.sweep_plot import comparison_figure, plot_comparison

    axes = [axis("push_force", -10, 10, 2), axis("model_error", 0.9, 1.1, 2), axis("push_time", 0.5)]
    res = [swingup_sweep(None, method=m, axes=axes, duration=3.0) for m in ("trajopt", "energy")]
    params = read_params()
    fig = comparison_figure(res, params)
    maps = [ax for ax in fig.axes if ax.get_xlabel()]
    assert len(maps) == 2 and all(ax.get_xlabel() == "push force [N]" for ax in maps)
    assert "model error" in maps[0].get_ylabel() or "scale" in maps[0].get_ylabel()
    assert "TVLQR" in maps[0].get_title() and "energy" in maps[1].get_title()
    assert all(f"of {r.n} succeed" in ax.get_title() for ax, r in zip(maps, res))
    path = plot_comparison(res, params, tmp_path / "cmp.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError):
        comparison_figure(res[:1], params)


def test_success_maps_of_sampled_and_one_axis_sweeps_are_labelled_scatters():
    from cartpole.models import read_params
    from cartpole.apps.sweep import axis
    from cartpole.viz.sweep_plot import success_map_figure

    params = read_params()
    two = swingup_sweep(None, axes=[axis("push_force", -10, 10), axis("push_time", 0.2, 0.6)], n=3, duration=1.0)
    fig = success_map_figure(two, params)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "push force [N]" and ax.get_ylabel() == "push time [s]"
    assert "of 3 runs succeed" in ax.get_title()
    xs = np.concatenate([c.get_offsets()[:, 0] for c in ax.collections])
    np.testing.assert_allclose(np.sort(xs), np.sort(two.axis_values("push_force", params)))
    one = swingup_sweep(None, axes=[axis("setting:energy_gain", 10, 20, 3)], duration=1.0)
    ax = success_map_figure(one, params).axes[0]
    assert ax.get_xlabel() == "energy_gain" and "of 3 runs" in ax.get_title()


def test_mpc_settings_reach_the_controller(monkeypatch):
    pytest.importorskip("cartpole.mpc.nmpc")
    import cartpole.apps.sweep as sweep_mod
    from cartpole.apps.sweep import axis

    seen = []
    real = sweep_mod.run_swingup

    def spy(model, **kw):
        seen.append((kw["period"], kw["horizon"]))
        return real(model, **kw)

    monkeypatch.setattr(sweep_mod, "run_swingup", spy)
    r = swingup_sweep(None, method="mpc", axes=[axis("setting:horizon", 0.8, 1.2, 2)], duration=0.5)
    assert seen == [(None, 0.8), (None, 1.2)] and [row["settings"] for row in r.rows()] == [
        {"horizon": 0.8}, {"horizon": 1.2}]
    assert np.isnan(r.rho) and all(row["replays"] for row in r.rows())
