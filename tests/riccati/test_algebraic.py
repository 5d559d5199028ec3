"""lqr / dlqr: the gain is SciPy's Riccati solution with python-control's sign (u = -K x), S is the true
cost-to-go, and every bad input raises LQRError with a sentence naming the problem."""
import numpy as np
import pytest
import scipy.linalg

from cartpole import Q_LAB, R_LAB, build_model
from cartpole.riccati import LQRError, dlqr, lqr


@pytest.fixture(scope="module")
def lab_matrices():
    model = build_model()
    A, B = model.linearize()
    Ad, Bd = model.linearize(discrete=True)
    return A, B, Ad, Bd


def _random_system(seed, n=4, m=2):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    L = rng.normal(size=(n, n))
    Q = L @ L.T + 0.1 * np.eye(n)
    M = rng.normal(size=(m, m))
    R = M @ M.T + 0.5 * np.eye(m)
    return A, B, Q, R


def test_continuous_gain_is_scipy_care_with_u_equals_minus_Kx(lab_matrices):
    A, B, _, _ = lab_matrices
    K, S, E = lqr(A, B, Q_LAB, R_LAB)
    S_ref = scipy.linalg.solve_continuous_are(A, B, Q_LAB, R_LAB)
    np.testing.assert_allclose(S, S_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(K, np.linalg.solve(R_LAB, B.T @ S_ref), rtol=1e-12, atol=1e-12)
    # python-control's convention: the closed loop is A - B K (u = -K x) and E are its eigenvalues
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(np.linalg.eigvals(A - B @ K)), atol=1e-9)
    assert E.real.max() < 0 and np.linalg.eigvals(A + B @ K).real.max() > 0


def test_discrete_gain_is_scipy_dare(lab_matrices):
    _, _, Ad, Bd = lab_matrices
    K, S, E = dlqr(Ad, Bd, Q_LAB, R_LAB)
    S_ref = scipy.linalg.solve_discrete_are(Ad, Bd, Q_LAB, R_LAB)
    np.testing.assert_allclose(S, S_ref, rtol=1e-10, atol=1e-10)
    K_ref = np.linalg.solve(R_LAB + Bd.T @ S_ref @ Bd, Bd.T @ S_ref @ Ad)
    np.testing.assert_allclose(K, K_ref, rtol=1e-10, atol=1e-12)
    assert np.abs(np.linalg.eigvals(Ad - Bd @ K)).max() < 1
    np.testing.assert_allclose(np.sort_complex(E), np.sort_complex(np.linalg.eigvals(Ad - Bd @ K)), atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_S_is_the_cost_to_go_of_the_closed_loop(seed):
    """Independent of the Riccati solver: S solves the closed-loop Lyapunov equation of cost Q + K'RK."""
    A, B, Q, R = _random_system(seed)
    K, S, _ = lqr(A, B, Q, R)
    Acl = A - B @ K
    P = scipy.linalg.solve_continuous_lyapunov(Acl.T, -(Q + K.T @ R @ K))
    np.testing.assert_allclose(S, P, rtol=1e-8, atol=1e-10)
    Ad = scipy.linalg.expm(0.05 * A)
    Bd = 0.05 * B
    Kd, Sd, _ = dlqr(Ad, Bd, Q, R)
    Acl = Ad - Bd @ Kd
    Pd = scipy.linalg.solve_discrete_lyapunov(Acl.T, Q + Kd.T @ R @ Kd)
    np.testing.assert_allclose(Sd, Pd, rtol=1e-8, atol=1e-10)


def test_scalar_R_and_1d_B_are_accepted(lab_matrices):
    A, B, _, _ = lab_matrices
    K1 = lqr(A, B, Q_LAB, 0.1).K
    K2 = lqr(A, B.ravel(), Q_LAB, [[0.1]]).K
    np.testing.assert_array_equal(K1, K2)


def test_result_unpacks_like_python_control(lab_matrices):
    A, B, _, _ = lab_matrices
    res = lqr(A, B, Q_LAB, R_LAB)
    K, S, E = res
    assert K is res.K and S is res.S and E is res.E and K.shape == (1, 4) and S.shape == (4, 4)


A2 = np.array([[0.0, 1.0], [2.0, 0.0]])
B2 = np.array([[0.0], [1.0]])


@pytest.mark.parametrize("A, B, Q, R, message", [
    (A2, B2, [[1.0, 0.5], [0.0, 1.0]], 1.0, "Q is not symmetric"),
    (A2, B2, np.diag([1.0, -0.5]), 1.0, "Q is not positive semidefinite"),
    (A2, B2, np.eye(2), 0.0, "R is not positive definite"),
    (A2, B2, np.eye(2), -1.0, "R is not positive definite"),
    (A2, np.eye(2), np.eye(2), [[1.0, 0.3], [0.0, 1.0]], "R is not symmetric"),
    (A2, np.ones((3, 1)), np.eye(2), 1.0, "B must have 2 rows"),
    (A2, B2, np.eye(3), 1.0, "Q has shape (3, 3) but must be (2, 2)"),
    (A2, B2, np.eye(2), np.eye(2), "R has shape (2, 2) but must be (1, 1)"),
    (np.ones((2, 3)), B2, np.eye(2), 1.0, "must be square"),
    (A2, np.array([0.0, np.nan]), np.eye(2), 1.0, "B contains NaN"),
    (A2, B2, np.diag([1.0, np.inf]), 1.0, "Q contains NaN or inf"),
])
@pytest.mark.parametrize("solver", [lqr, dlqr])
def test_bad_input_raises_its_message(solver, A, B, Q, R, message):
    with pytest.raises(LQRError, match=message.replace("(", r"\(").replace(")", r"\)")):
        solver(A, B, Q, R)


def test_unstabilisable_pair_is_named_with_its_mode():
    # second state unstable (eigenvalue 1) and untouched by the input
    A = np.array([[-1.0, 0.0], [0.0, 1.0]])
    B = np.array([[1.0], [0.0]])
    with pytest.raises(LQRError, match=r"not stabilisable: the mode with eigenvalue 1 "):
        lqr(A, B, np.eye(2), 1.0)
    Ad = np.array([[0.5, 0.0], [0.0, 1.2]])
    with pytest.raises(LQRError, match=r"not stabilisable: the mode with eigenvalue 1.2 "):
        dlqr(Ad, B, np.eye(2), 1.0)


def test_stabilisable_but_uncontrollable_pair_is_fine():
    # the uncontrollable mode is stable, so LQR exists
    A = np.array([[-1.0, 0.0], [0.0, 1.0]])
    B = np.array([[0.0], [1.0]])
    K, S, E = lqr(A, B, np.eye(2), 1.0)
    np.testing.assert_allclose(S, scipy.linalg.solve_continuous_are(A, B, np.eye(2), np.eye(1)), atol=1e-12)
    assert E.real.max() < 0


def test_cart_pole_without_actuator_on_the_cart_is_unstabilisable(lab_matrices):
    A, _, _, _ = lab_matrices
    with pytest.raises(LQRError, match="not stabilisable"):
        lqr(A, np.zeros((4, 1)), Q_LAB, R_LAB)


def _chain_model(name, chain_dir):
    from cartpole.models import SHIPPED_MJCF
    path = (SHIPPED_MJCF.with_name(f"cartpole_{name}.xml") if name in ("two_pole", "three_pole")
            else chain_dir / f"{name}.xml")
    return build_model(path)


@pytest.mark.parametrize("name", ["two_pole", "three_pole", "two_motors"])
def test_chains_of_poles_and_two_motors_give_a_stable_loop_and_a_small_residual(name, chain_dir):
    from cartpole.riccati import is_controllable, default_weights

    model = _chain_model(name, chain_dir)
    nx, nu = model.nx, model.nu
    Q, R = default_weights(model)
    A, B = model.linearize()
    Ad, Bd = model.linearize(discrete=True)
    assert is_controllable(A, B) and is_controllable(Ad, Bd)
    K, S, E = lqr(A, B, Q, R)
    assert K.shape == (nu, nx) and S.shape == (nx, nx) and E.shape == (nx,)
    assert np.linalg.eigvals(A - B @ K).real.max() < 0 and E.real.max() < 0
    care = A.T @ S + S @ A - S @ B @ np.linalg.solve(R, B.T @ S) + Q  # residual computed here, not by lqr
    assert np.abs(care).max() < 1e-9 * np.abs(S).max()
    np.testing.assert_allclose(S, S.T, atol=1e-12 * np.abs(S).max())
    assert np.linalg.eigvalsh(S).min() > 0
    Kd, Sd, Ed = dlqr(Ad, Bd, Q * model.dt, R * model.dt)
    assert Kd.shape == (nu, nx) and np.abs(np.linalg.eigvals(Ad - Bd @ Kd)).max() < 1
    Rd = R * model.dt
    dare = Ad.T @ Sd @ Ad - Sd - Ad.T @ Sd @ Bd @ np.linalg.solve(Rd + Bd.T @ Sd @ Bd, Bd.T @ Sd @ Ad) + Q * model.dt
    assert np.abs(dare).max() < 1e-9 * np.abs(Sd).max()
    # the same regulator as SciPy's
    np.testing.assert_allclose(S, scipy.linalg.solve_continuous_are(A, B, Q, R), rtol=1e-9, atol=1e-9)


def test_uncontrollable_modes_are_named_and_a_scalar_R_means_r_identity():
    from cartpole.riccati import is_controllable, uncontrollable_modes

    A = np.array([[-1.0, 0.0], [0.0, 1.0]])
    B = np.array([[0.0], [1.0]])
    np.testing.assert_allclose(uncontrollable_modes(A, B), [-1.0])
    assert uncontrollable_modes(A, B, discrete=False).size == 0  # stable, so still stabilisable
    assert not is_controllable(A, B) and is_controllable(A, np.ones((2, 1)))
    A, B, Q, R = _random_system(3, n=4, m=2)
    np.testing.assert_array_equal(lqr(A, B, Q, 0.7).K, lqr(A, B, Q, 0.7 * np.eye(2)).K)


@pytest.fixture(scope="module")
def shipped_model():
    import cartpole as cp

    return cp.build_model()


def test_lqr_on_a_plant_is_lqr_on_its_exact_linearisation_whatever_form_the_plant_takes(shipped_model):
    from cartpole.riccati import default_weights

    m = shipped_model
    Q, R = default_weights(m)
    on_matrices = lqr(*m.linearize(), Q, R)
    for plant in (m, m.params, m.params.mjcf):
        res = lqr(plant)
        np.testing.assert_allclose(res.K, on_matrices.K, rtol=1e-10)
        np.testing.assert_allclose(res.S, on_matrices.S, rtol=1e-10)
    # the python-control call shapes: positional, keyword, mixed, a lone R
    R1 = 1.0
    want = lqr(*m.linearize(), Q, R1).K
    for res in (lqr(m, Q, R1), lqr(m, Q=Q, R=R1), lqr(m, Q, R=R1), lqr(m, R=R1)):
        np.testing.assert_allclose(res.K, want, rtol=1e-10)
    with pytest.raises(LQRError, match="two weights"):
        lqr(m, Q, R1, R1)


def test_dlqr_on_a_plant_weighs_per_second_so_S_matches_the_continuous_design(shipped_model):
    m = shipped_model
    cont = lqr(m)
    disc = dlqr(m)
    from cartpole.riccati import default_weights

    Q, R = default_weights(m)
    per_sample = dlqr(*m.linearize(discrete=True), Q, R)
    np.testing.assert_allclose(disc.K, per_sample.K, rtol=1e-8)          # the scaling does not move the gain
    np.testing.assert_allclose(disc.S, per_sample.S * m.dt, rtol=1e-8)   # it scales S by the step
    assert np.abs(disc.S - cont.S).max() < 0.05 * np.abs(cont.S).max()  # S ~ the continuous one, O(dt)
    assert np.abs(per_sample.S - cont.S).max() > 10 * np.abs(cont.S).max()
    held = dlqr(m, period=4 * m.dt)
    Ad, Bd = m.hold(4).linearize()
    np.testing.assert_allclose(held.K, dlqr(Ad, Bd, Q, R).K, rtol=1e-8)
    assert np.abs(held.S - cont.S).max() < 0.2 * np.abs(cont.S).max()


def test_a_python_control_state_space_is_designed_as_python_control_designs_it(lab_matrices):
    control = pytest.importorskip("control")
    A, B, _, _ = lab_matrices
    sys = control.ss(A, B, np.eye(4), np.zeros((4, 1)))
    K, S, E = lqr(sys, Q_LAB, R_LAB)
    Kc, Sc, Ec = control.lqr(sys, Q_LAB, R_LAB)
    np.testing.assert_allclose(K, Kc, rtol=1e-8)
    np.testing.assert_allclose(S, Sc, rtol=1e-8)
    sysd = control.c2d(sys, 0.01)
    Kd, Sd, _ = dlqr(sysd, Q_LAB, R=R_LAB)
    Kdc, Sdc, _ = control.dlqr(sysd, Q_LAB, R_LAB)
    np.testing.assert_allclose(Kd, Kdc, rtol=1e-8)
    np.testing.assert_allclose(Sd, Sdc, rtol=1e-8)


@pytest.mark.parametrize("solver, dt, weights, message", [
    ("lqr", 0.01, 2, r"lqr was given a discrete-time system \(dt = 0.01\); design it with dlqr\(sys, Q, R\)"),
    ("dlqr", 0, 2, r"dlqr was given a continuous-time system \(dt = 0\); design it with lqr\(sys, Q, R\)"),
    ("lqr", 0, 1, r"needs both weights; call lqr\(sys, Q, R\)"),
])
def test_a_state_space_of_the_wrong_time_base_or_without_weights_is_refused(lab_matrices, solver, dt, weights,
                                                                            message):
    control = pytest.importorskip("control")
    A, B, _, _ = lab_matrices
    sys = control.ss(A, B, np.eye(4), np.zeros((4, 1)), dt)
    with pytest.raises(LQRError, match=message):
        {"lqr": lqr, "dlqr": dlqr}[solver](sys, *(Q_LAB, R_LAB)[:weights])


def test_a_diagonal_given_for_a_weight_matrix_says_how_to_make_it_one(lab_matrices):
    A, B, _, _ = lab_matrices
    with pytest.raises(LQRError, match=r"Q has shape \(4,\) but must be \(4, 4\) to match A and B; for a diagonal "
                                       r"of weights give np.diag\(q\)"):
        lqr(A, B, np.diag(Q_LAB), R_LAB)
