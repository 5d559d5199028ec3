"""The offline Hermite-Simpson swing-up solved by SQP on its stage-structured QP (exact Hessian, filter line search).

The NLP is :class:`~cartpole.ocp.collocation.DirectCollocation`'s compressed Hermite-Simpson problem, variable for
variable: scaled knots ``z_k = (x_k / s_x, u_k / s_u)`` (nz = nx + nu), k = 0..N, the defects
``d_k(z_k, z_k+1) = 0`` (nx each, divided by ``s_x``), box bounds on the knots (ctrl, cart rail, limited joints),
``x_0`` and ``x_N`` pinned, objective the effort ``integral u'u dt`` divided by ``sum(s_u^2) T``. Its pieces are
the interval functions compiled to C (:mod:`cartpole.ocp.compiled_nlp`: ``hs_dj`` defect and Jacobian, ``hs_eg`` cost
and gradient, the exact Hessian block of the interval's Lagrangian), here in their knot-shared form
(:func:`cartpole.ocp.compiled_nlp.knot_functions`: each knot's dynamics and curvature once), mapped over the knots and
intervals.

Each SQP step solves the QP of the exact Lagrangian Hessian and the linearised defects. That QP is an optimal
control problem once the defects are read as dynamics: the linearised defect
``d + J^a dz_k + J^b_x dx_k+1 + J^b_u du_k+1 = 0`` is explicit in ``dx_k+1`` after one small solve with ``J^b_x``
(nx x nx, the identity plus O(h)), so with the stage state ``s_k = dz_k`` and the stage control ``w_k = du_k+1``::

    s_k+1 = [dx_k+1; du_k+1] = [-(J^b_x)^-1 (d + J^a s_k + J^b_u w_k); w_k]

and interval k's Hessian block (which couples ``z_k`` and ``z_k+1``) becomes a stage cost in ``(s_k, w_k)`` by the
same substitution: an OCP QP in stage form (HPIPM's layout, ``casadi.conic``), stages of ``nz`` states and ``nu``
controls, the pinned ``x_0`` dropped from the first stage. The multipliers of the original defects follow from those
of the stage dynamics (the substitution adds interval k's gradient in ``z_k+1`` to them, then
``lambda_k = -(J^b_x)^-T mu_k``).

QP solver: ``riccati`` (default; :mod:`cartpole.solvers.riccati_qp`: the stage QP itself by Riccati recursions in C,
inputs held at their bounds removed from the recursion, held state bounds through their responses, a primal-dual
active set hot-started from the last QP's; O(N) a set), ``daqp`` (the stage QP condensed onto the knot controls
``v = (du_0 .. du_N)``, (N+1) nu unknowns, ``dx_k = g_k + G_k v`` by the stage dynamics, and solved by DAQP, PyPI
``daqp``, the dense dual active-set solver the NMPC uses, hot-started from the last QP's multipliers; see
:meth:`CollocationSQP._daqp_step`; it also takes every QP the Riccati active set cannot settle, infeasible
linearisations among them), ``qrqp`` (CasADi's sparse active-set solver, which factorises the banded KKT system of the
stage QP by sparse QR, hot-started from the previous iteration's active set) or ``hpipm`` (CasADi's interface to the
Riccati-recursion interior point). Every QP answer is checked (finite, inside the bounds, on the stage dynamics); a
failed check is solved again cold, then by HPIPM. The QP of each iteration is built in compiled C
(:mod:`cartpole.solvers.sqp_functions`: the stage form and its convexification in one call, the condensing (for DAQP)
in another, without any ``G' Q G`` product, and the defects' multipliers from the QP's in a third). Why not HPIPM:
CasADi's HPIPM interface allocates HPIPM's workspace on every call, HPIPM needs ``balance`` or ``robust`` mode and
finite stand-ins for free bounds (:data:`QP_INF`), and its less accurate answers cost many more SQP iterations; DAQP
takes the same iterations to the same optimum as qrqp, most of its time its own set-up of the dense condensed QP
(Cholesky and the inverse factor), which the Riccati solver does not need. What each part costs today is measured by
``cartpole bench`` (the docs' benchmarks page), not written here.

Hessian: the exact Lagrangian blocks with Levenberg-Marquardt damping ``delta I`` on every stage block (``delta``
starts at ``lm_init``, divided by 4 after a full step, multiplied by 4 after a shortened one, so it vanishes as the
iterates converge: quadratic convergence at the end), then made positive definite on the stage dynamics' null space
where it is not: a backward Riccati recursion over the stages raises any stage's reduced Hessian ``R + B' P B`` below
``reg_min`` (``sqp_stages`` in :mod:`cartpole.solvers.sqp_functions`), so every QP is convex. A running cost (tracking,
a reward) is not convex in the inputs: where an input saturates the free problem's reduced Hessian is indefinite at
the solution itself, and that stage-wise raise changes the QP there (measured: it converges only linearly); the
effort's Lagrangian is indefinite too where the dynamics' curvature weighs (on the triple the raise left the SQP at a
stationarity of 0.04 for 100 iterations). With the Riccati QP solver each QP is therefore first solved on the exact
Hessian (``sqp_stages`` without the raise) with IPOPT's inertia correction: no shift first, and where a reduced
Hessian of the active set is not positive definite ``delta I`` added to every stage block, from a third of the last
shift used (1e-4 the first time; no floor after, as IPOPT's ``delta_w_min`` is 1e-20) up by 8 until it is; the
convexified QP only when that fails. The shift must be free to decay: on the triple's minimum time the problem is
nearly singular where inputs leave their bounds (reduced-Hessian eigenvalues of 1e-6), and a floor of 1e-4 made every
step a proximal one that crept along that direction (200 iterations without converging; 14 without the floor). The Riccati solver adds
``rho/2`` times the squared residual of each held state row (the pinned ``x_N`` among them) to the recursion, which
changes neither the QP's solution nor its multipliers but lends the recursion the curvature the rows give the
constrained problem: without it the reduced Hessians near a pinned end were indefinite where the constrained QP is
convex, and the shift never returned to zero (tracking on a 30-interval mesh stalled). Near the solution the shift is zero: Newton
steps. Globalisation: a filter
line search on (``||d||_1``, cost) (Fletcher and Leyffer) with a second-order correction against the Maratos effect,
steps longer than ``max_step`` (scaled units) shortened. Converged when the largest defect and the largest entry of the
Lagrangian's gradient are below ``tol`` (scaled units, the collocation's IPOPT ``tol``); after a full step that test
is first made with the last QP's multipliers (the step was full, so that QP's active bounds hold at the new point),
so no QP is solved only to confirm convergence.

Minimum time (objective ``time``, ``T`` free): solved as a fixed-duration problem on the reference clock of
``T_0`` (the guess's duration, or ``T`` given to :meth:`CollocationSQP.solve_once`) with the time scale
``tau = T / T_0`` one more state (``_time_scaled``): dynamics ``(tau f(x, u), 0)``, running cost ``tau (1 + w
u'u)`` (``w`` the problem's ``time_effort_weight``), whose Simpson integral is ``T + w integral u'u dt``;
Hermite-Simpson with step ``h_0`` on these is Hermite-Simpson with step ``tau h_0`` on ``f``, the collocation's
free-time NLP, so the optimum is IPOPT's. ``tau`` is free at knot 0 (bounded by the problem's ``T_range``), the
Riccati QP solver's ``n_free`` state, and each step of it is held within :data:`TAU_STEP` of its value (a trust
region: the first linearisations of a far guess ask for durations the plan cannot reach). A QP the Riccati active set
does not settle goes to DAQP with ``d tau`` one more unknown of the condensed QP
(:func:`cartpole.solvers.sqp_functions.free_state_column`); qrqp and HPIPM, behind DAQP, keep ``tau`` for that step,
so convergence is then only declared on the Lagrangian's gradient, ``tau``'s entry included.

Infeasible linearisations: with ``qrqp`` and ``hpipm`` a linearisation whose QP is infeasible ends the solve
(``QP_Failed``): the two-pole standard problem from the benchmark's guess does so at the first iteration. With
``daqp`` (the default) the state-bound rows (rail, limited joints, the pinned ``x_N``) are made soft when the hard QP
is infeasible (DAQP's soft constraints): the step leaves the bounds, is projected back into them, the defects it
leaves are the filter's to judge, and that QP's multipliers are not taken (they price the penalty). Far from
feasibility (largest scaled defect above ``exact_hessian_below``) the Hessian is the cost's curvature only (the
defect multipliers dropped from it): the exact Hessian there, with multipliers from nearly infeasible QPs, is so
indefinite that its convexification blows up. On the two-pole problem from the bench's guess the SQP reaches
IPOPT's optimum, in far fewer iterations, with ``exact_hessian_below`` 0.1 (and with smaller thresholds, in more
iterations), while larger ones, the exact Hessian from the start among them, end in ``QP_Failed`` within a few
iterations (``tests/solvers/test_sqp.py`` holds this case). On the single pole the first defects are below 0.1, so
the default leaves its solve unchanged. An l1 or l2 elastic qrqp QP (slacks on every linearised defect) was tried
before the soft DAQP rows and is not kept: each QP was slow and the SQP did not converge. When the SQP does not converge, :meth:`CollocationSQP.solve` with
``fallback=True`` solves with IPOPT; IPOPT stays the default everywhere else.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from cartpole.codegen import Buffered
from cartpole.ocp import compiled_nlp
from cartpole.solvers import riccati_qp, sqp_functions
from cartpole.ocp.bounds import OCPError
from cartpole.ocp.collocation import DirectCollocation
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory


class SQPError(OCPError):
    """The SQP solver cannot be set up for this problem, or its solve did not converge."""


#: QP solvers: ``riccati`` (the stage QP by Riccati recursions and a primal-dual active set, in C:
#: :mod:`cartpole.solvers.riccati_qp`; a QP it cannot settle goes to ``daqp``), ``daqp`` (the stage QP condensed
#: onto the knot controls, DAQP's dense dual active set; qrqp then HPIPM when it fails), ``qrqp`` (CasADi's sparse
#: active-set solver: the banded KKT system by sparse QR, hot-started from the previous SQP iteration's active set;
#: when its answer fails the check of feasibility, HPIPM solves that QP) and ``hpipm`` alone (Riccati-recursion
#: interior point, through CasADi's interface).
QP_SOLVERS = ("riccati", "daqp", "qrqp", "hpipm")
_BIG = 1e30  # DAQP's "no bound"
_GAMMA = 1e-5  # the filter's margin
#: Largest relative change of a minimum-time problem's duration in one SQP step.
TAU_STEP = 0.5
#: Bound magnitude that stands for "no bound" in the QP (scaled units; HPIPM treats every variable as boxed and
#: converges badly with CasADi's default 1e8; steps of the scaled NLP are of order one).
QP_INF = 1e3


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
    """The minimum-time problem as a fixed-duration one (module docstring): the dynamics of ``(x, tau)`` on the
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
        ``MODULE:FUNCTION``) or ``time`` (T free: by its time scale, module docstring; the Riccati QP solver only).
        Each QP on the exact Hessian first, with IPOPT's inertia correction (module docstring).
    tol : float
        Converged when the largest defect and the largest entry of the Lagrangian's gradient (bound multipliers
        included, scaled units) are below ``tol`` (default 1e-8, the collocation's IPOPT ``tol``).
    max_iter : int
        SQP iterations before the solve counts as failed (default 200).
    reg_min : float
        Smallest eigenvalue a stage's reduced Hessian keeps (default 1e-4, scaled units).
    lm_init : float
        First Levenberg-Marquardt damping of the stage Hessian blocks (default 1e-2; the scaled effort Hessian's
        diagonal is about 1e-2 at N = 100).
    qp_solver : {'riccati', 'daqp', 'qrqp', 'hpipm'}
        The QP solver (module docstring); DAQP backs up the Riccati solver (which needs a C compiler: without one,
        or with ``ocp.compiled`` False, DAQP is used), HPIPM also backs up qrqp, qrqp and HPIPM back up DAQP.
    qp_options : dict, optional
        Merged into the options of ``casadi.conic`` for ``qp_solver`` (for HPIPM, ``{"hpipm": {...}}`` for its own).
    warm_qp : bool
        Hot-start each QP from the previous one's multipliers (active set).
    soc : bool
        Try a second-order correction before shortening a rejected full step.
    max_step : float
        Longest step (max over the scaled variables) taken; longer QP steps are shortened.
    exact_hessian_below : float
        Largest scaled defect at which the Hessian includes the defects' curvature (the exact Lagrangian); above
        it, the cost's only (default 0.1; why, in the module docstring).
    max_unsettled : int or None
        With ``qp_solver="riccati"``: feasible QPs the Riccati active set may hand to DAQP (infeasible linearisations,
        which DAQP solves with soft rows, are not counted) before the solve stops with status ``QP_Unsettled`` (None,
        the default: no limit). A feasible linearisation it cannot settle again and again makes each iteration cost a
        dense condensed QP, where IPOPT on the sparse problem is the better solver; the planner stops early
        (:data:`cartpole.planning.trajopt.SQP_MAX_UNSETTLED`) and lets IPOPT take over.

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
        QP solves of the last solve per solver (``qrqp``, ``hpipm``, ``daqp``: DAQP calls, row screening included;
        ``riccati``: the Riccati active set's convexified QPs, ``riccati_exact`` its QPs on the exact Hessian,
        ``riccati_unsettled`` those it handed to DAQP).
    qp_soft : int
        QPs of the last solve solved with soft state rows (``daqp`` only: the hard QP was infeasible).
    """

    def __init__(self, ocp: DirectCollocation, *, tol: float = 1e-8, max_iter: int = 200, reg_min: float = 1e-4,
                 lm_init: float = 1e-2, qp_solver: str = "riccati", qp_options: dict | None = None,
                 warm_qp: bool = True, soc: bool = True, max_step: float = 1.0, exact_hessian_below: float = 1e-1,
                 max_unsettled: int | None = None):
        if not isinstance(ocp, DirectCollocation):
            raise SQPError("CollocationSQP needs a DirectCollocation problem (cartpole.ocp.collocation).")
        if ocp.separated:
            raise SQPError("The SQP solver works on the compressed transcription; build the problem with "
                           "separated=False.")
        kind = ocp.objective_spec.kind
        if kind not in ("effort", "running", "time"):
            raise SQPError(f"The SQP solver handles effort, time and the running costs, not '{ocp.objective}'; "
                           f"solve it with IPOPT (DirectCollocation.solve).")
        if qp_solver not in QP_SOLVERS:
            raise SQPError(f"qp_solver '{qp_solver}' is not one of {', '.join(QP_SOLVERS)}.")
        # minimum time: the time scale tau = T / T_0 is one more state, free at knot 0 (module docstring); only the
        # Riccati solver has a free state at knot 0
        self._np = 1 if kind == "time" else 0
        if self._np and not (qp_solver == "riccati" and ocp.compiled
                             and riccati_qp.available(ocp.nx + 1, ocp.nu, 1)):
            raise SQPError("The SQP solves minimum-time problems with its Riccati QP solver only (compiled, so it "
                           "needs a C compiler); solve them with IPOPT (DirectCollocation.solve).")
        if qp_solver == "riccati" and not (ocp.compiled and riccati_qp.available(ocp.nx, ocp.nu)):
            qp_solver = "daqp"  # no C compiler: the condensed route (same answers)
        if qp_solver in ("riccati", "daqp"):
            import importlib.util

            if importlib.util.find_spec("daqp") is None:
                raise SQPError(f"qp_solver '{qp_solver}' needs the daqp package (pip install daqp); use 'qrqp'.")
        elif not ca.has_conic(qp_solver):
            raise SQPError(f"This CasADi build has no '{qp_solver}' QP plugin; use IPOPT (DirectCollocation.solve).")
        self.qp_solver, self.warm_qp, self.soc = qp_solver, bool(warm_qp), bool(soc)
        self.lm_init, self.max_step = float(lm_init), float(max_step)
        self.exact_hessian_below = float(exact_hessian_below)
        self.max_unsettled = None if max_unsettled is None else int(max_unsettled)
        self.ocp = ocp
        self.tol, self.max_iter, self.reg_min = float(tol), int(max_iter), float(reg_min)
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
        # each QP is first solved on the exact Hessian with IPOPT's inertia correction (module docstring), the
        # convexified QP only where that fails
        self._stages_raw = None
        if qp_solver == "riccati":
            raw, _ = sqp_functions.compiled_qp_functions(nx, nu, N, -np.inf, compiled=ocp.compiled, n_free=self._np)
            self._stages_raw = Buffered(raw[0])
        self._rqp = riccati_qp.StageQP(N, nx, nu, n_free=self._np) if qp_solver == "riccati" else None
        self._stages, self._condense, self._mult, self._stat = (Buffered(f) for f in funcs)
        self._setup_qp(qp_options or {})
        self.history: list[dict] = []

    # ---- the QP's layout ------------------------------------------------------------------------------------
    def _setup_qp(self, qp_options: dict) -> None:
        """Sparsity of HPIPM's OCP QP: stages ``s_0 = du_0`` (nu), ``s_k = dz_k`` (nz) for k = 1..N, controls
        ``w_k = du_k+1`` (nu) for k < N; variables ``[s_0, w_0, s_1, w_1, ..., s_N]``; rows: the stage dynamics
        ``s_k+1 = T_k (s_k, w_k) + t_k`` (nz each)."""
        N, nx, nu, nz = self.N, self.nx, self.nu, self.nz
        ns = [nu] + [nz] * N
        nw = self.nw
        off_s, o = [], 0
        for k in range(N + 1):
            off_s.append(o)
            o += ns[k] + (nw if k < N else 0)
        n = o
        self._n = n
        # knot entries each stage variable steps: s_0 -> z_0[nx:], s_k -> z_k
        z_flat = np.arange((N + 1) * nz).reshape(N + 1, nz)
        self._zi = np.concatenate([z_flat[0, nx:]] + [z_flat[k] for k in range(1, N + 1)])
        self._qi = np.concatenate([off_s[0] + np.arange(nu)] + [off_s[k] + np.arange(nz) for k in range(1, N + 1)])
        self._wi = np.concatenate([off_s[k] + ns[k] + np.arange(nw) for k in range(N)])  # controls w_k
        rows, cols = [], []
        for k in range(N):
            ny = ns[k] + nw
            r, c = np.meshgrid(np.arange(nz), np.arange(ny), indexing="ij")
            rows.append(nz * k + r.ravel())
            cols.append(off_s[k] + c.ravel())  # y_k = (s_k, w_k) contiguous
        self._a_count = sum(r.size for r in rows)
        rows.append(np.arange(nz * N))
        cols.append(np.concatenate([off_s[k + 1] + np.arange(nz) for k in range(N)]))
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        self._a_order = np.lexsort((rows, cols))  # CasADi's compressed-column order
        self._sp_a = ca.Sparsity.triplet(nz * N, n, rows[self._a_order].tolist(), cols[self._a_order].tolist())
        self._a_vals = np.empty(rows.size)
        self._a_vals[self._a_count:] = -1.0
        hr, hc = [], []
        for k in range(N + 1):
            ny = ns[k] + (nw if k < N else 0)
            r, c = np.meshgrid(np.arange(ny), np.arange(ny), indexing="ij")
            hr.append(off_s[k] + r.ravel())
            hc.append(off_s[k] + c.ravel())
        hr, hc = np.concatenate(hr), np.concatenate(hc)
        self._h_order = np.lexsort((hr, hc))
        self._sp_h = ca.Sparsity.triplet(n, n, hr[self._h_order].tolist(), hc[self._h_order].tolist())
        hp = {"mode": "robust", "iter_max": 200}
        hp_opts = {"N": N, "nx": ns, "nu": [nw] * N + [0], "ng": [0] * (N + 1), "inf": QP_INF,
                   "error_on_fail": False, "print_time": False}
        qr_opts = {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False,
                   "print_time": False, "max_iter": 1000}
        user = dict(qp_options)
        if self.qp_solver == "hpipm":
            hp.update(user.pop("hpipm", {}))
            hp_opts.update(user)
        else:
            qr_opts.update(user)
        hp_opts["hpipm"] = hp
        # called on numpy buffers (CasADi's DM conversions cost about as much as the QP): nonzeros in, solution out
        hn, gn, an = ca.MX.sym("h", self._sp_h.nnz()), ca.MX.sym("g", n), ca.MX.sym("a", self._sp_a.nnz())
        bn, lx, ux = ca.MX.sym("b", nz * N), ca.MX.sym("lbx", n), ca.MX.sym("ubx", n)
        x0, lx0, la0 = ca.MX.sym("x0", n), ca.MX.sym("lam_x0", n), ca.MX.sym("lam_a0", nz * N)
        self._qps = {}
        for name, opts in (("hpipm", hp_opts), ("qrqp", qr_opts)):
            if name == "qrqp" and self.qp_solver == "hpipm":
                continue
            qp = ca.conic(f"hs_sqp_{name}", name, {"h": self._sp_h, "a": self._sp_a}, opts)
            sol = qp(h=ca.MX(self._sp_h, hn), g=gn, a=ca.MX(self._sp_a, an), lba=bn, uba=bn, lbx=lx, ubx=ux, x0=x0,
                     lam_x0=lx0, lam_a0=la0)
            self._qps[name] = Buffered(ca.Function(f"hs_sqp_{name}_nz", [hn, gn, an, bn, lx, ux, x0, lx0, la0],
                                                    [sol["x"], sol["lam_a"], sol["lam_x"]]))
        self.qp_counts = {name: 0 for name in self._qps}
        self._y = np.zeros(n)
        self._lam_y = np.zeros(n)
        self._lam_a = np.zeros(nz * N)
        self._lbx = np.full(n, -np.inf)
        self._ubx = np.full(n, np.inf)

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
        ``lam`` (N, nx) and the knots' ``F``, ``JF`` of :meth:`_first_order`; far from feasible (module docstring)
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
        if self._stages_raw is not None:  # the exact Hessian's QP first (module docstring)
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
                out = self._daqp_step(Z, T, ct, Hs, gy, H, G, M, lbz, ubz, exact=True)
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
        if self.qp_solver in ("riccati", "daqp"):
            out = self._daqp_step(Z, T, ct, Hy, gy, H, G, M, lbz, ubz)
            if out is not None:
                if self._rqp is not None and not self._soft_step:
                    self._unsettled_feasible += 1  # a feasible QP the Riccati active set could not settle
                return out
            self._warm_ready = False  # DAQP failed: qrqp (cold), then HPIPM
            if self._rqp is not None:
                self._unsettled_feasible += 1
        self._tau_kept = bool(self._np)  # qrqp and HPIPM take the time scale as given for this step
        hvals = np.concatenate([Hy[0, nx:, nx:].ravel(), Hy[1:].ravel(), np.zeros(nz * nz)])[self._h_order]
        gvec = np.concatenate([gy[0, nx:], gy[1:].ravel(), np.zeros(nz)])
        self._a_vals[:self._a_count] = np.concatenate([T[0][:, nx:].ravel(), T[1:].ravel()])
        avals = self._a_vals[self._a_order]
        lbx, ubx = self._lbx, self._ubx
        lbx[self._qi] = (lbz - Z).ravel()[self._zi]
        ubx[self._qi] = (ubz - Z).ravel()[self._zi]
        rhs = np.zeros((N, nz))
        rhs[:, :nx] = -ct
        rhs = rhs.ravel()
        tries = [("qrqp", self.warm_qp), ("qrqp", False)] if self.qp_solver != "hpipm" else []
        ok = False
        for name, warm in tries + [("hpipm", False)]:
            if warm and not self._warm_ready:
                continue
            y, mu, nub, ok = self._solve_qp(name, T, hvals, gvec, avals, rhs, lbx, ubx, warm=warm)
            self.qp_counts[name] += 1
            if ok:
                break
        if self.warm_qp and ok and not self._soft_step:  # the next QP starts from this one's active set
            self._lam_y, self._lam_a, self._warm_ready = nub, mu, True
        dZ = np.zeros((N + 1, nz))
        dZ.ravel()[self._zi] = y[self._qi]
        Nb = np.zeros((N + 1, nz))
        Nb.ravel()[self._zi] = nub[self._qi]
        # multipliers of the defects from those of the stage dynamics (module docstring)
        dV = np.hstack([dZ[:-1], dZ[1:]])
        mu_orig = mu.reshape(N, nz) + (H @ dV[:, :, None])[:, nz:, 0] + G[:, nz:]
        lam = -(M.transpose(0, 2, 1) @ mu_orig[:, :nx, None])[:, :, 0]
        return dZ, lam, Nb, ok

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

    def _daqp_step(self, Z, T, ct, Hy, gy, H, G, M, lbz, ubz, *, exact: bool = False):
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
        Hessians (shifted then, :func:`_positive_definite`). Returns what :meth:`_qp_step` does, or None when DAQP
        failed."""
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
                v, _, flag, info = self._daqp(Hc, fc, A_all[sel], np.concatenate((vb_hi, hi_c[sel])),
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

    def _solve_qp(self, name, T, hvals, gvec, avals, rhs, lbx, ubx, *, warm: bool):
        """One QP solve; ``(y, lam_a, lam_x, ok)`` with ok: finite, inside the bounds and on the stage dynamics
        (checked here: the buffered call has no solver statistics)."""
        N, nx, nu, nz = self.N, self.nx, self.nu, self.nz
        zero_a = np.zeros(nz * N)
        lam_y = self._lam_y if warm else self._y
        lam_a = self._lam_a if warm else zero_a
        y, mu, nub = (a.copy() for a in self._qps[name](hvals, gvec, avals, rhs, lbx, ubx, self._y, lam_y, lam_a))
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(mu)) and np.all(np.isfinite(nub))):
            return y, mu, nub, False
        viol = max(float(np.max(lbx - y)), float(np.max(y - ubx)), 0.0)
        dZ = np.zeros((N + 1, nz))
        dZ.ravel()[self._zi] = y[self._qi]
        W = y[self._wi].reshape(N, self.nw)
        Yk = np.hstack([np.vstack([np.zeros(nx), dZ[1:N, :nx]]), np.vstack([y[:nu], dZ[1:N, nx:]]), W])
        gap = float(np.abs((T @ Yk[:, :, None])[:, :, 0] - rhs.reshape(N, nz) - dZ[1:]).max())
        return y, mu, nub, viol <= 1e-6 and gap <= 1e-6

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
        N, nx, nz = self.N, self.nx, self.nz
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
        Z = np.clip(Z, lbz, ubz)
        lam = np.zeros((N, nx))
        filt: list[tuple[float, float]] = []
        status, success, it = "Maximum_Iterations_Exceeded", False, 0
        self.history = []
        self._warm_ready = False
        lm = self.lm_init
        self.qp_counts = {name: 0 for name in self._qps}
        self.qp_soft = 0
        self._soft_step = False
        if self.qp_solver in ("riccati", "daqp"):
            import daqp

            self._daqp = daqp.solve
            self._condensing_setup(lbz, ubz)
        if self._rqp is not None:
            self._rqp.reset()
            self.qp_counts.update(riccati=0, riccati_unsettled=0, riccati_exact=0)
        self._unsettled_feasible = 0
        self._delta = 0.0
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
                self._soft_step = self._tau_kept = False
                dZ, lam_qp, Nb, ok = self._qp_step(Z, D, J, G, H, lbz, ubz, lm)
                soft_step, tau_kept = self._soft_step, self._tau_kept
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
                # (a zero step counts for a minimum time only from a QP with the time scale free: qrqp and HPIPM,
                # behind DAQP, keep it, and their zero step at a fixed-time optimum is no minimum)
                if infeas <= self.tol and (kkt <= self.tol or (step <= self.tol and not tau_kept)):
                    status, success = "Solve_Succeeded", True
                    break
                # filter line search on (theta = ||d||_1, f) (Fletcher and Leyffer), second-order correction
                c1 = float(np.abs(D).sum())
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
                    dZ_c, _, _, ok_c = self._qp_step(Z, D_soc, J, G, H, lbz, ubz, lm)
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
        from dataclasses import replace

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
