"""SQP for the compressed Hermite-Simpson collocation NLP of :class:`~cartpole.ocp.collocation.DirectCollocation`
(effort, a running cost, or minimum time through the time scale ``tau = T / T_0``, one more state free at the first
knot): the same scaled variables, defects, bounds and objective as its IPOPT path, so the same optimum.

Each iteration builds, in compiled C (:mod:`cartpole.solvers.sqp_functions`), the QP of the exact Lagrangian Hessian
and the linearised defects in stage form (the defects read as dynamics ``s_k+1 = T_k (s_k, w_k) + t_k`` with the
stage state ``s_k = dz_k`` and control ``w_k = du_k+1``) and solves it by Riccati recursions with a primal-dual
active set in C (:mod:`cartpole.solvers.riccati_qp`), with IPOPT's inertia correction where the Hessian is not
convex on the active set. A QP that active set does not settle, an infeasible linearisation (then with soft state
rows) and every QP without a C compiler go to DAQP on the QP condensed onto the knot controls. Steps are globalised
by a filter line search on (``||d||_1``, cost) with a second-order correction. Why these two QP solvers and no
other, with the measurements: the benchmarks page ("The collocation SQP's QP solvers").
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import replace
from typing import ClassVar, NamedTuple

import casadi as ca
import daqp
import numpy as np

from cartpole.codegen import Buffered
from cartpole.ocp import compiled_nlp
from cartpole.solvers import riccati_qp, sqp_functions
from cartpole.ocp.bounds import OCPError
from cartpole.ocp.collocation import DirectCollocation
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory
from cartpole.options import StageOptions


class SQPError(OCPError):
    """The SQP solver cannot be set up for this problem, or its solve did not converge."""


#: QP solvers: ``riccati`` (the stage QP by Riccati recursions and a primal-dual active set, in C:
#: :mod:`cartpole.solvers.riccati_qp`; a QP it cannot settle goes to ``daqp``) and ``daqp`` (the stage QP condensed
#: onto the knot controls, DAQP's dense dual active set, with soft state rows when the hard QP is infeasible).
QP_SOLVERS = ("riccati", "daqp")
_BIG = 1e30  # DAQP's "no bound"
_GAMMA = 1e-5  # the filter's margin
#: Largest relative change of a minimum-time problem's duration in one SQP step.
TAU_STEP = 0.5


@dataclasses.dataclass(frozen=True, eq=False)
class SQPOptions(StageOptions):
    """Settings of :class:`CollocationSQP`, validated on creation.

    Attributes
    ----------
    tol : float
        Converged when the largest defect and the largest entry of the Lagrangian's gradient (bound multipliers
        included, scaled units) are below ``tol`` (> 0; default 1e-8, the collocation's IPOPT ``tol``).
    max_iter : int
        SQP iterations (>= 0) before the solve counts as failed (default 200).
    reg_min : float
        Smallest eigenvalue (>= 0) a stage's reduced Hessian keeps (default 1e-4, scaled units).
    lm_init : float
        First Levenberg-Marquardt damping (>= 0) of the stage Hessian blocks (default 1e-2; the scaled effort Hessian's
        diagonal is about 1e-2 at N = 100).
    qp_solver : {'riccati', 'daqp'}
        The QP solver (:data:`QP_SOLVERS`); DAQP backs up the Riccati solver, which needs a C compiler (without one,
        or with the problem's ``compiled`` False, DAQP is used).
    warm_qp : bool
        Hot-start each QP from the previous one's multipliers (active set); default True.
    soc : bool
        Try a second-order correction before shortening a rejected full step; default True.
    max_step : float
        Longest step (> 0, max over the scaled variables) taken; longer QP steps are shortened (default 1).
    exact_hessian_below : float
        Largest scaled defect (>= 0) at which the Hessian includes the defects' curvature (the exact Lagrangian);
        above it, the cost's only (default 0.1; why: docs/architecture.md, SQP).
    max_unsettled : int or None
        With ``qp_solver="riccati"``: feasible QPs the Riccati active set may hand to DAQP (infeasible linearisations,
        which DAQP solves with soft rows, are not counted) before the solve stops with status ``QP_Unsettled`` (None,
        the default: no limit). A feasible linearisation it cannot settle again and again makes each iteration cost a
        dense condensed QP, where IPOPT on the sparse problem is the better solver; the planner stops early
        (:data:`cartpole.planning.trajopt.SQP_MAX_UNSETTLED`) and lets IPOPT take over.

    Raises
    ------
    SQPError
        An unknown ``qp_solver`` or a number outside the ranges above.
    """

    tol: float = 1e-8
    max_iter: int = 200
    reg_min: float = 1e-4
    lm_init: float = 1e-2
    qp_solver: str = "riccati"
    warm_qp: bool = True
    soc: bool = True
    max_step: float = 1.0
    exact_hessian_below: float = 1e-1
    max_unsettled: int | None = None

    error: ClassVar[type] = SQPError
    SCALARS: ClassVar[tuple] = ("tol", "max_iter", "reg_min", "lm_init", "max_step", "exact_hessian_below",
                                "max_unsettled")

    def __post_init__(self):
        if self.qp_solver not in QP_SOLVERS:
            raise SQPError(f"qp_solver '{self.qp_solver}' is not one of {', '.join(QP_SOLVERS)}.")
        self.number("tol", low=0.0, low_open=True)
        self.number("max_iter", low=0, integer=True)
        self.number("reg_min", low=0.0)
        self.number("lm_init", low=0.0)
        self.number("max_step", low=0.0, low_open=True)
        self.number("exact_hessian_below", low=0.0)
        self.number("max_unsettled", low=0, integer=True, optional=True)
        self.set_field("warm_qp", bool(self.warm_qp))
        self.set_field("soc", bool(self.soc))


class _StageQP(NamedTuple):
    """One SQP step's QP in stage form (CasADi's compiled ``sqp_stages`` outputs, reshaped): the stage dynamics
    ``T`` (N, nz, nz + nw) and offsets ``ct`` (N, nx), the stage Hessians ``Hy`` (N, ny, ny) and gradients ``gy``
    (N, ny), and the defects' maps ``M`` (N, nx, nx)."""
    T: np.ndarray
    ct: np.ndarray
    Hy: np.ndarray
    gy: np.ndarray
    M: np.ndarray


def _positive_definite(H: np.ndarray) -> np.ndarray:
    """``H`` (n, n) if its Cholesky factorisation exists, else ``H + delta I`` with the least ``delta`` of ``1e-8``,
    ``1e-7``, ... times its largest diagonal entry that makes it so: DAQP factorises the condensed Hessian whole, where
    the Riccati solver's inertia test saw only the reduced Hessians of its active set."""
    try:
        np.linalg.cholesky(H)
        return H
    except np.linalg.LinAlgError:
        pass
    scale = max(float(np.abs(np.diag(H)).max()), 1e-12)
    n = H.shape[0]
    for e in range(-8, 3):
        Hs = H + (scale * 10.0 ** e) * np.eye(n)
        try:
            np.linalg.cholesky(Hs)
            return Hs
        except np.linalg.LinAlgError:
            continue
    return H  # DAQP reports it


def _time_scaled(f: ca.Function, effort_weight: float) -> tuple[ca.Function, ca.Function]:
    """The minimum-time problem as a fixed-duration one (docs/architecture.md, SQP): the dynamics of ``(x, tau)`` on the
    reference clock, ``(tau f(x, u), 0)``, and the running cost ``tau (1 + effort_weight u'u)``, whose integral over
    the reference duration ``T_0`` is ``T + effort_weight integral u'u dt`` (``T = tau T_0``). Hermite-Simpson with
    step ``h_0`` on these is Hermite-Simpson with step ``tau h_0`` on ``f``: the collocation's free-time NLP."""
    nx, nu = f.size1_in(0), f.size1_in(1)
    xs, us = ca.SX.sym("x", nx + 1), ca.SX.sym("u", nu)
    tau = xs[nx]
    fs = ca.Function("f_time_scaled", [xs, us], [ca.vertcat(tau * f(xs[:nx], us), 0)], ["x", "u"], ["xdot"])
    cost = ca.Function("time_cost", [xs, us], [tau * (1 + effort_weight * ca.sumsqr(us))], ["x", "u"], ["l"])
    return fs, cost


class CollocationSQP:
    """The Hermite-Simpson swing-up of a :class:`DirectCollocation` solved by SQP on its stage-structured QP.

    Same NLP as the collocation's IPOPT path (same scaled variables, defects, bounds, objective), so the same
    optimum from the same guess; built once, solved many times.

    Parameters
    ----------
    ocp : DirectCollocation
        The problem: model, N, T, bounds, objective ``effort``, a running cost (``tracking``, the ``dmc_*`` rewards,
        ``MODULE:FUNCTION``) or ``time`` (T free: by its time scale; the Riccati QP solver only).
        Each QP on the exact Hessian first, with IPOPT's inertia correction (docs/architecture.md, SQP).
    options : SQPOptions, optional
        The solver's settings: tolerance, iterations, regularisation, QP solver, globalisation (default
        ``SQPOptions()``).

    Attributes
    ----------
    library : str or None
        The compiled knot-shared functions in use (:func:`cartpole.ocp.compiled_nlp.knot_maps`; None: CasADi's
        virtual machine, same numbers).
    qp_library : str or None
        The compiled QP-building functions in use (:mod:`cartpole.solvers.sqp_functions`; None: the virtual machine).
    history : list of dict
        Per iteration of the last solve: ``objective`` (scaled), ``infeasibility`` (max defect), ``stationarity``,
        ``step`` (max scaled step), ``damping`` (the Levenberg-Marquardt ``delta`` used), ``alpha`` (line-search
        step), ``soc`` (the second-order correction was taken).
    qp_counts : dict
        QP solves of the last solve per solver (``daqp``: DAQP calls, row screening included;
        ``riccati``: the Riccati active set's convexified QPs, ``riccati_exact`` its QPs on the exact Hessian,
        ``riccati_unsettled`` those it handed to DAQP).
    qp_soft : int
        QPs of the last solve solved with soft state rows (``daqp`` only: the hard QP was infeasible).
    """

    def __init__(self, ocp: DirectCollocation, *, options: SQPOptions | None = None):
        options = SQPOptions() if options is None else options
        if not isinstance(options, SQPOptions):
            raise SQPError(f"options must be an SQPOptions; got {type(options).__name__}.")
        if not isinstance(ocp, DirectCollocation):
            raise SQPError("CollocationSQP needs a DirectCollocation problem (cartpole.ocp.collocation).")
        if ocp.separated:
            raise SQPError("The SQP solver works on the compressed transcription; build the problem with "
                           "CollocationOptions(separated=False).")
        kind = ocp.objective_spec.kind
        if kind not in ("effort", "running", "time"):
            raise SQPError(f"The SQP solver handles effort, time and the running costs, not '{ocp.objective}'; "
                           f"solve it with IPOPT (DirectCollocation.solve).")
        qp_solver = options.qp_solver
        # minimum time: the time scale tau = T / T_0 is one more state, free at knot 0 (docs/architecture.md); only the
        # Riccati solver has a free state at knot 0
        self._np = 1 if kind == "time" else 0
        if self._np and not (qp_solver == "riccati" and ocp.compiled
                             and riccati_qp.available(ocp.nx + 1, ocp.nu, 1)):
            raise SQPError("The SQP solves minimum-time problems with its Riccati QP solver only (compiled, so it "
                           "needs a C compiler); solve them with IPOPT (DirectCollocation.solve).")
        if qp_solver == "riccati" and not (ocp.compiled and riccati_qp.available(ocp.nx, ocp.nu)):
            qp_solver = "daqp"  # no C compiler: the condensed route (same answers)
        self.options = options
        self.qp_solver, self.warm_qp, self.soc = qp_solver, options.warm_qp, options.soc
        self.lm_init, self.max_step = float(options.lm_init), float(options.max_step)
        self.exact_hessian_below = float(options.exact_hessian_below)
        self.max_unsettled = options.max_unsettled
        self.ocp = ocp
        self.tol, self.max_iter, self.reg_min = float(options.tol), int(options.max_iter), float(options.reg_min)
        N, nu = ocp.N, ocp.nu
        nx = ocp.nx + self._np  # the solver's states: the model's, then tau
        self.N, self.nx, self.nu, self.nz = N, nx, nu, nx + nu
        self.nw = nu  # stage controls: du_k+1
        sc = ocp.scale
        self.sx, self.su = np.r_[sc[:ocp.nx], np.ones(self._np)], np.array(sc[ocp.nx:])
        # the IPOPT problem's objective scaling (DirectCollocation._build): effort / (sum su^2 T)
        run = ocp.objective_spec.running if kind == "running" else None
        dynamics = ocp.model
        if self._np:
            dynamics, run = _time_scaled(ocp.model.f, ocp.time_effort_weight)
        self._running = run is not None
        self._cost_div = 1.0 if self._np else float(ocp.T) * (1.0 if self._running else float(np.sum(self.su ** 2)))
        # each knot's dynamics and curvature once, the intervals' parts between them (compiled_nlp.knot_functions),
        # the maps generated into one library per model and N
        maps, self.library = compiled_nlp.knot_maps(dynamics, N, self.sx, self.su, running=run, compiled=ocp.compiled)
        self._kf, self._mid1, self._mid2, self._kh = (Buffered(maps[n]) for n in compiled_nlp.KNOT_FUNCTIONS)
        funcs, self.qp_library = sqp_functions.compiled_qp_functions(nx, nu, N, self.reg_min, compiled=ocp.compiled,
                                                                     n_free=self._np)
        # each QP is first solved on the exact Hessian with IPOPT's inertia correction (docs/architecture.md, SQP), the
        # convexified QP only where that fails
        self._stages_raw = None
        if qp_solver == "riccati":
            raw, _ = sqp_functions.compiled_qp_functions(nx, nu, N, -np.inf, compiled=ocp.compiled, n_free=self._np)
            self._stages_raw = Buffered(raw[0])
        self._rqp = riccati_qp.StageQP(N, nx, nu, n_free=self._np) if qp_solver == "riccati" else None
        self._stages, self._condense, self._mult, self._stat = (Buffered(f) for f in funcs)
        self.qp_counts: dict[str, int] = {}
        self.history: list[dict] = []

    # ---- evaluations ----------------------------------------------------------------------------------------
    def _first_order(self, Z: np.ndarray):
        """At knots ``Z`` (N+1, nz): the defects (N, nx), their Jacobian blocks (N, nx, 2 nz), the cost, its
        gradient blocks (N, 2 nz), and the knots' ``f`` (N+1, nx) and its Jacobian (flat, CasADi's (nx, nz) blocks)
        for :meth:`_hessian` (copies)."""
        N, nx, nz = self.N, self.nx, self.nz
        nv, nj = 2 * nz, nx * nz
        Z = np.ascontiguousarray(Z)
        F, JF = (a.copy() for a in self._kf(Z))
        D, JD, E, GE = self._mid1(Z[:-1], Z[1:], F[:-nx], F[nx:], JF[:-nj], JF[nj:], self._h)
        D = D.reshape(N, nx).copy()
        J = JD.reshape(N, nv, nx).transpose(0, 2, 1).copy()
        f = float(E.sum()) / self._cost_div
        G = GE.reshape(N, nv) / self._cost_div
        return D, J, f, G, F, JF

    def _hessian(self, Z: np.ndarray, D: np.ndarray, lam: np.ndarray, F: np.ndarray, JF: np.ndarray) -> np.ndarray:
        """The Lagrangian's Hessian blocks (N, 2 nz, 2 nz) at knots ``Z`` with defects ``D``, defect multipliers
        ``lam`` (N, nx) and the knots' ``F``, ``JF`` of :meth:`_first_order`; far from feasible (docs/architecture.md)
        the cost's alone. Each knot's own curvature (weighted by both intervals touching it) is added to the block
        of the interval it starts (the last knot's to the last interval): the blocks sum to the NLP's Hessian."""
        N, nx, nz = self.N, self.nx, self.nz
        nv, nj = 2 * nz, nx * nz
        if float(np.abs(D).max()) > self.exact_hessian_below:  # far from feasible: the cost's curvature only
            lam = np.zeros_like(lam)
        Z = np.ascontiguousarray(Z)
        HM, WK, WK1 = self._mid2(Z[:-1], Z[1:], F[:-nx], F[nx:], JF[:-nj], JF[nj:], self._h,
                                 np.ascontiguousarray(lam), 1.0 / self._cost_div)
        H = HM.reshape(N, nv, nv).copy()  # symmetric: CasADi's column-major block is its transpose
        W = np.zeros((N + 1, nx))
        W[:-1] += WK.reshape(N, nx)
        W[1:] += WK1.reshape(N, nx)
        (KH,) = self._kh(Z, W)
        KH = KH.reshape(N + 1, nz, nz)
        H[:, :nz, :nz] += KH[:-1]
        H[-1, nz:, nz:] += KH[-1]
        return H

    def _eval(self, Z: np.ndarray, lam: np.ndarray):
        """At knots ``Z`` (N+1, nz) with defect multipliers ``lam`` (N, nx): :meth:`_first_order`'s first four and
        the Lagrangian's Hessian blocks (N, 2 nz, 2 nz) (copies)."""
        D, J, f, G, F, JF = self._first_order(Z)
        return D, J, f, G, self._hessian(Z, D, lam, F, JF)

    def _merit_parts(self, Z: np.ndarray) -> tuple[float, float, np.ndarray]:
        """Cost, l1 norm of the defects and the defects (N, nx) at knots ``Z``; the first-order parts kept in
        ``_trial`` (the point accepted next is usually this one: they are not evaluated twice)."""
        D, J, f, G, F, JF = self._first_order(Z)
        self._trial = (Z, D, J, f, G, F, JF)
        return f, float(np.abs(D).sum()), D

    # ---- one QP ---------------------------------------------------------------------------------------------
    def _qp_step(self, Z, D, J, G, H, lbz, ubz, lm: float):
        """The SQP step from ``Z``: ``(dZ (N+1, nz), defect multipliers (N, nx), bound multipliers (N+1, nz),
        success)``."""
        N, nx, nz = self.N, self.nx, self.nz
        ny = nz + self.nw
        if self._stages_raw is not None:  # the exact Hessian's QP first (docs/architecture.md, SQP)
            T, ct, Hy, gy, M = self._stages_raw(J, H, G, D, float(lm))
            T, ct = T.reshape(N, nz, ny), ct.reshape(N, nx)
            Hy, gy, M = Hy.reshape(N, ny, ny), gy.reshape(N, ny), M.reshape(N, nx, nx)
            rq = self._rqp
            held = rq.active.copy()
            lo, hi = self._step_bounds(Z, lbz, ubz)
            diag = np.arange(ny)
            delta = 0.0
            for _ in range(12):  # IPOPT's inertia correction: no shift first, then a third of the last one (1e-4 the
                # first time) up by 8
                if delta > 0.0:
                    Hs = Hy.copy()
                    Hs[:, diag, diag] += delta
                else:
                    Hs = Hy
                st = rq.solve(T, ct, Hs, gy, lo, hi)
                if st != 1:
                    break
                delta = (max(1e-20, self._delta / 3) if self._delta > 0 else 1e-4) if delta == 0.0 else 8 * delta
                rq.active[:] = held
            if st == 0:
                self._delta = delta if delta > 0 else self._delta
                self.qp_counts["riccati_exact"] += 1
                return self._riccati_step(Hs, gy, T, H, G, M)
            if st in (2, 3):  # convex where the active set stopped, but not settled: the same QP condensed for DAQP
                self.qp_counts["riccati_unsettled"] += 1
                self._delta = delta if delta > 0 else self._delta
                out = self._daqp_step(Z, _StageQP(T, ct, Hs, gy, M), H, G, lbz, ubz, exact=True)
                if out is not None:
                    if not self._soft_step:
                        self._unsettled_feasible += 1
                    rq.reset()
                    return out
            rq.active[:] = held
        # stage form, Levenberg-Marquardt damping and convexification in one compiled call (sqp_functions)
        T, ct, Hy, gy, M = self._stages(J, H, G, D, float(lm))
        T, ct = T.reshape(N, nz, ny), ct.reshape(N, nx)
        Hy, gy, M = Hy.reshape(N, ny, ny), gy.reshape(N, ny), M.reshape(N, nx, nx)
        if self._rqp is not None:
            rq = self._rqp
            status = rq.solve(T, ct, Hy, gy, *self._step_bounds(Z, lbz, ubz))
            self.qp_counts["riccati"] += 1
            if status == 0:
                return self._riccati_step(Hy, gy, T, H, G, M)
            self.qp_counts["riccati_unsettled"] += 1
            rq.reset()  # this QP goes to DAQP (a minimum time's with d tau one more unknown); the next starts afresh
        out = self._daqp_step(Z, _StageQP(T, ct, Hy, gy, M), H, G, lbz, ubz)
        if out is not None:
            if self._rqp is not None and not self._soft_step:
                self._unsettled_feasible += 1  # a feasible QP the Riccati active set could not settle
            return out
        self._warm_ready = False  # DAQP failed: the solve ends (QP_Failed)
        return np.zeros((N + 1, nz)), np.zeros((N, nx)), np.zeros((N + 1, nz)), False

    def _step_bounds(self, Z, lbz, ubz) -> tuple[np.ndarray, np.ndarray]:
        """The QP's bounds on the step from ``Z``: the knots' bounds, and for a minimum-time problem a trust region
        on the time scale (a relative change of at most :data:`TAU_STEP` an iteration: the first linearisations
        of a far guess ask for durations the plan cannot reach)."""
        lo, hi = lbz - Z, ubz - Z
        if self._np:
            c = self.nx - 1
            tau = Z[0, c]
            lo[0, c], hi[0, c] = max(lo[0, c], -TAU_STEP * tau), min(hi[0, c], TAU_STEP * tau)
        return lo, hi

    def _riccati_step(self, Hy, gy, T, H, G, M):
        """:meth:`_qp_step`'s answer from the Riccati solver's last solve (of the QP with stage Hessians ``Hy``): the
        step, the defects' multipliers by the stage dynamics' backward recursion (compiled), the bounds'."""
        dZ, Nb = self._rqp.dz.copy(), self._rqp.nb.copy()
        (lam,) = self._mult(dZ, Nb[:, :self.nx], Hy, gy, T, H, G, M)
        return dZ, lam.reshape(self.N, self.nx).copy(), Nb, True

    def _daqp_step(self, Z, stage: _StageQP, H, G, lbz, ubz, *, exact: bool = False):
        """The stage QP condensed onto the knot controls ``v = (du_0 .. du_N)`` ((N+1) nu, the states
        ``dx_k = g_k + G_k v`` by the stage dynamics, ``dx_0 = 0``) and solved by DAQP, hot-started from the previous
        QP's multipliers. The ctrl bounds are bounds on ``v``; the finite state bounds (rail, limited joints, the
        pinned ``x_N``) rows of ``G_k``, screened: DAQP sees the equalities and the rows active in the last QP, and
        any row its answer violates is added and the QP solved again (the answer is the full QP's: the rows left out
        are inactive). The multipliers of the stage dynamics follow by the backward recursion of the stage states'
        stationarity (compiled, :mod:`cartpole.solvers.sqp_functions`). An infeasible QP (the
        linearised defects cannot meet the state bounds) is
        solved again with those rows soft: the step then leaves the bounds, is projected back into them, and the
        filter judges the defects that leaves. ``exact``: ``Hy`` are exact (inertia-corrected) stage blocks, whose
        condensed Hessian may be indefinite where the Riccati solver's test saw only its active set's reduced
        Hessians (shifted then, :func:`_positive_definite`). ``stage`` is the QP in stage form (:class:`_StageQP`).
        Returns what :meth:`_qp_step` does, or None when DAQP failed."""
        T, ct, Hy, gy, M = stage
        N, nx, nu, nz = self.N, self.nx, self.nu, self.nz
        nc = (N + 1) * nu
        # condensed in one compiled call (sqp_functions): the stages' parts of the Hessian and gradient, and
        # [G_k, g_k] of knots 1..N (G_0 = 0, g_0 = 0)
        Hc, fc, Ga = sqp_functions.assemble_condensed(self._condense(T, ct, Hy, gy), N, nx, nu)  # knots 1..N
        Gs, gs = Ga[:, :, :nc], Ga[:, :, nc]
        dz_lo, dz_hi = self._step_bounds(Z, lbz, ubz)
        vb_hi = np.minimum(dz_hi[:, nx:].ravel(), _BIG)
        vb_lo = np.maximum(dz_lo[:, nx:].ravel(), -_BIG)
        if self._np:  # the time scale's step one more unknown, first: its column appended to the condensed QP
            Hc, fc, Gs = sqp_functions.free_state_column(T, Hy, gy, Hc, fc, Gs, gs)
            vb_hi = np.r_[min(dz_hi[0, nx - 1], _BIG), vb_hi]
            vb_lo = np.r_[max(dz_lo[0, nx - 1], -_BIG), vb_lo]
        nv = nc + self._np
        if exact or self._np:  # the convexified stage blocks make it positive definite; exact ones, or tau's row,
            # need not be
            Hc = _positive_definite(Hc)
        ri, rc = self._rows_k, self._rows_i  # knots >= 1: the rows of knot k are Ga[k - 1]
        A_all = Gs[ri - 1, rc, :]
        lo = dz_lo[ri, rc] - gs[ri - 1, rc]
        hi = dz_hi[ri, rc] - gs[ri - 1, rc]
        hi_c, lo_c = np.minimum(hi, _BIG), np.maximum(lo, -_BIG)
        warm = self.warm_qp and self._warm_ready
        lam_prev = self._daqp_lam if warm else None
        nr = ri.size
        v, lam_all, flag, soft = None, None, -1, False
        for sense_all in (self._sense_hard, self._sense_soft):
            # rows screened: the equalities, the rows active in the last QP, then any row the answer violates
            inset = self._row_eq.copy()
            if lam_prev is not None:
                inset |= lam_prev[nv:] != 0
            for _ in range(nr + 1):
                sel = np.flatnonzero(inset)
                sense = np.concatenate((sense_all[:nv], sense_all[nv:][sel]))
                dual = None if lam_prev is None else np.concatenate((lam_prev[:nv], lam_prev[nv:][sel]))
                v, _, flag, info = daqp.solve(Hc, fc, A_all[sel], np.concatenate((vb_hi, hi_c[sel])),
                                              np.concatenate((vb_lo, lo_c[sel])), sense, dual_start=dual,
                                              iter_limit=2000)
                self.qp_counts["daqp"] += 1
                if flag not in (1, 2):
                    if dual is not None:  # a hot start that failed: once more cold
                        lam_prev = None
                        continue
                    break
                v = np.asarray(v)
                rv = A_all @ v
                add = ~inset & ((rv > hi + 1e-9) | (rv < lo - 1e-9))
                if not add.any():
                    break
                inset |= add
            if flag in (1, 2):
                lam_all = np.zeros(nv + nr)
                la = np.asarray(info["lam"])
                lam_all[:nv] = la[:nv]
                lam_all[nv + sel] = la[nv:]
                break
            soft, lam_prev = True, None
        if flag not in (1, 2) or not np.isfinite(float(v.sum()) + float(lam_all.sum())):
            return None
        self._daqp_lam, self._warm_ready = lam_all, True
        if soft:
            self.qp_soft += 1
            self._soft_step = True
        dZ = np.empty((N + 1, nz))
        dZ[:, nx:] = v[self._np:].reshape(N + 1, nu)
        dZ[0, :nx] = 0.0  # x_0 pinned
        dZ[1:, :nx] = gs + Gs @ v
        Nb = np.zeros((N + 1, nz))
        Nb[:, nx:] = lam_all[self._np:nv].reshape(N + 1, nu)
        if self._np:
            dZ[0, nx - 1], Nb[0, nx - 1] = v[0], lam_all[0]
        Nb[ri, rc] = lam_all[nv:]
        if soft:  # the soft rows' violation: projected into the bounds, the defects carry it
            dZ = np.clip(Z + dZ, lbz, ubz) - Z
        # the defects' multipliers: the stage dynamics' backward recursion, then through M_k (compiled)
        (lam,) = self._mult(dZ, Nb[:, :nx], Hy, gy, T, H, G, M)
        lam = lam.reshape(N, nx).copy()
        return dZ, lam, Nb, True

    def _condensing_setup(self, lbz, ubz) -> None:
        """The condensed QP's state rows (the finite state bounds of knots 1..N) and their constraint types."""
        N, nx, nu = self.N, self.nx, self.nu
        nv = (N + 1) * nu + self._np  # a minimum time's d tau first
        fin = np.isfinite(lbz[:, :nx]) | np.isfinite(ubz[:, :nx])
        fin[0] = False  # x_0 is pinned: dx_0 = 0 by construction
        self._rows_k, self._rows_i = np.nonzero(fin)
        eq = lbz[self._rows_k, self._rows_i] == ubz[self._rows_k, self._rows_i]
        nr = self._rows_k.size
        self._row_eq = eq
        self._sense_hard = np.r_[np.zeros(nv), np.where(eq, 5, 0)].astype(np.int32)
        self._sense_soft = np.r_[np.zeros(nv), np.full(nr, 8)].astype(np.int32)
        self._daqp_lam = None
        if "daqp" not in self.qp_counts:
            self.qp_counts["daqp"] = 0

    @staticmethod
    def _acceptable(ft, ct, f, c, filt, theta_max) -> bool:
        """Filter test of a trial point (cost ``ft``, l1 infeasibility ``ct``) from the current (``f``, ``c``)."""
        if not (np.isfinite(ft) and np.isfinite(ct)) or ct > theta_max:
            return False
        if not (ct <= (1 - _GAMMA) * c or ft <= f - _GAMMA * c):
            return False
        return all(ct <= (1 - _GAMMA) * cj or ft <= fj - _GAMMA * cj for cj, fj in filt)

    def _stationarity(self, J, G, lam, Nb) -> float:
        """Largest entry of the Lagrangian's gradient (pinned boundary states excluded; compiled:
        ``sqp_stationarity`` of :mod:`cartpole.solvers.sqp_functions`)."""
        return float(self._stat(J, G, lam, Nb)[0][0])

    # ---- solving --------------------------------------------------------------------------------------------
    def solve_once(self, x0, x_goal=None, *, guess: Trajectory | None = None, T: float | None = None,
                   start: int = 0) -> tuple[Trajectory, SolveInfo]:
        """One SQP solve from one initial guess; never raises on non-convergence (check ``info.success``).

        Parameters
        ----------
        x0, x_goal : (nx,) arrays
            Start and final state ``[qpos, qvel]`` (``x_goal`` default the model's upright ``x_eq``; its hinge
            angles shifted by whole turns to the ones ``guess`` ends nearest), as
            :meth:`DirectCollocation.solve_once`.
        guess : Trajectory, optional
            Initial guess (stretched onto ``T``); default the straight line between the boundary states. Its knots
            are clipped into the bounds and its boundary states set to ``x0``, ``x_goal``.
        T : float, optional
            Duration in s (default the problem's); for a minimum-time problem the reference ``T_0`` of the time scale,
            the guess of T (default the guess's duration, else 2 s).

        Returns
        -------
        (Trajectory, SolveInfo)
            ``info.solver`` is ``"sqp"``, ``info.iterations`` the SQP iterations, ``info.status``
            ``Solve_Succeeded``, ``Maximum_Iterations_Exceeded``, ``QP_Failed``, ``QP_Unsettled`` (``max_unsettled``)
            or ``Line_Search_Failed``,
            ``info.objective`` as :class:`SolveInfo` (physical units).
        """
        ocp = self.ocp
        nx = self.nx
        x0 = ocp._check_state("start state", x0)
        x_goal = ocp._check_state("goal state", ocp.model.x_eq if x_goal is None else x_goal)
        x_goal = ocp._goal(x0, x_goal, guess)
        if self._np:  # minimum time: T is the guess of T (default the guess's duration), the time scale's reference
            T = float(T if T is not None else (guess.duration if guess is not None else 2.0))
        else:
            T = float(ocp.T if T is None else T)
        if not (np.isfinite(T) and T > 0):
            raise SQPError(f"Duration T = {T} s is not positive; give T > 0.")
        tic = time.perf_counter()
        Z, lbz, ubz = self._first_knots(x0, x_goal, guess, T)
        self._reset(lbz, ubz)
        Z, status, success, it = self._iterate(Z, lbz, ubz)
        elapsed = time.perf_counter() - tic
        if not np.all(np.isfinite(Z)):
            Z = np.clip(np.nan_to_num(Z), lbz, ubz)
            success = False
        if self._np:  # the plan's duration from its time scale, the knots without it
            T = float(T * Z[0, nx - 1])
            Z = np.delete(Z, np.s_[nx - self._np:nx], axis=1)
        traj, objective = self._trajectory(Z, T)
        if self._np:
            objective = T  # as DirectCollocation reports a minimum-time solve
        elif self._running:  # the running integral (a reward's, negated back), as DirectCollocation reports it
            objective = self._first_order(Z)[2] * self._cost_div
            objective = -objective if ocp.objective_spec.is_reward else objective
        info = SolveInfo(status=status, success=success, iterations=it, objective=float(objective),
                         solve_time_s=elapsed, solver="sqp", T=T, start=start)
        return traj, info

    def _first_knots(self, x0, x_goal, guess: Trajectory | None, T: float):
        """The first iterate ``Z`` (N+1, nz) (the guess packed as the problem packs it, scaled, clipped into the
        bounds) and the knots' bounds ``lbz``, ``ubz`` (N+1, nz); a minimum-time problem's time scale ``tau = T / T_0``
        is one more state, 1 at first, bounded at knot 0 by the problem's ``T_range``, free elsewhere."""
        ocp, N, nx, nz = self.ocp, self.N, self.nx, self.nz
        self._h = T / N
        n_z = (nz - self._np) * (N + 1)
        lbv, ubv = ocp._var_bounds(x0, x_goal, False)
        lbz, ubz = lbv[:n_z].reshape(N + 1, -1), ubv[:n_z].reshape(N + 1, -1)
        Z = ocp._pack_guess(guess, T, x0, x_goal, False)[:n_z].reshape(N + 1, -1)
        if self._np:  # tau = T / T_0: starts at one, bounded at knot 0 by the problem's T_range, free elsewhere
            col = nx - self._np
            lo_tau = np.full(N + 1, -np.inf)
            hi_tau = np.full(N + 1, np.inf)
            lo_tau[0], hi_tau[0] = ocp.T_range[0] / T, ocp.T_range[1] / T
            lbz, ubz = np.insert(lbz, col, lo_tau, axis=1), np.insert(ubz, col, hi_tau, axis=1)
            Z = np.insert(Z, col, 1.0, axis=1)
        return np.clip(Z, lbz, ubz), lbz, ubz

    def _reset(self, lbz, ubz) -> None:
        """The per-solve state (history, QP counts, warm starts, damping) as a new solve within ``lbz``, ``ubz``
        starts it."""
        self.history = []
        self._warm_ready = False
        self.qp_counts = {}
        self.qp_soft = 0
        self._soft_step = False
        self._condensing_setup(lbz, ubz)
        if self._rqp is not None:
            self._rqp.reset()
            self.qp_counts.update(riccati=0, riccati_unsettled=0, riccati_exact=0)
        self._unsettled_feasible = 0
        self._delta = 0.0

    def _iterate(self, Z, lbz, ubz):
        """The SQP iterations from knots ``Z`` within ``lbz``, ``ubz``: ``(Z, status, success, iterations)``."""
        N, nx = self.N, self.nx
        lam = np.zeros((N, nx))
        filt: list[tuple[float, float]] = []
        status, success, it = "Maximum_Iterations_Exceeded", False, 0
        lm = self.lm_init
        try:
            D, J, f, G, H = self._eval(Z, lam)
            theta_max = 1e4 * max(1.0, float(np.abs(D).sum()))
            last = None  # (defect, bound multipliers) of the last full, hard step
            for it in range(1, self.max_iter + 1):
                if last is not None and float(np.abs(D).max()) <= self.tol:
                    # converged already with the last QP's multipliers (its step was full, so its active bounds
                    # hold here): no QP solved just to confirm it
                    kkt = self._stationarity(J, G, *last)
                    if kkt <= self.tol:
                        self.history.append({"objective": f, "infeasibility": float(np.abs(D).max()),
                                             "stationarity": kkt, "step": 0.0, "damping": lm, "alpha": 0.0,
                                             "soc": False})
                        status, success = "Solve_Succeeded", True
                        break
                self._soft_step = False
                dZ, lam_qp, Nb, ok = self._qp_step(Z, D, J, G, H, lbz, ubz, lm)
                soft_step = self._soft_step
                infeas = float(np.abs(D).max())
                kkt = self._stationarity(J, G, lam_qp, Nb)
                step = float(np.abs(dZ).max())
                rec = {"objective": f, "infeasibility": infeas, "stationarity": kkt, "step": step, "damping": lm,
                       "alpha": 0.0, "soc": False}
                self.history.append(rec)
                if not ok:
                    status = "QP_Failed"
                    break
                if self.max_unsettled is not None and self._unsettled_feasible > self.max_unsettled:
                    status = "QP_Unsettled"
                    break
                if infeas <= self.tol and (kkt <= self.tol or step <= self.tol):
                    status, success = "Solve_Succeeded", True
                    break
                c1 = float(np.abs(D).sum())
                Z_new, alpha, ft = self._line_search(Z, dZ, (D, J, f, G, H), (lbz, ubz), lm, filt, theta_max, rec)
                lm = lm / 4 if alpha == 1.0 else min(4 * lm, 1e3)  # less damping after a full step, more after less
                if Z_new is None:
                    status = "Line_Search_Failed"
                    break
                if not ft <= f - _GAMMA * c1:  # accepted for its feasibility: the current point joins the filter
                    filt.append((c1, f))
                Z = Z_new
                if not soft_step:  # an elastic QP's multipliers price its penalty, not the NLP: kept
                    lam = lam_qp
                last = (lam_qp, Nb) if (alpha == 1.0 and not soft_step and not rec["soc"]) else None
                _, D, J, f, G, F, JF = self._trial  # the accepted point is the last one tried
                H = self._hessian(Z, D, lam, F, JF)
        except (RuntimeError, np.linalg.LinAlgError) as exc:  # a singular defect Jacobian, a NaN in CasADi
            status = f"Error: {(str(exc).strip().splitlines() or [type(exc).__name__])[-1]}"
        return Z, status, success, it

    def _line_search(self, Z, dZ, lin, bounds, lm: float, filt, theta_max: float, rec: dict):
        """Filter line search on (theta = ||d||_1, f) (Fletcher and Leyffer) along the QP step ``dZ`` from ``Z``, with
        a second-order correction: ``(Z_new or None, alpha, cost at the last point tried)``. ``lin`` is
        ``(D, J, f, G, H)`` at ``Z``, ``bounds`` ``(lbz, ubz)``; ``rec`` (this iteration's history entry) gets
        ``alpha`` and ``soc``."""
        D, J, f, G, H = lin
        c1 = float(np.abs(D).sum())
        step = float(np.abs(dZ).max())
        if step > self.max_step:  # a Newton step far outside where the linearisation holds: shortened
            dZ = dZ * (self.max_step / step)
        Z_new, alpha = None, 1.0
        Z_try = Z + dZ
        ft, ct, D_try = self._merit_parts(Z_try)
        if self._acceptable(ft, ct, f, c1, filt, theta_max):
            Z_new = Z_try
        elif self.soc:
            # second-order correction (Maratos): the same QP with the defects at the trial point
            dV = np.hstack([dZ[:-1], dZ[1:]])
            D_soc = D_try - (J @ dV[:, :, None])[:, :, 0]
            dZ_c, _, _, ok_c = self._qp_step(Z, D_soc, J, G, H, *bounds, lm)
            if ok_c:
                Z_try = Z + dZ_c
                ft, ct, _ = self._merit_parts(Z_try)
                if self._acceptable(ft, ct, f, c1, filt, theta_max):
                    Z_new = Z_try
                    rec["soc"] = True
        while Z_new is None:
            alpha *= 0.5
            if alpha < 1e-8:
                break
            Z_try = Z + alpha * dZ
            ft, ct, _ = self._merit_parts(Z_try)
            if self._acceptable(ft, ct, f, c1, filt, theta_max):
                Z_new = Z_try
        rec["alpha"] = alpha
        return Z_new, alpha, ft

    def solve(self, x0=None, x_goal=None, *, guess: Trajectory | None = None, T: float | None = None,
              fallback: bool = False) -> tuple[Trajectory, SolveInfo]:
        """SQP solve that raises on failure, or falls back to the problem's IPOPT from the same guess.

        Parameters as :meth:`solve_once` (``x0`` default the model's hanging rest). ``fallback`` True: when the SQP
        does not converge, solve with :meth:`DirectCollocation.solve_once` (IPOPT) from the same guess and return
        that (``info.solver == "ipopt"``; the SQP attempt is in ``info.attempts``).

        Raises
        ------
        SQPError
            The SQP did not converge (and ``fallback`` is False, or IPOPT did not converge either).
        """
        ocp = self.ocp
        x0 = ocp.model.x_hanging if x0 is None else x0
        traj, info = self.solve_once(x0, x_goal, guess=guess, T=T)
        if info.success:
            return traj, info
        if fallback:
            tr2, info2 = ocp.solve_once(x0, x_goal, guess=guess, T=T)
            name = "given" if guess is not None else "line"
            attempts = tuple(Attempt.of(i, ocp.objective, name, self.N, chosen=i is info2 and i.success)
                             for i in (info, info2))
            if info2.success:
                return tr2, replace(info2, attempts=attempts)
        raise SQPError(f"The SQP swing-up solve did not converge ({info.status} after {info.iterations} "
                       f"iterations); give another initial guess or solve with IPOPT.")

    def _trajectory(self, Z, T) -> tuple[Trajectory, float]:
        """The plan of knots ``Z`` (N+1, nz) scaled, as DirectCollocation returns it, and its effort
        ``integral u'u dt`` (ctrl^2 s)."""
        ocp, N, nx = self.ocp, self.N, self.nx - self._np
        X = (Z[:, :nx] * self.sx[:nx]).T
        U = (Z[:, nx:] * self.su).T
        if not hasattr(self, "_f_knots"):
            self._f_knots = Buffered(ocp._f_knots)
        # (N+1, nx) C-order is CasADi's (nx, N+1) column-major
        (F,) = self._f_knots(Z[:, :nx] * self.sx[:nx], Z[:, nx:] * self.su)
        xdot = F.reshape(N + 1, nx).T.copy()
        h = T / N
        Xc = 0.5 * (X[:, :-1] + X[:, 1:]) + h / 8 * (xdot[:, :-1] - xdot[:, 1:])
        Uc = 0.5 * (U[:, :-1] + U[:, 1:])
        effort = float(h / 6 * np.sum(U[:, :-1] ** 2 + 4 * Uc ** 2 + U[:, 1:] ** 2))
        t = np.linspace(0.0, T, N + 1)
        return Trajectory(t=t, x=X.T, u=U.T, xdot=xdot.T, x_mid=Xc.T, u_mid=Uc.T), effort
