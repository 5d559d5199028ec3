"""The functions a moving-horizon estimator evaluates every control period, compiled to C (with the SX fallback).

One interval of the estimation window is one control period: ``steps`` physics steps of the model's exact discrete
step (``model.step``, one step of the MJCF's integrator) with a ctrl of its own in each physics step, the same
composition as :attr:`cartpole.models.HoldModel.step_inputs`. Its value and exact state Jacobian come from one SX
function of a single physics step ``(x, u) -> (x+, dx+/dx)`` chained ``steps`` times by the chain rule
(``A = A_m ... A_1``) in an MX function, so the generated C holds the physics step once whatever ``steps`` is. The
measurement model ``h(x, u) -> y`` and its Jacobian ``dh/dx`` are one SX function. Both, mapped over a window of
``N`` intervals (``N + 1`` nodes), make one function: one call per period gives every linearisation the
Gauss-Newton step needs. The rest of a period is small numpy arithmetic, here too: the QP condensed onto the first
node and the noise (:func:`condensed_qp`, an O(N^2) forward recursion), its solution (:func:`solve_window_qp`: one
Cholesky solve, DAQP only when a position bound binds) and the arrival cost's EKF step (:func:`arrival_update`),
with the checks of the covariances and the default first estimate the estimator
(:class:`cartpole.estimation.mhe.MovingHorizonEstimator`) is built with.

The shared library is cached by :func:`cartpole.codegen.build_library` (keyed by its source, the flags, the CasADi
version and the CPU). With ``CARTPOLE_NO_COMPILE`` set, without a C compiler, or when the build fails, the same
CasADi functions run in CasADi's virtual machine (same numbers, slower), with a note on stderr.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import daqp
import numpy as np

from cartpole.codegen import QP_ITER_LIMIT, build_library, compiled_or_none, load_library
from cartpole.estimation.base import EstimationError
from cartpole.estimation.measurement import measurement_jacobians


@dataclass(frozen=True)
class WindowFunctions:
    """The per-period evaluations of one estimator: model, steps per period, measurement model and window length.

    Attributes
    ----------
    window : casadi.Function
        ``(X (nx, N+1), UU (nu steps, N), UH (nu, N+1)) -> (F (nx, N), A (nx, nx N), Y (ny, N+1), C (ny, nx (N+1)))``:
        for each interval ``j`` the state ``F_j`` one period after node ``X[:, j]`` under the ctrl ``UU[:, j]``
        (``vec`` of the period's (nu, steps) ctrl, one column per physics step) and its Jacobian ``A_j`` (column
        block ``j``); for each node ``j`` the predicted measurement ``h(X[:, j], UH[:, j])`` and ``C_j = dh/dx``.
    stage : casadi.Function
        One interval ``(x (nx,), Uvec (nu steps,)) -> (x_next (nx,), A (nx, nx))``.
    measurement : casadi.Function
        One node ``(x (nx,), u (nu,)) -> (y (ny,), C (ny, nx))``.
    library : str or None
        Path of the compiled shared library in use, None on the SX fallback.
    steps, N, ny : int
        Physics steps per period, intervals in the window, measurement size.
    """

    window: ca.Function
    stage: ca.Function
    measurement: ca.Function
    library: str | None
    steps: int
    N: int
    ny: int


def _one_step(model) -> ca.Function:
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    xn = model.step(x, u)
    return ca.Function("mhe_phys", [x, u], [xn, ca.jacobian(xn, x)], ["x", "u"], ["x_next", "A"], {"cse": True})


def _stage(model, steps: int) -> ca.Function:
    nx, nu = model.nx, model.nu
    one = _one_step(model)
    x, Uv = ca.MX.sym("x", nx), ca.MX.sym("U", nu * steps)
    xk, A = x, ca.MX.eye(nx)
    for j in range(steps):
        xk, Aj = one(xk, Uv[j * nu:(j + 1) * nu])
        A = ca.mtimes(Aj, A)
    return ca.Function("mhe_stage", [x, Uv], [ca.densify(xk), ca.densify(A)], ["x", "U"], ["x_next", "A"])


def _measurement(h: ca.Function, nx: int, nu: int) -> ca.Function:
    # y and dy/dx only (the MHE's ctrl enters through the model), from the one builder of h's Jacobians
    jac = measurement_jacobians(h, nx, nu)
    x, u = jac.sx_in() if jac.is_a("SXFunction") else jac.mx_in()
    y, C, _ = jac(x, u)
    return ca.Function("mhe_meas", [x, u], [y, C], ["x", "u"], ["y", "C"])


def window_functions(model, steps: int, h: ca.Function, N: int, *, compiled: bool = True) -> WindowFunctions:
    """Build (and, unless ``compiled`` is False or ``CARTPOLE_NO_COMPILE`` is set, compile to C) the window's
    evaluations.

    Parameters
    ----------
    model : CartPoleModel
        Anything with ``nx``, ``nu`` and ``step`` (one physics step of ``model.dt`` s, a CasADi Function
        ``(x (nx,), u (nu,)) -> x+``); any number of poles.
    steps : int
        Physics steps per control period.
    h : casadi.Function
        Measurement model ``(x (nx,), u (nu,)) -> y (ny,)``.
    N : int
        Intervals in the full window (``N + 1`` nodes).
    compiled : bool
        False keeps CasADi's virtual machine (the fallback, same numbers).

    Returns
    -------
    WindowFunctions
    """
    nx, nu = model.nx, model.nu
    stage = _stage(model, steps)
    meas = _measurement(h, nx, nu)
    ny = meas.size1_out(0)
    X, UU, UH = ca.MX.sym("X", nx, N + 1), ca.MX.sym("UU", nu * steps, N), ca.MX.sym("UH", nu, N + 1)
    F, A = stage.map(N)(X[:, :N], UU)
    Yh, C = meas.map(N + 1)(X, UH)
    window = ca.Function("mhe_window", [X, UU, UH], [ca.densify(v) for v in (F, A, Yh, C)], ["X", "UU", "UH"],
                         ["F", "A", "Y", "C"])
    library = None

    def build():
        lib, _ = build_library([window, stage, meas], f"mhe/{steps}x{N}")
        return lib, load_library(lib, ("mhe_window", "mhe_stage", "mhe_meas"))

    built = compiled_or_none(build, "MHE functions") if compiled else None
    if built is not None:
        library, ext = built
        window, stage, meas = ext["mhe_window"], ext["mhe_stage"], ext["mhe_meas"]
    return WindowFunctions(window=window, stage=stage, measurement=meas, library=library, steps=int(steps),
                           N=int(N), ny=int(ny))


#: DAQP's "no bound" (the active-set iterations it may take: :data:`cartpole.codegen.QP_ITER_LIMIT`).
_BIG = 1e30


def riccati_window_step(A, d, C, r_meas, RV, L, P_inv, arrival_gap, e):
    """The window's unconstrained Gauss-Newton step by a backward Riccati recursion over its nodes (O(n), the
    structure of the problem: a linear-quadratic smoother whose inputs are the noises), the same minimiser as the
    condensed normal equations of :func:`condensed_qp`.

    With ``M_j = (RV C_j)' (RV C_j)``, ``m_j = (RV C_j)' RV r_j`` and the cost-to-go from node ``j`` written
    ``dx' P_j dx + 2 p_j' dx``: ``P_n = M_n``, ``p_n = m_n``; for ``j = n-1 .. 0``, with ``q = p_j+1 + P_j+1 d_j``,
    ``G_j = I + L' P_j+1 L``, ``N_j = L' P_j+1 A_j``, ``K_j = G_j^-1 N_j``, ``k_j = G_j^-1 (L' q + e_j)``::

        P_j = M_j + A_j' P_j+1 A_j - N_j' K_j,      p_j = m_j + A_j' q - N_j' k_j

    then ``dx_0 = -(P_0 + P^-1)^-1 (p_0 + P^-1 (x_0 - x_bar))`` and forward ``de_j = -K_j dx_j - k_j``,
    ``dx_j+1 = A_j dx_j + L de_j + d_j`` (``G_j`` and ``P_0 + P^-1`` by Cholesky). The C of
    ``cartpole/csrc/mhe.c.jinja`` (``mh_riccati``) does these operations in this order.

    Parameters
    ----------
    A, d, C, r_meas, RV, L, P_inv, arrival_gap, e
        As :func:`condensed_qp`.

    Returns
    -------
    dX : (n+1, nx) array
        The nodes' steps (SI units).
    dE : (n, r) array
        The noises' steps.
    """
    n, nx, r = d.shape[0], P_inv.shape[0], L.shape[1]
    RC = RV @ C  # (n+1, ny, nx)
    Rr = r_meas @ RV.T  # (n+1, ny)
    P = RC[n].T @ RC[n]
    p = RC[n].T @ Rr[n]
    K, k = np.zeros((n, r, nx)), np.zeros((n, r))
    for j in range(n - 1, -1, -1):
        q = p + P @ d[j]
        PL = P @ L
        G = np.eye(r) + L.T @ PL
        Nj = PL.T @ A[j]
        Gc = np.linalg.cholesky(G)
        K[j] = np.linalg.solve(Gc.T, np.linalg.solve(Gc, Nj))
        k[j] = np.linalg.solve(Gc.T, np.linalg.solve(Gc, L.T @ q + e[j]))
        P = RC[j].T @ RC[j] + A[j].T @ P @ A[j] - Nj.T @ K[j]
        p = RC[j].T @ Rr[j] + A[j].T @ q - Nj.T @ k[j]
    Pc = np.linalg.cholesky(P + P_inv)
    dX, dE = np.zeros((n + 1, nx)), np.zeros((n, r))
    dX[0] = -np.linalg.solve(Pc.T, np.linalg.solve(Pc, p + P_inv @ arrival_gap))
    for j in range(n):
        dE[j] = -K[j] @ dX[j] - k[j]
        dX[j + 1] = A[j] @ dX[j] + L @ dE[j] + d[j]
    return dX, dE


def condensed_qp(A, d, C, r_meas, RV, L, P_inv, arrival_gap, e):
    """The window's Gauss-Newton QP condensed onto ``z = (dx_0, de_0 .. de_n-1)``.

    The steps of the nodes are ``dx_j = c_j + S_j z`` through the linearised shooting constraints ``dx_j+1 = A_j dx_j
    + L de_j + d_j``; the cost ``||x_0 + dx_0 - x_bar||^2_{P^-1} + sum_j ||RV (r_j + C_j dx_j)||^2 +
    sum_j ||e_j + de_j||^2`` is ``z' H z + 2 g' z`` plus a constant.

    Parameters
    ----------
    A : (n, nx, nx) array
        State Jacobians of the intervals.
    d : (n, nx) array
        Shooting gaps ``F_j + L e_j - x_j+1`` (SI units).
    C : (n+1, ny, nx) array
        Measurement Jacobians of the nodes.
    r_meas : (n+1, ny) array
        Measurement residuals ``h(x_j, u_j) - y_j`` (sensor units).
    RV : (ny, ny) array
        ``RV' RV = V^-1``.
    L : (nx, r) array
        ``W = L L'``.
    P_inv : (nx, nx) array
        ``P^-1``, the arrival cost's weight.
    arrival_gap : (nx,) array
        ``x_0 - x_bar`` (SI units).
    e : (n, r) array
        The iterate's noise.

    Returns
    -------
    H : (nz, nz) array
        Positive definite Hessian, ``nz = nx + n r``.
    g : (nz,) array
        Gradient.
    S : (n+1, nx, nz) array
        Sensitivities of the nodes' steps.
    c : (n+1, nx) array
        Offsets of the nodes' steps (SI units).
    """
    n, nx, r = d.shape[0], P_inv.shape[0], L.shape[1]
    nz = nx + n * r
    # [S_j, c_j] side by side: one product per stage carries both
    T = np.zeros((n + 1, nx, nz + 1))
    T[0, :, :nx] = np.eye(nx)
    for j in range(n):
        T[j + 1] = A[j] @ T[j]
        T[j + 1, :, nx + j * r:nx + (j + 1) * r] = L
        T[j + 1, :, nz] += d[j]
    B = ((RV @ C) @ T).reshape(-1, nz + 1)  # [RV C_j S_j, RV C_j c_j] stacked over the nodes
    B[:, nz] += (r_meas @ RV.T).ravel()
    M = B.T @ B[:, :nz]  # [H; g'] of the measurements in one product
    H, g = M[:nz], M[nz].copy()
    H[:nx, :nx] += P_inv
    g[:nx] += P_inv @ arrival_gap
    H.flat[nx * (nz + 1)::nz + 1] += 1.0
    g[nx:] += e.ravel()
    return H, g, T[:, :, :nz], T[:, :, nz]


def solve_window_qp(H, g, S, c, q, joints, low, high):
    """``min 1/2 z' H z + g' z`` with the positions ``q_j + c_j + S_j z`` of the bounded joints inside their ranges
    at every node: the Cholesky solve when its minimiser respects them (then it is the solution: the QP is convex),
    else DAQP on the same QP with its cost divided by ``max(diag H)`` (the same minimiser).

    Why the division: an encoder-read position weighs ``1 / V`` (about 1e13 per m^2 for a 2048-count slide encoder)
    against 1 for each noise entry, so ``H``'s condition number is about 1e13 and a position row ``a`` of the
    constraints has ``a' H^-1 a`` about 1e-12, below DAQP's ``zero_tol`` (1e-11, absolute): DAQP then takes the
    violated row for a zero row and reports the QP infeasible (exit flag -1), although it is feasible. Scaled so
    that ``H``'s largest diagonal entry is 1, those products are of order one and DAQP solves it; the minimiser, the
    active set and the constraints do not change (the multipliers are divided by the same factor). DAQP's own
    iterate is accurate only to about ``1e-16 cond(H)`` relative in the weakly weighted directions (the noise: its
    steps were off by thousands of units), so its answer is then polished (:func:`polish_active_set`): the
    equality-constrained QP on DAQP's active set solved by one LU factorisation of its KKT matrix, kept when it is
    feasible and its multipliers have the right signs, which makes it the QP's exact solution.

    Parameters
    ----------
    H, g : (nz, nz), (nz,) arrays
        From :func:`condensed_qp` (``H`` is used in place by DAQP's copy, not changed).
    S, c : (n+1, nx, nz), (n+1, nx) arrays
        From :func:`condensed_qp`.
    q : (n+1, nb) array
        The iterate's positions of the bounded joints (m, rad).
    joints : (nb,) int array
        Their qpos indices.
    low, high : (nb,) arrays
        Their ranges (m, rad; one side may be infinite).

    Returns
    -------
    (nz,) array or None
        The step; the unconstrained one when DAQP fails, None when ``H`` is singular.
    """
    try:
        z = np.linalg.solve(H, -g)
    except np.linalg.LinAlgError:
        return None
    if not joints.size:
        return z
    Sb = S[:, joints, :]
    v = q + c[:, joints]
    qz = v + Sb @ z
    if not ((qz > high + 1e-12).any() or (qz < low - 1e-12).any()):
        return z

    nz = H.shape[0]
    rows = np.ascontiguousarray(Sb.reshape(-1, nz))
    upper = np.minimum((high - v).ravel(), _BIG)
    lower = np.maximum((low - v).ravel(), -_BIG)
    sense = np.zeros(rows.shape[0], dtype=np.int32)
    scale = 1.0 / float(np.max(np.diag(H)))
    zq, _, flag, _ = daqp.solve(np.ascontiguousarray(H * scale), np.ascontiguousarray(g * scale), rows, upper, lower,
                                sense, iter_limit=QP_ITER_LIMIT)
    if flag not in (1, 2):
        return z
    return polish_active_set(H * scale, g * scale, rows, upper, lower, np.asarray(zq))


#: m or rad: a row this close to one of its limits counts as active, or as violated beyond it, when a QP solution is
#: polished; and the most working-set changes the polish may make.
ACTIVE_TOL = 1e-9
POLISH_ITER_LIMIT = 50


def polish_active_set(H, g, rows, upper, lower, z):
    """The solution of ``min 1/2 z' H z + g' z, lower <= rows z <= upper`` refined from an approximate solution
    ``z``: a primal active-set iteration with exact linear algebra. The working set starts as the rows within
    :data:`ACTIVE_TOL` of a limit at ``z``; each iteration solves the equality-constrained QP on it,
    ``[H A'; A 0] [z; mu] = [-g; b]`` (LU with partial pivoting), then adds the most violated row if any is violated
    by more than :data:`ACTIVE_TOL`, else drops the row whose multiplier has the wrong sign the most (an optimum has
    ``mu >= 0`` on an upper limit, ``<= 0`` on a lower), else stops: the KKT conditions then hold and, the QP being
    strictly convex, that is its solution.

    Parameters
    ----------
    H, g : (nz, nz), (nz,) arrays
        The cost (``H`` positive definite; scaled to a largest diagonal entry near 1 for the LU).
    rows : (nr, nz) array
        The constraint rows.
    upper, lower : (nr,) arrays
        Their limits (``+-1e30`` or infinite where absent).
    z : (nz,) array
        The approximate solution (a dual active-set solver's).

    Returns
    -------
    (nz,) array
        The solution satisfying the KKT conditions, or ``z`` unchanged when no such point was reached within
        :data:`POLISH_ITER_LIMIT` working-set changes.
    """
    nz, nr = H.shape[0], rows.shape[0]
    r = rows @ z
    side = np.zeros(nr, dtype=int)  # +1 held at its upper limit, -1 at its lower, 0 free
    side[r >= upper - ACTIVE_TOL] = 1
    side[(r <= lower + ACTIVE_TOL) & (side == 0)] = -1
    for _ in range(POLISH_ITER_LIMIT):
        act = np.flatnonzero(side)
        na = act.size
        K = np.zeros((nz + na, nz + na))
        K[:nz, :nz] = H
        K[nz:, :nz] = rows[act]
        K[:nz, nz:] = rows[act].T
        b = np.where(side[act] > 0, upper[act], lower[act])
        try:
            sol = np.linalg.solve(K, np.r_[-g, b])
        except np.linalg.LinAlgError:
            return z
        if not np.all(np.isfinite(sol)):
            return z
        zp, mu = sol[:nz], sol[nz:]
        rp = rows @ zp
        excess = np.maximum(rp - upper, lower - rp)
        excess[act] = 0.0
        if excess.size and excess.max() > ACTIVE_TOL:
            i = int(np.argmax(excess))
            side[i] = 1 if rp[i] > upper[i] else -1
            continue
        wrong = -mu * side[act]  # > 0: a multiplier of the wrong sign
        if na and wrong.max() > 0:
            side[act[int(np.argmax(wrong))]] = 0
            continue
        return zp
    return z


def arrival_update(x_bar, P, x0, y0, h0, C0, F0, A0, V, W):
    """The arrival cost one node later: an extended-Kalman-filter measurement update of ``(x_bar, P)`` with the
    leaving measurement ``y0`` and its prediction over the leaving interval, linearised at the estimate ``x0`` of
    the leaving node (:mod:`cartpole.estimation.mhe`'s module doc; Joseph form).

    Parameters
    ----------
    x_bar : (nx,) array
        The arrival cost's centre at the leaving node (SI units).
    P : (nx, nx) array
        Its covariance.
    x0 : (nx,) array
        The estimate of the leaving node (SI units).
    y0 : (ny,) array
        Its measurement (sensor units).
    h0, C0 : (ny,), (ny, nx) arrays
        ``h`` and ``dh/dx`` at ``x0``.
    F0, A0 : (nx,), (nx, nx) arrays
        The interval's end state and ``dF/dx`` from ``x0`` (SI units).
    V, W : (ny, ny), (nx, nx) arrays
        Measurement and process covariances.

    Returns
    -------
    x_bar : (nx,) array
        The centre at the next node (SI units).
    P : (nx, nx) array
        Its covariance, symmetric.
    """
    PCt = P @ C0.T
    K = np.linalg.solve(C0 @ PCt + V, PCt.T).T
    xf = x_bar + K @ (y0 - h0 - C0 @ (x_bar - x0))
    IKC = np.eye(P.shape[0]) - K @ C0
    Pf = IKC @ P @ IKC.T + K @ V @ K.T
    P_new = A0 @ Pf @ A0.T + W
    return F0 + A0 @ (xf - x0), 0.5 * (P_new + P_new.T)


def symmetric_matrix(name: str, M, n: int) -> np.ndarray:
    """The covariance ``name`` given as ``M`` as a finite symmetric (n, n) array (a number: that times I; a vector:
    its diagonal); an :class:`EstimationError` sentence naming ``name`` otherwise."""
    try:
        M = np.array(M, dtype=float)
    except (TypeError, ValueError):
        raise EstimationError(f"The covariance {name} must be a ({n}, {n}) matrix of numbers.") from None
    if M.ndim == 0:
        M = M * np.eye(n)
    elif M.shape == (n,):
        M = np.diag(M)
    if M.shape != (n, n) or not np.all(np.isfinite(M)):
        raise EstimationError(f"The covariance {name} must be a finite ({n}, {n}) matrix (or its diagonal); got "
                              f"shape {M.shape}.")
    if not np.allclose(M, M.T, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(M).max())):
        raise EstimationError(f"The covariance {name} is not symmetric; give a symmetric ({n}, {n}) matrix.")
    return 0.5 * (M + M.T)


def positive_definite(name: str, M, n: int) -> np.ndarray:
    """:func:`symmetric_matrix` that must also be positive definite (else one sentence naming ``name``)."""
    M = symmetric_matrix(name, M, n)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise EstimationError(f"The covariance {name} is not positive definite (smallest eigenvalue "
                              f"{np.linalg.eigvalsh(M).min():.3g}); give variances > 0.") from None
    return M


def inverse_factor(P: np.ndarray) -> np.ndarray:
    """``R`` with ``R' R = P^-1`` (``R = L^-1``, ``P = L L'``); a covariance that rounding made indefinite is lifted
    by the least diagonal that restores its factor."""
    jitter = 0.0
    scale = max(float(np.trace(P)) / P.shape[0], 1e-300)
    for _ in range(8):
        try:
            L = np.linalg.cholesky(P + jitter * np.eye(P.shape[0]))
            return np.linalg.inv(L)
        except np.linalg.LinAlgError:
            jitter = 1e-14 * scale if jitter == 0.0 else 100 * jitter
    raise EstimationError("The MHE's arrival covariance is not positive definite; give a P0 and W with variances "
                          "> 0.")

