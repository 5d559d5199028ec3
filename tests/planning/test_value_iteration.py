"""Value iteration for a pendulum driven at its hinge (cartpole.planning.value_iteration): on a coarse grid (seconds),
its policy swings dm_control's pendulum up from hanging in MuJoCo and holds it, its value at a start is the return
its policy earns there within the grid's stated error, and its batched returns are the single runs'."""
from __future__ import annotations

import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.dmc import episode_starts, rewards
from cartpole.planning.value_iteration import (BandReward, DMCReward, HingeValues, HoldStep, ValueIterationError,
                                               ValueIterationOptions, ValuePolicy, action_set, cached_hinge_values,
                                               hinge_values, policy_returns)
from cartpole.sim import simulate
from tests.mj_replay import replay_with_mj_step

TASK = "dmc_pendulum_swingup"
ASSETS = SHIPPED_MJCF.parent
#: The grid whose error docs/dmc.md states (claim dmc.pendulum-vi-gap: the value within this of the closed-loop
#: return at each of dm_control's twenty starts, 100 x 101 nodes).
COARSE = ValueIterationOptions(angles=100, rates=101)
STATED_GAP = 30.0


@pytest.fixture(scope="module")
def pendulum():
    return build_model(ASSETS / "dmc_pendulum.xml")


@pytest.fixture(scope="module")
def coarse(pendulum):
    reward = DMCReward(pendulum, TASK)
    return hinge_values(pendulum, reward, options=COARSE), reward


def test_the_policy_swings_up_from_hanging_and_holds_in_mujoco(pendulum, coarse):
    values, reward = coarse
    x0 = np.asarray(pendulum.x_hanging, float)
    roll = simulate(pendulum.params.mjcf, ValuePolicy(values, pendulum, reward), x0, 20.0)
    x = np.column_stack([roll.qpos, roll.qvel])
    u = np.asarray(roll.ctrl, float).reshape(-1, pendulum.nu)
    paid = rewards(pendulum, TASK, x[1:], u)
    assert not roll.info.get("diverged")
    assert paid[-250:].min() == 1.0  # the last 5 s inside dm_control's 8 degrees
    assert paid[:50].max() == 0.0  # it had to swing up: not up within the first second
    qpos, qvel = replay_with_mj_step(pendulum.params.mjcf, roll.qpos[0], roll.qvel[0], roll.ctrl)
    assert np.array_equal(qpos, roll.qpos) and np.array_equal(qvel, roll.qvel)


def test_the_value_at_a_start_is_the_closed_loop_return_within_the_stated_gap(pendulum, coarse):
    values, reward = coarse
    X0 = np.vstack([pendulum.x_hanging, episode_starts(pendulum, TASK, 1, seed=0), episode_starts(pendulum, TASK, 1,
                                                                                                    seed=4)])
    achieved = policy_returns(ValuePolicy(values, pendulum, reward), X0, values.horizon)
    assert np.all(np.abs(values.value_at(X0) - achieved) <= STATED_GAP)
    assert np.all(achieved > 600.0)  # each swung up and held (from hanging the most is about 700)


def test_batched_returns_are_the_single_runs(pendulum, coarse):
    values, reward = coarse
    policy = ValuePolicy(values, pendulum, reward)
    x0 = episode_starts(pendulum, TASK, 1, seed=1)[0]
    steps = 120
    roll = simulate(pendulum.params.mjcf, policy, x0, steps * float(pendulum.dt))
    x = np.column_stack([roll.qpos, roll.qvel])
    single = float(np.sum(rewards(pendulum, TASK, x[1:], np.asarray(roll.ctrl, float).reshape(-1, 1))))
    assert policy_returns(policy, x0[None, :], steps)[0] == single


def test_the_tail_is_extrapolated_once_every_node_gains_alike(pendulum):
    reward = BandReward(pendulum)
    grid = dict(angles=60, rates=61, horizon=1000)
    quick = hinge_values(pendulum, reward, options=ValueIterationOptions(**grid, tol=1e-3))
    every = hinge_values(pendulum, reward, options=ValueIterationOptions(**grid, tol=1e-300))
    assert quick.iterations < every.iterations == 1000
    assert quick.gain == pytest.approx(1.0, abs=1e-3)  # held in the band for good
    assert np.allclose(quick.value, every.value, atol=(1000 - quick.iterations) * 1e-3)
    assert np.array_equal(quick.policy, every.policy)


def test_actions_hold_the_range_ends_and_zero_gentlest_first():
    u = action_set(-1.0, 1.0, 4).ravel()
    assert u[0] == 0.0 and set(u) >= {-1.0, 1.0}
    assert list(np.abs(u)) == sorted(np.abs(u))
    assert 0.0 not in action_set(0.5, 2.0, 3)


def test_the_tables_survive_the_cache(pendulum, tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    reward = BandReward(pendulum)
    opts = ValueIterationOptions(angles=16, rates=9, horizon=50)
    first = cached_hinge_values(pendulum, reward, options=opts)
    again = cached_hinge_values(pendulum, reward, options=opts)
    assert again.solve_s == 0.0 and first.solve_s > 0.0  # the second read from disk
    assert np.array_equal(first.value, again.value) and np.array_equal(first.policy, again.policy)
    assert HingeValues.from_bytes(first.to_bytes()).reward == first.reward


def test_refusals_name_what_to_change(pendulum):
    with pytest.raises(ValueIterationError, match="one pole driven at its hinge"):
        hinge_values(ASSETS / "dmc_cartpole.xml", lambda x, u: np.zeros(len(x)))
    with pytest.raises(ValueIterationError, match="angles"):
        ValueIterationOptions(angles=3)
    with pytest.raises(ValueIterationError, match="u_limits"):
        hinge_values(pendulum, BandReward(pendulum), u_limits=[[-np.inf, 1.0]])
    values = hinge_values(pendulum, BandReward(pendulum), options=ValueIterationOptions(angles=16, rates=9,
                                                                                         horizon=5))
    with pytest.raises(ValueIterationError, match="reward"):
        ValuePolicy(values, pendulum, DMCReward(pendulum, TASK))
    with pytest.raises(ValueIterationError, match="another model"):
        ValuePolicy(values, ASSETS / "dmc_acrobot.xml", BandReward(pendulum))


def test_a_hinge_limited_to_less_than_a_turn_gets_a_grid_over_its_range(tmp_path):
    """The hinge limited to [-30, 320] degrees (hanging at 180 inside, upright at 0 inside, no full turn): the grid
    spans the range, not the circle, and the policy swings up (the wall at 320, short of upright, in its way) and
    holds, in MuJoCo with the limit."""
    xml = (ASSETS / "dmc_pendulum.xml").read_text().replace('damping="0.1"/>',
                                                           'damping="0.1" limited="true" range="-30 320"/>')
    path = tmp_path / "limited_pendulum.xml"
    path.write_text(xml)
    model = build_model(path)
    reward = BandReward(model)
    values = hinge_values(model, reward, options=ValueIterationOptions(angles=80, rates=81))
    lo, hi = np.deg2rad([-30.0, 320.0])
    d = values.spacing[0]
    assert not values.periodic and lo <= values.angles[0] < lo + d and hi - d < values.angles[-1] <= hi
    assert np.min(np.abs(values.angles)) < 1e-12  # a node at upright
    roll = simulate(path, ValuePolicy(values, model, reward), np.asarray(model.x_hanging, float), 20.0)
    q = np.asarray(roll.qpos)[:, 0]
    assert not roll.info.get("diverged") and q.min() > lo - 0.05 and q.max() < hi + 0.05
    assert np.all(np.abs(q[-250:]) <= reward.band)  # up and held for the last 5 s


def test_every_step_pays_each_physics_step_of_a_held_action(pendulum):
    """An action-repeat wrapper's return (TD-MPC2 holds each action for two of dm_control's steps and sums both
    rewards): with ``every_step`` a period of two steps pays the reward of both states it passes; over one step it is
    the same table as without."""
    reward = DMCReward(pendulum, TASK)
    X = episode_starts(pendulum, TASK, 6, seed=3)
    U = np.linspace(-1.0, 1.0, len(X))[:, None]
    one = HoldStep(pendulum, 1)
    mid, _ = one(X, U)
    end, _ = one(mid, U)
    reached, bad, paid = HoldStep(pendulum, 2).pay(X, U, reward, every_step=True)
    assert np.array_equal(reached, end) and not bad.any()
    assert np.array_equal(paid, rewards(pendulum, TASK, mid, U) + rewards(pendulum, TASK, end, U))
    opts = ValueIterationOptions(angles=16, rates=9, horizon=20)
    a = hinge_values(pendulum, reward, options=opts)
    b = hinge_values(pendulum, reward, options=opts.replace(every_step=True))
    assert np.array_equal(a.value, b.value) and b.every_step and not a.every_step
