"""The environments' own episodes (cartpole.apps.envscore): dm_control's and Gymnasium's resets, steps and rewards,
run with the toolkit's controllers, against the toolkit's transcription of them and its own MuJoCo replay.

The planned dm_control episodes (a plan of minutes on a loaded machine) are run through the toolkit's own MuJoCo loop
in tests/apps/test_dmc_episodes.py; here the dm_control tasks are stepped by dm_control itself, with the upright LQR
for a few steps (the scoring's bookkeeping: the start, the rewards, the replay) and, for the acrobot, with its own
controller (the DDP MPC) through its swing-up."""
from __future__ import annotations

import numpy as np
import pytest

from dataclasses import replace

from cartpole.apps import envscore
from cartpole.apps.envscore import (ENVIRONMENTS, EnvScoreError, choose, design, environment, episode_return, score,
                                    score_episode)
from cartpole.control import LinearFeedback
from cartpole.models import build_model
from cartpole.ocp.dmc import episode_starts, rewards

DMC = [name for name, env in ENVIRONMENTS.items() if env.suite == "dmc"]
GYM = [name for name, env in ENVIRONMENTS.items() if env.suite == "gym"]


def _upright_lqr(env, mjcf, x0, hold):
    model = build_model(mjcf)
    return LinearFeedback.for_model(model, period=hold * model.dt if hold > 1 else None)


@pytest.mark.parametrize("name", DMC)
def test_dm_control_starts_and_pays_as_the_toolkits_transcription_of_its_task(name):
    """dm_control's reset with seed 0 is the first start cartpole.ocp.dmc draws for seed 0; what env.step paid for
    each step is the transcribed reward of the state reached and the ctrl held; the states replay bit for bit."""
    ep = score_episode(name, 0, controller=_upright_lqr, max_steps=120)
    model = build_model(ep.mjcf)
    objective = environment(name).objective
    assert ep.steps == 120 and ep.x.shape == (121, model.nx) and ep.ctrl.shape == (120, model.nu)
    np.testing.assert_array_equal(ep.x0, episode_starts(model, objective, 1, seed=0)[0])
    ours = rewards(model, objective, ep.x[1:], ep.ctrl)
    np.testing.assert_allclose(ep.rewards, ours, rtol=0, atol=1e-12)
    assert ep.return_ == pytest.approx(float(np.sum(ours)), abs=1e-9)
    assert ep.replays and not ep.warned


@pytest.mark.parametrize("name", GYM)
def test_gymnasium_pendulums_held_by_the_lqr_over_their_action_hold_for_the_whole_episode(name):
    """Gymnasium's own reset, frame skip, termination and reward: the LQR designed over the hold keeps every pole
    up for the episode's 1000 steps (never terminated), and the run replays bit for bit on Gymnasium's own file."""
    result = score(name, 1, 0)
    ep = result["episodes"][0]
    assert ep["steps"] == 1000 and not ep["terminated"] and ep["replays"] and not ep["warned"]
    assert result["returns"][0] > 0.9 * 1000 * (1 if name == "InvertedPendulum-v5" else 9.0)


def test_acrobot_seed_0_swung_up_by_its_controller_in_dm_control():
    """The DDP MPC from dm_control's own seed-0 start: within the first 4 s dm_control pays nearly the full reward
    (the tip at the target) for the last half second, and the run replays exactly."""
    def one_horizon(env, mjcf, x0, hold):  # the first of the candidates the scoring chooses among (no choice here)
        return design(replace(env, horizons=env.horizons[:1], iterations=()), mjcf, x0, hold)

    ep = score_episode("acrobot-swingup", 0, controller=one_horizon, max_steps=400)
    assert ep.replays and not ep.warned and ep.design is None
    assert ep.rewards[-50:].min() > 0.9


def test_chosen_controller_earns_in_dm_control_what_the_toolkits_own_run_predicted():
    """Among candidates the one that earns most in the toolkit's MuJoCo run of the episode is chosen, and
    dm_control's own episode from the same start pays exactly that return (its physics is the file's to the bit)."""
    def candidates(env, mjcf, x0, hold):
        model = build_model(mjcf)
        pushes = {"rest": lambda t, x: np.zeros(model.nu), "pump": lambda t, x: np.sign(x[model.nq + 1:]) + 0.0}
        return choose(pushes, model, mjcf, env.objective, x0)

    ep = score_episode("acrobot-swingup", 0, controller=candidates)
    predicted = ep.design["predicted"]
    assert set(predicted) == {"rest", "pump"} and predicted["rest"] != predicted["pump"]
    assert ep.design["choice"] == max(predicted, key=predicted.get)
    assert round(ep.return_, 4) == ep.design["predicted_return"] and ep.replays  # the JSON rounds to 4 places
    model = build_model(ep.mjcf)
    assert episode_return(model, ep.mjcf, "dmc_acrobot_swingup", lambda t, x: np.zeros(model.nu), ep.x0) == \
        pytest.approx(predicted["rest"], abs=1e-4)


@pytest.mark.parametrize("kwargs, words", [({"name": "acrobot"}, "Unknown environment 'acrobot'"),
                                           ({"name": "acrobot-swingup", "seed": -1}, "seed = -1"),
                                           ({"name": "acrobot-swingup", "max_steps": 0}, "max_steps = 0")])
def test_bad_environment_seed_or_length_is_one_sentence(kwargs, words):
    with pytest.raises(EnvScoreError, match=words):
        score_episode(**kwargs)


def test_bad_episode_count_is_one_sentence():
    with pytest.raises(EnvScoreError, match="n = 0"):
        score("InvertedPendulum-v5", 0)


def _fake_mpc(env, model, x0, period, horizon, iterations=1):
    """A cheap stand-in for the DDP MPC candidate (horizon, iterations): a constant push that differs by both."""
    u = np.full(model.nu, np.clip(0.1 * horizon * (-1) ** iterations, -1, 1))
    return lambda t, x: u.copy()


@pytest.mark.parametrize("search_below", [-np.inf, np.inf])
def test_more_iterations_are_searched_only_below_the_return_the_horizons_reach(monkeypatch, search_below):
    """best_mpc: the one-iteration candidate of each horizon first; the candidates with more DDP iterations a step
    only when none of those predicts search_below; the choice is the one predicting most among all that ran."""
    monkeypatch.setattr(envscore, "_ddp_mpc", _fake_mpc)
    env = replace(environment("acrobot-swingup"), horizons=(2.0, 3.0), iterations=(3,), search_below=search_below)
    model = build_model(str(envscore.ASSETS / env.asset))
    x0 = episode_starts(model, env.objective, 1, seed=0)[0]
    chosen = envscore.best_mpc(env, model, str(envscore.ASSETS / env.asset), x0, float(model.dt))
    expected = {"2", "3"} | ({"2x3", "3x3"} if search_below == np.inf else set())
    assert set(chosen.predicted) == expected
    assert chosen.choice == max(chosen.predicted, key=chosen.predicted.get)
    assert chosen.as_dict()["predicted_return"] == pytest.approx(max(chosen.predicted.values()), abs=1e-4)
    assert envscore.episode_return(model, str(envscore.ASSETS / env.asset), env.objective, chosen, x0) == \
        pytest.approx(chosen.predicted[chosen.choice], abs=1e-9)


def test_a_stepped_supervisor_takes_the_acrobots_start_with_the_design_the_toolkit_makes_from_it():
    """cartpole score's supervisor-stepped on dm_control's acrobot: at t = 0 its swing-up MPC is designed from the
    start itself (charged no time: the environment waits), so over the swing-up's first second it applies exactly the
    ctrl of the toolkit's controller designed from that start; the decision keeps the design's wall time."""
    def one_horizon(env):
        return replace(env, horizons=env.horizons[:1], iterations=())

    def toolkit(env, mjcf, x0, hold):
        return design(one_horizon(env), mjcf, x0, hold)

    def stepped(env, mjcf, x0, hold):
        return envscore.CONTROLLERS["supervisor-stepped"](one_horizon(env), mjcf, x0, hold)

    ours = score_episode("acrobot-swingup", 0, controller=toolkit, max_steps=100)
    sup = score_episode("acrobot-swingup", 0, controller=stepped, max_steps=100)
    assert sup.replays and not sup.warned
    first = sup.design["decisions"][0]
    assert first["kind"] == "mpc" and first["t"] == 0.0 and first["charged_s"] == 0.0 and first["design_s"] > 0.0
    assert np.array_equal(sup.ctrl, ours.ctrl)


def test_a_stepped_supervisor_refuses_a_charged_latency_in_one_sentence():
    env = environment("acrobot-swingup")
    with pytest.raises(EnvScoreError, match="charges its planning no time"):
        envscore.supervised(env, str(envscore.ASSETS / env.asset), None, 1, charged_latency=0.3, stepped=True)


def test_the_supervisor_catches_gymnasiums_double_pendulum_start_outside_its_verified_basin():
    """InvertedDoublePendulum-v5's seed-0 start lies outside the catch's verified basin but within what the catch
    holds: the supervisor catches it at once (certified by the catch's run on the model, GYM_CATCH_ROLLOUT) instead of
    braking while it plans, which ended the episode; it earns what the toolkit's LQR earns over the same
    steps."""
    sup = score_episode("InvertedDoublePendulum-v5", 0, controller=envscore.supervised, max_steps=100)
    lqr = score_episode("InvertedDoublePendulum-v5", 0, max_steps=100)
    first = sup.design["decisions"][0]
    assert first["kind"] == "catch" and 0.0 < first["certified_s"] <= envscore.GYM_CATCH_ROLLOUT
    assert sup.steps == 100 and not sup.terminated and sup.replays and not sup.warned
    assert sup.return_ == pytest.approx(lqr.return_, rel=1e-3)
