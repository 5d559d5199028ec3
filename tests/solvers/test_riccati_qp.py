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


def _dense_reference(T, ct, Hy, gy, lo, hi):
    """The same QP condensed onto the inputs ``v = (du_0, w_0 .. w_N-1)`` and solved by DAQP: ``(dz (N+1, nz),
    input multipliers (N+1, nu), state-row multipliers (N+1, nx))``."""
    import daqp

    N, nz, ny = T.shape
    nu = ny - nz
    nx = nz - nu
    nv = (N + 1) * nu
    # s_k = G_k v + g_k
    G = np.zeros((N + 1, nz, nv))
    g = np.zeros((N + 1, nz))
    G[0, nx:, :nu] = np.eye(nu)
    for k in range(N):
        Wk = np.zeros((nu, nv))
        Wk[:, (k + 1) * nu:(k + 2) * nu] = np.eye(nu)
        G[k + 1] = T[k, :, :nz] @ G[k] + T[k, :, nz:] @ Wk
        g[k + 1] = T[k, :, :nz] @ g[k] + np.r_[ct[k], np.zeros(nu)]
    H = np.zeros((nv, nv))
    f = np.zeros(nv)
    for k in range(N):
        Wk = np.zeros((nu, nv))
        Wk[:, (k + 1) * nu:(k + 2) * nu] = np.eye(nu)
        Y = np.vstack([G[k], Wk])
        y0 = np.r_[g[k], np.zeros(nu)]
        H += Y.T @ Hy[k] @ Y
        f += Y.T @ (Hy[k] @ y0 + gy[k])
    rows = [(k, i) for k in range(1, N + 1) for i in range(nx) if np.isfinite(lo[k, i]) or np.isfinite(hi[k, i])]
    A = np.array([G[k, i] for k, i in rows])
    big = 1e30
    bu = np.r_[np.minimum(hi[:, nx:].ravel(), big), [min(hi[k, i], big) - g[k, i] for k, i in rows]]
    bl = np.r_[np.maximum(lo[:, nx:].ravel(), -big), [max(lo[k, i], -big) - g[k, i] for k, i in rows]]
    sense = np.r_[np.zeros(nv), [5 if lo[k, i] == hi[k, i] else 0 for k, i in rows]].astype(np.int32)
    v, _, flag, info = daqp.solve(0.5 * (H + H.T), f, A, bu, bl, sense)
    assert flag == 1
    lam = np.asarray(info["lam"])
    dz = np.einsum("kij,j->ki", G, v) + g
    rows_lam = np.zeros((N + 1, nx))
    for (k, i), value in zip(rows, lam[nv:]):
        rows_lam[k, i] = value
    return dz, lam[:nv].reshape(N + 1, nu), rows_lam


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("nx,nu", [(4, 1), (6, 2)])
def test_the_riccati_active_set_finds_the_dense_qps_optimum_and_multipliers(seed, nx, nu):
    rng = np.random.default_rng(seed)
    N = 30
    T, ct, Hy, gy, lo, hi = _random_stage_qp(rng, N, nx, nu)
    qp = riccati_qp.StageQP(N, nx, nu)
    assert qp.solve(T, ct, Hy, gy, lo, hi) == 0
    dz, lam_u, lam_rows = _dense_reference(T, ct, Hy, gy, lo, hi)
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
