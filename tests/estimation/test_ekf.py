"""The extended Kalman filter: its prediction is m physics steps of the model with a ctrl per step and its Jacobian
(central differences), it tracks a swinging pole from quantised encoders (and from a nonlinear tip sensor) where
the Kalman filter linearised at upright fails, it is the Kalman filter once its covariance has converged on a linear
model with a linear measurement, a whole turn of the pole moves its estimate a whole turn, and it refuses bad calls."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from cartpole.estimation import EstimationError
from cartpole.estimation.ekf import (
    INITIAL_RATE_STD,
    UNMEASURED_POSITION_STD,
    ExtendedKalmanFilter,
    bench_ekf,
    default_initial_covariance,
)
from cartpole.estimation.kalman import KalmanFilter
from cartpole.models import SHIPPED_MJCF, build_model, hold_model, state_error

M = 2  # physics steps per period: 10 ms on the shipped 5 ms cart
RESOLUTION = np.array([1e-3, 2 * np.pi / 2048])  # m, rad: 1 mm on the cart, 2048 counts a turn on the pole


@pytest.fixture(scope="module")
def model():
    return build_model(SHIPPED_MJCF)


def _sym(model):
    return ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)


def encoders(model):
    x, u = _sym(model)
    return ca.Function("h", [x, u], [x[:model.nq]])


def tip_sensor(model, length=0.6):
    """Cart encoder and the world x, z of a point ``length`` m along the pole (z from the hinge)."""
    x, u = _sym(model)
    s, th = x[model.slide], x[model.hinges[0]]
    return ca.Function("h_tip", [x, u], [ca.vertcat(s, s + length * ca.sin(th), length * ca.cos(th))])


def encoder_noise(fraction=0.25):
    noise = fraction * RESOLUTION
    return noise, np.diag(RESOLUTION ** 2 / 12 + noise ** 2)


def swing(model, periods=600, amp=0.4, omega=5.0):
    """The exact held model from hanging under ctrl amp cos(omega t) (changing inside each period): the pole swings
    up to about 2 rad either side of hanging. Returns the states (periods+1, nx) and the ctrl per period."""
    hold = model.hold(M)
    xs, Us = [np.array(model.x_hanging, dtype=float)], []
    for k in range(periods):
        t = (k * M + np.arange(M)) * model.dt
        U = amp * np.cos(omega * t)[None, :] + model.u_hanging[:, None]
        Us.append(U)
        xs.append(np.asarray(hold.step_inputs(xs[-1], U)).ravel())
    return np.array(xs), Us


def run(est, ys, Us):
    out = [est.reset(ys[0])]
    out += [est.update(y, U) for y, U in zip(ys[1:], Us)]
    return np.array(out)


def quantised(xs, model, noise, seed):
    rng = np.random.default_rng(seed)
    q = xs[:, :model.nq] + noise * rng.standard_normal((len(xs), model.nq))
    return RESOLUTION * np.round(q / RESOLUTION)


def test_prediction_is_m_physics_steps_and_its_jacobian(model):
    """With a measurement it all but ignores (V = 1e12) the update is the prediction: m calls of the one-step model
    with the ctrl of each step, and a covariance A P0 A' + W with A by central differences of those m calls."""
    x0 = np.array(model.x_hanging, dtype=float)
    x0[model.hinges[0]] -= 1.2
    P0 = np.diag(np.linspace(0.1, 0.4, model.nx))
    ekf = ExtendedKalmanFilter(model, M, encoders(model), 1e12, P0=P0, initial_state=lambda y: x0.copy())
    ekf.reset(np.zeros(model.nq))
    U = np.array([[0.3, -0.7]])

    def m_steps(x):
        for j in range(M):
            x = model.step_np(x, U[:, j])
        return x

    x1 = ekf.update(np.asarray(encoders(model)(m_steps(x0), 0)).ravel(), U)
    np.testing.assert_allclose(x1, m_steps(x0), atol=1e-10)
    eps = 1e-6
    A = np.column_stack([(m_steps(x0 + eps * e) - m_steps(x0 - eps * e)) / (2 * eps) for e in np.eye(model.nx)])
    np.testing.assert_allclose(ekf.P, A @ P0 @ A.T + ekf.W, rtol=1e-6, atol=1e-9)


def test_tracks_a_swing_from_encoders_where_the_upright_kalman_filter_fails(model):
    xs, Us = swing(model)
    th = model.hinges[0]
    assert np.ptp(xs[:, th]) > 3.0  # the pole swings through large angles
    noise, V = encoder_noise()
    ys = quantised(xs, model, noise, seed=3)
    ekf = ExtendedKalmanFilter(model, M, encoders(model), V)
    ekf_err = state_error(run(ekf, ys, Us), xs, model.hinges)[100:]  # after a 1 s transient
    kf_err = state_error(run(KalmanFilter(model, M, encoders(model), V), ys, Us), xs, model.hinges)[100:]
    rms_ekf = np.sqrt(np.mean(ekf_err ** 2, axis=0))
    rms_kf = np.sqrt(np.mean(kf_err ** 2, axis=0))
    sd = np.sqrt(np.diag(ekf.P))  # the EKF's own claim at the end (the truth has no process noise: it is within)
    assert np.all(rms_ekf <= sd), (rms_ekf, sd)
    assert np.all(rms_ekf[:model.nq] <= 2 * RESOLUTION)  # positions: within two counts of the encoders
    # the KF linearised at upright: worse on every state, its pole rate off by a tenth of a swing's
    assert np.all(rms_kf > 2 * rms_ekf), (rms_kf, rms_ekf)
    rate = model.nq + th
    assert rms_kf[rate] > 10 * rms_ekf[rate] and rms_kf[rate] > 0.05 * np.abs(xs[:, rate]).max()


def test_tracks_a_swing_from_a_nonlinear_tip_sensor(model):
    xs, Us = swing(model)
    h = tip_sensor(model)
    std = np.array([3e-4, 1e-3, 1e-3])
    rng = np.random.default_rng(4)
    ys = np.array([np.asarray(h(x, 0)).ravel() for x in xs]) + std * rng.standard_normal((len(xs), 3))
    x_start = np.array(xs[0])
    ekf = ExtendedKalmanFilter(model, M, h, np.diag(std ** 2), initial_state=lambda y: np.r_[
        y[0], x_start[1:model.nq], np.zeros(model.nq)])
    err = state_error(run(ekf, ys, Us), xs, model.hinges)[100:]
    rms = np.sqrt(np.mean(err ** 2, axis=0))
    assert np.all(rms <= np.sqrt(np.diag(ekf.P))), rms
    # the default first covariance: the cart from its encoder's variance; the angle is not read one-to-one
    P0 = default_initial_covariance(h, model, np.diag(std ** 2))
    expected = np.r_[np.full(model.nq, UNMEASURED_POSITION_STD ** 2), np.full(model.nq, INITIAL_RATE_STD ** 2)]
    expected[model.slide] = std[0] ** 2
    np.testing.assert_array_equal(P0, np.diag(expected))


class LinearCart:
    """The cart linearised at hanging, x+ = x* + A1 (x - x*) + B1 (u - u*) per physics step, shaped like a model."""

    def __init__(self, model):
        self.nq, self.nx, self.nu, self.dt = model.nq, model.nx, model.nu, model.dt
        self.hinges, self.slides = model.hinges, model.slides
        self.x_eq, self.u_eq = np.array(model.x_hanging), np.array(model.u_hanging)
        self.x_hanging = self.x_eq
        self.A1, self.B1 = model.linearize(self.x_eq, self.u_eq, discrete=True)
        x, u = ca.SX.sym("x", self.nx), ca.SX.sym("u", self.nu)
        nxt = self.x_eq + ca.mtimes(ca.DM(self.A1), x - self.x_eq) + ca.mtimes(ca.DM(self.B1), u - self.u_eq)
        self.step = ca.Function("linear_step", [x, u], [nxt])
        self._hold = {}

    def linearize(self, x=None, u=None, *, discrete=True):
        return self.A1, self.B1

    def hold(self, m):
        return self._hold.setdefault(m, hold_model(self, m))


def test_equals_the_kalman_filter_on_a_linear_model_once_converged(model):
    lin = LinearCart(model)
    x, u = _sym(model)
    s, th = model.slide, model.hinges[0]
    h = ca.Function("h_lin", [x, u], [ca.vertcat(x[s], x[s] + 0.6 * x[th], x[th])])  # linear, not a selection
    V = np.diag([1e-7, 4e-7, 1e-6])
    kf = KalmanFilter(lin, M, h, V)
    ekf = ExtendedKalmanFilter(lin, M, h, V)  # both start from the encoders, the rest hanging, zero rates
    rng = np.random.default_rng(8)
    hold = lin.hold(M)
    xt = np.array(lin.x_eq, dtype=float)
    xt[th] += 0.3
    ys, Us = [], []
    for k in range(800):
        ys.append(np.asarray(h(xt, 0)).ravel() + np.sqrt(np.diag(V)) * rng.standard_normal(3))
        U = 0.3 * rng.standard_normal((model.nu, M))
        Us.append(U)
        xt = np.asarray(hold.step_inputs(xt, U)).ravel() + 1e-3 * rng.standard_normal(model.nx)
    a = run(kf, ys, Us[:-1])
    b = run(ekf, ys, Us[:-1])
    assert np.abs(a[1] - b[1]).max() > 1e-4  # the EKF starts with another gain ...
    np.testing.assert_allclose(ekf.P, kf.P_post, rtol=1e-8, atol=1e-8 * np.abs(kf.P_post).max())
    np.testing.assert_allclose(ekf.K, kf.L, rtol=1e-8, atol=1e-8 * np.abs(kf.L).max())
    np.testing.assert_allclose(b[-100:], a[-100:], rtol=0, atol=1e-8)  # ... and ends with the same estimates


def test_a_whole_turn_of_the_pole_gives_the_estimate_a_whole_turn_away(model):
    xs, Us = swing(model, periods=200)
    noise, V = encoder_noise()
    ys = quantised(xs, model, noise, seed=9)
    turn = np.zeros(model.nq)
    turn[model.hinges[0]] = 2 * np.pi
    ekf = ExtendedKalmanFilter(model, M, encoders(model), V)
    a = run(ekf, ys, Us)
    b = run(ekf, ys + turn, Us)
    np.testing.assert_allclose(b - a, np.tile(np.r_[turn, np.zeros(model.nq)], (len(a), 1)), atol=1e-8)


def test_refusals_are_one_sentence(model):
    ekf = ExtendedKalmanFilter(model, M, encoders(model), encoder_noise()[1])
    with pytest.raises(EstimationError, match="reset"):
        ekf.update(np.zeros(model.nq), np.zeros((model.nu, M)))
    ekf.reset(np.zeros(model.nq))
    with pytest.raises(EstimationError, match="one column per physics step"):
        ekf.update(np.zeros(model.nq), np.zeros((model.nu, M + 1)))
    with pytest.raises(EstimationError, match="P0 is not positive definite"):
        ExtendedKalmanFilter(model, M, encoders(model), 1e-6, P0=np.zeros(model.nx))
    with pytest.raises(EstimationError, match="W is not positive semidefinite"):
        ExtendedKalmanFilter(model, M, encoders(model), 1e-6, W=-np.eye(model.nx))
    with pytest.raises(EstimationError, match="whole number"):
        ExtendedKalmanFilter(model, 0, encoders(model), 1e-6)


def test_bench_reports_a_median_update_time(model):
    out = bench_ekf(model, M, encoders(model), encoder_noise()[1], updates=50)
    assert out["updates"] == 50 and out["median_us"] > 0 and out["p90_us"] >= out["median_us"]
