"""The functions a nonlinear MPC evaluates every control period, compiled to C (with the SX fallback).

One stage of the multiple-shooting problem is ``steps`` MJCF physics steps of the model's exact discrete step
(``model.step``: one step of the MJCF's own integrator) with the ctrl held, i.e. one control period. Its value and
its exact Jacobians come from one SX function of a single physics step, ``(x, u) -> (x+, dx+/dx, dx+/du)``, chained
``steps`` times by the chain rule (``A = A_m ... A_1``, ``B = sum A_m ... A_{i+1} B_i``) in an MX function. That
stage mapped over the ``N`` stages of the horizon, followed by the condensing of the Gauss-Newton QP onto the inputs
(:func:`_qp_data`), is one function: one call per SQP step gives the QP's Hessian, gradient and state predictions.
The generated C holds the single step once and each stage's condensing arithmetic once (``map`` and ``mapaccum``
loops), so its size grows neither with ``steps`` nor with ``N``, and any number of poles compiles in seconds, once
per model, period and horizon.

The shared library is cached like the collocation's (:mod:`cartpole.codegen`:
:func:`~cartpole.codegen.cache_dir`, keyed by :func:`~cartpole.codegen.model_key`, period, horizon,
variant, source, flags and CasADi version). With ``CARTPOLE_NO_COMPILE`` set, without a C compiler, or when the
build fails, the same CasADi functions run in CasADi's virtual machine (same numbers, slower), with a note on
stderr.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from cartpole.models import CartPoleModel
from cartpole.codegen import build_library, compiled_or_none, load_library, model_key


@dataclass(frozen=True)
class StageFunctions:
    """The horizon's stage evaluations for one model, period and horizon length.

    Attributes
    ----------
    qp_data : casadi.Function
        ``(x (nx,), S (nx, N+1), U (nu, N), x_goal (nx,), u_goal (nu,), Q (nx, nx), R (nu, nu), P (nx, nx)) ->
        (H (N nu, N nu), h (N nu,), g (nx, N+1), G (nx, N nu N) [, Fu (N nu, N nu), fu (N nu,)])``: the
        Gauss-Newton QP of one step from nodes ``S``, inputs ``U`` with ``s_0 = x``, condensed: cost
        ``1/2 z' H z + h' z`` (half the OCP's cost, constants dropped) and state corrections ``ds_k = g_k + G_k z``
        (``G`` holds ``G_1 .. G_N`` side by side; ``G_0 = 0``). Plain (:func:`_qp_data_plain`): ``z = du``, the
        input steps. Pre-stabilised (:func:`_qp_data_stabilized`): ``z = dv`` with ``du = fu + Fu dv``. Stages,
        Jacobians and condensing in one call.
    prestabilized : bool
        Which of the two.
    stage : casadi.Function
        One stage ``(x (nx,), u (nu,)) -> (x_next, A (nx, nx), B (nx, nu))`` (compiled with ``qp_data``).
    rollout : casadi.Function
        ``(x (nx,), U (nu, N)) -> (nx, N)``: the states after each stage from ``x`` under the inputs ``U`` (a
        forward simulation, to re-seed the iterate from a measured state).
    step_expr : casadi.Function
        One control period as one SX expression ``(x, u) -> x_next`` (for an NLP with ``expand=True``).
    library : str or None
        Path of the compiled shared library in use, None on the SX fallback.
    steps : int
        Physics steps per stage.
    N : int
        Stages.
    """

    qp_data: ca.Function
    prestabilized: bool
    rollout: ca.Function
    stage: ca.Function
    step_expr: ca.Function
    library: str | None
    steps: int
    N: int


def _one_step(model: CartPoleModel) -> ca.Function:
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    xn = model.step(x, u)
    return ca.Function("nmpc_step", [x, u], [xn, ca.jacobian(xn, x), ca.jacobian(xn, u)], ["x", "u"],
                       ["x_next", "A", "B"], {"cse": True})


def _chained(one: ca.Function, steps: int, nx: int, nu: int, sym=ca.MX, name: str = "nmpc_stage") -> ca.Function:
    x, u = sym.sym("x", nx), sym.sym("u", nu)
    xk, A, B = x, sym.eye(nx), sym.zeros(nx, nu)
    for _ in range(steps):
        xk, Ai, Bi = one(xk, u)
        A = ca.mtimes(Ai, A)
        B = ca.mtimes(Ai, B) + Bi
    if sym is ca.SX:  # one flat expression (the single step inlined ``steps`` times), dense Jacobians
        return ca.Function(name, [x, u], [xk, ca.densify(A), ca.densify(B)], ["x", "u"],
                           ["x_next", "A", "B"], {"cse": True})
    return ca.Function("nmpc_stage", [x, u], [xk, A, B], ["x", "u"], ["x_next", "A", "B"])


def stage_expression(model: CartPoleModel, steps: int, name: str = "nmpc_stage") -> ca.Function:
    """One stage ``(x (nx,), u (nu,)) -> (x_next (nx,), A (nx, nx), B (nx, nu))`` as one SX expression: the same
    chain rule over ``steps`` physics steps as :attr:`StageFunctions.stage` (the same values), the single step
    inlined ``steps`` times and the Jacobians dense, for straight-line generated C (the exported NMPC's).

    Parameters
    ----------
    model : CartPoleModel
    steps : int
        Physics steps per stage.
    name : str
        The Function's name (the C symbol it is generated under).

    Returns
    -------
    casadi.Function
    """
    return _chained(_one_step(model), int(steps), model.nx, model.nu, ca.SX, name)


def stage_rollout(model: CartPoleModel, steps: int, N: int, name: str = "nmpc_rollout") -> ca.Function:
    """``(x (nx,), U (nu, N)) -> S (nx, N)``: the states after each of ``N`` stages of ``steps`` physics steps from
    ``x`` under the inputs ``U`` (the forward simulation :attr:`StageFunctions.rollout` is).

    Parameters
    ----------
    model : CartPoleModel
    steps : int
        Physics steps per stage.
    N : int
        Stages.
    name : str
        The Function's name.

    Returns
    -------
    casadi.Function
    """
    step_expr = _period_expr(model, int(steps))
    x0, Ur = ca.MX.sym("x", model.nx), ca.MX.sym("U", model.nu, int(N))
    return ca.Function(name, [x0, Ur], [step_expr.mapaccum(int(N))(x0, Ur)], ["x", "U"], ["S"])


def _period_expr(model: CartPoleModel, steps: int) -> ca.Function:
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    xk = x
    for _ in range(steps):
        xk = model.step(xk, u)
    return ca.Function("nmpc_period", [x, u], [xk], ["x", "u"], ["x_next"])


def _condensing_inputs(stage: ca.Function, nx: int, nu: int, N: int) -> tuple:
    """The symbols both condensings take (``x``, ``S`` (nx, N+1), ``U`` (nu, N), ``x_goal``, ``u_goal``, ``Q``, ``R``,
    ``P``) and the stages along ``S``, ``U``: ``F`` (nx, N), ``A`` (nx, nx N), ``B`` (nx, nu N) and the shooting
    gaps ``c = F - S[:, 1:]``."""
    x, S, U = ca.MX.sym("x", nx), ca.MX.sym("S", nx, N + 1), ca.MX.sym("U", nu, N)
    goal, u_goal = ca.MX.sym("x_goal", nx), ca.MX.sym("u_goal", nu)
    Q, R, P = ca.MX.sym("Q", nx, nx), ca.MX.sym("R", nu, nu), ca.MX.sym("P", nx, nx)
    F, A, B = stage.map(N)(S[:, :N], U)  # (nx, N), (nx, nx N), (nx, nu N)
    return x, S, U, goal, u_goal, Q, R, P, F, A, B, F - S[:, 1:]


def _qp_data_plain(stage: ca.Function, nx: int, nu: int, N: int) -> ca.Function:
    """The condensed Gauss-Newton QP of one MPC step in the input steps ``du`` (MX; see
    :attr:`StageFunctions.qp_data`, ``prestabilized=False``).

    Forward: ``ds_0 = x - s_0``, ``ds_k+1 = A_k ds_k + B_k du_k + c_k`` (``c_k = F(s_k, u_k) - s_k+1``), so
    ``ds_k = g_k + G_k du`` with ``G_k+1 = A_k G_k + B_k E_k`` (``E_k`` selects ``du_k``). Backward (the O(N^2)
    condensing: no ``G' W G`` product): ``Lambda_N = P``, ``Lambda_k = Q + A_k' Lambda_k+1 A_k``, ``lambda_N =
    P e_N``, ``lambda_k = Q e_k + A_k' lambda_k+1`` with ``e_k = s_k + g_k - x*``; then row block ``i`` of the
    Hessian is ``B_i' Lambda_i+1 G_i+1`` (+ R on the diagonal block; ``G_i+1`` is zero right of block ``i``) and
    ``h_i = B_i' lambda_i+1 + R (u_i - u*)``. Both recursions are ``mapaccum`` loops over one stage's SX function
    and the rows a ``map``, so the generated C holds each stage's arithmetic once: compact for any N.
    """
    nz = N * nu
    x, S, U, goal, u_goal, Q, R, P, F, A, B, c = _condensing_inputs(stage, nx, nu, N)
    # forward: (g, G) accumulated; inputs A_k, B_k, c_k, E_k
    # (the per-stage functions are SX: unrolled, they run faster than MX's generic dense loops and still compile
    # in seconds)
    g_, G_ = ca.SX.sym("g", nx), ca.SX.sym("G", nx, nz)
    A_, B_, c_, E_ = ca.SX.sym("A", nx, nx), ca.SX.sym("B", nx, nu), ca.SX.sym("c", nx), ca.SX.sym("E", nu, nz)
    fwd = ca.Function("nmpc_fwd", [g_, G_, A_, B_, c_, E_],
                      [ca.mtimes(A_, g_) + c_, ca.mtimes(A_, G_) + ca.mtimes(B_, E_)]).mapaccum("nmpc_fwd_acc", N, 2)
    eye = np.eye(nz)
    E = ca.DM(np.hstack([eye[k * nu:(k + 1) * nu, :] for k in range(N)]))  # E_k side by side, (nu, nz N)
    gs, Gs = fwd(x - S[:, 0], ca.MX.zeros(nx, nz), A, B, c, E)  # (nx, N): g_1..g_N; (nx, nz N): G_1..G_N
    g_all = ca.horzcat(x - S[:, 0], gs)  # (nx, N+1)
    e = S + g_all - ca.repmat(goal, 1, N + 1)
    # backward over k = N-1 .. 0: (Lambda, lambda) accumulated; inputs A_k, e_k
    L_, l_, e_ = ca.SX.sym("L", nx, nx), ca.SX.sym("l", nx), ca.SX.sym("e", nx)
    Q_ = ca.SX.sym("Q", nx, nx)
    bwd = ca.Function("nmpc_bwd", [L_, l_, A_, e_, Q_],
                      [Q_ + ca.mtimes([A_.T, L_, A_]), ca.mtimes(Q_, e_) + ca.mtimes(A_.T, l_)]
                      ).mapaccum("nmpc_bwd_acc", N, 2)
    rev = list(range(N - 1, -1, -1))
    A_rev = ca.horzcat(*[A[:, k * nx:(k + 1) * nx] for k in rev])
    Ls, ls = bwd(P, ca.mtimes(P, e[:, N]), A_rev, e[:, rev], Q)  # Lambda_N-1..Lambda_0, lambda_N-1..lambda_0
    # Lambda_k+1, lambda_k+1 for k = 0..N-1: Lambda_1..Lambda_N-1 (outputs reversed), then P
    L_next = ca.horzcat(*[Ls[:, j * nx:(j + 1) * nx] for j in range(N - 2, -1, -1)], P)
    l_next = ca.horzcat(*[ls[:, j] for j in range(N - 2, -1, -1)], ca.mtimes(P, e[:, N]))
    # rows: H row block k = B_k' Lambda_k+1 G_k+1 (transposed: column block k of H'), h_k
    Gk1, Lk1, lk1, uk, ug_, R_ = (ca.SX.sym("G", nx, nz), ca.SX.sym("L", nx, nx), ca.SX.sym("l", nx),
                                  ca.SX.sym("u", nu), ca.SX.sym("ug", nu), ca.SX.sym("R", nu, nu))
    BtL = ca.mtimes(B_.T, Lk1)
    E_ = ca.SX.sym("E", nu, nz)
    D = ca.mtimes(BtL, B_)  # the diagonal block (without R)
    row = ca.Function("nmpc_row", [B_, Lk1, Gk1, E_, lk1, uk, ug_, R_],
                      [(ca.mtimes(BtL, Gk1) - ca.mtimes(D, E_)).T, D + R_,
                       ca.mtimes(B_.T, lk1) + ca.mtimes(R_, uk - ug_)]).map(N)
    # Ht (nz, nz): column block k = the strictly lower part of row block k of H; Dk the diagonal blocks
    Ht, Dk, h = row(B, L_next, Gs, E, l_next, U, u_goal, R)
    H = Ht + Ht.T + ca.diagcat(*ca.horzsplit(Dk, nu))
    return ca.Function("nmpc_qp_data", [x, S, U, goal, u_goal, Q, R, P],
                       [ca.densify(H), ca.vec(h), g_all, Gs],
                       ["x", "S", "U", "x_goal", "u_goal", "Q", "R", "P"], ["H", "h", "g", "G"])


def _qp_data_stabilized(stage: ca.Function, nx: int, nu: int, N: int) -> ca.Function:
    """The condensed, pre-stabilised Gauss-Newton QP of one MPC step (MX; see :attr:`StageFunctions.qp_data`,
    ``prestabilized=True``).

    The step of the inputs is written ``du_k = -K_k ds_k + dv_k`` and the QP is solved for ``dv`` (the closed-loop
    paradigm). ``K_k`` are the gains of the finite-horizon LQR along the current iterate (the Riccati recursion of
    ``A_k``, ``B_k``, ``Q``, ``R`` from ``P``). The prediction then runs on ``Abar_k = A_k - B_k K_k``, whose
    products stay moderate where those of ``A_k`` (an unstable plant) grow like ``exp(lambda t)`` and make the
    condensed QP of a long horizon, or of a fast chain of poles, ill-conditioned; with the exact Riccati gains the
    Hessian in ``dv`` is even block diagonal (the constraints carry the coupling).

    Forward: ``ds_0 = x - s_0``, ``ds_k+1 = Abar_k ds_k + B_k dv_k + c_k`` (``c_k = F(s_k, u_k) - s_k+1``), so
    ``ds_k = g_k + G_k dv`` with ``G_k+1 = Abar_k G_k + B_k E_k`` (``E_k`` selects ``dv_k``), and
    ``du_k = f_k + F_k dv`` with ``f_k = -K_k g_k``, ``F_k = E_k - K_k G_k``. Backward (the O(N^2) condensing, no
    ``G' W G``): ``Lambda_N = P``, ``Lambda_k = Q + K_k'RK_k + Abar_k' Lambda_k+1 Abar_k``, ``lambda_N = P e_N``,
    ``lambda_k = Q e_k - K_k' R r_k + Abar_k' lambda_k+1`` with ``e_k = s_k + g_k - x*``, ``r_k = u_k + f_k - u*``.
    Then block ``(i, j < i)`` of the Hessian is ``B_i' Lambda_i+1 G_i+1 - R K_i G_i`` at ``j``, block ``(i, i)``
    ``B_i' Lambda_i+1 B_i + R``, and ``h_i = B_i' lambda_i+1 + R r_i``. The recursions are ``mapaccum`` loops over
    one stage's SX function and the rows a ``map``, so the generated C holds each stage's arithmetic once.
    """
    nz = N * nu
    x, S, U, goal, u_goal, Q, R, P, F, A, B, c = _condensing_inputs(stage, nx, nu, N)
    rev = list(range(N - 1, -1, -1))
    A_rev = ca.horzcat(*[A[:, k * nx:(k + 1) * nx] for k in rev])
    B_rev = ca.horzcat(*[B[:, k * nu:(k + 1) * nu] for k in rev])
    # (the per-stage functions are SX: unrolled, they run faster than MX's generic dense loops and still compile
    # in seconds)
    g_, G_ = ca.SX.sym("g", nx), ca.SX.sym("G", nx, nz)
    A_, B_, c_, E_, K_ = (ca.SX.sym("A", nx, nx), ca.SX.sym("B", nx, nu), ca.SX.sym("c", nx), ca.SX.sym("E", nu, nz),
                          ca.SX.sym("K", nu, nx))
    Q_, R_, Pn_ = ca.SX.sym("Q", nx, nx), ca.SX.sym("R", nu, nu), ca.SX.sym("Pn", nx, nx)
    # Riccati backward over k = N-1 .. 0: P accumulated, K_k out
    BtP = ca.mtimes(B_.T, Pn_)
    Kk = ca.solve(R_ + ca.mtimes(BtP, B_), ca.mtimes(BtP, A_))
    Acl = A_ - ca.mtimes(B_, Kk)
    ric = ca.Function("nmpc_riccati", [Pn_, A_, B_, Q_, R_],
                      [Q_ + ca.mtimes([Kk.T, R_, Kk]) + ca.mtimes([Acl.T, Pn_, Acl]), Kk]
                      ).mapaccum("nmpc_riccati_acc", N, 1)
    _, K_rev = ric(P, A_rev, B_rev, Q, R)  # K_N-1 .. K_0
    K = ca.horzcat(*[K_rev[:, j * nx:(j + 1) * nx] for j in rev])  # K_0 .. K_N-1, (nu, nx N)
    Ab_ = A_ - ca.mtimes(B_, K_)
    # forward, (g, G) accumulated; also out: f_k = -K g_k, F_k = E_k - K G_k (of the stage's incoming g, G)
    fwd = ca.Function("nmpc_fwd", [g_, G_, A_, B_, c_, E_, K_],
                      [ca.mtimes(Ab_, g_) + c_, ca.mtimes(Ab_, G_) + ca.mtimes(B_, E_), -ca.mtimes(K_, g_),
                       E_ - ca.mtimes(K_, G_)]).mapaccum("nmpc_fwd_acc", N, 2)
    eye = np.eye(nz)
    E = ca.DM(np.hstack([eye[k * nu:(k + 1) * nu, :] for k in range(N)]))  # E_k side by side, (nu, nz N)
    g0 = x - S[:, 0]
    gs, Gs, fs, Fs = fwd(g0, ca.MX.zeros(nx, nz), A, B, c, E, K)  # g_1..g_N, G_1..G_N, f_0..f_N-1, F_0..F_N-1
    g_all = ca.horzcat(g0, gs)  # (nx, N+1)
    e = S + g_all - ca.repmat(goal, 1, N + 1)
    r = U + fs - ca.repmat(u_goal, 1, N)  # (nu, N)
    # backward over k = N-1 .. 0: (Lambda, lambda) accumulated
    L_, l_, e_, r_ = ca.SX.sym("L", nx, nx), ca.SX.sym("l", nx), ca.SX.sym("e", nx), ca.SX.sym("r", nu)
    KtR = ca.mtimes(K_.T, R_)
    bwd = ca.Function("nmpc_bwd", [L_, l_, A_, B_, K_, e_, r_, Q_, R_],
                      [Q_ + ca.mtimes(KtR, K_) + ca.mtimes([Ab_.T, L_, Ab_]),
                       ca.mtimes(Q_, e_) - ca.mtimes(KtR, r_) + ca.mtimes(Ab_.T, l_)]
                      ).mapaccum("nmpc_bwd_acc", N, 2)
    lN = ca.mtimes(P, e[:, N])
    K_rev2 = ca.horzcat(*[K[:, k * nx:(k + 1) * nx] for k in rev])
    Ls, ls = bwd(P, lN, A_rev, B_rev, K_rev2, e[:, rev], r[:, rev], Q, R)  # Lambda_N-1..Lambda_0, lambda_N-1..lambda_0
    # Lambda_k+1, lambda_k+1 for k = 0..N-1: Lambda_1..Lambda_N-1 (outputs reversed), then P
    L_next = ca.horzcat(*[Ls[:, j * nx:(j + 1) * nx] for j in range(N - 2, -1, -1)], P)
    l_next = ca.horzcat(*[ls[:, j] for j in range(N - 2, -1, -1)], lN)
    G_prev = ca.horzcat(ca.MX.zeros(nx, nz), Gs[:, :nz * (N - 1)])  # G_0..G_N-1
    # rows: the strictly lower part of H's row block k (transposed: column block k of Ht), its diagonal block, h_k
    Gk1, Gk, Lk1, lk1 = ca.SX.sym("G1", nx, nz), ca.SX.sym("G0", nx, nz), ca.SX.sym("L", nx, nx), ca.SX.sym("l", nx)
    BtL = ca.mtimes(B_.T, Lk1)
    D = ca.mtimes(BtL, B_)
    row = ca.Function("nmpc_row", [B_, K_, Lk1, Gk1, Gk, E_, lk1, r_, R_],
                      [(ca.mtimes(BtL, Gk1) - ca.mtimes(D, E_) - ca.mtimes([R_, K_, Gk])).T, D + R_,
                       ca.mtimes(B_.T, lk1) + ca.mtimes(R_, r_)]).map(N)
    Ht, Dk, h = row(B, K, L_next, Gs, G_prev, E, l_next, r, R)
    H = Ht + Ht.T + ca.diagcat(*ca.horzsplit(Dk, nu))
    Fu = ca.vertcat(*ca.horzsplit(Fs, nz))  # (nz, nz): row block k = F_k
    return ca.Function("nmpc_qp_data", [x, S, U, goal, u_goal, Q, R, P],
                       [ca.densify(H), ca.vec(h), g_all, Gs, ca.densify(Fu), ca.vec(fs)],
                       ["x", "S", "U", "x_goal", "u_goal", "Q", "R", "P"], ["H", "h", "g", "G", "Fu", "fu"])


def stage_functions(model: CartPoleModel, steps: int, N: int, *, compiled: bool = True,
                    prestabilized: bool = False) -> StageFunctions:
    """Build (and, unless ``compiled`` is False or ``CARTPOLE_NO_COMPILE`` is set, compile to C) the stage functions.

    Parameters
    ----------
    model : CartPoleModel
        Its ``step`` is one physics step of ``model.dt`` s (the MJCF's integrator); any number of poles.
    steps : int
        Physics steps per stage (control period = ``steps * model.dt``).
    N : int
        Stages in the horizon.
    compiled : bool
        False keeps CasADi's virtual machine (the fallback, same numbers).
    prestabilized : bool
        Condense in the steps relative to the Riccati feedback (:func:`_qp_data_stabilized`) instead of the
        input steps (:func:`_qp_data_plain`): well conditioned over long horizons, about twice the evaluation cost.

    Returns
    -------
    StageFunctions
    """
    nx, nu = model.nx, model.nu
    one = _one_step(model)
    stage = _chained(one, steps, nx, nu)
    qp_data = (_qp_data_stabilized if prestabilized else _qp_data_plain)(stage, nx, nu, N)
    step_expr = _period_expr(model, steps)
    rollout = stage_rollout(model, steps, N)
    library = None

    def build():
        lib, _ = build_library([stage, qp_data, rollout], model_key(model) + f"/{steps}x{N}/{int(prestabilized)}")
        return lib, load_library(lib, ("nmpc_stage", "nmpc_qp_data", "nmpc_rollout"))

    built = compiled_or_none(build, "NMPC functions") if compiled else None
    if built is not None:
        library, ext = built
        stage, qp_data, rollout = ext["nmpc_stage"], ext["nmpc_qp_data"], ext["nmpc_rollout"]
    return StageFunctions(stage=stage, qp_data=qp_data, prestabilized=bool(prestabilized), rollout=rollout,
                          step_expr=step_expr, library=library,
                          steps=int(steps), N=int(N))
