"""The SQP's QP, built in compiled C: stage form, convexification and condensing of one iteration in two calls.

:class:`cartpole.solvers.sqp.CollocationSQP` evaluates the interval functions (defects, Jacobians, gradient, exact
Hessian blocks) and then needs, per iteration, the QP in stage form (docs/architecture.md, SQP). Built in numpy that
cost as much as everything else in the iteration: many small batched products, a Python-side Riccati pass and an
O(N^3) dense condensed Hessian. Here the same arithmetic is three CasADi Functions generated from one stage's SX and
mapped over the stages (``map``/``mapaccum``: the C holds each stage's arithmetic once, compact for any N), compiled
to C once per size and cached like the interval functions (:func:`cartpole.codegen.build_library`), CasADi's virtual
machine as the fallback:

``sqp_stages (J (nv, nx N), H (nv, nv N), G (nv, N), D (nx, N), lm) -> (T (ny, nz N), ct (nx, N), Hy (ny, ny N),
gy (ny, N), M (nx, nx N))``
    Interval k's linearised defect ``D_k + J^a dz_k + J^b_x dx_k+1 + J^b_u du_k+1`` solved for ``dx_k+1``
    (``M_k = (J^b_x)^-1``): the stage dynamics ``s_k+1 = T_k (s_k, w_k) + (ct_k, 0)``; the Hessian block and
    gradient in the stage variables ``y_k = (s_k, w_k)`` (``Hy_k = P_k' H_k P_k + lm I``, ``P_k`` the map from
    ``y_k`` to ``(z_k, z_k+1)``); then the backward Riccati recursion that raises any stage's reduced Hessian
    ``R + B' P B`` whose Gershgorin bound is below ``reg_min`` (the first stage, whose state ``s_0 = du_0`` is free,
    included), so the QP is convex. Inputs and outputs are numpy's C-order blocks (``J`` (N, nx, nv) is CasADi's
    ``J_k'`` side by side), so each output reads as (N, rows, cols) of the named matrix.
``sqp_condense (T, ct, Hy, gy) -> (Y (nc, 2nu N), band (2nu, 2nu N), f (nc,), e (2nu, N), GT (nc + 1, nx N))``
    The QP condensed onto the knot controls ``v = (du_0 .. du_N)`` (nc = (N+1) nu): ``dx_k = g_k + G_k v``
    (``GT`` holds ``[G_k, g_k]'`` for knots k = 1..N; ``G_0 = 0``, ``g_0 = 0``) by the forward recursion ``G_k+1 =
    A_k G_k + Bw_k E_k`` (``A_k``, ``Bw_k`` the state rows of ``T_k``, ``E_k`` selecting ``du_k, du_k+1``); the
    Hessian without any ``G' Q G`` product: with ``P_N = 0``, ``P_k = Q_k + A_k' P_k+1 A_k`` (the states' cost-to-go
    of the linear system), ``sum_k G_k' Q_k G_k = sum_k (X_k E_k + E_k' X_k' - E_k' Bw_k' P_k+1 Bw_k E_k)`` with
    ``X_k = G_k+1' P_k+1 Bw_k`` (each pair of inputs counted once through the later state it reaches), which with
    the cross terms gives ``Hc = sum_k (Y_k E_k + E_k' Y_k') + sum_k E_k' band_k E_k``, ``Y_k = G_k' (S_k' + A_k'
    P_k+1 Bw_k)``, ``band_k = R_k + Bw_k' P_k+1 Bw_k`` (``Q``, ``S``, ``R`` the blocks of ``Hy_k`` in ``(dx_k;
    du_k, du_k+1)``), and the gradient ``fc = f + sum_k E_k' e_k``: O(N^2 nx nu) flops instead of O(N^3), the
    stage terms fused into the forward recursion. :func:`assemble_condensed` places the blocks.
``sqp_multipliers (dZ (nz, N+1), nbx (nx, N+1), Hy, gy, T, H, G, M) -> lam (nx, N)``
    The defects' multipliers from a QP step ``dZ`` and the state bounds' multipliers: the stage dynamics'
    multipliers by the backward recursion of the stage states' stationarity, then ``lambda_k =
    -M_k' (mu_k + [H_k dV_k + G_k]_(z_k+1))`` (:mod:`cartpole.solvers.sqp`).
``sqp_stationarity (J, G, lam (nx, N), nb (nz, N+1)) -> kkt``
    The largest entry of the NLP Lagrangian's gradient in the knots, ``nb_k + [G_k + J_k' lam_k]_(z_k) +
    [G_k-1 + J_k-1' lam_k-1]_(z_k)``, the pinned ``x_0`` and ``x_N`` left out (the SQP's convergence test).
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import casadi as ca
import numpy as np

from cartpole.ocp.bounds import OCPError
from cartpole.codegen import build_library, compiled_or_none, load_library


#: ``mapaccum``'s nesting base: the N stages accumulate as nested folds of at most this many calls. One unnested fold
#: of N calls costs CasADi superlinear time and memory to build (the condensing's, its accumulator (N+2, nx), took
#: 1.3 GB at N = 200 and about 7 GB at N = 315 in ``mapaccum`` alone; nested: 0.2 GB, under a second); the copies
#: the nesting adds cost about nothing a call next to the stages' arithmetic.
ACC_BASE = 10


def _acc(steps: int) -> dict:
    """``mapaccum`` options for ``steps`` stages: nested folds of :data:`ACC_BASE` calls (bounded memory to build)."""
    return {"base": max(2, min(int(steps), ACC_BASE))}


#: Compiler flags of this library, whatever its length (:func:`cartpole.codegen.choose_cflags` compiles long
#: sources without optimisation): it is many small stage functions, each the same size for any N (the condensing's
#: N-row products are loops, :func:`_condense_function`), which gcc optimises in about linear time, and the optimised
#: build is several times faster a call than -O0. (N = 499: 1.2 MB of C, 0.5 MB of it index tables, -O3 in seconds;
#: with the condensing's stage unrolled in SX, N = 315 was 1.9 MB and 93 s of -O3 on a loaded machine.)
CFLAGS = ("-O3", "-march=native")


def _gershgorin_low(M: ca.SX) -> ca.SX:
    """Gershgorin lower bound of the eigenvalues of the symmetric SX matrix ``M``."""
    n = M.size1()
    low = None
    for i in range(n):
        gi = M[i, i] - sum(ca.fabs(M[i, j]) for j in range(n) if j != i)
        low = gi if low is None else ca.fmin(low, gi)
    return low


def _raise_to(low: ca.SX, eps: float) -> ca.SX:
    """Shift that lifts a lower eigenvalue bound ``low`` to ``max(eps, |low|)`` where it is below ``eps``."""
    return ca.if_else(low < eps, ca.fmax(eps, ca.fabs(low)) - low, 0)


def _stage_function(nx: int, nu: int) -> ca.Function:
    """One interval's stage form (module docstring, ``sqp_stages`` before the Riccati pass)."""
    nz = nx + nu
    nv, ny = 2 * nz, nz + nu
    Jt, H = ca.SX.sym("Jt", nv, nx), ca.SX.sym("H", nv, nv)
    g, d, lm = ca.SX.sym("g", nv), ca.SX.sym("d", nx), ca.SX.sym("lm")
    J = Jt.T
    Ja, Jbx, Jbu = J[:, :nz], J[:, nz:nz + nx], J[:, nz + nx:]
    M = ca.solve(Jbx, ca.SX.eye(nx))
    # dense: the flat output buffer is read as (N, nz, ny) (eye's off-diagonal zeros are otherwise not stored)
    T = ca.densify(ca.vertcat(ca.horzcat(-ca.mtimes(M, Ja), -ca.mtimes(M, Jbu)),
                              ca.horzcat(ca.SX.zeros(nu, nz), ca.SX.eye(nu))))  # (nz, ny)
    ct = -ca.mtimes(M, d)
    P = ca.vertcat(ca.horzcat(ca.SX.eye(nz), ca.SX.zeros(nz, nu)), T)  # (nv, ny)
    Hy = ca.mtimes([P.T, H, P])
    Hy = 0.5 * (Hy + Hy.T) + lm * ca.SX.eye(ny)
    gy = ca.mtimes(P.T, ca.mtimes(H[:, nz:nz + nx], ct) + g)
    return ca.Function("sqp_stage", [Jt, H, g, d, lm], [T.T, ct, Hy, gy, M.T], {"cse": True})


def _riccati_step(P, A, B, Q, S, R, eps: float) -> tuple:
    """One regularised Riccati step (SX): ``(P_prev, d)`` with ``d`` the shift added to ``R`` so that
    ``R + B' P B`` keeps its Gershgorin bound above ``eps``."""
    BP = ca.mtimes(B.T, P)
    Rb = R + ca.mtimes(BP, B)
    d = _raise_to(_gershgorin_low(Rb), eps)
    Rb = Rb + d * ca.SX.eye(R.size1())
    L = S + ca.mtimes(BP, A)
    Pn = Q + ca.mtimes([A.T, P, A]) - ca.mtimes(L.T, ca.solve(Rb, L))
    return 0.5 * (Pn + Pn.T), d


def _riccati_stage(nz: int, nw: int, eps: float) -> ca.Function:
    """One step of the regularised Riccati recursion over a stage: ``(P, Tt (ny, nz), Hy) -> (P_prev, d)``
    (:func:`_riccati_step`; ``d`` goes to the stage's ``w`` block)."""
    ny = nz + nw
    P, Tt, Hy = ca.SX.sym("P", nz, nz), ca.SX.sym("Tt", ny, nz), ca.SX.sym("Hy", ny, ny)
    T = Tt.T
    Pn, d = _riccati_step(P, T[:, :nz], T[:, nz:], Hy[:nz, :nz], Hy[nz:, :nz], Hy[nz:, nz:], eps)
    return ca.Function("sqp_riccati_stage", [P, Tt, Hy], [Pn, d], {"cse": True})


def _first_stage(nx: int, nu: int, eps: float) -> ca.Function:
    """The first stage's convexification (its state ``s_0 = du_0``, nu, is free: ``dx_0 = 0``): ``(P_1, Tt_0, Hy_0)
    -> Hy_0`` with the ``w`` block and then the ``du_0`` block raised as needed."""
    nz = nx + nu
    ny = nz + nu
    P, Tt, Hy = ca.SX.sym("P", nz, nz), ca.SX.sym("Tt", ny, nz), ca.SX.sym("Hy", ny, ny)
    T = Tt.T
    P0, dw = _riccati_step(P, T[:, nx:nz], T[:, nz:], Hy[nx:nz, nx:nz], Hy[nz:, nx:nz], Hy[nz:, nz:], eps)
    du = _raise_to(_gershgorin_low(P0), eps)
    shift = ca.diagcat(ca.SX.zeros(nx, nx), du * ca.SX.eye(nu), dw * ca.SX.eye(nu))
    return ca.Function("sqp_first_stage", [P, Tt, Hy], [Hy + shift], {"cse": True})


def _block_cols(width: int, n: int, count: int) -> list[int]:
    """Column indices of the first ``n`` columns of each of ``count`` blocks ``width`` wide, side by side."""
    return np.concatenate([np.arange(k * width, k * width + n) for k in range(count)]).tolist()


def _reverse_blocks(X: ca.MX, width: int, count: int) -> ca.MX:
    """The ``count`` column blocks (``width`` wide) of ``X`` in reverse order."""
    cols = np.concatenate([np.arange(k * width, (k + 1) * width) for k in range(count - 1, -1, -1)])
    return X[:, cols.tolist()]


def qp_functions(nx: int, nu: int, N: int, reg_min: float, n_free: int = 0) -> list[ca.Function]:
    """``[sqp_stages, sqp_condense, sqp_multipliers, sqp_stationarity]`` (module docstring) for ``nx`` states,
    ``nu`` inputs and ``N >= 2`` intervals, in CasADi's virtual machine (:func:`compiled_qp_functions` compiles
    them); the last ``n_free`` states are parameters free at the boundary knots (the stationarity counts them)."""
    return [_stages_function(nx, nu, N, reg_min), _condense_function(nx, nu, N), _multipliers_function(nx, nu, N),
            _stationarity_function(nx, nu, N, n_free)]


def _stages_function(nx: int, nu: int, N: int, reg_min: float) -> ca.Function:
    """``sqp_stages`` (module docstring): the stage form, then the Riccati pass that convexifies it."""
    nz = nx + nu
    nv, ny = 2 * nz, nz + nu
    Jt, H = ca.MX.sym("J", nv, nx * N), ca.MX.sym("H", nv, nv * N)
    G, D, lm = ca.MX.sym("G", nv, N), ca.MX.sym("D", nx, N), ca.MX.sym("lm")
    Tt, ct, Hy, gy, Mt = _stage_function(nx, nu).map(N)(Jt, H, G, D, lm)
    # the Riccati pass over stages N-1 .. 1, then the first stage
    ric = _riccati_stage(nz, nu, reg_min).mapaccum("sqp_riccati", N - 1, [0], [0], _acc(N - 1))
    Ps, dk = ric(ca.MX.zeros(nz, nz), _reverse_blocks(Tt[:, nz:], nz, N - 1), _reverse_blocks(Hy[:, ny:], ny, N - 1))
    d = _reverse_blocks(dk, 1, N - 1)  # stages 1 .. N-1
    Pl = Ps[:, (N - 2) * nz:]  # P after stage 1
    Hs_, ds_ = ca.SX.sym("Hy", ny, ny), ca.SX.sym("d")
    wblock = ca.DM(np.diag(np.r_[np.zeros(nz), np.ones(nu)]))
    lift = ca.Function("sqp_lift", [Hs_, ds_], [Hs_ + ds_ * wblock]).map(N - 1)
    Hy0 = _first_stage(nx, nu, reg_min)(Pl, Tt[:, :nz], Hy[:, :ny])
    Hy_reg = ca.horzcat(Hy0, lift(Hy[:, ny:], d))
    return ca.Function("sqp_stages", [Jt, H, G, D, lm], [Tt, ct, Hy_reg, gy, Mt],
                       ["J", "H", "G", "D", "lm"], ["T", "ct", "Hy", "gy", "M"])


def _stage_symbols(nx: int, nu: int, N: int):
    """The stage form's inputs as MX symbols, ``(T, ct, Hy, gy)`` (``sqp_stages``' outputs), and ``A_k'`` side by
    side (nx, nx N): ``T``'s block k is ``T_k'`` (ny, nz), its first nx rows and columns ``A_k'``."""
    nz, ny = nx + nu, nx + 2 * nu
    Ti, cti = ca.MX.sym("T", ny, nz * N), ca.MX.sym("ct", nx, N)
    Hyi, gyi = ca.MX.sym("Hy", ny, ny * N), ca.MX.sym("gy", ny, N)
    return Ti, cti, Hyi, gyi, Ti[:nx, _block_cols(nz, nx, N)]


def _offset_pattern(nx: int, nu: int, N: int) -> ca.Sparsity:
    """The sparsity of ``[Bf_0', .., Bf_N-1']`` ((nc + 1, nx N), nc = (N+1) nu): block k's column j holds the rows
    ``k nu .. (k+2) nu - 1`` (``Bw_k'``) and the last (``ct_k'``), in that order, so its nonzeros are the columns of
    ``[Bw'; ct']`` ((2nu + 1, nx N)) one after the other: one node, where a block per stage is O(N) C."""
    nc = (N + 1) * nu
    col_rows = np.r_[np.arange(2 * nu), nc]  # block 0's rows; block k's are shifted by k nu (the last excepted)
    shift = np.r_[np.full(2 * nu, nu), 0]
    rows = (col_rows[None, None, :] + np.arange(N)[:, None, None] * shift).repeat(nx, axis=1).ravel()
    cols = np.repeat(np.arange(N * nx), 2 * nu + 1)
    return ca.Sparsity.triplet(nc + 1, nx * N, rows.tolist(), cols.tolist())


def _condense_function(nx: int, nu: int, N: int) -> ca.Function:
    """``sqp_condense`` (module docstring): the QP condensed onto the knot controls."""
    ny = nx + 2 * nu
    nc = (N + 1) * nu  # condensed unknowns
    Ti, cti, Hyi, gyi, ATs = _stage_symbols(nx, nu, N)
    # Ti's block k is T_k' (ny, nz): its first nx rows and columns A_k', the rows below them Bw_k' (2nu, nx)
    BWs = Ti[nx:, _block_cols(nx + nu, nx, N)]  # (2nu, nx N)
    Qs = Hyi[:nx, _block_cols(ny, nx, N)]  # (nx, nx N)
    # backward: P_k = Q_k + A_k' P_k+1 A_k, k = N-1 .. 1 (P_N = 0)
    P_, Q_, AT_ = ca.SX.sym("P", nx, nx), ca.SX.sym("Q", nx, nx), ca.SX.sym("AT", nx, nx)
    lyap = ca.Function("sqp_lyap", [P_, AT_, Q_], [ca.mtimes([AT_, P_, AT_.T]) + Q_]
                       ).mapaccum("sqp_lyap_acc", N - 1, [0], [0], _acc(N - 1))
    Prev = lyap(ca.MX.zeros(nx, nx), _reverse_blocks(ATs[:, nx:], nx, N - 1), _reverse_blocks(Qs[:, nx:], nx, N - 1))
    Pnext = ca.horzcat(_reverse_blocks(Prev, nx, N - 1), ca.MX.zeros(nx, nx))  # P_1 .. P_N
    # forward, one stage per knot: GT_k+1 = GT_k A_k' + Bf_k' with GT = [G; g]' (nc + 1, nx), Bf_k' holding Bw_k' in
    # the rows du_k, du_k+1 and ct_k' in the last; and, from G_k, the stage's part of the Hessian and gradient:
    # with G_k+1' = G_k' A_k' + E_k' Bw_k', X_k = G_k' W_k + E_k' Bw_k' P_k+1 Bw_k, W_k = S_k' + A_k' P_k+1 Bw_k
    # (nx, 2nu), so Hc = sum_k (Y_k E_k + E_k' Y_k') + sum_k E_k' (R_k + Bw_k' P_k+1 Bw_k) E_k with Y_k = G_k' W_k;
    # the gradient's G_k' (Q_k g_k + q_k) in the same product
    # the stage's arithmetic in nx and nu (SX), its two products with the (nc + 1)-row GT_k as MX (one loop each in
    # the C, whatever N): an SX stage of N-row products holds O(N) operations, O(N^2) over the stages
    Pk1, Tk = ca.SX.sym("P", nx, nx), ca.SX.sym("Tt", ny, nx + nu)
    Hk, gk, gm = ca.SX.sym("Hy", ny, ny), ca.SX.sym("gy", ny), ca.SX.sym("g", nx)  # gm: g_k (nx,)
    Ak, Bw = Tk[:nx, :nx].T, Tk[nx:, :nx].T  # (nx, nx), (nx, 2nu)
    Qk, Sk, Rk = Hk[:nx, :nx], Hk[nx:, :nx], Hk[nx:, nx:]
    PB = ca.mtimes(Pk1, Bw)
    W = ca.horzcat(Sk.T + ca.mtimes(Ak.T, PB), ca.mtimes(Qk, gm) + gk[:nx])  # (nx, 2nu + 1)
    band = Rk + ca.mtimes(Bw.T, PB)
    ek = ca.mtimes(Sk, gm) + gk[nx:]
    small = ca.Function("sqp_cond_small", [Pk1, Tk, Hk, gk, gm], [ca.densify(Ak.T), W, band, ek])
    GT_, BT_ = ca.MX.sym("GT", nc + 1, nx), ca.MX.sym("BT", nc + 1, nx)
    Pm, Tm, Hm, gym = ca.MX.sym("P", nx, nx), ca.MX.sym("Tt", ny, nx + nu), ca.MX.sym("Hy", ny, ny), ca.MX.sym("gy", ny)
    ATk, Wk, band_k, e_k = small(Pm, Tm, Hm, gym, GT_[nc, :].T)
    GW = ca.mtimes(GT_[:nc, :], Wk)  # (nc, 2nu + 1)
    fwd = ca.Function("sqp_cond_stage", [GT_, BT_, Pm, Tm, Hm, gym],
                      [ca.mtimes(GT_, ATk) + BT_, GW[:, :2 * nu], band_k, GW[:, 2 * nu], e_k]
                      ).mapaccum("sqp_cond_acc", N, [0], [0], _acc(N))
    BT = ca.MX(_offset_pattern(nx, nu, N), ca.vec(ca.vertcat(BWs, ca.reshape(cti, 1, nx * N))))
    GTs, Yt, B_, F_, E_ = fwd(ca.MX.zeros(nc + 1, nx), ca.densify(BT), Pnext, Ti, Hyi, gyi)
    return ca.Function("sqp_condense", [Ti, cti, Hyi, gyi], [Yt, B_, ca.sum2(F_), E_, GTs],
                       ["T", "ct", "Hy", "gy"], ["Y", "band", "f", "e", "GT"])


def _multipliers_function(nx: int, nu: int, N: int) -> ca.Function:
    """``sqp_multipliers`` (module docstring): the defects' multipliers of a QP step."""
    nz = nx + nu
    nv, ny = 2 * nz, nz + nu
    Ti, _, Hyi, gyi, ATs = _stage_symbols(nx, nu, N)
    Hk, gk, AT_ = ca.SX.sym("Hy", ny, ny), ca.SX.sym("gy", ny), ca.SX.sym("AT", nx, nx)
    dZ, nbx = ca.MX.sym("dZ", nz, N + 1), ca.MX.sym("nbx", nx, N + 1)
    Hm, Gm_, Mm = ca.MX.sym("H", nv, nv * N), ca.MX.sym("G", nv, N), ca.MX.sym("M", nx, nx * N)
    zk, zk1, nb = ca.SX.sym("zk", nz), ca.SX.sym("zk1", nz), ca.SX.sym("nb", nx)
    Hv, gv = ca.SX.sym("H", nv, nv), ca.SX.sym("g", nv)
    yk = ca.vertcat(zk, zk1[nx:])  # (dx_k, du_k, du_k+1)
    rk = ca.mtimes(Hk[:nx, :], yk) + gk[:nx] + nb
    ck = (ca.mtimes(Hv, ca.vertcat(zk, zk1)) + gv)[nz:nz + nx]
    loc = ca.Function("sqp_mult_stage", [zk, zk1, nb, Hk, gk, Hv, gv], [rk, ck]).map(N)
    r, cc = loc(dZ[:, :N], dZ[:, 1:], nbx[:, :N], Hyi, gyi, Hm, Gm_)
    m_, r_ = ca.SX.sym("m", nx), ca.SX.sym("r", nx)
    adj = ca.Function("sqp_adj", [m_, AT_, r_], [ca.mtimes(AT_, m_) + r_]
                      ).mapaccum("sqp_adj_acc", N - 1, [0], [0], _acc(N - 1))
    # m_k-1 = A_k' m_k + r_k, k = N-1 .. 1, from m_N-1 = nbx_N; ATs holds A_k' side by side
    mrev = adj(nbx[:, N], _reverse_blocks(ATs[:, nx:], nx, N - 1), _reverse_blocks(r[:, 1:], 1, N - 1))
    mx = ca.horzcat(_reverse_blocks(mrev, 1, N - 1), nbx[:, N])  # m_0 .. m_N-1
    mu_, c_, Mk = ca.SX.sym("mu", nx), ca.SX.sym("c", nx), ca.SX.sym("Mt", nx, nx)
    lamf = ca.Function("sqp_lam", [mu_, c_, Mk], [-ca.mtimes(Mk, mu_ + c_)]).map(N)  # Mk as passed is M_k'
    lam = lamf(mx, cc, Mm)
    return ca.Function("sqp_multipliers", [dZ, nbx, Hyi, gyi, Ti, Hm, Gm_, Mm], [lam],
                       ["dZ", "nbx", "Hy", "gy", "T", "H", "G", "M"], ["lam"])


def _stationarity_function(nx: int, nu: int, N: int, n_free: int) -> ca.Function:
    """``sqp_stationarity`` (module docstring): the largest entry of the Lagrangian's gradient in the knots."""
    nz = nx + nu
    nv = 2 * nz
    Js, Gs_, lams, nbs = (ca.MX.sym("J", nv, nx * N), ca.MX.sym("G", nv, N), ca.MX.sym("lam", nx, N),
                          ca.MX.sym("nb", nz, N + 1))
    Jt_k, g_k, l_k = ca.SX.sym("Jt", nv, nx), ca.SX.sym("g", nv), ca.SX.sym("l", nx)
    part = ca.mtimes(Jt_k, l_k) + g_k  # interval k's share of the gradient in (z_k, z_k+1)
    a_, b_ = ca.Function("sqp_stat_stage", [Jt_k, g_k, l_k], [part[:nz], part[nz:]]).map(N)(Js, Gs_, lams)
    gr = nbs + ca.horzcat(a_, ca.MX.zeros(nz, 1)) + ca.horzcat(ca.MX.zeros(nz, 1), b_)
    free = np.ones((nz, N + 1))
    free[:nx - n_free, 0] = free[:nx - n_free, N] = 0.0  # x_0 and x_N pinned (but parameters): multipliers free
    return ca.Function("sqp_stationarity", [Js, Gs_, lams, nbs], [ca.mmax(ca.fabs(gr * ca.DM(free)))],
                       ["J", "G", "lam", "nb"], ["kkt"])


#: This module's source: a library built from another version of these functions is never reused.
_SOURCE_DIGEST = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]


def assemble_condensed(outputs, N: int, nx: int, nu: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The condensed QP from ``sqp_condense``'s outputs (flat numpy buffers, in its order): ``(Hc (nc, nc), fc
    (nc,), Ga (N, nx, nc + 1))`` with nc = (N+1) nu; ``Ga[k - 1] = [G_k, g_k]`` for knots k = 1..N (module
    docstring). New arrays, except ``Ga``: a view of the last output's buffer."""
    Yt, band, f_g, f_e, GT = outputs
    nc = (N + 1) * nu
    Yt, band, f_e = Yt.reshape(N, 2 * nu, nc), band.reshape(N, 2 * nu, 2 * nu), f_e.reshape(N, 2 * nu)
    Hc = np.zeros((nc, nc))  # rows of sum_k E_k' Y_k', then its transpose added
    Hc[:N * nu] += Yt[:, :nu].reshape(N * nu, nc)
    Hc[nu:] += Yt[:, nu:].reshape(N * nu, nc)
    Hc += Hc.T
    H4 = Hc.reshape(N + 1, nu, N + 1, nu)
    k0, k1 = np.arange(N), np.arange(1, N + 1)
    H4[k0, :, k0, :] += band[:, :nu, :nu]
    H4[k1, :, k1, :] += band[:, nu:, nu:]
    H4[k0, :, k1, :] += band[:, :nu, nu:]
    H4[k1, :, k0, :] += band[:, nu:, :nu]
    fc = f_g.copy()
    fc[:N * nu] += f_e[:, :nu].ravel()
    fc[nu:] += f_e[:, nu:].ravel()
    return Hc, fc, GT.reshape(N, nx, nc + 1)


def free_state_column(T, Hy, gy, Hc, fc, Gs, gs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The condensed QP (:func:`assemble_condensed`, ``dx_0 = 0``) with knot 0's last state entry free: its step,
    a parameter the stage dynamics carry (the SQP's time scale of a minimum-time problem), one more unknown, first.

    Its response ``t_k`` (nx) through the stage dynamics ``T`` (N, nz, nz + nu) from the unit step (``t_0 = e_nx``),
    its Hessian row and gradient entry from the stage blocks ``Hy`` (N, ny, ny), ``gy`` (N, ny) (``y_k = (t_k, 0,
    0)`` per unit step, against ``Y_k`` of the inputs' columns ``Gs`` (N, nx, nc) of knots 1..N and the constants
    ``gs`` (N, nx)), and its column of the states' map: ``(Hc (nc + 1, nc + 1), fc (nc + 1,), Gs (N, nx, nc + 1))``.
    O(N nc nx) in numpy: the route of the QPs the Riccati solver does not settle."""
    N, nz, ny = T.shape
    nu = ny - nz
    nx = nz - nu
    nc = Hc.shape[0]
    t = np.zeros((N + 1, nx))
    t[0, nx - 1] = 1.0
    for k in range(N):
        t[k + 1] = T[k, :nx, :nx] @ t[k]
    Ht = np.einsum("kij,kj->ki", Hy[:, :, :nx], t[:-1])  # (N, ny): Hy_k y_k per unit step
    G0 = np.concatenate([np.zeros((1, nx, nc)), Gs[:-1]])  # G_k of knots 0..N-1
    g0 = np.concatenate([np.zeros((1, nx)), gs[:-1]])
    row = np.einsum("kir,ki->r", G0, Ht[:, :nx])
    row[:N * nu] += Ht[:, nx:nz].ravel()  # du_k
    row[nu:] += Ht[:, nz:].ravel()  # w_k = du_k+1
    h_tt = float(np.einsum("ki,ki->", t[:-1], Ht[:, :nx]))
    f_t = float(np.einsum("ki,ki->", t[:-1], np.einsum("kij,kj->ki", Hy[:, :nx, :nx], g0) + gy[:, :nx]))
    H = np.empty((nc + 1, nc + 1))
    H[0, 0], H[0, 1:], H[1:, 0], H[1:, 1:] = h_tt, row, row, Hc
    return H, np.r_[f_t, fc], np.concatenate([t[1:, :, None], Gs], axis=2)


def compiled_qp_functions(nx: int, nu: int, N: int, reg_min: float, *, compiled: bool = True, n_free: int = 0
                          ) -> tuple[list[ca.Function], str | None]:
    """:func:`qp_functions` compiled to C and cached (one library per size and ``reg_min``), with the path of the
    library (``n_free`` as :func:`qp_functions`); CasADi's virtual machine (same numbers, and None) with ``compiled`` False, ``CARTPOLE_NO_COMPILE`` set
    or when the build fails (one line on stderr). The library is keyed by its recipe (the sizes, ``reg_min``,
    ``n_free``, the CasADi version and this module's source digest, :data:`_SOURCE_DIGEST`: everything
    :func:`qp_functions` generates from), so a cached one loads without building the Functions again."""
    if N < 2:
        raise OCPError(f"The SQP's QP functions need N >= 2 intervals, not {N}; use N >= 2 (100 is typical).")
    def build():
        recipe = f"sqp-qp/{nx}x{nu}x{N}/{n_free}/{reg_min!r}/{ca.__version__}/{_SOURCE_DIGEST}"
        lib, _ = build_library(lambda: qp_functions(nx, nu, N, reg_min, n_free), "", recipe=recipe, cflags=CFLAGS,
                               recipe_is_key=True)
        names = ("sqp_stages", "sqp_condense", "sqp_multipliers", "sqp_stationarity")
        ext = load_library(lib, names)
        return [ext[name] for name in names], lib

    built = compiled_or_none(build, "SQP QP functions", "using CasADi's virtual machine (same results)") \
        if compiled else None
    return built if built is not None else (qp_functions(nx, nu, N, reg_min, n_free), None)
