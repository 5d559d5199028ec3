"""LinearFeedback for any nq/nu: K (nu, nx), vector u_eq, per-actuator limits, wrapped hinge errors, and
LinearFeedback.for_model balancing chains of poles in MuJoCo about their computed equilibrium."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.control import FeedbackError, LinearFeedback
from cartpole.riccati import LQRError, dlqr, default_weights, lqr
from cartpole.models import state_error
from cartpole.sim import SimOptions, replays_exactly, simulate

TWO_POLE = cp.SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
THREE_POLE = cp.SHIPPED_MJCF.with_name("cartpole_three_pole.xml")


def test_law_is_u_eq_minus_K_wrapped_error_clipped_per_actuator():
    K = np.array([[1.0, 2.0, 0.0, 0.5, 0.0, 0.0], [0.0, -1.0, 3.0, 0.0, 0.2, 0.0]])
    x_eq = np.array([0.1, 0.0, 0.02, 0.0, 0.0, 0.0])
    c = LinearFeedback(K, x_eq, [0.05, -0.1], u_limits=[[-1.0, 1.0], [-0.2, 0.3]], hinges=(1, 2))
    assert (c.nu, c.nx) == (2, 6) and c.u_limits.shape == (2, 2) and c.hinges == (1, 2)
    x = np.array([0.2, 0.01, 0.03, 0.1, -0.2, 0.0])
    u = c(0.0, x)
    assert isinstance(u, np.ndarray) and u.shape == (2,)
    np.testing.assert_allclose(u, np.clip([0.05, -0.1] - K @ (x - x_eq), [-1.0, -0.2], [1.0, 0.3]), rtol=0, atol=1e-14)
    turned = x + np.array([0, 2 * np.pi, -4 * np.pi, 0, 0, 0])  # hinge angles never wrap in MuJoCo; errors do
    np.testing.assert_array_equal(c(0.0, turned), u)
    big = c(0.0, x + np.array([0, 0, 0, 0, -50.0, 0]))
    assert big[1] == 0.3  # the second actuator's own limit


def test_one_input_keeps_the_single_pole_call_shapes():
    c = LinearFeedback([-1.0, -20.0, -2.0, -3.0], u_limits=(-0.3, 0.5))  # (nx,) gain, one (low, high) pair
    assert c.K.shape == (1, 4) and c.hinges == (1,) and c.u_eq.shape == (1,)
    np.testing.assert_array_equal(c.u_limits, [[-0.3, 0.5]])
    x = np.array([0.0, 0.01, 0.0, 0.0])
    assert c(0.0, x).shape == (1,) and c(0.0, x)[0] == pytest.approx(0.2)
    S = np.diag([1.0, 2.0, 3.0, 4.0])
    c = LinearFeedback(np.zeros(4), S=S)
    assert c.cost_to_go([0.0, 2 * np.pi + 0.1, 0.0, 0.0]) == pytest.approx(2 * 0.01)
    np.testing.assert_allclose(c.cost_to_go(np.eye(4)), [1.0, 2.0, 3.0, 4.0])  # a batch of states


@pytest.mark.parametrize("kwargs, message", [
    (dict(K=np.zeros((1, 3))), "nx = 2 nq even"),
    (dict(K=np.zeros((1, 4)), x_eq=np.zeros(6)), "x_eq has shape"),
    (dict(K=np.zeros((2, 4)), u_eq=[0.0, 0.0, 0.0]), "u_eq has 3 entries"),
    (dict(K=np.zeros((2, 4)), u_limits=[[-1, 1]] * 3), "u_limits"),
    (dict(K=np.zeros((1, 4)), u_limits=(1.0, -1.0)), "low <= high"),
    (dict(K=np.zeros((1, 4)), S=np.eye(3)), "S has shape"),
    (dict(K=np.zeros((1, 4)), hinges=(2,)), "hinges"),
])
def test_shapes_that_disagree_are_one_sentence(kwargs, message):
    with pytest.raises(FeedbackError, match=message):
        LinearFeedback(**kwargs)
    with pytest.raises(FeedbackError, match="without S"):
        LinearFeedback(np.zeros((1, 4))).cost_to_go(np.zeros(4))


def test_for_model_is_the_lab_lqr_about_x_eq_with_the_models_hinges_and_ranges():
    model = cp.build_model(TWO_POLE)
    c = LinearFeedback.for_model(model)
    Q, R = default_weights(model)
    ref = lqr(*model.linearize(), Q, R)
    np.testing.assert_array_equal(c.K, ref.K)
    np.testing.assert_array_equal(c.S, ref.S)
    np.testing.assert_array_equal(c.x_eq, model.x_eq)
    np.testing.assert_array_equal(c.u_eq, model.u_eq)
    np.testing.assert_array_equal(c.u_limits, model.params.ctrl_range)
    assert c.hinges == model.hinges == (1, 2)
    d = LinearFeedback.for_model(model, discrete=True)
    Ad, Bd = model.linearize(discrete=True)
    np.testing.assert_allclose(d.K, dlqr(Ad, Bd, Q * model.dt, R * model.dt).K, rtol=1e-12)
    # the shipped single pole: exactly the lab's gain
    one = cp.build_model()
    np.testing.assert_array_equal(LinearFeedback.for_model(one).K, lqr(*one.linearize(), cp.Q_LAB, cp.R_LAB).K)


@pytest.mark.parametrize("path", [TWO_POLE, THREE_POLE], ids=["two_pole", "three_pole"])
def test_for_model_balances_chains_of_poles_in_mujoco_and_the_run_replays_exactly(path):
    model = cp.build_model(path)
    c = LinearFeedback.for_model(model)
    x0 = np.array(model.x_eq)
    x0[model.hinges[0]] += 0.05  # the first pole tilted 0.05 rad
    run = simulate(path, c, x0, 6.0)
    assert run.qpos.shape == (run.t.size, model.nq) and run.ctrl.shape == (run.t.size - 1, 1)
    assert replays_exactly(run)
    e = model.state_error(run.x)
    assert np.abs(e[-1]).max() < 1e-2  # back at rest, every pole upright
    assert np.all(np.abs(e[:, list(model.hinges)]) < 0.3)  # never fell
    lo, hi = model.params.cart_range
    assert lo < run.qpos[:, model.slide].min() and run.qpos[:, model.slide].max() < hi


def test_gym_pendulum_built_off_vertical_is_balanced_about_its_nonzero_x_eq(chain_dir):
    path = chain_dir / "gym_single_off_vertical.xml"
    model = cp.build_model(path)
    assert model.x_eq[1] == pytest.approx(-1 / 600, rel=1e-6)  # 1 mm over 0.6 m: upright is not qpos = 0
    c = LinearFeedback.for_model(model)
    np.testing.assert_array_equal(c.x_eq, model.x_eq)
    np.testing.assert_allclose(c(0.0, model.x_eq), model.u_eq, atol=0)  # at x_eq the law gives u_eq
    x0 = np.array(model.x_eq)
    x0[1] += 0.05
    run = simulate(path, c, x0, 8.0)
    assert replays_exactly(run)
    e = model.state_error(run.x[-1])
    assert np.abs(e).max() < 1e-3, e
    # it settles on the computed upright, not on qpos = 0 (which is 1.7 mrad away and not a rest)
    assert abs(run.qpos[-1, 1] - model.x_eq[1]) < 1e-4 and abs(run.qpos[-1, 1]) > 1e-3
    # a law about the origin instead holds the pole about 1.7 mrad off its upright with the cart drifting
    naive = LinearFeedback(c.K, u_limits=model.params.ctrl_range, S=c.S)
    off = simulate(path, naive, x0, 8.0)
    assert np.abs(state_error(off.x[-1], model.x_eq, model.hinges)).max() > 10 * np.abs(e).max()


def test_two_motor_cart_continuous_gain_refused_at_its_step_discrete_design_balances(chain_dir):
    path = chain_dir / "two_motors.xml"
    model = cp.build_model(path)
    with pytest.raises(LQRError, match="unstable when applied every 0.005 s physics step.*discrete=True"):
        LinearFeedback.for_model(model)
    c = LinearFeedback.for_model(model, discrete=True)
    assert c.K.shape == (2, 6) and c.u_limits.shape == (2, 2)
    x0 = np.array(model.x_eq)
    x0[1] += 0.05
    run = simulate(path, c, x0, 5.0)
    assert run.ctrl.shape == (run.t.size - 1, 2)
    assert replays_exactly(run)
    assert np.abs(model.state_error(run.x[-1])).max() < 1e-2
    assert np.all(np.abs(run.ctrl) <= model.params.ctrl_range[:, 1])


def test_lqr_designed_over_a_five_step_hold_balances_gymnasiums_double_pendulum_held_five_steps():
    """Gymnasium's InvertedDoublePendulum-v5 holds each action for 5 of its 0.01 s RK4 steps: the gain designed at
    the physics step falls there, the one designed on the exact discrete model over the hold balances."""
    from pathlib import Path

    from cartpole.models import build_model
    from cartpole.sim import SimOptions, replays_exactly, simulate

    path = Path(__file__).resolve().parent.parent / "assets" / "gymnasium_inverted_double_pendulum.xml"
    model = build_model(path)
    period = 5 * model.dt
    x0 = model.x_eq.copy()
    x0[model.hinges[0]] += 0.05
    x0[model.hinges[1]] -= 0.05
    held = simulate(path, LinearFeedback.for_model(model, period=period), x0, 10.0,
                    options=SimOptions(control_period=period))
    naive = simulate(path, LinearFeedback.for_model(model), x0, 10.0, options=SimOptions(control_period=period))
    assert np.abs(model.state_error(held.x[-1])).max() < 1e-3
    assert replays_exactly(held)
    assert np.abs(model.state_error(naive.x)[:, list(model.hinges)]).max() > 1.0  # the poles fell


def test_for_model_is_the_lqr_of_the_plant_about_the_given_equilibrium_with_its_eigenvalues():
    model = cp.build_model()
    res = lqr(model)
    c = LinearFeedback.for_model(model)
    np.testing.assert_array_equal(c.K, res.K)
    np.testing.assert_array_equal(c.S, res.S)
    np.testing.assert_array_equal(c.E, res.E)
    moved = np.array(model.x_eq)
    moved[model.slide] = 0.3
    held = LinearFeedback.for_model(model.params, x_eq=moved, u_limits=None)
    np.testing.assert_array_equal(held.x_eq, moved)
    assert held(0.0, moved).tolist() == list(model.u_eq) and np.all(np.isinf(held.u_limits))
    d = LinearFeedback.for_model(model, discrete=True)
    np.testing.assert_allclose(d.S, dlqr(model).S)
    assert np.all(np.abs(d.E) < 1)
