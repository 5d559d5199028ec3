"""RealAIGym's reset (:class:`cartpole.sim.Reset`): the controller off, a gravity-compensated PID on every hinge
towards a random pose for its length, at seeded times spread over the run; logged so the run replays exactly."""
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model, read_params, wrap_angle
from cartpole.sim import DisturbanceError, Reset, SimOptions, replays_exactly, simulate

ACROBOT = SHIPPED_MJCF.with_name("realaigym_acrobot.xml")


@pytest.fixture(scope="module")
def acrobot():
    params = read_params(ACROBOT)
    return params, build_model(params)


def _run(params, model, reset, duration, controller=None):
    force = reset.start(params, x_hanging=model.x_hanging, hinges=model.hinges, timestep=params.timestep)
    asked = []

    def ctrl(t, x):
        asked.append(t)
        return np.full(params.nu, 1.5) if controller is None else controller(t, x)
    run = simulate(params, force.gate(ctrl), np.asarray(model.x_hanging, float), duration, disturbance=force)
    return force, run, np.asarray(asked)


def test_reset_times_are_spread_over_the_run_and_moved_by_at_most_the_jitter():
    reset = Reset(count=15, duration=60.0, seed=4)
    _, times = reset.draws()
    even = np.linspace(60 / 16, 60 - 60 / 16, 15)
    assert np.all(np.abs(times - even) <= 1.0) and np.any(np.abs(times - even) > 0.1)
    poses, _ = reset.draws()
    assert poses.shape == (15, 4) and np.all(np.abs(poses) <= np.pi)
    assert not np.allclose(Reset(seed=5).draws()[0], poses)  # the seed decides


def test_a_reset_switches_the_controller_off_and_replays_exactly(acrobot):
    params, model = acrobot
    force, run, asked = _run(params, model, Reset(count=2, duration=3.0, seed=1), 3.0)
    assert len(force.events) == 2 and replays_exactly(run)
    h = params.timestep
    for a, b in force.windows:
        assert np.all(run.ctrl[a:b] == 0.0)  # the controller's ctrl is zero during the reset
        assert not np.any(np.isin(np.round(asked / h).astype(int), np.arange(a, b)))  # and it is not asked
        assert np.any(run.info["qfrc_applied"][a:b] != 0.0)  # the PID pushes both hinges, the unactuated one too
        assert np.all(run.info["qfrc_applied"][a:b, list(model.hinges)] != 0.0)
    outside = np.ones(len(run.ctrl), bool)
    for a, b in force.windows:
        outside[a:b] = False
    assert np.all(run.ctrl[outside] == 1.5) and not np.any(run.info["qfrc_applied"][outside])


def test_a_longer_reset_brings_the_chain_near_its_pose_and_holds_it_there(acrobot):
    """With 2 s instead of 0.2 the PID settles: every hinge near its goal angle, nearly at rest, the torque limit
    kept on every step."""
    params, model = acrobot
    reset = Reset(count=1, duration=3.0, length=2.0, seed=3, jitter=0.0)
    force, run, _ = _run(params, model, reset, 4.0, controller=lambda t, x: np.zeros(params.nu))
    a, b = force.windows[0]
    hinges = list(model.hinges)
    start_err = np.abs(force.goals[0] - run.qpos[a, hinges])
    end_err = np.abs(force.goals[0] - run.qpos[b, hinges])
    assert np.all(end_err < 0.1) and np.all(end_err < 0.2 * start_err)
    assert np.all(np.abs(run.qvel[b, hinges]) < 0.5)
    assert np.abs(run.info["qfrc_applied"]).max() <= reset.max_torque


def test_the_pid_holds_the_chain_against_gravity_at_its_goal(acrobot):
    """At the goal at rest the P and D terms are zero: what is left is the holding torque (plus the integral of
    that one step's zero error), so the chain stays."""
    params, model = acrobot
    reset = Reset(count=1, duration=2.0, seed=0, jitter=0.0)
    force = reset.start(params, x_hanging=model.x_hanging, hinges=model.hinges, timestep=params.timestep)
    a, _ = force.windows[0]
    x = np.asarray(model.x_hanging, float).copy()
    x[list(model.hinges)] = force.poses[0]
    f = force(a * params.timestep, x)
    np.testing.assert_allclose(f, np.clip(force.holding_torque(x), -6, 6), atol=1e-12)
    assert np.abs(force.holding_torque(x)).max() > 0.1  # gravity does pull there


@pytest.mark.parametrize("kw, fix", [({"count": 0}, "count"), ({"length": 0}, "length"), ({"seed": -1}, "seed"),
                                     ({"kp": 0}, "kp"), ({"max_torque": float("nan")}, "max_torque")])
def test_bad_resets_are_refused_in_one_sentence(kw, fix):
    with pytest.raises(DisturbanceError, match=fix):
        Reset(**kw)


def test_at_a_control_period_the_resets_start_on_control_instants_and_the_ctrl_is_zero_through_them(acrobot):
    params, model = acrobot
    period = 5 * params.timestep
    force = Reset(count=3, duration=3.0, seed=2).start(params, x_hanging=model.x_hanging, hinges=model.hinges,
                                                       timestep=params.timestep, period=period)
    run = simulate(params, force.gate(lambda t, x: np.full(params.nu, 1.5)), np.asarray(model.x_hanging, float), 3.0,
                   disturbance=force, options=SimOptions(control_period=period))
    assert replays_exactly(run) and len(force.events) == 3
    zero = np.all(run.ctrl == 0.0, axis=1)
    pushed = np.any(run.info["qfrc_applied"] != 0.0, axis=1)
    assert np.array_equal(zero, pushed)  # off exactly while the PID acts
    assert all(a % 5 == 0 and (b - a) % 5 == 0 for a, b in force.windows)
