"""TVLQRController: the tracking law, angle wrapping, the hand-over to the catch, and tracking in MuJoCo."""
import numpy as np
import pytest

from cartpole import Q_LAB, R_LAB
from cartpole.control.linear import LinearFeedback
from cartpole.control.tvlqr import TVLQRController
from cartpole.riccati import dlqr, lqr
from cartpole.riccati.tvlqr import tvlqr
from cartpole.models import build_model, wrap_angle
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.planning.options import PlanOptions


@pytest.fixture(scope="module")
def plan():
    # the law along the collocation plan itself (the exact-discrete reference is tests/test_swingup_starts.py's)
    return trajopt_swingup(options=PlanOptions(exact_discrete=False))


def test_law_is_feedforward_minus_gain_times_wrapped_error(plan):
    c = TVLQRController(plan.trajectory, plan.gains, plan.catch, u_limits=(-np.inf, np.inf))
    t = 0.4
    x = plan.trajectory.state(t) + np.array([0.01, -0.02, 0.03, 0.05])
    u_ff = plan.trajectory.input(t + 0.5 * plan.gains.dt)[0]  # zero-order-hold mean over the step
    expected = u_ff - plan.gains.gain(t)[0] @ (x - plan.trajectory.state(t))
    assert c(t, x) == pytest.approx(float(expected), rel=1e-12)
    x_turned = x + np.array([0, 2 * np.pi, 0, 0])  # MuJoCo hinge angles never wrap
    assert c(t, x_turned) == pytest.approx(c(t, x), rel=1e-12)


def test_hands_over_to_the_catch_at_the_end_of_the_plan(plan):
    c = plan.controller
    c.reset()
    x = np.array([0.05, 0.02, 0.0, 0.1])
    c(0.0, plan.trajectory.x[0])
    assert c.handover_time is None
    T = plan.trajectory.duration
    assert c(T + 0.01, x) == pytest.approx(plan.catch(T + 0.01, x))
    assert c.handover_time == pytest.approx(T + 0.01)
    c(0.0, plan.trajectory.x[0])  # time went back: a new run
    assert c.handover_time is None
    lo, hi = plan.model.params.ctrl_range[0]
    assert lo <= c(0.1, np.array([1.0, np.pi, 5.0, 20.0])) <= hi  # clipped to the ctrl range


def test_catch_is_the_discrete_lab_lqr_and_the_hand_over_has_no_gain_jump(plan):
    dt = plan.gains.dt
    Ad0, Bd0 = plan.model.linearize(discrete=True)
    ref = dlqr(Ad0, Bd0, Q_LAB * dt, R_LAB * dt)
    np.testing.assert_allclose(plan.catch.K, ref.K, rtol=1e-12)
    np.testing.assert_allclose(plan.catch.S, ref.S, rtol=1e-12)
    # the terminal cost is the discrete catch's cost-to-go at the plan's end state
    Ad, Bd = plan.model.linearize(plan.trajectory.x[-1], plan.trajectory.u[-1], discrete=True)
    dref = dlqr(Ad, Bd, Q_LAB * dt, R_LAB * dt)
    np.testing.assert_allclose(plan.gains.S[-1], dref.S, rtol=1e-12)
    # so the last TVLQR gain is the catch's gain: no jump at the hand-over (K[-1] is linearised one step
    # before the end, hence not bit-equal); the continuous lab gain would differ by ~15 % here
    np.testing.assert_allclose(plan.gains.K[-1, 0], plan.catch.K[0], rtol=1e-3)
    cont = lqr(*plan.model.linearize(), Q_LAB, R_LAB)
    assert np.abs(cont.K - plan.catch.K).max() > 0.05 * np.abs(cont.K).max()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tvlqr_tracks_from_perturbed_starts_in_mujoco(plan, seed):
    rng = np.random.default_rng(seed)
    x0 = plan.trajectory.x[0] + rng.uniform(-1, 1, 4) * np.array([0.05, 0.1, 0.1, 0.2])
    ro = simulate(None, plan.controller, x0, plan.T + 1.0)
    assert replays_exactly(ro)
    during = ro.t <= plan.T
    err = ro.x[during] - plan.trajectory.state(ro.t[during])
    err[:, 1] = wrap_angle(err[:, 1])
    # the pole follows the plan to its end (the lab Q weights the cart position lightly, so a few cm of cart
    # offset may remain; the catch removes it slowly)
    assert abs(err[-1, 1]) < 0.05 and abs(err[-1, 0]) < 0.1
    assert np.abs(ro.qpos[:, 0]).max() < plan.model.params.cart_range[1]
    assert np.abs(err[:, 1]).max() < 0.3
    last = ro.t >= ro.t[-1] - 0.5
    assert np.all(np.abs(wrap_angle(ro.qpos[last, 1])) < 0.05)


def test_open_loop_feedforward_alone_does_not_swing_up_a_perturbed_start(plan):
    # Control for the claim above: without feedback the same perturbed start misses upright.
    zero = plan.gains.__class__(t=plan.gains.t, K=np.zeros_like(plan.gains.K), S=plan.gains.S, dt=plan.gains.dt)
    never = LinearFeedback(np.zeros((1, 4)))
    c = TVLQRController(plan.trajectory, zero, never, u_limits=plan.model.params.ctrl_range)
    x0 = plan.trajectory.x[0] + np.array([0.05, 0.1, -0.1, 0.2])
    ro = simulate(None, c, x0, plan.T)
    assert abs(wrap_angle(ro.qpos[-1, 1])) > 0.05



class _Hold:
    """A plan resting at ``(x, u)`` for ``T`` s (any nx, nu): what TVLQR and its controller read from a plan."""

    def __init__(self, x, u, T, n=11):
        self.t = np.linspace(0.0, T, n)
        self.x = np.tile(np.asarray(x, float), (n, 1))
        self.u = np.tile(np.asarray(u, float), (n, 1))
        self.duration = float(T)

    def state(self, t):
        return self.x[0] if np.ndim(t) == 0 else np.tile(self.x[0], (np.size(t), 1))

    def input(self, t):
        return self.u[0] if np.ndim(t) == 0 else np.tile(self.u[0], (np.size(t), 1))


def test_two_inputs_law_shapes_wrapping_and_hand_over_in_mujoco(chain_dir):
    path = chain_dir / "two_motors.xml"
    model = build_model(path)
    catch = LinearFeedback.for_model(model, discrete=True)
    plan = _Hold(model.x_eq, model.u_eq, 1.0)
    gains = tvlqr(model, plan)
    c = TVLQRController(plan, gains, catch)
    assert c.u_limits.shape == (2, 2) and c.hinges == (1, 2)
    x = np.array(model.x_eq) + np.array([0.01, 0.02, -0.01, 0.0, 0.05, 0.0])
    u = c(0.3, x)
    assert u.shape == (2,)
    np.testing.assert_allclose(u, np.clip(model.u_eq - gains.gain(0.3) @ (x - model.x_eq), *model.params.ctrl_range.T),
                               rtol=1e-12)
    np.testing.assert_allclose(c(0.31, x + np.array([0, 2 * np.pi, -2 * np.pi, 0, 0, 0])), u, rtol=1e-12)
    ro = simulate(path, c, x, 3.0)
    assert ro.ctrl.shape[1] == 2 and replays_exactly(ro)
    assert c.handover_time == pytest.approx(1.0)
    assert np.abs(model.state_error(ro.x[-1])).max() < 1e-2
