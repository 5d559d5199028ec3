"""Finite-horizon TVLQR: discrete recursion on the exact discrete model, and the continuous Riccati ODE."""
import numpy as np
import pytest

from cartpole import Q_LAB, R_LAB
from cartpole.riccati import LQRError, dlqr, lqr
from cartpole.riccati.tvlqr import TVLQRGains, reference, tvlqr
from cartpole.models import build_model
from cartpole.ocp.collocation import DirectCollocation
from cartpole.ocp.trajectory import Trajectory


def _upright_rest(T, n=11):
    t = np.linspace(0, T, n)
    z = np.zeros((n, 4))
    return Trajectory(t=t, x=z, u=np.zeros(n), xdot=z)


@pytest.fixture(scope="module")
def model():
    return build_model()


@pytest.fixture(scope="module")
def swing(model):
    traj, info = DirectCollocation(model, N=60, T=1.5).solve([0, np.pi, 0, 0])
    assert info.success
    return traj


def test_upright_rest_gives_the_dlqr_gain_at_every_step(model):
    dt = model.dt
    g = tvlqr(model, _upright_rest(1.0), Q_LAB, R_LAB)
    Ad, Bd = model.linearize(discrete=True)
    ref = dlqr(Ad, Bd, Q_LAB * dt, R_LAB * dt)
    assert g.K.shape == (200, 1, 4) and g.S.shape == (201, 4, 4) and g.method == "discrete"
    np.testing.assert_allclose(g.K[:, 0], np.broadcast_to(ref.K, (200, 4)), rtol=1e-8, atol=1e-10)


def test_long_horizon_from_zero_terminal_cost_converges_to_dlqr(model):
    dt = model.dt
    g = tvlqr(model, _upright_rest(6.0), Q_LAB, R_LAB, Qf=np.zeros((4, 4)))
    Ad, Bd = model.linearize(discrete=True)
    ref = dlqr(Ad, Bd, Q_LAB * dt, R_LAB * dt)
    np.testing.assert_allclose(g.K[0, 0], ref.K[0], rtol=1e-6)
    assert not np.allclose(g.K[-1, 0], ref.K[0], rtol=1e-2)  # near the end it has not converged yet


def test_discrete_linearisation_is_the_models_ABd_along_the_resampled_plan(model, swing):
    # Rebuild one step of the recursion independently from model.linearize at the reference point.
    g = tvlqr(model, swing, Q_LAB, R_LAB)
    t, xr, ur = reference(swing, model.dt)
    k = 97
    A, B = model.linearize(xr[k], ur[k], discrete=True)
    S1 = g.S[k + 1]
    K = np.linalg.solve(R_LAB * model.dt + B.T @ S1 @ B, B.T @ S1 @ A)
    np.testing.assert_allclose(g.K[k], K, rtol=1e-9)
    S = Q_LAB * model.dt + A.T @ S1 @ (A - B @ K)
    np.testing.assert_allclose(g.S[k], S, rtol=1e-9)
    # the zero-order-hold input of a step is the mean of the first-order hold over it
    t_fine = np.linspace(t[k], t[k] + model.dt, 1001)
    assert ur[k, 0] == pytest.approx(np.mean(swing.input(t_fine)), rel=1e-6, abs=1e-9)


def test_riccati_ode_and_discrete_recursion_agree_at_small_dt(model, swing):
    dt = 5e-4
    gd = tvlqr(model, swing, Q_LAB, R_LAB, dt=dt)
    gc = tvlqr(model, swing, Q_LAB, R_LAB, dt=dt, method="continuous")
    assert gd.K.shape == gc.K.shape
    scale = np.abs(gc.K).max()
    assert np.abs(gd.K - gc.K).max() < 0.02 * scale
    # terminal costs: dlqr's S with weights Q dt, R dt approaches the continuous lqr's S
    A, B = model.linearize()
    np.testing.assert_allclose(gc.S[-1], lqr(A, B, Q_LAB, R_LAB).S, rtol=1e-12)
    assert np.abs(gd.S[-1] - gc.S[-1]).max() < 0.02 * np.abs(gc.S[-1]).max()


def test_gain_and_cost_to_go_are_functions_of_time(model, swing):
    g = tvlqr(model, swing, Q_LAB, R_LAB)
    np.testing.assert_array_equal(g.gain(g.t[10] + 0.4 * g.dt), g.K[10])  # held over the step
    np.testing.assert_array_equal(g.gain(-1.0), g.K[0])
    np.testing.assert_array_equal(g.gain(100.0), g.K[-1])
    assert g.gain(np.array([0.1, 0.2])).shape == (2, 1, 4)
    np.testing.assert_allclose(g.cost_to_go(g.t_final), g.S[-1])
    mid = g.cost_to_go(g.t[3] + 0.5 * g.dt)
    np.testing.assert_allclose(mid, 0.5 * (g.S[3] + g.S[4]))
    for S in g.S[::25]:
        assert np.allclose(S, S.T) and np.linalg.eigvalsh(S).min() > 0


def test_bad_input_is_an_lqr_error(model, swing):
    with pytest.raises(LQRError, match="method"):
        tvlqr(model, swing, Q_LAB, R_LAB, method="magic")
    with pytest.raises(LQRError, match="positive definite"):
        tvlqr(model, swing, Q_LAB, 0.0)
    with pytest.raises(LQRError, match="disagree"):
        TVLQRGains(t=np.zeros(3), K=np.zeros((2, 1, 4)), S=np.zeros((4, 4, 4)), dt=0.1)


class _Hold:
    """A plan that rests at ``(x, u)`` for ``T`` s: the least a TVLQR reference needs (any nx, nu)."""

    def __init__(self, x, u, T, n=11):
        self.t = np.linspace(0.0, T, n)
        self.x = np.tile(np.asarray(x, float), (n, 1))
        self.u = np.tile(np.atleast_1d(np.asarray(u, float)), (n, 1))
        self.duration = float(T)

    def state(self, t):
        return self.x[0] if np.ndim(t) == 0 else np.tile(self.x[0], (np.size(t), 1))

    def input(self, t):
        return self.u[0] if np.ndim(t) == 0 else np.tile(self.u[0], (np.size(t), 1))


def test_two_inputs_have_the_right_shapes_and_converge_to_dlqr_far_from_the_end(chain_dir):
    """LTI: the two-motor cart resting at its upright equilibrium; far from the horizon end the finite-horizon
    gain is the infinite-horizon dlqr gain, near it (zero terminal cost) it is not."""
    from cartpole.riccati import default_weights

    model = build_model(chain_dir / "two_motors.xml")
    Q, R = default_weights(model)
    dt = model.dt
    g = tvlqr(model, _Hold(model.x_eq, model.u_eq, 10.0), Q, R, Qf=np.zeros((6, 6)))
    n = int(round(10.0 / dt))
    assert g.K.shape == (n, 2, 6) and g.S.shape == (n + 1, 6, 6) and (g.nu, g.nx) == (2, 6)
    assert g.gain(0.3).shape == (2, 6) and g.gain(np.array([0.1, 0.2, 0.3])).shape == (3, 2, 6)
    assert g.cost_to_go(0.3).shape == (6, 6) and g.cost_to_go(np.array([0.1, 0.2])).shape == (2, 6, 6)
    Ad, Bd = model.linearize(discrete=True)
    ref = dlqr(Ad, Bd, Q * dt, R * dt)
    np.testing.assert_allclose(g.K[0], ref.K, rtol=1e-6, atol=1e-9 * np.abs(ref.K).max())
    np.testing.assert_allclose(g.S[0], ref.S, rtol=1e-6, atol=1e-9 * np.abs(ref.S).max())
    assert not np.allclose(g.K[-1], ref.K, rtol=1e-2)
    # default terminal cost: the catch's S, so every step's gain is the dlqr gain
    g2 = tvlqr(model, _Hold(model.x_eq, model.u_eq, 0.5), Q, R)
    np.testing.assert_allclose(g2.K, np.broadcast_to(ref.K, g2.K.shape), rtol=1e-8, atol=1e-10)


def test_riccati_backward_on_a_random_lti_system_with_two_inputs():
    from cartpole.riccati import riccati_backward

    rng = np.random.default_rng(4)
    A = np.eye(5) + 0.05 * rng.normal(size=(5, 5))
    B = 0.1 * rng.normal(size=(5, 2))
    Q, R = np.diag(rng.uniform(0.5, 2.0, 5)), np.diag([0.3, 0.8])
    K, S = riccati_backward(np.tile(A, (400, 1, 1)), np.tile(B, (400, 1, 1)), Q, R, np.zeros((5, 5)))
    assert K.shape == (400, 2, 5) and S.shape == (401, 5, 5)
    ref = dlqr(A, B, Q, R)
    np.testing.assert_allclose(K[0], ref.K, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(S[0], ref.S, rtol=1e-8, atol=1e-12)
    # the last step of a zero terminal cost is the one-step problem: K = 0, S = Q
    np.testing.assert_allclose(K[-1], 0.0, atol=0)
    np.testing.assert_allclose(S[-2], Q, atol=0)
    with pytest.raises(LQRError, match="riccati_backward needs"):
        riccati_backward(np.zeros((3, 5, 5)), np.zeros((4, 5, 2)), Q, R, Q)
