"""Moving-horizon estimation: tracks a swinging cart from quantised encoders, equals the batch least squares and the
Kalman filter (computed here in numpy) on a linear plant, keeps positions inside the joints' ranges (against SciPy's
bounded least squares), and refuses bad settings in one sentence."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import lsq_linear

from cartpole.errors import CartPoleError
from cartpole.estimation import EstimationError
from cartpole.estimation.mhe import MHEOptions, MovingHorizonEstimator, bench_mhe, horizon_periods
from cartpole.estimation.noise import process_covariance
from cartpole.models import SHIPPED_MJCF, build_model


@pytest.fixture(scope="module")
def model():
    return build_model(SHIPPED_MJCF)


def _encoders(model, joints=None):
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    joints = list(range(model.nq)) if joints is None else list(joints)
    return ca.Function("h", [x, u], [ca.vertcat(*[x[j] for j in joints])])


class LinearPlant:
    """A linear plant x+ = A1 x + B1 u per physics step (the cart's linearisation at hanging), in the shape the
    estimator reads from a model."""

    def __init__(self, model):
        A1, B1 = (np.asarray(M) for M in model.ABd(model.x_hanging, model.u_hanging))
        self.A1, self.B1 = A1, B1
        self.nq, self.nx, self.nu, self.dt = model.nq, model.nx, model.nu, model.dt
        x, u = ca.SX.sym("x", self.nx), ca.SX.sym("u", self.nu)
        self.step = ca.Function("linear_step", [x, u], [ca.mtimes(ca.DM(A1), x) + ca.mtimes(ca.DM(B1), u)])

    def period(self, m):
        """(Ad, [G_0 .. G_m-1]): x_k+1 = Ad x_k + sum_i G_i U[:, i]."""
        P = [np.linalg.matrix_power(self.A1, m - 1 - i) @ self.B1 for i in range(m)]
        return np.linalg.matrix_power(self.A1, m), P


def _linear_data(plant, m, K, C, D, W_true, V, seed):
    """Truth, ctrl (K, nu, m) and measurements (K+1, ny) of the linear plant; u_j is the last ctrl before sample j."""
    rng = np.random.default_rng(seed)
    Ad, G = plant.period(m)
    x = np.zeros(plant.nx)
    x[1] = 0.05
    X, Us = [x], []
    for k in range(K):
        U = 0.5 * rng.standard_normal((plant.nu, m))
        x = Ad @ x + sum(G[i] @ U[:, i] for i in range(m)) + rng.multivariate_normal(np.zeros(plant.nx), W_true)
        X.append(x)
        Us.append(U)
    uh = [np.zeros(plant.nu)] + [U[:, -1] for U in Us]
    Y = np.array([C @ X[j] + D @ uh[j] + rng.multivariate_normal(np.zeros(len(V)), V) for j in range(K + 1)])
    return np.array(X), Us, uh, Y


def _linear_h(plant, C, D):
    x, u = ca.SX.sym("x", plant.nx), ca.SX.sym("u", plant.nu)
    return ca.Function("h_lin", [x, u], [ca.mtimes(ca.DM(C), x) + ca.mtimes(ca.DM(D), u)])


def _batch_least_squares(plant, m, C, D, V, W, P0, xbar, Us, uh, Y, bounds=None):
    """The whole problem in the stacked states x_0..x_K: weighted rows, solved by numpy (or SciPy with bounds)."""
    nx = plant.nx
    K = len(Us)
    Ad, G = plant.period(m)
    RV, RW, RP = (np.linalg.inv(np.linalg.cholesky(M)) for M in (V, W, P0))
    rows, rhs = [], []

    def block(j, M):
        out = np.zeros((M.shape[0], nx * (K + 1)))
        out[:, j * nx:(j + 1) * nx] = M
        return out

    rows.append(block(0, RP))
    rhs.append(RP @ xbar)
    for j in range(K + 1):
        rows.append(block(j, RV @ C))
        rhs.append(RV @ (Y[j] - D @ uh[j]))
    for j in range(K):
        rows.append(block(j + 1, RW) - block(j, RW @ Ad))
        rhs.append(RW @ sum(G[i] @ Us[j][:, i] for i in range(m)))
    M, b = np.vstack(rows), np.concatenate(rhs)
    if bounds is None:
        return np.linalg.lstsq(M, b, rcond=None)[0].reshape(K + 1, nx)
    lo = np.tile(np.r_[bounds[:, 0], np.full(plant.nq, -np.inf)], K + 1)
    hi = np.tile(np.r_[bounds[:, 1], np.full(plant.nq, np.inf)], K + 1)
    sol = lsq_linear(M, b, bounds=(lo, hi), method="bvls", tol=1e-14, lsmr_tol="auto", max_iter=10_000)
    return sol.x.reshape(K + 1, nx)


LIN_C = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
LIN_D = np.array([[0.1], [0.0]])  # the cart's reading depends on the ctrl: exercises u_j in h(x_j, u_j)


def test_mhe_tracks_a_swinging_cart_from_quantised_encoders_rates_included(model):
    m, N, K = 2, 10, 300
    hold = model.hold(m)
    nq, nu = model.nq, model.nu
    A, _ = model.AB(model.x_hanging, model.u_hanging)
    w = np.abs(np.linalg.eigvals(np.asarray(A)).imag).max()  # the hanging pole's frequency: large swings
    x = model.x_hanging.copy()
    X, Us = [x], []
    for k in range(K):
        U = np.zeros((nu, m))
        for i in range(m):
            U[0, i] = 0.6 * np.sin(w * (k * m + i) * model.dt) - 0.5 * x[0] - 0.5 * x[nq]  # weak centring
        x = np.asarray(hold.step_inputs(x, U)).ravel()
        X.append(x)
        Us.append(U)
    X = np.array(X)
    hinge = model.hinges[0]
    assert np.ptp(X[:, hinge]) > 2.0 and np.abs(X[:, nq + hinge]).max() > 5.0  # swings of +-1 rad and more
    rng = np.random.default_rng(7)
    quantum, sd = np.array([1e-3, 2 * np.pi / 2048]), np.array([2e-3, 2e-3])
    Y = np.round((X[:, :nq] + sd * rng.standard_normal((K + 1, nq))) / quantum) * quantum
    est = MovingHorizonEstimator(model, m, _encoders(model), np.diag(sd ** 2 + quantum ** 2 / 12), accel_std=0.5,
                                 options=MHEOptions(horizon=N))
    est.reset(Y[0])
    Xh = np.array([est.update(Y[k + 1], Us[k]) for k in range(K)])
    err = (Xh - X[1:])[N:]
    rms = np.sqrt(np.mean(err ** 2, axis=0))
    meas_rms = np.sqrt(np.mean((Y - X[:, :nq]) ** 2, axis=0))
    period = m * model.dt
    fd_rms = np.sqrt(np.mean(((Y[2:] - Y[1:-1]) / period - X[2:, nq:])[N:] ** 2, axis=0))  # differenced encoders
    assert np.all(rms[:nq] < 0.6 * meas_rms), (rms, meas_rms)
    assert np.all(rms[nq:] < 0.1 * fd_rms), (rms, fd_rms)
    assert np.all(rms[nq:] < 0.01 * np.sqrt(np.mean(X[:, nq:] ** 2, axis=0)))
    assert est.failures == []


@pytest.mark.parametrize("compiled", [True, False])
def test_unconstrained_mhe_on_a_linear_plant_is_the_batch_least_squares(model, compiled):
    plant = LinearPlant(model)
    m, K = 3, 14
    V = np.diag([1e-4, 4e-4])
    W = np.diag([1e-6, 2e-6, 1e-4, 3e-4])
    P0 = np.diag([1e-2, 1e-2, 1.0, 1.0])
    _, Us, uh, Y = _linear_data(plant, m, K, LIN_C, LIN_D, W, V, seed=3)
    xbar = np.r_[Y[0] - LIN_D @ uh[0], 0.2, -0.1]
    est = MovingHorizonEstimator(plant, m, _linear_h(plant, LIN_C, LIN_D), V, W=W, initial_state=lambda y0: xbar,
                                 options=MHEOptions(horizon=K + 5, P0=P0, compiled=compiled,
                                                    joint_ranges=np.full((plant.nq, 2), [-np.inf, np.inf])))
    assert (est.library is not None) == compiled
    est.reset(Y[0])
    for k in range(K):
        x_hat = est.update(Y[k + 1], Us[k])
    ref = _batch_least_squares(plant, m, LIN_C, LIN_D, V, W, P0, xbar, Us, uh, Y)
    np.testing.assert_allclose(x_hat, ref[-1], rtol=0, atol=1e-8)
    np.testing.assert_allclose(est.window, ref, rtol=0, atol=1e-8)


def test_sliding_mhe_on_a_linear_plant_is_the_kalman_filter_with_a_singular_process_covariance(model):
    plant = LinearPlant(model)
    m, N, K = 2, 3, 25
    period = m * plant.dt
    W = process_covariance(3.0, period, plant.nq)  # rank nq: the noise lives in its range
    V = np.diag([1e-4, 4e-4])
    P0 = np.diag([1e-2, 1e-2, 1.0, 1.0])
    _, Us, uh, Y = _linear_data(plant, m, K, LIN_C, LIN_D, W, V, seed=5)
    xbar = np.zeros(plant.nx)
    est = MovingHorizonEstimator(plant, m, _linear_h(plant, LIN_C, LIN_D), V, W=W, initial_state=lambda y0: xbar,
                                 options=MHEOptions(horizon=N, P0=P0,
                                                    joint_ranges=np.full((plant.nq, 2), [-np.inf, np.inf])))
    est.reset(Y[0])
    mhe = [est.update(Y[k + 1], Us[k]) for k in range(K)]
    Ad, G = plant.period(m)
    x, P = xbar.copy(), P0.copy()
    kf = []
    for j in range(K + 1):
        if j:
            x = Ad @ x + sum(G[i] @ Us[j - 1][:, i] for i in range(m))
            P = Ad @ P @ Ad.T + W
        gain = P @ LIN_C.T @ np.linalg.inv(LIN_C @ P @ LIN_C.T + V)
        x = x + gain @ (Y[j] - LIN_C @ x - LIN_D @ uh[j])
        P = (np.eye(plant.nx) - gain @ LIN_C) @ P
        kf.append(x)
    np.testing.assert_allclose(np.array(mhe), np.array(kf[1:]), rtol=0, atol=1e-8)
    np.testing.assert_allclose(est.arrival[1], est.arrival[1].T)  # the arrival covariance stays symmetric


def test_a_measurement_beyond_the_rail_gives_an_estimate_on_it(model):
    lo, hi = model.params.joint_ranges[model.slide]
    assert np.isfinite(hi)
    m, N = 2, 10
    est = MovingHorizonEstimator(model, m, _encoders(model), np.diag([1e-6, 1e-6]), accel_std=1.0,
                                 options=MHEOptions(horizon=N))
    y = np.array(model.x_hanging[:model.nq])
    y[model.slide] = hi + 0.3
    x0 = est.reset(y)
    assert lo <= x0[model.slide] <= hi
    U = np.zeros((model.nu, m))
    for _ in range(2 * N):
        x_hat = est.update(y, U)
        assert np.all(est.window[:, model.slide] <= hi) and np.all(est.window[:, model.slide] >= lo)
    assert x_hat[model.slide] == pytest.approx(hi, abs=1e-6)  # as close to the reading as the rail allows
    assert est.failures == []


def test_beyond_the_rail_with_a_fine_encoder_the_window_qp_meets_its_kkt_conditions(model, monkeypatch):
    # a 1 um slide quantum weighs a reading ~1e13 per m^2 against 1 per noise entry (cond(H) ~ 1e13): DAQP alone
    # called this feasible QP infeasible (its zero_tol), and when scaled, stopped on the wrong active set
    import cartpole.estimation.mhe as mhe_module
    from cartpole.estimation.mhe_functions import solve_window_qp

    seen = []

    def spy(H, g, S, c, q, joints, low, high):
        z = solve_window_qp(H, g, S, c, q, joints, low, high)
        seen.append((H, g, S[:, joints, :].reshape(-1, H.shape[0]), (q + c[:, joints]).ravel(), low, high, z))
        return z

    monkeypatch.setattr(mhe_module, "solve_window_qp", spy)
    lo, hi = model.params.joint_ranges[model.slide]
    m, N = 2, 10
    est = MovingHorizonEstimator(model, m, _encoders(model), np.diag([1e-12 / 12, 1e-6]), accel_std=1.0,
                                 options=MHEOptions(horizon=N, c_step=False))  # the Python step's QP, spied on
    y = np.array(model.x_hanging[:model.nq])
    est.reset(y)
    for k in range(2 * N):
        y[model.slide] = hi + 0.12 + 0.02 * np.sin(0.4 * k)
        est.update(y, np.zeros((model.nu, m)))
    bounded = 0
    for H, g, rows, v, low, high, z in seen:
        r = v + rows @ z
        up = np.flatnonzero(r >= high - 1e-9)
        if not up.size:
            continue
        bounded += 1
        assert np.all(r <= high + 1e-9) and np.all(r >= low - 1e-9)  # feasible
        grad = H @ z + g  # stationarity with multipliers >= 0 on the rows held at the upper limit
        mu, *_ = np.linalg.lstsq(rows[up].T, -grad, rcond=None)
        assert np.all(mu >= 0)
        assert np.abs(grad + rows[up].T @ mu).max() <= 1e-12 * np.abs(H).max() * max(1.0, np.abs(z).max())
    assert bounded >= N and est.failures == []
    assert est.window[-1, model.slide] == pytest.approx(hi, abs=1e-9)


def test_bounded_mhe_on_a_linear_plant_is_scipys_bounded_least_squares(model):
    plant = LinearPlant(model)
    m, K = 2, 12
    V = np.diag([1e-4, 4e-4])
    W = np.diag([1e-6, 2e-6, 1e-4, 3e-4])
    P0 = np.diag([1e-2, 1e-2, 1.0, 1.0])
    _, Us, uh, Y = _linear_data(plant, m, K, LIN_C, LIN_D, W, V, seed=11)
    Y[6:, 0] += 0.2  # the cart's reading jumps beyond its range
    bounds = np.array([[-0.05, 0.05], [-np.inf, np.inf]])
    xbar = np.zeros(plant.nx)
    est = MovingHorizonEstimator(plant, m, _linear_h(plant, LIN_C, LIN_D), V, W=W, initial_state=lambda y0: xbar,
                                 options=MHEOptions(horizon=K, P0=P0, joint_ranges=bounds))
    est.reset(Y[0])
    for k in range(K):
        est.update(Y[k + 1], Us[k])
    ref = _batch_least_squares(plant, m, LIN_C, LIN_D, V, W, P0, xbar, Us, uh, Y, bounds=bounds)
    assert np.isclose(ref[:, 0], 0.05).sum() >= 3  # the bound is active at several nodes
    np.testing.assert_allclose(est.window, ref, rtol=0, atol=1e-7)


def test_the_default_first_estimate_takes_measured_positions_and_hangs_the_rest(model):
    est = MovingHorizonEstimator(model, 2, _encoders(model, [model.slide]), [1e-6], options=MHEOptions(horizon=3))
    x0 = est.reset([0.3])
    expected = np.array(model.x_hanging, dtype=float)
    expected[model.slide] = 0.3
    expected[model.nq:] = 0.0
    np.testing.assert_array_equal(x0, expected)


def test_horizon_in_seconds_is_whole_periods():
    assert horizon_periods(0.1, 0.01) == 10
    assert horizon_periods(0.02, 0.02) == 1


def _one_sentence(err):
    assert isinstance(err.value, CartPoleError)
    msg = str(err.value)
    assert "\n" not in msg and msg.endswith("."), msg


@pytest.mark.parametrize("kwargs", [{"horizon": 0}, {"horizon": 2.5}, {"horizon": -3}, {"horizon": "ten"},
                                    {"V": np.diag([1e-6, -1e-6])}, {"V": np.array([[1.0, 0.5], [0.0, 1.0]])},
                                    {"V": np.eye(3)}, {"W": -np.eye(4)}, {"W": np.eye(4), "accel_std": 1.0},
                                    {"P0": np.zeros((4, 4))}, {"steps": 0}, {"joint_ranges": [[1.0, -1.0]] * 2}])
def test_bad_settings_are_one_sentence(model, kwargs):
    args = {"steps": 2, "V": np.diag([1e-6, 1e-6]), **kwargs}
    window = {k: args.pop(k) for k in ("horizon", "P0", "joint_ranges") if k in args}
    with pytest.raises(EstimationError) as err:
        MovingHorizonEstimator(model, args.pop("steps"), _encoders(model), args.pop("V"), **args,
                               options=MHEOptions(**window))
    _one_sentence(err)


@pytest.mark.parametrize("horizon, period", [(0.105, 0.01), (0.0, 0.01), (-0.1, 0.01), (0.1, 0.0), ("a", 0.01)])
def test_a_horizon_that_is_not_whole_periods_is_one_sentence(horizon, period):
    with pytest.raises(EstimationError) as err:
        horizon_periods(horizon, period)
    _one_sentence(err)


def test_bad_measurements_and_ctrl_are_one_sentence(model):
    est = MovingHorizonEstimator(model, 2, _encoders(model), np.diag([1e-6, 1e-6]), options=MHEOptions(horizon=3))
    with pytest.raises(EstimationError) as err:
        est.update([0.0, np.pi], np.zeros((1, 2)))  # before reset
    _one_sentence(err)
    est.reset([0.0, np.pi])
    for y, U in [([0.0], np.zeros((1, 2))), ([0.0, np.nan], np.zeros((1, 2))), ([0.0, np.pi], np.zeros((1, 3)))]:
        with pytest.raises(EstimationError) as err:
            est.update(y, U)
        _one_sentence(err)


def test_bench_reports_the_step_time_and_small_errors():
    out = bench_mhe(n=60, horizon=0.05, period=0.01)
    assert out["N"] == 5 and out["n"] == 60
    assert 0 < out["step_ms_median"] <= out["step_ms_max"]
    assert len(out["rms_error"]) == 4 and max(out["rms_error"]) < 0.1


def test_options_of_another_kind_are_one_sentence(model):
    with pytest.raises(EstimationError, match="The MHE's options must be an MHEOptions") as err:
        MovingHorizonEstimator(model, 2, _encoders(model), np.diag([1e-6, 1e-6]), options={"horizon": 3})
    _one_sentence(err)
    with pytest.raises(EstimationError, match="MHEOptions.P0 must be numbers") as err:
        MHEOptions(P0="wide")
    _one_sentence(err)
