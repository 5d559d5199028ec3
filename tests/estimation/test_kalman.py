"""The steady-state Kalman filter: its gain is SciPy's discrete Riccati solution; its period model is the held
model's linearisation; on the exact discrete cart with quantised encoders its rate estimates converge, its error
covariance over a long run is the steady-state posterior it claims, the lab's LQG settles as the LQR on the true
state does; hinge angles a whole turn away give the same estimate a turn away; unobservable states are named."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import scipy.linalg

from cartpole.estimation import EstimationError
from cartpole.estimation.kalman import KalmanFilter, kalman_gain, state_names
from cartpole.estimation.measurement import measured_positions, positions_initial_state
from cartpole.estimation.noise import process_covariance
from cartpole.riccati import dlqr, default_weights
from cartpole.models import SHIPPED_MJCF, build_model

M = 2  # physics steps per period: 10 ms on the shipped 5 ms cart
#: The lab's encoders: 1 mm on the cart, 2048 counts a turn on the pole (m, rad).
RESOLUTION = np.array([1e-3, 2 * np.pi / 2048])


@pytest.fixture(scope="module")
def model():
    return build_model(SHIPPED_MJCF)


def _sym(model):
    return ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)


def encoders(model):
    x, u = _sym(model)
    return ca.Function("h", [x, u], [x[:model.nq]])


def tip_sensor(model, length=0.6):
    """Cart encoder and the world x of a point ``length`` m along the pole: s + l sin(theta) (nonlinear)."""
    x, u = _sym(model)
    s, th = x[model.slide], x[model.hinges[0]]
    return ca.Function("h_tip", [x, u], [ca.vertcat(s, s + length * ca.sin(th))])


def encoder_noise(noise_fraction):
    """Per-axis noise std (m, rad) and the measurement covariance: quantisation res^2/12 plus the noise."""
    noise = noise_fraction * RESOLUTION
    return noise, np.diag(RESOLUTION ** 2 / 12 + noise ** 2)


def read_encoders(x, model, noise, rng):
    """Mid-tread quantised positions of ``x`` with Gaussian noise before the quantiser."""
    q = np.asarray(x[:model.nq]) + noise * rng.standard_normal(model.nq)
    return RESOLUTION * np.round(q / RESOLUTION)


# ---- the gain ---------------------------------------------------------------------------------------------------
def test_gain_is_scipys_riccati_solution_and_its_filter_gain():
    rng = np.random.default_rng(7)
    n, ny = 5, 2
    Ad = rng.standard_normal((n, n)) * 0.6
    Ad[0, 0] = 1.2  # an unstable mode the sensors must see
    C = rng.standard_normal((ny, n))
    G = rng.standard_normal((n, 2))
    W = G @ G.T  # singular, as the white-acceleration model is
    R = rng.standard_normal((ny, ny))
    V = R @ R.T + 0.1 * np.eye(ny)
    L, P, E = kalman_gain(Ad, C, W, V)
    P_ref = scipy.linalg.solve_discrete_are(Ad.T, C.T, W, V)
    L_ref = P_ref @ C.T @ np.linalg.inv(C @ P_ref @ C.T + V)
    np.testing.assert_allclose(P, P_ref, rtol=1e-9, atol=1e-9 * np.abs(P_ref).max())
    np.testing.assert_allclose(L, L_ref, rtol=1e-9, atol=1e-9 * np.abs(L_ref).max())
    E_ref = np.linalg.eigvals((np.eye(n) - L_ref @ C) @ Ad)
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(E_ref), atol=1e-9)
    assert np.abs(E).max() < 1


def test_filter_gain_on_the_cart_is_scipys(model):
    _, V = encoder_noise(0.5)
    kf = KalmanFilter(model, M, encoders(model), V)
    P_ref = scipy.linalg.solve_discrete_are(kf.A.T, kf.C.T, kf.W, kf.V)
    L_ref = P_ref @ kf.C.T @ np.linalg.inv(kf.C @ P_ref @ kf.C.T + kf.V)
    np.testing.assert_allclose(kf.P, P_ref, rtol=1e-9, atol=1e-9 * np.abs(P_ref).max())
    np.testing.assert_allclose(kf.L, L_ref, rtol=1e-9, atol=1e-9 * np.abs(L_ref).max())
    np.testing.assert_allclose(kf.P_post, P_ref - L_ref @ kf.C @ P_ref, atol=1e-9 * np.abs(P_ref).max())


def test_period_model_is_the_held_models_linearisation(model):
    kf = KalmanFilter(model, M, encoders(model), encoder_noise(0.5)[1])
    hold = model.hold(M)
    Ad, Bd = hold.linearize(model.x_eq, model.u_eq)
    np.testing.assert_allclose(kf.A, Ad, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(kf.B.reshape(model.nx, M, model.nu).sum(axis=1), Bd, rtol=1e-12, atol=1e-14)
    # with a ctrl per physics step: the held model's Jacobian with respect to every column of U
    A_U, B_U = (np.asarray(v) for v in hold.ABd_inputs(model.x_eq, np.tile(model.u_eq[:, None], (1, M))))
    np.testing.assert_allclose(kf.B, B_U, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(kf.A, A_U, rtol=1e-12, atol=1e-14)


def test_nonlinear_measurement_is_linearised_at_the_operating_point(model):
    h = tip_sensor(model)
    kf = KalmanFilter(model, M, h, np.diag([1e-7, 1e-6]))
    eps = 1e-6
    C_fd = np.column_stack([(np.asarray(h(model.x_eq + eps * e, model.u_eq)) - np.asarray(
        h(model.x_eq - eps * e, model.u_eq))).ravel() / (2 * eps) for e in np.eye(model.nx)])
    np.testing.assert_allclose(kf.C, C_fd, atol=1e-8)
    # the default first estimate: the cart from its encoder, the angle (not read one-to-one) from upright
    assert measured_positions(h, model.nq, model.nu) == ((0, model.slide),)
    x0 = kf.reset([0.1, 0.1 + 0.6 * np.sin(0.2)])
    expected = np.array(model.x_eq, dtype=float)
    expected[model.slide] = 0.1
    expected[model.nq:] = 0.0
    np.testing.assert_array_equal(x0, expected)


# ---- on the exact discrete model ---------------------------------------------------------------------------------
def _lqg_run(model, est, x0, K, noise, seed, periods):
    """The exact held model under u = u* - K (x_hat - x*) (x_hat the truth when est is None), quantised encoders;
    returns the true states (periods+1, nx) and the estimates (periods+1, nx)."""
    hold = model.hold(M)
    rng = np.random.default_rng(seed)
    xs = [np.array(x0, dtype=float)]
    xh = [est.reset(read_encoders(xs[0], model, noise, rng)) if est is not None else xs[0]]
    for _ in range(periods):
        u = np.clip(model.u_eq - K @ model.state_error(xh[-1]), model.u_low, model.u_high)
        xs.append(hold.step_np(xs[-1], u))
        y = read_encoders(xs[-1], model, noise, rng)
        xh.append(est.update(y, np.tile(u[:, None], (1, M))) if est is not None else xs[-1])
    return np.array(xs), np.array(xh)


def _lqr(model):
    Q, R = default_weights(model)
    return dlqr(*model.hold(M).linearize(), Q, R).K


def test_rate_estimates_converge_within_the_steady_posterior(model):
    noise, V = encoder_noise(0.5)
    kf = KalmanFilter(model, M, encoders(model), V)
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.slide], x0[model.hinges[0]] = 0.1, 0.08
    x0[model.nq + model.slide], x0[model.nq + model.hinges[0]] = 0.4, -0.8  # the filter starts at zero rates
    xs, xh = _lqg_run(model, kf, x0, _lqr(model), noise, seed=3, periods=300)
    err = xh - xs
    sd = np.sqrt(np.diag(kf.P_post))
    rates = slice(model.nq, model.nx)
    assert np.all(np.abs(err[0, rates]) > 3 * sd[rates])  # the start is far off ...
    # ... and within 0.2 s (the error's slowest eigenvalue is |E| ~ 0.7 a period) inside 3 sigma most of the time
    settled = err[20:]
    inside = np.mean(np.abs(settled) <= 3 * sd, axis=0)
    assert np.all(inside >= 0.95), inside
    assert np.all(np.sqrt(np.mean(settled ** 2, axis=0)) <= 1.5 * sd)


def test_error_covariance_over_a_long_run_is_the_steady_posterior(model):
    """Truth: the exact held model about hanging with process noise drawn from the filter's own W (white
    acceleration) and a small sinusoidal ctrl; measurements: encoders with noise half a count before the quantiser,
    which makes the quantisation error nearly white with variance res^2/12. The estimation error's covariance must
    then be P_post, within the sampling error estimated from batch means, and its normalised squared error (NEES)
    must average nx."""
    noise, V = encoder_noise(0.5)
    sigma = np.array([1.0, 3.0])
    kf = KalmanFilter(model, M, encoders(model), V, accel_std=sigma, x_op=model.x_hanging, u_op=model.u_hanging)
    hold = model.hold(M)
    T = hold.period
    G = np.vstack([0.5 * T * T * np.eye(model.nq), T * np.eye(model.nq)])
    np.testing.assert_allclose(kf.W, process_covariance(sigma, T, model.nq))
    rng = np.random.default_rng(11)
    n, skip = 16000, 200
    x = np.array(model.x_hanging, dtype=float)
    kf.reset(read_encoders(x, model, noise, rng))
    errs = np.empty((n, model.nx))
    for k in range(n):
        u = 0.05 * np.sin(2 * np.pi * 0.7 * k * T) + model.u_hanging
        x = hold.step_np(x, u) + G @ (sigma * rng.standard_normal(model.nq))
        errs[k] = kf.update(read_encoders(x, model, noise, rng), np.tile(u[:, None], (1, M))) - x
    e = errs[skip:]
    var = np.mean(e ** 2, axis=0)
    batches = np.array([np.mean(b ** 2, axis=0) for b in np.array_split(e, 40)])
    se = batches.std(axis=0, ddof=1) / np.sqrt(len(batches))
    p = np.diag(kf.P_post)
    assert np.all(np.abs(var - p) <= 4 * se), (var / p, se / p)
    assert np.all(np.abs(var / p - 1) < 0.15), var / p
    means = np.array([b.mean(axis=0) for b in np.array_split(e, 40)])
    assert np.all(np.abs(e.mean(axis=0)) <= 4 * means.std(axis=0, ddof=1) / np.sqrt(len(means)))  # unbiased
    nees = np.einsum("ki,ij,kj->k", e, np.linalg.inv(kf.P_post), e)
    assert abs(nees.mean() / model.nx - 1) < 0.1, nees.mean()


def test_lab_lqg_settles_as_the_lqr_on_the_true_state(model):
    """The default process noise on the lab's rig (2048 counts, 1 mm, 10 ms): from the lab's five starts the LQG
    on the exact discrete model settles (|theta| <= 0.05 rad thereafter) within 3 periods of the LQR that reads the
    true state, and over the last second its cart stays within 5 mm and its pole within 10 mrad of that LQR's."""
    noise, V = encoder_noise(0.25)
    kf = KalmanFilter(model, M, encoders(model), V)
    K = _lqr(model)
    th = model.hinges[0]
    starts = [(0.0, 5.0), (0.0, -5.0), (0.0, 8.0), (0.2, 3.0), (-0.3, -4.0)]  # the lab's (m, deg)
    period = model.hold(M).period
    n = round(3.0 / period)
    last = round(1.0 / period)
    for i, (s0, deg) in enumerate(starts):
        x0 = np.array(model.x_eq, dtype=float)
        x0[model.slide] += s0
        x0[th] += np.deg2rad(deg)
        times, runs = [], []
        for est in (None, kf):
            xs, _ = _lqg_run(model, est, x0, K, noise, seed=i, periods=n)
            out = np.flatnonzero(np.abs(xs[:, th] - model.x_eq[th]) > 0.05)
            times.append(0.0 if out.size == 0 else (out[-1] + 1) * period)
            runs.append(xs[-last:])
        assert abs(times[1] - times[0]) <= 3 * period + 1e-9, (s0, deg, times)
        gap = np.abs(runs[1] - runs[0]).max(axis=0)
        assert gap[model.slide] < 5e-3 and gap[th] < 1e-2, (s0, deg, gap)


def test_a_whole_turn_of_the_pole_gives_the_estimate_a_whole_turn_away(model):
    noise, V = encoder_noise(0.5)
    kf = KalmanFilter(model, M, encoders(model), V)
    rng = np.random.default_rng(5)
    th = model.hinges[0]
    turn = np.zeros(model.nq)
    turn[th] = 2 * np.pi
    ys = []
    for k in range(50):
        x = np.array(model.x_eq, dtype=float)
        x[model.slide] += 0.02 * k / 50
        x[th] += 0.05 * np.cos(k / 7)
        ys.append(read_encoders(x, model, noise, rng))
    U = [np.full((model.nu, M), 0.1 * np.sin(k / 5)) for k in range(50)]
    runs = []
    for shift in (np.zeros(model.nq), turn):
        out = [kf.reset(ys[0] + shift)]
        out += [kf.update(y + shift, u) for y, u in zip(ys[1:], U[:-1])]
        runs.append(np.array(out))
    diff = runs[1] - runs[0]
    np.testing.assert_allclose(diff[:, th], 2 * np.pi, atol=1e-9)
    np.testing.assert_allclose(np.delete(diff, th, axis=1), 0.0, atol=1e-9)


# ---- refusals ----------------------------------------------------------------------------------------------------
def test_pole_rate_sensor_alone_names_the_cart_position(model):
    x, u = _sym(model)
    h = ca.Function("h_rate", [x, u], [x[model.nq + model.hinges[0]]])
    with pytest.raises(EstimationError) as info:
        KalmanFilter(model, M, h, 1e-4)
    msg = str(info.value)
    assert msg.startswith("The cart position cannot be seen from these sensors")
    assert "pole" not in msg and msg.count(".") <= 2  # one sentence (a decimal point may appear)


def test_unobservable_states_are_named_by_default_index():
    Ad = np.eye(3)
    with pytest.raises(EstimationError, match=r"^x1 and x2 cannot be seen"):
        kalman_gain(Ad, [[1.0, 0.0, 0.0]], np.eye(3), 1.0)
    # an unobservable mode that decays is fine (detectable)
    _, _, E = kalman_gain(np.diag([1.0, 0.5]), [[1.0, 0.0]], np.eye(2), 1.0)
    assert np.abs(E).max() < 1


@pytest.mark.parametrize("W, V, match", [
    (-np.eye(2), 1.0, "W is not positive semidefinite"),
    (np.array([[1.0, 0.5], [0.0, 1.0]]), 1.0, "W is not symmetric"),
    (np.eye(2), 0.0, "V is not positive definite"),
    (np.eye(2), np.eye(2), r"V must be a finite \(1, 1\)"),
    (np.eye(3), 1.0, r"W must be a finite \(2, 2\)"),
])
def test_bad_covariances_are_refused_in_one_sentence(W, V, match):
    with pytest.raises(EstimationError, match=match):
        kalman_gain(np.array([[1.0, 0.01], [0.0, 1.0]]), [[1.0, 0.0]], W, V)


def test_bad_shapes_and_calls_are_refused(model):
    with pytest.raises(EstimationError, match="square"):
        kalman_gain(np.ones((2, 3)), [[1.0, 0.0, 0.0]], np.eye(2), 1.0)
    with pytest.raises(EstimationError, match="C must be"):
        kalman_gain(np.eye(2), [[1.0, 0.0, 0.0]], np.eye(2), 1.0)
    kf = KalmanFilter(model, M, encoders(model), encoder_noise(0.5)[1])
    with pytest.raises(EstimationError, match="reset"):
        kf.update(np.zeros(model.nq), np.zeros((model.nu, M)))
    kf.reset(np.zeros(model.nq))
    with pytest.raises(EstimationError, match="one column per physics step"):
        kf.update(np.zeros(model.nq), np.zeros((model.nu, M + 1)))
    with pytest.raises(EstimationError, match="measurement must be"):
        kf.update(np.zeros(model.nq + 1), np.zeros((model.nu, M)))
    with pytest.raises(EstimationError, match="not both"):
        KalmanFilter(model, M, encoders(model), 1e-6, W=np.eye(model.nx), accel_std=1.0)
    x = ca.SX.sym("x", model.nx + 1)
    with pytest.raises(EstimationError, match="must take"):
        KalmanFilter(model, M, ca.Function("h", [x, ca.SX.sym("u", model.nu)], [x[0]]), 1e-6)


def test_state_names_and_the_default_first_estimate(model):
    names = state_names(model)
    nq, s, th = model.nq, model.slide, model.hinges[0]
    assert (names[s], names[th], names[nq + s], names[nq + th]) == (
        "the cart position", "the pole angle", "the cart velocity", "the pole angular velocity")
    first = positions_initial_state(encoders(model), model, model.x_hanging)
    y0 = np.linspace(0.3, 2.0, nq)
    np.testing.assert_array_equal(first(y0), np.r_[y0, np.zeros(nq)])
    x, u = _sym(model)
    angle_only = ca.Function("h", [x, u], [x[th]])
    expected = np.array(model.x_hanging, dtype=float)
    expected[th], expected[nq:] = 0.7, 0.0
    np.testing.assert_array_equal(positions_initial_state(angle_only, model, model.x_hanging)([0.7]), expected)
