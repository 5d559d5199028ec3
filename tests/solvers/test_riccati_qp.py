"""The Riccati active-set QP (cartpole.solvers.riccati_qp) gives the stage QP's unique optimum, the one a dense QP
solver finds on the same problem written out in full, and reports what it cannot solve instead of answering wrong."""
import numpy as np
import pytest

from cartpole.solvers import riccati_qp

pytestmark = pytest.mark.skipif(not riccati_qp.available(4, 1), reason="no C compiler")


def _random_stage_qp(rng, N, nx, nu, *, rail=0.3, u_box=0.5):
    """A strictly convex stage QP in the SQP's layout: dynamics ``s_k+1 = ([Ax Au] s_k + Bx w_k + c_k, w_k)``, SPD
    stage Hessians, |input| <= ``u_box``, a bound on the first state entry of every knot (the rail) and the states
    of knot N pinned."""
    nz, ny = nx + nu, nx + 2 * nu
    T = np.zeros((N, nz, ny))
    T[:, :nx, :nz] = np.eye(nx, nz) + 0.1 * rng.standard_normal((N, nx, nz))
    T[:, :nx, nz:] = 0.1 * rng.standard_normal((N, nx, nu))
    T[:, nx:, nz:] = np.eye(nu)
    ct = 0.05 * rng.standard_normal((N, nx))
    Lh = rng.standard_normal((N, ny, ny)) / np.sqrt(ny)
    Hy = Lh @ Lh.transpose(0, 2, 1) + 0.05 * np.eye(ny)
    gy = rng.standard_normal((N, ny))
    lo = np.full((N + 1, nz), -np.inf)
    hi = np.full((N + 1, nz), np.inf)
    lo[:, nx:], hi[:, nx:] = -u_box, u_box
    lo[1:, 0], hi[1:, 0] = -rail, rail
    lo[N, :nx] = hi[N, :nx] = 0.02 * rng.standard_normal(nx)
    return T, ct, Hy, gy, lo, hi


def _dense_reference(T, ct, Hy, gy, lo, hi, n_free=0):
    """The same QP condensed onto ``v = (knot 0's free entries, w_0 .. w_N-1)`` (the last ``n_free`` states of knot
    0, then ``du_0``) and solved by DAQP: ``(dz (N+1, nz), input multipliers (N+1, nu), state-row multipliers
    (N+1, nx), knot 0's free states' multipliers (n_free,))``."""
    import daqp

    N, nz, ny = T.shape
    nu = ny - nz
    nx = nz - nu
    e0, n0 = nx - n_free, n_free + nu
    nv = n0 + N * nu
    # s_k = G_k v + g_k
    G = np.zeros((N + 1, nz, nv))
    g = np.zeros((N + 1, nz))
    G[0, e0:, :n0] = np.eye(n0)
    for k in range(N):
        Wk = np.zeros((nu, nv))
        Wk[:, n0 + k * nu:n0 + (k + 1) * nu] = np.eye(nu)
        G[k + 1] = T[k, :, :nz] @ G[k] + T[k, :, nz:] @ Wk
        g[k + 1] = T[k, :, :nz] @ g[k] + np.r_[ct[k], np.zeros(nu)]
    H = np.zeros((nv, nv))
    f = np.zeros(nv)
    for k in range(N):
        Wk = np.zeros((nu, nv))
        Wk[:, n0 + k * nu:n0 + (k + 1) * nu] = np.eye(nu)
        Y = np.vstack([G[k], Wk])
        y0 = np.r_[g[k], np.zeros(nu)]
        H += Y.T @ Hy[k] @ Y
        f += Y.T @ (Hy[k] @ y0 + gy[k])
    rows = [(k, i) for k in range(1, N + 1) for i in range(nx) if np.isfinite(lo[k, i]) or np.isfinite(hi[k, i])]
    A = np.array([G[k, i] for k, i in rows])
    big = 1e30
    vlo = np.r_[lo[0, e0:], lo[1:, nx:].ravel()]
    vhi = np.r_[hi[0, e0:], hi[1:, nx:].ravel()]
    bu = np.r_[np.minimum(vhi, big), [min(hi[k, i], big) - g[k, i] for k, i in rows]]
    bl = np.r_[np.maximum(vlo, -big), [max(lo[k, i], -big) - g[k, i] for k, i in rows]]
    sense = np.r_[np.zeros(nv), [5 if lo[k, i] == hi[k, i] else 0 for k, i in rows]].astype(np.int32)
    v, _, flag, info = daqp.solve(0.5 * (H + H.T), f, A, bu, bl, sense)
    assert flag == 1
    lam = np.asarray(info["lam"])
    dz = np.einsum("kij,j->ki", G, v) + g
    rows_lam = np.zeros((N + 1, nx))
    for (k, i), value in zip(rows, lam[nv:]):
        rows_lam[k, i] = value
    lam_u = np.vstack([lam[n_free:n0], lam[n0:nv].reshape(N, nu)])
    return dz, lam_u, rows_lam, lam[:n_free]


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("nx,nu", [(4, 1), (6, 2)])
def test_the_riccati_active_set_finds_the_dense_qps_optimum_and_multipliers(seed, nx, nu):
    rng = np.random.default_rng(seed)
    N = 30
    T, ct, Hy, gy, lo, hi = _random_stage_qp(rng, N, nx, nu)
    qp = riccati_qp.StageQP(N, nx, nu)
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 0
    dz, lam_u, lam_rows, _ = _dense_reference(T, ct, Hy, gy, lo, hi)
    scale = 1.0 + np.abs(dz).max()
    assert np.abs(qp.dz[1:] - dz[1:]).max() <= 1e-8 * scale
    assert np.abs(qp.dz[0, nx:] - dz[0, nx:]).max() <= 1e-8 * scale and np.all(qp.dz[0, :nx] == 0.0)
    # bound multipliers in CasADi's (and DAQP's) sign: positive at an upper bound
    assert np.abs(qp.nb[:, nx:] - lam_u).max() <= 1e-7 * (1.0 + np.abs(lam_u).max())
    assert np.abs(qp.nb[1:, :nx] - lam_rows[1:]).max() <= 1e-7 * (1.0 + np.abs(lam_rows).max())
    held = qp.active.reshape(N + 1, nx + nu)
    assert np.any(np.abs(held[1:N, nx:]) == 1), "the test QP should hold some input bounds"
    assert np.all(held[N, :nx] == 2)  # the pinned states: equalities, always held


def test_any_starting_active_set_ends_at_the_same_optimum():
    rng = np.random.default_rng(11)
    N, nx, nu = 40, 4, 1
    T, ct, Hy, gy, lo, hi = _random_stage_qp(rng, N, nx, nu)
    qp = riccati_qp.StageQP(N, nx, nu)
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 0
    first, final = qp.dz.copy(), qp.active.copy()
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 0 and qp.iterations == 1  # from its own answer: one pass
    qp.active[:] = rng.choice([-1, 0, 1], size=qp.active.size)  # nonsense: many wrong guesses
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 0
    # several active sets, each refactorising only the stages below its latest change: the same optimum
    assert qp.iterations > 2
    assert np.abs(qp.dz - first).max() <= 1e-9 and np.array_equal(qp.active, final)


def test_an_infeasible_qp_is_reported_not_answered():
    rng = np.random.default_rng(3)
    N, nx, nu = 20, 4, 1
    T, ct, Hy, gy, lo, hi = _random_stage_qp(rng, N, nx, nu)
    lo[:, nx:] = hi[:, nx:] = 0.0  # every input pinned at zero: the pinned end state is out of reach
    qp = riccati_qp.StageQP(N, nx, nu)
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 2


def test_a_qp_of_the_wrong_size_is_refused_in_one_sentence():
    qp = riccati_qp.StageQP(10, 4, 1)
    with pytest.raises(ValueError, match="entries where"):
        qp.solve(np.zeros((9, 5, 6)), np.zeros((10, 4)), np.zeros((10, 6, 6)), np.zeros((10, 6)),
                 np.zeros((11, 5)), np.zeros((11, 5)))


@pytest.mark.parametrize("seed", range(3))
def test_the_held_rows_penalty_changes_neither_the_solution_nor_the_multipliers(seed):
    rng = np.random.default_rng(100 + seed)
    N, nx, nu = 30, 4, 1
    T, ct, Hy, gy, lo, hi = _random_stage_qp(rng, N, nx, nu)
    answers = []
    for rho in (0.0, None, 1e8):
        qp = riccati_qp.StageQP(N, nx, nu)
        assert qp.solve(T, ct, Hy, gy, lo, hi, rho=rho) == 0
        answers.append((qp.dz.copy(), qp.nb.copy()))
    for dz, nb in answers[1:]:
        assert np.abs(dz - answers[0][0]).max() <= 1e-8 * (1.0 + np.abs(dz).max())
        assert np.abs(nb - answers[0][1]).max() <= 1e-6 * (1.0 + np.abs(nb).max())


def _kkt_reference(T, ct, Hy, gy, b):
    """The equality-constrained stage QP (no bounds but ``dx_0 = 0`` and ``dx_N = b``) by one sparse solve of its
    full KKT system (well conditioned in this form however unstable the dynamics): ``(s (N+1, nz), multipliers of
    dx_N = b (nx))``."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    N, nz, ny = T.shape
    nu = ny - nz
    nx = nz - nu
    ns, nw = (N + 1) * nz, N * nu
    n = ns + nw

    def y_index(k):
        return np.r_[k * nz + np.arange(nz), ns + k * nu + np.arange(nu)]

    H = sp.lil_matrix((n, n))
    g = np.zeros(n)
    for k in range(N):
        idx = y_index(k)
        H[np.ix_(idx, idx)] = H[np.ix_(idx, idx)].toarray() + Hy[k]
        g[idx] += gy[k]
    rows, rhs = [], []
    A = sp.lil_matrix((N * nz + 2 * nx, n))
    for k in range(N):
        r = k * nz + np.arange(nz)
        A[np.ix_(r, (k + 1) * nz + np.arange(nz))] = np.eye(nz)
        A[np.ix_(r, y_index(k))] = -T[k]
        rhs.append(np.r_[ct[k], np.zeros(nu)])
    A[np.ix_(N * nz + np.arange(nx), np.arange(nx))] = np.eye(nx)
    A[np.ix_(N * nz + nx + np.arange(nx), N * nz + np.arange(nx))] = np.eye(nx)
    rhs += [np.zeros(nx), b]
    m = A.shape[0]
    K = sp.bmat([[H, A.T], [A, None]]).tocsc()
    sol = spla.spsolve(K, np.r_[-g, np.concatenate(rhs)])
    return sol[:ns].reshape(N + 1, nz), sol[n + m - nx:]


def test_a_pinned_end_behind_a_long_unstable_horizon_is_met_exactly():
    """100 stages whose states grow 1.3x each (2.5e11 over the horizon) and cost nothing (the effort objective: the
    triple's kind of stage elimination): the held rows' penalty keeps the recursion a stabilised regulator, and the
    answer is the full KKT system's; without it the pinned end is missed by orders of magnitude."""
    rng = np.random.default_rng(7)
    N, nx, nu = 100, 4, 1
    T, ct, Hy, gy, lo, hi = _random_stage_qp(rng, N, nx, nu)
    T[:, :nx, :nx] = 1.3 * np.eye(nx) + 0.02 * rng.standard_normal((N, nx, nx))
    Hy[:, :nx, :] = Hy[:, :, :nx] = 0.0  # inputs cost, states do not
    lo[:, nx:], hi[:, nx:] = -np.inf, np.inf
    lo[1:N, 0], hi[1:N, 0] = -np.inf, np.inf  # no rail (the end stays pinned)
    s_ref, nu_ref = _kkt_reference(T, ct, Hy, gy, hi[N, :nx])
    qp = riccati_qp.StageQP(N, nx, nu)
    assert qp.solve(T, ct, Hy, gy, lo, hi, rho=0.0) == 0
    assert np.abs(qp.dz[N, :nx] - hi[N, :nx]).max() > 1.0  # the open-loop propagation loses the end
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 0
    scale = 1.0 + np.abs(s_ref).max()
    assert np.abs(qp.dz[1:] - s_ref[1:]).max() <= 1e-8 * scale
    assert np.abs(qp.dz[N, :nx] - hi[N, :nx]).max() <= 1e-10
    assert np.abs(qp.nb[N, :nx] - nu_ref).max() <= 1e-6 * (1.0 + np.abs(nu_ref).max())


@pytest.mark.parametrize("seed", range(3))
def test_a_parameter_free_at_knot_0_is_chosen_with_the_inputs(seed):
    """The last state free at knot 0 and carried unchanged (the SQP's time scale): the same optimum, and the
    multipliers of its bounds, as the dense QP's in which it is one more unknown."""
    rng = np.random.default_rng(200 + seed)
    N, nx, nu = 30, 5, 1
    T, ct, Hy, gy, lo, hi = _random_stage_qp(rng, N, nx, nu)
    T[:, nx - 1, :] = 0.0
    T[:, nx - 1, nx - 1] = 1.0  # p_k+1 = p_k
    ct[:, nx - 1] = 0.0
    T[:, :nx - 1, nx - 1] *= 5.0  # the parameter moves the others
    lo[1:, nx - 1], hi[1:, nx - 1] = -np.inf, np.inf  # free: not pinned at the end either
    lo[0, nx - 1], hi[0, nx - 1] = -0.03, 0.03  # bounded at knot 0 (held in one of the seeds)
    qp = riccati_qp.StageQP(N, nx, nu, n_free=1)
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 0
    dz, lam_u, lam_rows, lam_p = _dense_reference(T, ct, Hy, gy, lo, hi, n_free=1)
    scale = 1.0 + np.abs(dz).max()
    assert np.abs(qp.dz - dz).max() <= 1e-8 * scale
    assert np.all(qp.dz[0, :nx - 1] == 0.0) and abs(qp.dz[0, nx - 1]) > 1e-6  # it moved
    assert np.abs(qp.nb[:, nx:] - lam_u).max() <= 1e-7 * (1.0 + np.abs(lam_u).max())
    assert np.abs(qp.nb[1:, :nx] - lam_rows[1:]).max() <= 1e-7 * (1.0 + np.abs(lam_rows).max())
    assert abs(qp.nb[0, nx - 1] - lam_p[0]) <= 1e-7 * (1.0 + abs(lam_p[0]))
