"""MPC by warm-started DDP: each control period, a few iterations of the box-DDP of :mod:`cartpole.solvers.ddp` on the
exact held model, from the measured state and the previous solution shifted by one period.

The problem is the NMPC's (:mod:`cartpole.mpc.nmpc`) with DDP's handling of its constraints::

    min  sum_k period * L(s_k, u_k)  +  e_N' S e_N  +  rail penalty
    s.t. s_0 = x,  s_k+1 = F(s_k, u_k)   (F: ``steps`` MJCF steps of the model with the ctrl held, exact)
         u_low <= u_k <= u_high          (the box, inside the DDP's backward pass)

with ``e_N`` the wrapped terminal error. The running cost ``L`` is the MPC's objective (``MPCOptions.objective``):
by default the NMPC's tracking ``d' Q d + (u - u*)' R (u - u*)`` with ``d`` the tracking error whose hinge entries are
``2 (1 - cos e)`` (:func:`cartpole.ocp.objectives.tracking_cost`: smooth and periodic), and ``S`` the cost-to-go of the
discrete LQR of one period at upright with the same ``Q``, ``R`` (the infinite-horizon cost beyond the horizon, as in
the NMPC). Any other running objective of the trajectory optimisation (``effort``, the ``dmc_*`` rewards negated,
``MODULE:FUNCTION``) is taken as it is, and ``S`` is then that objective's own cost-to-go near upright: the discrete
LQR of its quadratic model there (``Q_L, R_L, N_L`` half the Hessian of ``L`` at ``(x*, u*)``, times the period), so
the cost beyond the horizon is priced in the objective's units (:func:`objective_cost_to_go`). Where that LQR does not
exist (``effort`` has no state cost: the cart's drift is free, the Riccati equation has no stabilising solution) the
``Q``, ``R`` LQR's ``S`` is used, scaled to the objective's input weight (:attr:`DDPMPCController.terminal` says
which). The rail (the slide's range shrunk by ``cart_margin``) and any other limited joint enter as the
augmented-Lagrangian penalty of the DDP with its multipliers at zero and the penalty ``10 rail_penalty``: a soft
constraint.

The first solution is converged offline from the plan's inputs (:func:`cartpole.planning.trajopt.trajopt_swingup`
for the same objective, sampled on the MPC grid). In the loop each instant takes ``iterations`` DDP iterations (default one: real-time
DDP) and applies the first input. Safe action as the NMPC's: a solve that fails or returns anything non-finite is
recorded in :attr:`DDPMPCController.failures` and the upright LQR (near upright) or the previous solution's input
is applied.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from cartpole.control.linear import LinearFeedback
from cartpole.riccati import dlqr, default_weights
from cartpole.models import CartPoleModel, CartPoleParams, Plant, plant_model, plant_params
from cartpole.mpc.nmpc import SAFE_LQR_ANGLE, NMPCError
from cartpole.mpc.options import MPCOptions, mpc_grid
from cartpole.ocp.bounds import bounds_from_params
from cartpole.riccati.algebraic import LQRError
from cartpole.ocp.bounds import OCPError
from cartpole.ocp.objectives import make_objective, tracking_cost
from cartpole.ocp.trajectory import Trajectory
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.solvers.ddp import DDP, DDPOptions, DDPProblem


class DDPMPCController:
    """Receding-horizon DDP, call shape ``u = controller(t, x)`` (see the module doc).

    Parameters
    ----------
    model : CartPoleModel
        The planning model (rebuilt at ``params.timestep`` when its ``dt`` differs).
    params : CartPoleParams
        The MJCF MuJoCo runs: timestep, ctrlranges, joint ranges.
    options : MPCOptions, optional
        ``period``, ``horizon``, ``iterations``, ``init_iterations``, ``cart_margin``, ``rail_penalty``, ``Q``, ``R``,
        ``compiled``, ``objective`` are read (:class:`~cartpole.mpc.options.MPCOptions`).
    guess : Trajectory, optional
        A plan whose inputs seed the first solution and extend the shifted tail while it lasts.
    x0 : (nx,) array, optional
        When given, the first solution is converged for this start offline (not in :attr:`solve_ms`).
    step_budget : float, optional
        s of wall time an instant's DDP iterations may take before their answer is too late for it: a step over it
        applies the previous solution's input shifted to this instant (what a real-time loop sends at its deadline)
        and keeps the late solution as the next step's warm start, each such step recorded in
        :attr:`over_budget`. The solve itself is not interrupted (the iterations run to their end); what is bounded
        is that no ctrl waits for an answer later than the budget. None (default): every step applies its own
        solution however long it took.

    Attributes
    ----------
    period, horizon : float
        s, after rounding to whole MJCF steps and stages.
    N, steps : int
        Stages; physics steps per stage.
    solve_ms : list of float
        Wall-clock ms of each instant's DDP iterations.
    failures : list of dict
        ``{"t", "reason", "action"}`` per instant where the safe action ran.
    over_budget : list of dict
        ``{"t", "ms"}`` per instant whose solve took more than ``step_budget``: the previous solution's shifted input
        was applied.
    lqr : LinearFeedback
        The upright discrete LQR of one period with ``Q``, ``R`` (the safe action).
    objective : str
        The running objective's name (``tracking`` by default).
    terminal : str
        Where the terminal weight came from: ``"lqr"`` (the ``Q``, ``R`` LQR: tracking), ``"objective"`` (the
        objective's own LQR cost-to-go at upright) or ``"lqr scaled"`` (the objective has none; module doc).
    S : (nx, nx) array
        The terminal weight on the wrapped error from upright.
    init_info : dict
        The offline solve: ``iterations``, ``status``, ``cost``.
    """

    def __init__(self, model: CartPoleModel, params: CartPoleParams, *, options: MPCOptions | None = None,
                 guess=None, x0=None, step_budget: float | None = None):
        options = MPCOptions() if options is None else options
        self.options = options
        if step_budget is not None and (isinstance(step_budget, bool) or not isinstance(step_budget, (int, float))
                                        or not np.isfinite(step_budget) or step_budget <= 0):
            raise NMPCError(f"step_budget = {step_budget!r} must be a positive number of seconds or None.")
        self.step_budget = None if step_budget is None else float(step_budget)
        if not isinstance(model, CartPoleModel) or not isinstance(params, CartPoleParams):
            raise NMPCError("DDPMPCController needs a CartPoleModel (planning) and the CartPoleParams MuJoCo runs.")
        dt = float(params.timestep)
        if abs(model.dt - dt) > 1e-15:
            model = model.rebuilt(dt=dt)
        steps, N = mpc_grid(options, dt)  # refused when the period or horizon cannot be used as given
        self.model, self.params, self.steps, self.N = model, params, steps, N
        self.period, self.horizon = steps * dt, N * steps * dt
        self.iterations = int(options.iterations)
        Q0, R0 = default_weights(model)
        Q = Q0 if options.Q is None else np.asarray(options.Q, float)
        R = R0 if options.R is None else np.atleast_2d(np.asarray(options.R, float))
        held = model.hold(steps)
        Ad, Bd = held.linearize(model.x_eq, model.u_eq)
        lq = dlqr(Ad, Bd, Q * self.period, R * self.period)
        self.lqr = LinearFeedback(lq.K, model.x_eq, model.u_eq, hinges=model.hinges,
                                  u_limits=np.asarray(params.ctrl_range), S=lq.S)
        x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
        name = options.objective
        if name is None or name == "tracking":
            running = ca.Function("mpc_tracking", [x, u], [tracking_cost(model, x, u, np.diag(Q), np.diag(R))])
            S, self.terminal, self.objective = np.asarray(lq.S), "lqr", "tracking"
        else:
            try:
                obj = make_objective(model, name)
            except OCPError as exc:
                raise NMPCError(str(exc)) from None
            running, self.objective = obj.running, obj.name  # None: effort, u'u (the DDP's own)
            S, self.terminal = objective_cost_to_go(model, Ad, Bd, running, self.period, lq.S, R)
        self.S = S
        b = bounds_from_params(params, cart_margin=options.cart_margin)
        self.u_low, self.u_high = np.array(b.u_low, float), np.array(b.u_high, float)
        problem = DDPProblem(u_low=self.u_low, u_high=self.u_high, running=running, q_low=b.q_low, q_high=b.q_high,
                             x_goal=model.x_eq, hinges=model.hinges, Qf=S, goal_constraint=False)
        self.ddp = DDP(held.step, self.period, N, problem,
                       options=DDPOptions(penalty=10 * options.rail_penalty, max_outer=1, compiled=options.compiled))
        self._plan = guess if isinstance(guess, Trajectory) else None
        U = np.array([self._tail_input(k * steps, None) for k in range(N)])
        self.init_info = {"iterations": 0, "status": "not converged offline", "cost": float("nan")}
        if x0 is not None:
            U, self.init_info = self._converged(x0, U)
        self._U0 = U
        self.reset()

    def _converged(self, x0, U) -> tuple[np.ndarray, dict]:
        """The solution (N, nu) converged from ``x0`` (nx,) starting from the inputs ``U`` (N, nu): at most
        ``init_iterations * 20`` DDP iterations; and ``{"iterations", "status", "cost"}``."""
        x0 = np.asarray(x0, dtype=float).ravel()
        if x0.shape != (self.model.nx,) or not np.all(np.isfinite(x0)):
            raise NMPCError(f"x0 must be {self.model.nx} finite numbers [qpos, qvel].")
        r = self.ddp.solve(x0, U, max_iterations=max(1, int(self.options.init_iterations)) * 20)
        return np.array(r.u), {"iterations": r.iterations, "status": r.status, "cost": r.cost}

    def converge(self, x0) -> dict:
        """Start a new run (:meth:`reset`) from ``x0`` (nx,) with its solution converged from there, as the
        constructor's ``x0`` does offline (from the first solution, at most ``init_iterations * 20`` DDP iterations;
        not in :attr:`solve_ms`: the caller times it), the first solution itself kept for later resets. A run that
        takes over at ``x0`` then starts from a solution for it instead of one iterate a period away from the upright's
        inputs. Returns ``{"iterations", "status", "cost"}``; :class:`~cartpole.mpc.nmpc.NMPCError` for an ``x0`` that
        is not ``nx`` finite numbers."""
        U, info = self._converged(x0, self._U0.copy())
        self.reset()
        self._U = U
        return info

    def reset(self) -> None:
        """Start a new run: back to the first solution, empty :attr:`solve_ms` and :attr:`failures` (done
        automatically when called with an earlier time than the last call)."""
        self._U = self._U0.copy()
        self._X = None
        self._k_plan = 0
        self._k_last = None
        self._u_hold = None
        self.solve_ms: list[float] = []
        self.failures: list[dict] = []
        self.over_budget: list[dict] = []

    def _tail_input(self, k_phys: int, x_last) -> np.ndarray:
        t = k_phys * float(self.params.timestep)
        if self._plan is not None and self._plan.t[0] + t < self._plan.t[-1]:
            u = self._plan.input(self._plan.t[0] + t + 0.5 * self.period)
            return np.clip(np.atleast_1d(u), self.u_low, self.u_high)
        return self.lqr(t, self.model.x_eq if x_last is None else x_last)

    def _shift(self, n: int) -> None:
        for _ in range(min(n, self.N)):
            k_end = self._k_plan + self.N * self.steps
            last = None if self._X is None else self._X[-1]
            self._U = np.vstack([self._U[1:], self._tail_input(k_end, last)])
            self._k_plan += self.steps
        if n > self.N:
            self._k_plan += (n - self.N) * self.steps

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s) for the measured state ``x`` (nx,): re-solved once a period has passed since
        the last solve, held in between."""
        k = int(round(float(t) / float(self.params.timestep)))
        if self._k_last is not None and k < self._k_last:
            self.reset()
        if self._u_hold is not None and k - self._k_last < self.steps:
            return self._u_hold.copy()
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (self.model.nx,):
            raise NMPCError(f"The state has {x.size} entries; the controller needs {self.model.nx} [qpos, qvel].")
        t0 = time.perf_counter()
        if k > self._k_plan:
            self._shift((k - self._k_plan) // self.steps)
        shifted = None if self._k_last is None else np.clip(self._U[0], self.u_low, self.u_high)
        try:
            if not np.all(np.isfinite(x)):
                raise ValueError("the measured state is not finite")
            r = self.ddp.solve(x, self._U, max_iterations=self.iterations, max_outer=1)
            if not (np.all(np.isfinite(r.u)) and np.all(np.isfinite(r.x))):
                raise ValueError("the DDP returned a non-finite solution")
            self._U, self._X = np.array(r.u), np.array(r.x)
            u = np.clip(self._U[0], self.u_low, self.u_high)
        except Exception as exc:  # noqa: BLE001 - never raise inside the loop: the documented safe action
            finite = bool(np.all(np.isfinite(x)))
            near = finite and np.all(np.abs(self.lqr.error(x)[list(self.model.hinges)]) <= SAFE_LQR_ANGLE)
            if finite and not near:
                u, action = np.clip(self._U[0], self.u_low, self.u_high), "previous plan"
            else:
                u, action = (self.lqr(t, x) if finite else self.model.u_eq.copy()), "upright LQR"
            self.failures.append({"t": float(t), "reason": str(exc) or type(exc).__name__, "action": action})
        ms = 1e3 * (time.perf_counter() - t0)
        self.solve_ms.append(ms)
        if self.step_budget is not None and shifted is not None and ms > 1e3 * self.step_budget:
            u = shifted  # the answer came after the step's deadline: the previous solution's input, shifted
            self.over_budget.append({"t": float(t), "ms": ms})
        self._k_last = k
        self._u_hold = np.array(u, dtype=float)
        return self._u_hold.copy()

    @property
    def plan(self) -> tuple[np.ndarray | None, np.ndarray]:
        """The current solution: predicted states (N+1, nx) (None before the first solve) and inputs (N, nu)."""
        return (None if self._X is None else self._X.copy()), self._U.copy()


def objective_cost_to_go(model: CartPoleModel, Ad, Bd, running, period: float, S_lqr, R_lqr
                         ) -> tuple[np.ndarray, str]:
    """The terminal weight of a running objective ``L`` near upright: the cost-to-go ``S`` (nx, nx) of its discrete
    LQR over one period and where it came from.

    ``L``'s quadratic model at ``(x*, u*)`` is ``dz' H dz / 2`` (``H`` its Hessian in ``z = (x, u)``: exact, from
    the symbols; a dm_control ``tolerance`` whose bounds are the single point upright contributes its sigmoid's
    curvature there, :func:`cartpole.ocp.dmc.tolerance`), so the stage cost ``period * L`` is ``x' Q x + u' R u + 2 x' N u`` with ``(Q, N; N', R) = period H / 2``;
    the LQR of that cost on ``(Ad, Bd)`` (cross term removed by ``u = v - R^-1 N' x``) prices the state beyond the
    horizon in ``L``'s own units. When it does not exist (``R`` not positive definite, ``Q`` not positive
    semi-definite, no stabilising Riccati solution: ``effort`` has no state cost at all) the ``Q_lqr, R_lqr`` LQR's
    ``S_lqr`` is returned scaled by ``R``'s size over ``R_lqr``'s (the two weigh the input alike).

    Parameters
    ----------
    model : CartPoleModel
    Ad, Bd : (nx, nx), (nx, nu) arrays
        The model held over one period, linearised at upright.
    running : casadi.Function or None
        ``L(x, u)``, cost per second; None for ``effort`` (``u' u``).
    period : float
        s.
    S_lqr, R_lqr : arrays
        The fallback LQR's cost-to-go and its input weight (per second).

    Returns
    -------
    (S, source)
        ``source`` ``"objective"`` or ``"lqr scaled"``.
    """

    nx, nu = model.nx, model.nu
    z = ca.SX.sym("z", nx + nu)
    L = ca.sumsqr(z[nx:]) if running is None else running(z[:nx], z[nx:])
    H = np.array(ca.Function("mpc_cost_hessian", [z], [ca.hessian(L, z)[0]])(
        np.concatenate([model.x_eq, model.u_eq])).full(), dtype=float)
    W = 0.5 * float(period) * 0.5 * (H + H.T)
    Q, N, R = W[:nx, :nx], W[:nx, nx:], W[nx:, nx:]
    Ad, Bd = np.asarray(Ad, float), np.asarray(Bd, float)
    if np.all(np.isfinite(W)) and np.linalg.eigvalsh(R).min() > 0:
        RiN = np.linalg.solve(R, N.T)
        Qt = Q - N @ RiN
        Qt = 0.5 * (Qt + Qt.T)
        if np.linalg.eigvalsh(Qt).min() >= -1e-12 * max(1.0, float(np.abs(Qt).max())):
            try:
                return np.asarray(dlqr(Ad - Bd @ RiN, Bd, Qt, R).S), "objective"
            except LQRError:
                pass
    scale = float(np.trace(R)) / (float(period) * float(np.trace(np.atleast_2d(R_lqr)))) if np.trace(R) > 0 else 1.0
    return np.asarray(S_lqr) * scale, "lqr scaled"


def seed_plan_options(plan, options: MPCOptions):
    """``plan`` (PlanOptions) for the DDP MPC's seed: its objective the MPC's when it names none (the seed is planned
    for what the MPC minimises); ``plan`` itself when either has none."""
    if plan.objective is None and options.objective is not None:
        return plan.replace(objective=options.objective)
    return plan


def ddp_mpc_swingup(plant: Plant = None, x0=None, *, plan_model: CartPoleModel | None = None,
                    options: MPCOptions | None = None, plan=None) -> DDPMPCController:
    """A DDP-MPC controller set up to swing up from ``x0`` and balance at ``model.x_eq``: the offline plan
    (:func:`cartpole.planning.trajopt.trajopt_swingup`) seeds it (unless ``options.seed_plan`` is False: no plan,
    the upright LQR's inputs), then the first solution is converged offline.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The MJCF MuJoCo runs.
    x0 : (nx,) array, optional
        Start (default the planning model's hanging rest).
    plan_model : CartPoleModel, optional
        The planning model (default the MJCF's own).
    options : MPCOptions, optional
    plan : PlanOptions, optional
        The offline plan's settings (default the same rail margin as the controller's, and the MPC's objective when
        the plan names none).

    Returns
    -------
    DDPMPCController
    """

    options = MPCOptions() if options is None else options
    plan = seed_plan_options(PlanOptions(cart_margin=options.cart_margin) if plan is None else plan, options)
    params = plant_params(plant)
    model = plant_model(plant) if plan_model is None else plan_model
    x0 = model.x_hanging if x0 is None else np.asarray(x0, dtype=float).ravel()
    guess = trajopt_swingup(params, x0=x0, plan_model=model, options=plan).trajectory if options.seed_plan else None
    return DDPMPCController(model, params, options=options, guess=guess, x0=x0)
