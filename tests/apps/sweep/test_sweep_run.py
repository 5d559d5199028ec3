"""The robustness sweep end to end (cartpole.apps.sweep.swingup_sweep): a few seeded perturbed starts on the shipped
asset all swing up, every run from MuJoCo; resumed runs, grids, basins found on disk, and the success maps."""
import numpy as np
import pytest

from cartpole.apps.sweep import SweepResult, SweepRuns, axis, sweep_starts, swingup_sweep
from cartpole.apps.swingup import SwingupOptions
from cartpole.sim.options import LoopOptions


def lasting(seconds: float) -> SwingupOptions:
    """The options of runs of ``seconds`` s."""
    return SwingupOptions(loop=LoopOptions(duration=seconds))


def test_quick_sweep_succeeds_on_the_shipped_asset():
    seen = []
    r = swingup_sweep(None, runs=SweepRuns(n=4, seed=0), progress=seen.append)
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
    r = swingup_sweep(None, "energy", lasting(2.0), runs=SweepRuns(n=2, seed=5, gain_jitter=0.2))
    assert len(r.options) == 2 and r.options[0] != r.options[1]
    assert all(0.8 * 15.0 <= o["energy_gain"] <= 1.2 * 15.0 and o["energy_accel"] <= 1.0 for o in r.options)


def test_done_runs_are_skipped_and_on_row_sees_each_finished_run():
    full = swingup_sweep(None, "energy", lasting(2.0), runs=SweepRuns(n=3, seed=4))
    seen = []
    row1 = {k: v for k, v in zip(("success", "replays", "time_to_upright", "caught_at", "cart_clearance",
                                  "peak_ctrl", "error"), (bool(full.success[1]), bool(full.replays[1]),
                                                          full.time_to_upright[1], full.caught_at[1],
                                                          full.cart_clearance[1], full.peak_ctrl[1], None))}
    part = swingup_sweep(None, "energy", lasting(2.0), runs=SweepRuns(n=3, seed=4), done={1: row1},
                         on_row=lambda i, x0, row: seen.append((i, tuple(x0))))
    assert [i for i, _ in seen] == [0, 2]  # run 1 was not run again
    assert [x0 for _, x0 in seen] == [tuple(full.starts[0]), tuple(full.starts[2])]
    assert part.rows() == full.rows()


def test_a_trajopt_sweep_reports_the_basin_of_the_hand_over_lqr():
    from cartpole.models import build_model, read_params
    from cartpole.planning.trajopt import handover_catch
    from cartpole.validation.basin import estimate_basin

    params = read_params()
    res = swingup_sweep(params, "trajopt", runs=SweepRuns(n=1, seed=0))
    direct = estimate_basin(params, handover_catch(params, build_model(params)))  # estimated anew, no cache
    assert res.rho == direct.rho


def test_a_grid_sweep_is_the_product_of_its_axes_and_each_run_is_exactly_run_swingup():
    from cartpole.models import build_model, read_params
    from cartpole.apps.swingup import run_swingup

    axes = [axis("push_force", -15, 15, 2), axis("model_error", 0.9, 1.1, 2), axis("push_time", 1.0)]
    r = swingup_sweep(None, "energy", lasting(4.0), runs=SweepRuns(axes=axes))
    rows = r.rows()
    assert [(row["push"], row["model_error"]) for row in rows] == [
        ([[1.0, -15.0]], 0.9), ([[1.0, -15.0]], 1.1), ([[1.0, 15.0]], 0.9), ([[1.0, 15.0]], 1.1)]
    assert all(row["start"] == list(build_model().x_hanging) for row in rows)  # no start axis: hanging rest
    np.testing.assert_array_equal(r.axis_values("push_force", read_params()), [-15, -15, 15, 15])
    one = run_swingup(None, "energy",
                      SwingupOptions(loop=LoopOptions(duration=4.0, push=[(1.0, 15.0)], model_error=0.9)))
    assert rows[2]["success"] == one.success
    assert rows[2]["time_to_upright"] == (one.metrics["time_to_upright"] if one.success else None)
    assert rows[2]["peak_ctrl"] == one.metrics["peak_ctrl"] and rows[2]["cart_clearance"] == one.metrics["cart_clearance"]
    assert [a["name"] for a in r.summary()["axes"]] == ["push_force", "model_error", "push_time"]


def test_a_sweep_finds_its_basins_on_disk_the_second_time(tmp_path, monkeypatch):
    import cartpole.validation.basin as basin_mod

    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    axes = [axis("model_error", 0.9, 1.1, 2)]
    first = swingup_sweep(None, "energy", lasting(0.5), runs=SweepRuns(axes=axes))
    assert len(list((tmp_path / "basins").glob("*.npz"))) == 2  # one catch per planning model
    monkeypatch.setattr(basin_mod, "estimate_basin", lambda *a, **k: pytest.fail("estimated again"))
    again = swingup_sweep(None, "energy", lasting(0.5), runs=SweepRuns(axes=axes))
    assert again.rows() == first.rows() and again.rho == first.rho


def test_success_map_is_a_labelled_png(tmp_path):
    from cartpole.models import read_params
    from cartpole.viz.sweep_plot import plot_success_map, success_map_figure

    # too short to hold: failures drawn as crosses
    r = swingup_sweep(None, "energy", lasting(1.0), runs=SweepRuns(n=3, seed=1))
    params = read_params(None)
    fig = success_map_figure(r, params)
    ax = fig.axes[0]
    assert "[rad]" in ax.get_xlabel() and "[rad/s]" in ax.get_ylabel() and "of 3 starts" in ax.get_title()
    path = plot_success_map(r, params, tmp_path / "figures" / "map.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_comparison_figure_puts_two_methods_side_by_side(tmp_path):
    from cartpole.models import read_params
    from cartpole.viz.sweep_plot import comparison_figure, plot_comparison

    axes = [axis("push_force", -10, 10, 2), axis("model_error", 0.9, 1.1, 2), axis("push_time", 0.5)]
    res = [swingup_sweep(None, m, lasting(3.0), runs=SweepRuns(axes=axes)) for m in ("trajopt", "energy")]
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
    from cartpole.viz.sweep_plot import success_map_figure

    params = read_params()
    two = swingup_sweep(None, "energy", lasting(1.0),
                        runs=SweepRuns(axes=[axis("push_force", -10, 10), axis("push_time", 0.2, 0.6)], n=3))
    fig = success_map_figure(two, params)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "push force [N]" and ax.get_ylabel() == "push time [s]"
    assert "of 3 runs succeed" in ax.get_title()
    xs = np.concatenate([c.get_offsets()[:, 0] for c in ax.collections])
    np.testing.assert_allclose(np.sort(xs), np.sort(two.axis_values("push_force", params)))
    one = swingup_sweep(None, "energy", lasting(1.0), runs=SweepRuns(axes=[axis("setting:energy_gain", 10, 20, 3)]))
    ax = success_map_figure(one, params).axes[0]
    assert ax.get_xlabel() == "energy_gain" and "of 3 runs" in ax.get_title()
