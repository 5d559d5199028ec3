"""Where a sweep's runs run (cartpole.apps.sweep.executors): one runner's rows, the same on this process and on a
pool of workers, a run that raises as a failed row, settings reaching the controller, and a pool that leaves no
worker behind."""
import numpy as np
import pytest

import cartpole.apps.sweep.executors as executors
from cartpole.apps.sweep import Runner, SweepError, SweepRuns, axis, sweep_starts, swingup_sweep
from cartpole.apps.swingup import SwingupOptions
from cartpole.sim.options import LoopOptions
from cartpole.models import read_params
from cartpole.validation.basin import BasinCache


def lasting(seconds: float) -> SwingupOptions:
    """The options of runs of ``seconds`` s."""
    return SwingupOptions(loop=LoopOptions(duration=seconds))


def test_a_run_that_raises_is_a_failed_row_with_its_sentence(monkeypatch):
    from cartpole.apps.swingup import SwingupError

    real = executors.run_swingup
    starts = sweep_starts(3, seed=2)

    def flaky(model, method, options, **kw):
        if np.allclose(kw["x0"], starts[1]):
            raise SwingupError("No plan from this start; try another.")
        return real(model, method, options, **kw)

    monkeypatch.setattr(executors, "run_swingup", flaky)
    r = swingup_sweep(None, "energy", lasting(1.0), runs=SweepRuns(n=3, seed=2))
    rows = r.rows()
    assert [row["run"] for row in rows] == [0, 1, 2]
    assert rows[1]["success"] is False and rows[1]["error"] == "No plan from this start; try another."
    assert rows[1]["time_to_upright"] is None and rows[0]["error"] is None and rows[0]["replays"] is True


def test_sampled_axes_are_seeded_and_give_the_same_rows_on_two_and_three_workers():
    axes = [axis("start:hinge", 2.9, 3.4), axis("start:slider_rate", -0.2, 0.2), axis("setting:energy_gain", 12, 18, 2)]
    one = swingup_sweep(None, "energy", lasting(2.0), runs=SweepRuns(axes=axes, n=2, seed=7))
    assert one.n == 4  # 2 grid points x 2 draws
    starts = np.asarray(one.starts)
    assert np.all((2.9 <= starts[:, 1]) & (starts[:, 1] <= 3.4)) and np.all(starts[:, [0, 3]] == 0)
    assert [row["settings"] for row in one.rows()] == [{"energy_gain": 12.0}] * 2 + [{"energy_gain": 18.0}] * 2
    other = swingup_sweep(None, "energy", lasting(2.0), runs=SweepRuns(axes=axes, n=2, seed=8))
    assert not np.allclose(other.starts, starts)
    for workers in (2, 3):
        seen = []
        many = swingup_sweep(None, "energy", lasting(2.0), runs=SweepRuns(axes=axes, n=2, seed=7), workers=workers,
                             on_row=lambda i, x0, row: seen.append(i))
        assert many.workers == workers and sorted(seen) == [0, 1, 2, 3]  # each run once, whoever ran it
        assert many.rows() == one.rows()  # floats compared exactly


def test_the_pool_runs_some_runs_here_and_the_rest_in_its_workers(monkeypatch):
    """This process is one of the W: with W = 2 it runs a share itself beside one worker process, and the worker
    runs the rest (neither idles while runs remain)."""
    import os

    here = []
    real = Runner.run

    def spy(self, *a, **k):
        here.append(os.getpid())
        return real(self, *a, **k)

    # the fork server up (its first start imports the toolkit)
    swingup_sweep(None, "energy", lasting(0.2), runs=SweepRuns(n=2), workers=2)
    monkeypatch.setattr(Runner, "run", spy)  # the worker has the module as the fork server imported it: not spied
    r = swingup_sweep(None, runs=SweepRuns(n=8, seed=1), workers=2)
    assert r.n == 8 and set(here) == {os.getpid()}
    assert 1 <= len(here) <= 7, len(here)


def test_a_worker_builds_the_same_runner_from_the_settings():
    params = read_params()
    runner = Runner(params, "energy", lasting(1.0), BasinCache.on_disk())
    twin = Runner(*runner.settings())
    x0 = sweep_starts(1, seed=5)[0]
    assert twin.run(x0, {}) == runner.run(x0, {})


def test_mpc_settings_reach_the_controller(monkeypatch):
    pytest.importorskip("cartpole.mpc.nmpc")

    seen = []
    real = executors.run_swingup

    def spy(model, method, options, **kw):
        seen.append((options.mpc.period, options.mpc.horizon))
        return real(model, method, options, **kw)

    monkeypatch.setattr(executors, "run_swingup", spy)
    r = swingup_sweep(None, "mpc", lasting(0.5), runs=SweepRuns(axes=[axis("setting:horizon", 0.8, 1.2, 2)]))
    assert seen == [(None, 0.8), (None, 1.2)] and [row["settings"] for row in r.rows()] == [
        {"horizon": 0.8}, {"horizon": 1.2}]
    assert np.isnan(r.rho) and all(row["replays"] for row in r.rows())


def test_planner_settings_are_swept_by_their_option_field_name_and_checked_first():
    from cartpole.apps.sweep import SweepError
    from cartpole.apps.sweep.plan import LOOP_SETTINGS, SETTINGS
    from cartpole.planning.options import PlanOptions

    assert SETTINGS["trajopt"] == PlanOptions.scalar_names() + LOOP_SETTINGS and "cart_margin" in SETTINGS["trajopt"]
    with pytest.raises(SweepError, match=r"^The sweep axis setting:N reaches 0: .*\.$"):
        swingup_sweep(None, "trajopt", runs=SweepRuns(axes=[axis("setting:N", 0, 40, 2)]))
    with pytest.raises(SweepError, match="has no setting 'no_such'"):
        swingup_sweep(None, "trajopt", runs=SweepRuns(axes=[axis("setting:no_such", 1, 2, 2)]))


def test_the_rigs_delay_is_swept_by_name_rounded_to_whole_steps_and_checked_first():
    from cartpole.apps.sweep import axis

    res = swingup_sweep(None, "energy", lasting(6.0), runs=SweepRuns(axes=[axis("setting:delay", 0.0, 0.0126, 2)]))
    rows = res.rows()
    delays = [r["settings"]["delay"] for r in rows]
    assert delays == [0.0, 0.0126]  # the row keeps the value drawn; the run used the nearest whole step
    assert all(r["success"] and r["replays"] for r in rows)
    with pytest.raises(SweepError, match=r"^The sweep axis setting:delay reaches -0\.01: give delays from 0 to .*\.$"):
        swingup_sweep(None, "energy", runs=SweepRuns(axes=[axis("setting:delay", -0.01, 0.02, 2)]))
