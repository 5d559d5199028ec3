"""Control-limited iterative LQR / DDP on the exact discrete model, with state constraints by augmented Lagrangian.

The problem, on a discrete model ``x_k+1 = f(x_k, u_k)`` (one MJCF step, or a hold of several:
:meth:`~cartpole.models.CartPoleModel.hold`, so a plan replays in MuJoCo to round-off)::

    minimise    sum_k dt * L(x_k, u_k)  +  Phi(x_N)
    subject to  u_low <= u_k <= u_high                        (box: in the backward pass)
                q_low <= q_k <= q_high,  |s_k - c| <= cart_max  (the OCP's bounds: augmented Lagrangian)
                x_N = x_goal (hinge errors wrapped)             (optional: augmented Lagrangian)

``L`` is any running cost of the collocation (:func:`cartpole.ocp.objectives.make_objective`: ``effort``,
``tracking``, the ``dmc_*`` rewards negated, ``MODULE:FUNCTION``), ``Phi`` an optional terminal quadratic
``(x_N - x_goal)' Qf (x_N - x_goal)`` plus any terminal cost Function of ``x_N``.

The method is box-DDP (Tassa, Mansard and Todorov, ICRA 2014) in its Gauss-Newton form (iLQR: the dynamics'
second derivatives are dropped, the costs' are kept): a backward pass of the quadratic model of the cost-to-go,
each step's input update the solution of a small box QP (projected Newton; the clamped inputs get no feedback), a
forward pass that rolls the nonlinear model out with ``u = u_bar + alpha k + K (x - x_bar)`` and a backtracking line
search on the actual cost, and the Levenberg-Marquardt regularisation schedule of Tassa et al. 2012 (``mu`` grows
when a backward pass meets a non-positive-definite ``Quu`` or a line search fails, shrinks after a success).
State constraints enter as augmented-Lagrangian penalties (ALTRO, Howell et al. 2019): an inner DDP on the
penalised cost, then the multipliers updated and the penalty raised until the constraints hold.

Every derivative comes from the symbolic model as one CasADi Function mapped over the horizon (compiled to C
through :mod:`cartpole.codegen`), so one call gives every stage's ``f_x``, ``f_u``, ``l_x``, ``l_u``, ``l_xx``,
``l_uu``, ``l_ux``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from cartpole._arrays import readonly
from cartpole.codegen import Buffered, build_library, compiled_or_none, load_library
from cartpole.errors import CartPoleError
from cartpole.ocp.bounds import bounds_from_model
from cartpole.ocp.objectives import make_objective


class DDPError(CartPoleError, ValueError):
    """A DDP problem that cannot be set up: shapes that disagree, bounds the start violates, bad options."""


@dataclass(frozen=True)
class DDPOptions:
    """Settings of :class:`DDP`.

    Attributes
    ----------
    max_iterations : int
        Inner (DDP) iterations per augmented-Lagrangian round.
    max_outer : int
        Augmented-Lagrangian rounds.
    tolerance : float
        Relative cost decrease below which an inner solve has converged.
    constraint_tolerance : float
        Largest constraint violation accepted (m, rad: the state's own units).
    penalty : float
        First penalty weight ``rho`` of the constraints.
    penalty_growth : float
        Factor on ``rho`` when a round did not shrink the violation enough.
    mu0, mu_min, mu_max : float
        First, smallest and largest Levenberg-Marquardt regularisation on ``Quu``.
    line_search : tuple of float
        Step lengths ``alpha`` tried, in order.
    compiled : bool
        Compile the stage derivatives and the passes to C (unless ``CARTPOLE_NO_COMPILE`` is set); default True.
    """

    max_iterations: int = 300
    max_outer: int = 12
    tolerance: float = 1e-8
    constraint_tolerance: float = 1e-6
    penalty: float = 10.0
    penalty_growth: float = 10.0
    mu0: float = 1e-6
    mu_min: float = 1e-9
    mu_max: float = 1e10
    line_search: tuple = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625, 0.0078125, 0.001)
    compiled: bool = True


@dataclass(frozen=True)
class DDPProblem:
    """What :class:`DDP` minimises on its discrete model, besides the dynamics: the costs, the ctrl box, the position
    bounds and the goal. Shapes are checked against the model when the :class:`DDP` is built.

    Attributes
    ----------
    u_low, u_high : (nu,) arrays
        ctrl bounds (MuJoCo ctrl units), finite, ``u_low < u_high``.
    running : casadi.Function or None
        ``(x, u) -> cost`` per second; None for ``effort`` (``u'u``).
    q_low, q_high : (nq,) arrays or None
        Position bounds per joint (m or rad; ``-inf``/``inf`` where free), held at every node by augmented
        Lagrangian; None: no bound.
    x_goal : (nx,) array or None
        Terminal equality ``x_N = x_goal`` (hinge errors wrapped); None: no goal.
    hinges : tuple of int
        qpos indices of the hinges (their errors are wrapped).
    Qf : (nx, nx) array or None
        Terminal quadratic weight on ``x_N - x_goal`` (needs ``x_goal``).
    goal_constraint : bool
        Hold ``x_N = x_goal`` as a constraint (True, default) or only weigh it by ``Qf`` (False: a receding horizon's
        terminal cost).
    terminal : casadi.Function or None
        ``x (nx,) -> cost``, a terminal cost of any form, added to ``Phi`` (e.g. a soft goal).
    """

    u_low: object
    u_high: object
    running: ca.Function | None = None
    q_low: object = None
    q_high: object = None
    x_goal: object = None
    hinges: tuple = ()
    Qf: object = None
    goal_constraint: bool = True
    terminal: ca.Function | None = None


@dataclass
class _Iterate:
    """The state of one :meth:`DDP.solve`: the rollout, the last gains, the augmented Lagrangian's multipliers and
    penalty, the regularisation, the accepted costs and the iterations so far."""
    X: np.ndarray
    U: np.ndarray
    K: np.ndarray
    lam: np.ndarray
    mu_c: np.ndarray
    rho: float
    mu: float
    history: list = field(default_factory=list)
    iterations: int = 0


@dataclass(frozen=True)
class DDPResult:
    """What :meth:`DDP.solve` found.

    Attributes
    ----------
    t : (N+1,) array
        Times of the nodes, s.
    x : (N+1, nx) array
        States ``[qpos, qvel]`` (m, rad, m/s, rad/s) of the rollout of ``u`` from ``x0`` on the discrete model.
    u : (N, nu) array
        The ctrl held over each step (MuJoCo ctrl units).
    K : (N, nu, nx) array
        The last backward pass's feedback gains (ctrl per unit state error), zero on clamped inputs.
    cost : float
        ``sum dt L + Phi`` of the result (the running cost's own units times s), without the constraint penalties.
    violation : float
        Largest constraint violation (m or rad), 0 when every constraint holds.
    converged : bool
        The inner solve converged and the violation is within ``constraint_tolerance``.
    iterations : int
        DDP iterations over all rounds.
    outer : int
        Augmented-Lagrangian rounds.
    status : str
        ``"converged"``, ``"constraints violated"`` (the last round converged with a violation above the
        tolerance: every round used), ``"max_iterations"`` or ``"line_search"`` (no step decreased the cost at the
        largest regularisation).
    history : tuple of float
        The penalised cost after each accepted iteration.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    K: np.ndarray
    cost: float
    violation: float
    converged: bool
    iterations: int
    outer: int
    status: str
    history: tuple = field(default=())

    def __post_init__(self):
        for name in ("t", "x", "u", "K"):
            object.__setattr__(self, name, readonly(getattr(self, name)))


class DDP:
    """Box-DDP with augmented-Lagrangian state constraints on a discrete model (see the module doc).

    Parameters
    ----------
    step : casadi.Function
        ``(x (nx,), u (nu,)) -> x+ (nx,)``, the discrete model over ``dt`` (a physics step or a hold).
    dt : float
        Its step in s.
    N : int
        Steps in the horizon.
    problem : DDPProblem
        The costs, the ctrl box, the position bounds and the goal.
    options : DDPOptions, optional
        The solver's settings (default ``DDPOptions()``).
    """

    def __init__(self, step: ca.Function, dt: float, N: int, problem: DDPProblem, *,
                 options: DDPOptions | None = None):
        self.options = DDPOptions() if options is None else options
        if not isinstance(problem, DDPProblem):
            raise DDPError(f"problem must be a DDPProblem; got {type(problem).__name__}.")
        self.problem = problem
        p = problem
        self.nx, self.nu = int(step.numel_in(0)), int(step.numel_in(1))
        nx, nu = self.nx, self.nu
        self.nq = nx // 2
        if not (int(N) == N and N >= 1):
            raise DDPError(f"The horizon must be a whole number of steps >= 1; got {N}.")
        if not (math.isfinite(dt) and dt > 0):
            raise DDPError(f"The step must be a positive number of seconds; got {dt}.")
        self.N, self.dt = int(N), float(dt)
        self.u_low = np.broadcast_to(np.asarray(p.u_low, float), (nu,)).copy()
        self.u_high = np.broadcast_to(np.asarray(p.u_high, float), (nu,)).copy()
        if not (np.all(np.isfinite(self.u_low)) and np.all(np.isfinite(self.u_high))
                and np.all(self.u_low < self.u_high)):
            raise DDPError("The ctrl bounds must be finite with low < high for every input.")
        ql = np.full(self.nq, -np.inf) if p.q_low is None else np.asarray(p.q_low, float)
        qh = np.full(self.nq, np.inf) if p.q_high is None else np.asarray(p.q_high, float)
        self.bounded = [j for j in range(self.nq) if np.isfinite(ql[j]) or np.isfinite(qh[j])]
        self.q_low, self.q_high = ql, qh
        self.hinges = tuple(int(h) for h in p.hinges)
        self.x_goal = None if p.x_goal is None else np.asarray(p.x_goal, float).ravel()
        if self.x_goal is not None and self.x_goal.shape != (nx,):
            raise DDPError(f"The goal must be {nx} numbers [qpos, qvel].")
        self.Qf = None if p.Qf is None else np.asarray(p.Qf, float)
        if self.Qf is not None and (self.x_goal is None or self.Qf.shape != (nx, nx)):
            raise DDPError(f"The terminal weight Qf must be ({nx}, {nx}) and needs a goal x_goal.")
        self.goal_constraint = bool(p.goal_constraint) and self.x_goal is not None
        terminal = p.terminal
        if terminal is not None and (not isinstance(terminal, ca.Function) or terminal.n_in() != 1
                                     or terminal.numel_in(0) != nx or terminal.numel_out(0) != 1):
            raise DDPError(f"The terminal cost must be a CasADi Function x ({nx},) -> scalar.")
        self.terminal_cost = terminal
        self._build(step, p.running, self.options.compiled)

    # ---- the compiled pieces ----------------------------------------------------------------------------------
    def _constraints(self, x):
        """Inequalities ``g(x) <= 0`` (the position bounds), SX."""
        g = []
        for j in self.bounded:
            if np.isfinite(self.q_high[j]):
                g.append(x[j] - self.q_high[j])
            if np.isfinite(self.q_low[j]):
                g.append(self.q_low[j] - x[j])
        return ca.vertcat(*g) if g else ca.SX.zeros(0, 1)

    def _terminal_error(self, x):
        e = x - self.x_goal
        for h in self.hinges:  # wrapped smoothly: sin of the error, and 1 - cos folded into the angle's magnitude
            e[h] = ca.atan2(ca.sin(e[h]), ca.cos(e[h]))
        return e

    def _build(self, step, running, compiled: bool):
        nx, nu, dt = self.nx, self.nu, self.dt
        x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
        g = self._constraints(x)
        self.ng = ng = int(g.numel())
        lam, rho = ca.SX.sym("lam", ng), ca.SX.sym("rho")
        L = ca.dot(u, u) if running is None else running(x, u)
        stage_cost = dt * L
        # ALTRO's penalty for g <= 0: rho/2 |max(0, g + lam/rho)|^2 - |lam|^2 / (2 rho), smooth where active
        viol = ca.fmax(0, g + lam / rho)
        pen = 0.5 * rho * ca.dot(viol, viol) - ca.dot(lam, lam) / (2 * rho) if ng else ca.SX(0)
        xn = step(x, u)
        total = stage_cost + pen
        lx, lu = ca.gradient(total, x), ca.gradient(total, u)
        H, _ = ca.hessian(total, ca.vertcat(x, u))
        lxx, luu, lux = H[:nx, :nx], H[nx:, nx:], H[nx:, :nx]
        fx, fu = ca.jacobian(xn, x), ca.jacobian(xn, u)
        stage = ca.Function("ddp_stage", [x, u, lam, rho],
                            [ca.densify(v) for v in (xn, fx, fu, lx, lu, lxx, luu, lux, stage_cost, g)],
                            ["x", "u", "lam", "rho"],
                            ["xn", "fx", "fu", "lx", "lu", "lxx", "luu", "lux", "l", "g"])
        rollout = ca.Function("ddp_step", [x, u], [xn], ["x", "u"], ["xn"])
        cost = ca.Function("ddp_cost", [x, u, lam, rho], [ca.densify(stage_cost), ca.densify(pen), ca.densify(g)],
                           ["x", "u", "lam", "rho"], ["l", "pen", "g"])
        # terminal: the goal equality c = e(x) (wrapped), with multipliers nu_c, and Qf; and the bounds at x_N
        nc = nx if self.goal_constraint else 0
        mu_c = ca.SX.sym("mu_c", nc)
        e = self._terminal_error(x) if self.x_goal is not None else ca.SX.zeros(0, 1)
        qf = ca.mtimes([e.T, ca.DM(self.Qf), e]) if (self.Qf is not None and self.x_goal is not None) else ca.SX(0)
        if self.terminal_cost is not None:
            qf = qf + self.terminal_cost(x)
        phi = qf
        cterm = e if self.goal_constraint else ca.SX.zeros(0, 1)
        if self.goal_constraint:
            phi = phi + ca.dot(mu_c, e) + 0.5 * rho * ca.dot(e, e)
        phi_pen = phi + pen
        Vx, (Vxx, _) = ca.gradient(phi_pen, x), ca.hessian(phi_pen, x)
        terminal = ca.Function("ddp_terminal", [x, lam, mu_c, rho],
                               [ca.densify(v) for v in (phi_pen, Vx, Vxx, cterm, g, qf)],
                               ["x", "lam", "mu_c", "rho"], ["phi", "Vx", "Vxx", "c", "g", "qf"])
        self.nc = nc
        N = self.N
        X, U = ca.MX.sym("X", nx, N), ca.MX.sym("U", nu, N)
        LAM, R = ca.MX.sym("LAM", ng, N), ca.MX.sym("R")
        outs = stage.map(N)(X, U, LAM, ca.repmat(R, 1, N))
        stages = ca.Function("ddp_stages", [X, U, LAM, R], outs, ["X", "U", "LAM", "rho"],
                             stage.name_out())
        couts = cost.map(N)(X, U, LAM, ca.repmat(R, 1, N))
        costs = ca.Function("ddp_costs", [X, U, LAM, R], couts, ["X", "U", "LAM", "rho"], cost.name_out())
        backward, forward = self._passes(xn, x, u)
        funs = [stages, costs, rollout, terminal, backward, forward]
        self.library = None
        def build():
            lib, _ = build_library(funs)  # keyed by the generated source (N included)
            return lib, load_library(lib, tuple(f.name() for f in funs))

        built = compiled_or_none(build, "DDP functions") if compiled else None
        if built is not None:
            self.library, ext = built
            funs = [ext[f.name()] for f in funs]
        self._stages, self._costs, self._step, self._terminal, self._back, self._fwd = (Buffered(f) for f in funs)

    def _passes(self, xn, x, u):
        """The backward and forward passes as CasADi Functions, looped in C (``mapaccum``).

        Backward, per stage from the last: the Gauss-Newton ``Q`` terms, ``du`` the unconstrained Newton step
        ``-Quu^-1 Qu`` clipped into the ctrl box, feedback ``-Quu^-1 Qux`` on the inputs not clipped; for one input
        that is the box QP's exact solution (Tassa et al. 2014), for several the clipped Newton step (the line search
        checks the decrease either way). The smallest leading principal minor of each regularised ``Quu`` is returned
        so that a non-positive-definite one raises ``mu``.
        """
        nx, nu, N = self.nx, self.nu, self.N
        Vx, Vxx = ca.SX.sym("Vx", nx), ca.SX.sym("Vxx", nx, nx)
        A, B = ca.SX.sym("fx", nx, nx), ca.SX.sym("fu", nx, nu)
        lx, lu = ca.SX.sym("lx", nx), ca.SX.sym("lu", nu)
        lxx, luu, lux = ca.SX.sym("lxx", nx, nx), ca.SX.sym("luu", nu, nu), ca.SX.sym("lux", nu, nx)
        ub, mu = ca.SX.sym("u", nu), ca.SX.sym("mu")
        lo, hi = ca.DM(self.u_low), ca.DM(self.u_high)
        Qx = lx + ca.mtimes(A.T, Vx)
        Qu = lu + ca.mtimes(B.T, Vx)
        VB = ca.mtimes(Vxx, B)
        Qxx = lxx + ca.mtimes([A.T, Vxx, A])
        Quu = luu + ca.mtimes(B.T, VB)
        Qux = lux + ca.mtimes(VB.T, A)
        Quu_r = Quu + mu * ca.SX.eye(nu)
        minors = [ca.det(Quu_r[:i, :i]) for i in range(1, nu + 1)]
        pd = minors[0]
        for m_ in minors[1:]:
            pd = ca.fmin(pd, m_)
        inv = ca.inv(Quu_r)
        du0 = -ca.mtimes(inv, Qu)
        dlo, dhi = lo - ub, hi - ub
        du = ca.fmin(ca.fmax(du0, dlo), dhi)
        free = ca.logic_and(du0 > dlo, du0 < dhi)
        K = ca.mtimes(ca.diag(free), -ca.mtimes(inv, Qux))
        Vx_new = Qx + ca.mtimes([K.T, Quu, du]) + ca.mtimes(K.T, Qu) + ca.mtimes(Qux.T, du)
        Vxx_new = Qxx + ca.mtimes([K.T, Quu, K]) + ca.mtimes(K.T, Qux) + ca.mtimes(Qux.T, K)
        Vxx_new = 0.5 * (Vxx_new + Vxx_new.T)
        dV1, dV2 = ca.dot(du, Qu), 0.5 * ca.mtimes([du.T, Quu, du])
        one = ca.Function("ddp_back1", [Vx, Vxx, A, B, lx, lu, lxx, luu, lux, ub, mu],
                          [Vx_new, Vxx_new, du, K, dV1, dV2, pd])
        backward = one.mapaccum("ddp_backward", N, 2)
        # forward: x+ = f(x, clip(u_bar + alpha k + K (x - x_bar)))
        xs, xbar, kff = ca.SX.sym("x", nx), ca.SX.sym("xbar", nx), ca.SX.sym("k", nu)
        Kf, alpha = ca.SX.sym("K", nu, nx), ca.SX.sym("alpha")
        un = ca.fmin(ca.fmax(ub + alpha * kff + ca.mtimes(Kf, xs - xbar), lo), hi)
        step = ca.Function("ddp_f", [x, u], [xn])
        fwd1 = ca.Function("ddp_fwd1", [xs, xbar, ub, kff, Kf, alpha], [step(xs, un), un])
        forward = fwd1.mapaccum("ddp_forward", N, 1)
        return backward, forward

    # ---- the iteration ----------------------------------------------------------------------------------------
    def _roll(self, x0, U):
        X = np.empty((self.N + 1, self.nx))
        X[0] = x0
        for k in range(self.N):
            X[k + 1] = self._step(X[k], U[k])[0]
        return X

    def _total(self, X, U, lam, mu_c, rho):
        """(penalised cost, cost without penalties, violation)."""
        N, ng = self.N, self.ng
        l, pen, g = self._costs(X[:N].ravel(), U.ravel(), lam[:N].ravel(), np.array([rho]))
        phi, _, _, c, gN, qf = self._terminal(X[N], lam[N], mu_c, np.array([rho]))
        cost = float(l.sum()) + float(qf[0])
        viol = 0.0
        if ng:
            viol = max(float(np.max(g)) if g.size else 0.0, float(np.max(gN)), 0.0)
        if self.nc:
            viol = max(viol, float(np.max(np.abs(c))))
        return float(l.sum() + pen.sum() + phi[0]), cost, viol

    def _backward(self, D, VxN, VxxN, U, mu):
        """One backward pass (compiled, :meth:`_passes`); returns (k (N, nu), K (N, nu, nx), (dV1, dV2)) or None when
        a regularised ``Quu`` is not positive definite at this ``mu``."""
        N, nx, nu = self.N, self.nx, self.nu
        # the stages' blocks, last first (the pass runs backward in time), CasADi's column-major (rows, N*cols)
        def rev(a, rows, cols):
            return np.ascontiguousarray(a.reshape(N, cols, rows)[::-1].reshape(N * cols * rows))
        args = [VxN, VxxN.T.ravel(), rev(D[1], nx, nx), rev(D[2], nx, nu), rev(D[3], nx, 1), rev(D[4], nu, 1),
                rev(D[5], nx, nx), rev(D[6], nu, nu), rev(D[7], nu, nx),
                np.ascontiguousarray(U[::-1].ravel()), np.full(N, mu)]
        out = self._back(*args)
        pd = out[6]
        if not np.all(pd > 0):
            return None
        kff = out[2].reshape(N, nu)[::-1]
        K = out[3].reshape(N, nx, nu)[::-1].transpose(0, 2, 1)
        return np.ascontiguousarray(kff), np.ascontiguousarray(K), (float(out[4].sum()), float(out[5].sum()))

    def _forward(self, X, U, kff, K, alpha):
        N = self.N
        out = self._fwd(X[0], X[:N].ravel(), U.ravel(), kff.ravel(), K.transpose(0, 2, 1).ravel(),
                        np.full(N, alpha))
        Xn = np.empty_like(X)
        Xn[0] = X[0]
        Xn[1:] = out[0].reshape(N, self.nx)
        if not np.all(np.isfinite(Xn)):
            return None, None
        return Xn, out[1].reshape(N, self.nu).copy()

    def solve(self, x0, U0=None, *, max_iterations: int | None = None, max_outer: int | None = None) -> DDPResult:
        """Minimise from ``x0`` (nx,) starting at the ctrl sequence ``U0`` ((N, nu); default zeros, clipped into
        the bounds).

        Parameters
        ----------
        x0 : (nx,) array
        U0 : (N, nu) array, optional
        max_iterations, max_outer : int, optional
            Replace the options' limits for this solve (a receding horizon's few warm-started iterations).

        Returns
        -------
        DDPResult
        """
        o = self.options
        if max_iterations is not None or max_outer is not None:
            o = replace(o, **{k: int(v) for k, v in (("max_iterations", max_iterations), ("max_outer", max_outer))
                              if v is not None})
        N, nx, nu = self.N, self.nx, self.nu
        x0 = np.asarray(x0, float).ravel()
        if x0.shape != (nx,) or not np.all(np.isfinite(x0)):
            raise DDPError(f"The start must be {nx} finite numbers [qpos, qvel].")
        U = np.zeros((N, nu)) if U0 is None else np.array(U0, dtype=float).reshape(N, nu)
        U = np.clip(U, self.u_low, self.u_high)
        X = self._roll(x0, U)
        if not np.all(np.isfinite(X)):
            raise DDPError("The first rollout blew up; give a gentler initial ctrl sequence.")
        it = _Iterate(X=X, U=U, K=np.zeros((N, nu, nx)), lam=np.zeros((N + 1, self.ng)), mu_c=np.zeros(self.nc),
                      rho=o.penalty, mu=o.mu0)
        status, prev_viol, outer, inner_ok = "max_iterations", np.inf, 0, False
        for outer in range(1, o.max_outer + 1):
            inner_ok, failed = self._round(it, o)
            if failed:
                status = "line_search"
            _, cost, viol = self._total(it.X, it.U, it.lam, it.mu_c, it.rho)
            if viol <= o.constraint_tolerance and (inner_ok or status == "line_search"):
                status = "converged" if inner_ok else status
                break
            self._update_multipliers(it)
            if viol > 0.25 * prev_viol:
                it.rho *= o.penalty_growth
            prev_viol = viol
            it.mu = o.mu0
        _, cost, viol = self._total(it.X, it.U, it.lam, it.mu_c, it.rho)
        if status == "max_iterations" and inner_ok:  # the last round converged; its constraints still do not hold
            status = "constraints violated"
        converged = status == "converged" and viol <= o.constraint_tolerance
        t = self.dt * np.arange(N + 1)
        return DDPResult(t=t, x=it.X, u=it.U, K=it.K, cost=cost, violation=viol, converged=bool(converged),
                         iterations=it.iterations, outer=outer, status=status, history=tuple(it.history))

    def _round(self, it: _Iterate, o: DDPOptions) -> tuple[bool, bool]:
        """One augmented-Lagrangian round: the inner DDP on the penalised cost at fixed multipliers, from and into
        ``it``. Returns ``(converged, line search failed)``."""
        J, _, _ = self._total(it.X, it.U, it.lam, it.mu_c, it.rho)
        for _ in range(o.max_iterations):
            it.iterations += 1
            kind, Kb, found = self._iteration(it, J, o)
            if kind == "stationary":
                it.K = Kb
                return True, False
            if kind == "failed":
                return False, True
            Xn, Un, Jn = found
            it.K = Kb
            dJ = J - Jn
            it.X, it.U, J = Xn, Un, Jn
            it.history.append(J)
            it.mu = max(it.mu / 10, o.mu_min)
            if dJ <= o.tolerance * max(1.0, abs(J)):
                return True, False
        return False, False

    def _iteration(self, it: _Iterate, J: float, o: DDPOptions):
        """One DDP iteration from ``it`` (penalised cost ``J``): backward passes at a growing regularisation ``mu``
        until one is positive definite and its line search finds a decrease. Returns ``("stationary", K, None)`` (no
        decrease to search for), ``("accepted", K, (X, U, J))`` or ``("failed", None, None)`` (``mu`` above its
        largest)."""
        N, nx = self.N, self.nx
        rho = np.array([it.rho])
        D = self._stages(it.X[:N].ravel(), it.U.ravel(), it.lam[:N].ravel(), rho)
        D = [np.array(d) for d in D]
        _, VxN, VxxN, _, _, _ = (np.array(v) for v in self._terminal(it.X[N], it.lam[N], it.mu_c, rho))
        VxxN = VxxN.reshape(nx, nx).T
        while it.mu <= o.mu_max:
            back = self._backward(D, VxN, VxxN, it.U, it.mu)
            if back is None:
                it.mu = max(it.mu * 10, 1e-6)
                continue
            kff, Kb, dV = back
            if -(dV[0] + dV[1]) <= o.tolerance * max(1.0, abs(J)):  # no decrease to search for: stationary
                return "stationary", Kb, None
            found = self._line_search(it, kff, Kb, dV, J, o)
            if found is not None:
                return "accepted", Kb, found
            it.mu = max(it.mu * 10, 1e-6)
        return "failed", None, None

    def _line_search(self, it: _Iterate, kff, K, dV, J: float, o: DDPOptions):
        """The first step length of ``o.line_search`` whose rollout (feedforward ``kff``, feedback ``K``) decreases
        the penalised cost ``J`` enough for the expected decrease ``dV`` = (dV1, dV2): ``(X, U, J)``, or None."""
        d1, d2 = dV
        for alpha in o.line_search:
            Xn, Un = self._forward(it.X, it.U, kff, K, alpha)
            if Xn is None:
                continue
            Jn, _, _ = self._total(Xn, Un, it.lam, it.mu_c, it.rho)
            expected = -(alpha * d1 + alpha ** 2 * d2)
            if Jn < J and (expected <= 0 or (J - Jn) >= 1e-4 * expected or J - Jn > 1e-12 * abs(J)):
                return Xn, Un, Jn
        return None

    def _update_multipliers(self, it: _Iterate) -> None:
        """The augmented Lagrangian's multiplier updates (ALTRO): ``lam <- max(0, lam + rho g)``, ``mu_c <- mu_c +
        rho c``."""
        N, ng, rho = self.N, self.ng, it.rho
        if ng:
            _, _, g = self._costs(it.X[:N].ravel(), it.U.ravel(), it.lam[:N].ravel(), np.array([rho]))
            g = np.array(g).reshape(N, ng)
            it.lam[:N] = np.maximum(0.0, it.lam[:N] + rho * g)
            gN = np.array(self._terminal(it.X[N], it.lam[N], it.mu_c, np.array([rho]))[4])
            it.lam[N] = np.maximum(0.0, it.lam[N] + rho * gN)
        if self.nc:
            c = np.array(self._terminal(it.X[N], it.lam[N], it.mu_c, np.array([rho]))[3])
            it.mu_c = it.mu_c + rho * c


def ddp_for_model(model, T: float, *, steps: int = 1, objective=None, x_goal=None, bounds=None,
                  Qf=None, options: DDPOptions | None = None) -> DDP:
    """A :class:`DDP` on a :class:`~cartpole.models.CartPoleModel`'s exact discrete model over ``T`` s.

    Parameters
    ----------
    model : CartPoleModel
    T : float
        Horizon, s (rounded to whole steps of ``steps * model.dt``).
    steps : int
        Physics steps the ctrl is held for each DDP step (1: every MJCF step; more: the exact held model).
    objective : str, Objective or callable, optional
        The running cost (:func:`cartpole.ocp.objectives.make_objective`; default ``effort``; ``time`` is not a
        running cost: search over ``T`` instead).
    x_goal : (nx,) array, optional
        Terminal equality; default the upright equilibrium ``model.x_eq``; pass ``False`` for none.
    bounds : OCPBounds, optional
        ctrl and position bounds (default :func:`cartpole.ocp.bounds.bounds_from_model`).
    Qf : (nx, nx) array, optional
        Terminal weight on ``x_N - x_goal``.
    options : DDPOptions, optional
        The solver's settings (default ``DDPOptions()``).

    Returns
    -------
    DDP
    """
    bounds = bounds_from_model(model) if bounds is None else bounds
    obj = make_objective(model, objective)
    if obj.kind == "time":
        raise DDPError("DDP solves a fixed horizon: minimise time by a search over T (or pick effort, tracking, "
                       "a dmc_* reward or MODULE:FUNCTION).")
    running = obj.running  # None for effort: u'u
    h = float(model.dt) * int(steps)
    step = model.step if int(steps) == 1 else model.hold(int(steps)).step
    N = max(1, int(round(float(T) / h)))
    goal = model.x_eq if x_goal is None else (None if x_goal is False else x_goal)
    # the OCP's position bounds already hold the cart inside its rail less the margin (bounds_from_params)
    problem = DDPProblem(u_low=bounds.u_low, u_high=bounds.u_high, running=running, q_low=bounds.q_low,
                         q_high=bounds.q_high, x_goal=goal, hinges=model.hinges, Qf=Qf)
    return DDP(step, h, N, problem, options=options)

