"""Knockdowns and throws: generalized forces on the joints, seeded, logged every physics step, replayed exactly."""
import numpy as np
import pytest

from cartpole.control import LinearFeedback
from cartpole.control.energy import EnergyShapingController
from cartpole.control.switching import SWINGUP_CATCH_R, SwitchingController
from cartpole.models import build_model, read_params
from cartpole.sim import (UPRIGHT_BAND, DisturbanceError, Knockdown, Rollout, Throw, replay, replays_exactly,
                          simulate)
from cartpole.validation import BasinCache, uptime_metrics


@pytest.fixture(scope="module")
def cart():
    params = read_params(None)
    return params, build_model(params)


def test_knock_waits_until_upright_for_after_seconds_then_pushes_only_the_hinges(cart):
    params, model = cart
    force = Knockdown(0.5, 0.2, seed=3).start(params, x_eq=model.x_eq, hinges=model.hinges)
    up = np.asarray(model.x_eq, dtype=float)
    h = params.timestep
    n_wait = int(round(0.5 / h))
    assert all(not force(k * h, up).any() for k in range(n_wait))
    f = force(n_wait * h, up)
    assert f[list(model.hinges)].all() and not np.delete(f, list(model.hinges)).any()
    assert len(force.events) == 1 and force.events[0][1] - force.events[0][0] == pytest.approx(0.2)
    down = up.copy()
    down[model.hinges[0]] += np.pi
    assert np.array_equal(force(n_wait * h + 0.1, down), f)  # the knock is held for its length, wherever it goes
    assert not force(n_wait * h + 0.3, up).any()  # over: wait again
    assert len(force.events) == 1


def test_knocks_are_seeded(cart):
    params, model = cart
    up = np.asarray(model.x_eq, dtype=float)

    def first(seed):
        f = Knockdown(0.01, 0.1, seed=seed).start(params, x_eq=model.x_eq, hinges=model.hinges)
        return next(v for k in range(100) if (v := f(k * params.timestep, up)).any())
    assert np.array_equal(first(1), first(1)) and not np.array_equal(first(1), first(2))


def test_a_knocked_down_energy_swingup_swings_up_again_and_the_log_replays(cart, tmp_path):
    params, model = cart
    catch = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R)
    basin = BasinCache.on_disk(tmp_path / "basins").get(params, catch)
    controller = SwitchingController(EnergyShapingController(model), catch, basin.rho)
    force = Knockdown(1.0, 0.3, seed=1).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, controller, model.x_eq, 12.0, disturbance=force)
    assert run.info["diverged"] is None
    assert run.info["qfrc_applied"].shape == (run.ctrl.shape[0], params.nq)
    assert replays_exactly(run)
    stats = uptime_metrics(run, model, events=force.events)
    assert stats["knockdowns"] >= 2
    # every knock is followed by a swing-up, but the last may have had too little run left
    assert stats["recoveries"] >= stats["knockdowns"] - 1
    assert all(t > run.t[-1] - 4.0 for t in stats["unrecovered_at"])
    assert 0.2 < stats["uptime"] < 1.0
    path = tmp_path / "run.json"
    run.save(path)
    again = Rollout.load(path)
    assert np.array_equal(again.info["qfrc_applied"], run.info["qfrc_applied"]) and replays_exactly(again)


def test_without_the_logged_forces_the_replay_differs(cart):
    params, model = cart
    hold = LinearFeedback.for_model(model)
    force = Knockdown(0.2, 0.2, seed=0).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, hold, model.x_eq, 1.0, disturbance=force)
    bare = replay(params, run.x[0], run.ctrl)
    assert not np.allclose(bare.x, run.x)


def test_throws_change_the_hinge_rates_at_random_times(cart):
    params, model = cart
    force = Throw(0.5, max_rate=8.0, seed=2).start(params, x_eq=model.x_eq, hinges=model.hinges,
                                                   timestep=params.timestep)
    run = simulate(params, lambda t, x: np.zeros(params.nu), model.x_eq, 2.0, disturbance=force)
    assert len(force.events) >= 2 and replays_exactly(run)
    k = int(round(force.events[0][0] / params.timestep))
    jump = run.qvel[k + 1] - run.qvel[k]
    assert np.abs(jump[list(model.hinges)]).max() > 0.5


def test_uptime_counts_a_run_held_upright_as_up_without_swingups(cart):
    params, model = cart
    run = simulate(params, LinearFeedback.for_model(model), model.x_eq, 1.0)
    stats = uptime_metrics(run, model)
    assert stats["uptime"] == pytest.approx(1.0) and stats["swingups"] == 0 and stats["upright_band"] == UPRIGHT_BAND
    assert uptime_metrics(run, model, duration=2.0)["uptime"] == pytest.approx(0.5)


@pytest.mark.parametrize("text, fix", [("3", "AFTER:LENGTH"), ("a:b", "seconds"), ("3:0.3:-1", "seed"),
                                       ("0:0.3", "wait"), ("3:1e9", "length")])
def test_bad_knockdowns_are_refused_in_one_sentence(text, fix):
    with pytest.raises(DisturbanceError, match=fix):
        Knockdown.parse(text)


def test_loop_options_take_a_knockdown_as_text_and_build_the_runs_disturbance(cart):
    from cartpole.sim import LoopOptions

    params, model = cart
    loop = LoopOptions(knockdown="2:0.3:5", throw=Throw(1.0, seed=1))
    assert loop.knockdown == Knockdown(2.0, 0.3, 5) and loop.disturbed and not LoopOptions().disturbed
    force = loop.disturbance(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, LinearFeedback.for_model(model), model.x_eq, 3.0, disturbance=force)
    assert len(force.events) >= 2 and replays_exactly(run)
    assert LoopOptions().disturbance(params, x_eq=model.x_eq, hinges=model.hinges) is None
