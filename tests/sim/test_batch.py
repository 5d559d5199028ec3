"""Batched closed-loop replay: each run equals simulate() with LinearFeedback and its log replays exactly."""
import numpy as np
import pytest

from cartpole import Q_LAB, R_LAB, build_model, lqr, read_params, simulate
from cartpole.control.linear import LinearFeedback
from cartpole.sim import Rollout, replays_exactly
from cartpole.sim.batch import random_starts, simulate_batch_linear


@pytest.mark.parametrize("name", ["shipped", "flipped_offset_armature", "implicitfast_gear"])
def test_batch_equals_simulate_with_linear_feedback(name, variant_dir):
    from cartpole.models import SHIPPED_MJCF

    path = SHIPPED_MJCF if name == "shipped" else variant_dir / f"cartpole_{name}.xml"
    params = read_params(path)
    K = lqr(*build_model(params).linearize(), Q_LAB, R_LAB).K
    X0 = random_starts(6, seed=7)
    X0[0, 1] += 2 * np.pi  # hinge angles never wrap: the error fed to K must
    X0[1] = [0.3, 0.25, 0.0, 0.0]  # saturates the ctrl at the start
    x_eq = np.array([0.1, 0.0, 0.0, 0.0])
    states, ctrl = simulate_batch_linear(params, K, X0, 1.5, x_eq=x_eq, u_eq=0.0, nthread=2)
    n = int(round(1.5 / params.timestep))
    assert states.shape == (6, n + 1, 4) and ctrl.shape == (6, n, 1)
    assert np.any(np.abs(ctrl) == params.u_max)
    for i, x0 in enumerate(X0):
        run = simulate(params, LinearFeedback(K, x_eq), x0, 1.5)
        np.testing.assert_allclose(states[i], run.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ctrl[i], run.ctrl, rtol=0, atol=1e-12)
        # the batched log is itself an honest log: mj_step reproduces it bit for bit
        t = np.arange(n + 1) * params.timestep
        log = Rollout(t=t, qpos=states[i, :, :2], qvel=states[i, :, 2:], ctrl=ctrl[i], mjcf=params.mjcf)
        assert replays_exactly(log, params)


def test_ctrl_limits_of_the_law_are_applied_like_linear_feedback():
    params = read_params()
    K = lqr(*build_model(params).linearize(), Q_LAB, R_LAB).K
    X0 = np.array([[0.0, 0.2, 0.0, 0.0], [0.1, -0.1, 0.2, 0.0]])
    fractions = []
    states, ctrl = simulate_batch_linear(params, K, X0, 1.0, u_limits=(-0.3, 0.5), progress=fractions.append)
    assert ctrl.min() == -0.3 and ctrl.max() == 0.5  # tighter than ctrlrange, and both reached
    assert fractions[-1] == 1.0 and np.all(np.diff(fractions) > 0) and len(fractions) >= 10
    for i, x0 in enumerate(X0):
        run = simulate(params, LinearFeedback(K, u_limits=(-0.3, 0.5)), x0, 1.0)
        np.testing.assert_allclose(states[i], run.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ctrl[i], run.ctrl, rtol=0, atol=1e-12)


def test_batch_on_the_calling_thread_gives_the_same_runs():
    K = lqr(*build_model().linearize(), Q_LAB, R_LAB).K
    X0 = random_starts(3, seed=1)
    a, ua = simulate_batch_linear(None, K, X0, 0.5, nthread=0)
    b, ub = simulate_batch_linear(None, K, X0, 0.5, nthread=2)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ua, ub)


def test_bad_batch_input_is_refused():
    from cartpole import CartPoleError

    with pytest.raises(CartPoleError, match="X0 of shape"):
        simulate_batch_linear(None, np.ones(4), np.zeros((3, 3)), 1.0)
    with pytest.raises(CartPoleError, match="NaN"):
        simulate_batch_linear(None, np.ones(4), np.full((2, 4), np.nan), 1.0)



def test_batch_equals_simulate_for_a_two_pole_cart():
    from cartpole.models import SHIPPED_MJCF

    path = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
    params = read_params(path)
    model = build_model(params)
    law = LinearFeedback.for_model(model)
    X0 = random_starts(5, seed=2, model=model)
    assert X0.shape == (5, 6) and np.all(np.abs(X0 - model.x_eq) <= [0.5, 0.075, 0.075, 0.3, 0.15, 0.15])
    X0[0, 2] += 2 * np.pi  # the second hinge one turn around: its error must wrap
    states, ctrl = simulate_batch_linear(params, law, X0, 2.0, nthread=2)
    n = int(round(2.0 / params.timestep))
    assert states.shape == (5, n + 1, 6) and ctrl.shape == (5, n, 1)
    for i, x0 in enumerate(X0):
        run = simulate(params, law, x0, 2.0)
        np.testing.assert_allclose(states[i], run.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ctrl[i], run.ctrl, rtol=0, atol=1e-12)
    # the same law given as arrays (the model's hinges wrapped by default)
    again, _ = simulate_batch_linear(params, law.K, X0, 2.0, x_eq=law.x_eq, u_eq=law.u_eq, u_limits=law.u_limits,
                                     nthread=2)
    np.testing.assert_array_equal(again, states)


def test_batch_with_two_motors_equals_simulate(chain_dir):
    path = chain_dir / "two_motors.xml"
    model = build_model(path)
    law = LinearFeedback.for_model(model, discrete=True)
    X0 = random_starts(3, seed=5, model=model)
    states, ctrl = simulate_batch_linear(path, law, X0, 1.0, nthread=0)
    assert ctrl.shape[2] == 2
    for i, x0 in enumerate(X0):
        run = simulate(path, law, x0, 1.0)
        np.testing.assert_allclose(states[i], run.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ctrl[i], run.ctrl, rtol=0, atol=1e-12)


def test_mismatched_batch_law_is_refused():
    from cartpole import CartPoleError
    from cartpole.models import SHIPPED_MJCF

    path = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
    with pytest.raises(CartPoleError, match=r"Need K of shape \(1, 6\) and X0 of shape \(B, 6\)"):
        simulate_batch_linear(path, np.ones(4), np.zeros((2, 4)), 1.0)
    law = LinearFeedback(np.zeros(6))
    with pytest.raises(CartPoleError, match="either a LinearFeedback or K"):
        simulate_batch_linear(path, law, np.zeros((2, 6)), 1.0, x_eq=np.zeros(6))
