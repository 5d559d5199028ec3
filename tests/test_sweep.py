"""The robustness sweep: a few seeded perturbed starts on the shipped asset all swing up, every run from MuJoCo."""
import numpy as np
import pytest

from cartpole.sweep import SweepError, SweepResult, sweep_starts, swingup_sweep


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
        swingup_sweep(None, method="mpc", n=1)
    with pytest.raises(SweepError, match="use --method energy"):
        swingup_sweep(None, method="trajopt", n=1, gain_jitter=0.1)
    with pytest.raises(SweepError, match="workers"):
        swingup_sweep(None, n=1, workers=0)


def test_a_run_that_raises_is_a_failed_row_with_its_sentence(monkeypatch):
    import cartpole.sweep as sweep_mod
    from cartpole.swingup import SwingupError

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

    r = subprocess.run([sys.executable, "-m", "cartpole.sweep", "--n", "1", "--json"], capture_output=True,
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
    from cartpole.ocp.pipeline import handover_catch
    from cartpole.sweep import swingup_sweep
    from cartpole.validation.basin import estimate_basin

    params = read_params()
    res = swingup_sweep(params, method="trajopt", n=1, seed=0)
    direct = estimate_basin(params, handover_catch(params, build_model(params)))  # estimated anew, no cache
    assert res.rho == direct.rho
