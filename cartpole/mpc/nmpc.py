"""Nonlinear MPC in the MuJoCo loop: multiple shooting on the exact discrete model, real-time iteration (RTI).

The optimal-control problem re-solved every control period ``period`` (a whole number ``steps`` of MJCF physics
steps), over ``N`` stages of one period each (``horizon = N period``), from the measured state ``x``::

    min   1/2 sum_k [e_k' Q_s e_k + (u_k - u*)' R_s (u_k - u*)]  +  1/2 e_N' P e_N  +  rho_1 sigma + rho_2 sigma^2 / 2
    s.t.  s_0 = x,   s_k+1 = F(s_k, u_k)                        (F: ``steps`` MJCF steps of ``model.step``, u held)
          u_low <= u_k <= u_high                                 (the MJCF's ctrlranges)
          q_low - sigma <= q_k <= q_high + sigma,  sigma >= 0    (the cart's rail shrunk by ``cart_margin``, and
                                                                   any other limited joint; k = 1..N, soft)

with ``e_k = s_k - x*`` (hinge entries of ``x*`` moved by whole turns to the upright nearest the last node
``s_N``: the wrapped angle error, taken once per horizon so the cost stays smooth along it), stage weights
``Q_s = Q period``, ``R_s = R period`` (``Q``, ``R`` default :func:`cartpole.riccati.default_weights`) and the terminal
weight ``P`` the cost-to-go ``S`` of the discrete LQR of the same stage at the upright equilibrium (``dlqr(Ad, Bd,
Q period, R period)`` on one period of the exact model): the LQR's infinite-horizon cost beyond the horizon. The
rail is soft with one exact-penalty slack ``sigma`` (m or rad) shared by every bound (``rho_1`` = ``rail_penalty``,
``rho_2 = 10 rho_1``): inside the rail it changes nothing, and a push that makes the hard rail infeasible leaves
the QP feasible.

Real-time iteration (Diehl's RTI, acados' ``SQP_RTI``): each control instant takes ``iterations`` (default one)
Gauss-Newton SQP step from the previous solution shifted by one stage (its last stage extended with the offline
plan's input while the plan lasts, else the upright LQR's) and applies the first input at once. The cost is
quadratic, so Gauss-Newton is exact in the cost and drops only the dynamics' second derivatives. The QP of a
step comes from one call of C compiled from CasADi (:mod:`cartpole.mpc.stage_functions`): the stages' values and
exact Jacobians ``A_k``, ``B_k``, condensed onto the inputs by the O(N^2) backward recursion (``ds = g + G du``;
``N nu + 1`` variables with the slack, dense Hessian), evaluated on numpy buffers (no CasADi DM conversions).
Condensing in ``du`` is ill-conditioned when the plant's fastest unstable mode grows by much over the horizon
(``exp(lambda T)``: 260 for the single pole at 1.2 s, 2e5 for three poles): above :data:`GROWTH_LIMIT` the QP is
pre-stabilised by default (``prestabilize``): its unknowns are the steps relative to the Riccati feedback along
the iterate, ``du_k = -K_k ds_k + dv_k``, which is well conditioned for any horizon and costs about twice as much.
The QP is solved by DAQP (a dual active-set solver for small dense QPs, PyPI ``daqp``) or qpOASES (shipped with
CasADi, ``casadi.conic("qpoases")``); both give the same solution. DAQP is the default because qpOASES, even
hot-started with no working-set change, re-factorises each new dense matrix, and HPIPM through ``sqpmethod`` costs
more again (DESIGN.md); :func:`cartpole.apps.bench.mpc.run_mpc_benchmark` measures the step against IPOPT.

One implementation: by default each control instant runs the compiled C of ``cartpole/csrc/nmpc.c.jinja``
(shift, the stages' linearisations through the CasADi-generated stage, the condensing, the dual active-set QP of
``cartpole/csrc/qp_dual.c``, the safe action), built once per model and settings and called through ctypes
(:mod:`cartpole.mpc.nmpc_c`): the C that ``cartpole export --controller nmpc`` ships, so the loop's ctrl and the
exported folder's are equal. The Python step described here (DAQP or qpOASES) is the path without a C compiler
(``c_step=False``, or a ``qp_solver`` given) and the tests' reference: from the same iterate both take the same
Gauss-Newton step to rounding.

Safe action: a QP that fails, or a step that returns anything non-finite, never raises inside the loop. The
controller applies the upright discrete LQR of the period (clipped to the ctrlranges) when every pole is within
:data:`SAFE_LQR_ANGLE` of upright; otherwise (mid swing-up) the previous plan's input for this instant (that plan
shifted by the periods since it was solved) while the plan has stages left, else that LQR. It records the instant
in :attr:`NMPCController.failures`, and the next instant tries again from the plan's inputs simulated from the
measured state.
"""
from __future__ import annotations

import contextlib
import ctypes
import importlib.util
import os
import sys
import time
from dataclasses import dataclass

import casadi as ca
import daqp
import numpy as np

from cartpole._arrays import readonly
from cartpole.codegen import QP_ITER_LIMIT, Buffered
from cartpole.control.linear import LinearFeedback
from cartpole.models import CartPoleModel, CartPoleParams, Plant, plant_model, plant_params
from cartpole.mpc.ipopt_nlp import IpoptNLP, StepFailed as _StepFailed
from cartpole.mpc.nmpc_c import compiled_nmpc
from cartpole.mpc.options import DEFAULT_PERIOD, RAIL_PENALTY, MPCOptions, NMPCError, mpc_grid
from cartpole.mpc.stage_functions import StageFunctions, stage_functions
from cartpole.ocp.bounds import bounds_from_params
from cartpole.ocp.trajectory import Trajectory
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.riccati import default_weights, dlqr

_BIG = 1e30  # DAQP's "no bound"
#: rad: within this of upright (every pole, wrapped) the safe action is the upright LQR, not the previous plan.
SAFE_LQR_ANGLE = 0.5
#: Growth ``exp(lambda_max horizon)`` of the fastest upright mode above which the QP is pre-stabilised by default:
#: measured, plain condensing solved every instant up to 1.1e4 (single pole at 2 s) and failed some from 2e5
#: (three poles at 1.2 s, two poles at 2 s, single pole at 3 s); but already at 6.7e3 (two poles at 1.2 s) its
#: Hessian's condition number is about 1e6, against about 5 pre-stabilised, which the exported C's agreement with
#: this controller and its float32 build need. The single pole at 1.2 s (260) stays plain.
GROWTH_LIMIT = 1e3
_RESEED_ABOVE = 1e3  # an iterate with an entry this large (m, rad, m/s, rad/s) is garbage: re-seed it


@dataclass(frozen=True)
class MPCProblem:
    """The OCP every control period re-solves (shared by the RTI controller and the IPOPT baseline).

    Attributes
    ----------
    steps, N : int
        Physics steps per stage and stages.
    dt, period, horizon : float
        Physics step, control period ``steps dt`` and horizon ``N period``, s.
    Qs, Rs, P : arrays (nx, nx), (nu, nu), (nx, nx)
        Stage weights (per period) and terminal weight.
    x_goal, u_goal : (nx,), (nu,) arrays
        Target ``x*``, ``u*``.
    hinges : tuple of int
        qpos indices whose target is moved by whole turns to the nearest upright.
    u_low, u_high : (nu,) arrays
        ctrl bounds.
    bounded : tuple of int
        qpos indices with a (soft) position bound; ``q_low``, ``q_high`` (len(bounded),) the bounds.
    rho1, rho2 : float
        Slack penalty (linear, quadratic).
    """

    steps: int
    N: int
    dt: float
    Qs: np.ndarray
    Rs: np.ndarray
    P: np.ndarray
    x_goal: np.ndarray
    u_goal: np.ndarray
    hinges: tuple
    u_low: np.ndarray
    u_high: np.ndarray
    bounded: tuple
    q_low: np.ndarray
    q_high: np.ndarray
    rho1: float
    rho2: float

    @property
    def period(self) -> float:
        """Control period in s."""
        return self.steps * self.dt

    @property
    def horizon(self) -> float:
        """Horizon in s."""
        return self.N * self.period

    @property
    def nx(self) -> int:
        """State dimension."""
        return int(self.x_goal.size)

    @property
    def nu(self) -> int:
        """Input dimension."""
        return int(self.u_goal.size)

    def goal_near(self, s_last) -> np.ndarray:
        """``x*`` (nx,) with each hinge angle moved by whole turns to the one nearest ``s_last`` (nx,)."""
        goal = np.array(self.x_goal, dtype=float)
        h = list(self.hinges)
        if h:
            goal[h] += 2 * np.pi * np.round((np.asarray(s_last)[h] - goal[h]) / (2 * np.pi))
        return goal


def _matrix(name: str, M, n: int) -> np.ndarray:
    M = np.asarray(M, dtype=float)
    M = M * np.eye(n) if M.ndim == 0 else M
    if M.shape == (n,):
        M = np.diag(M)
    if M.shape != (n, n) or not np.all(np.isfinite(M)):
        raise NMPCError(f"{name} must be a finite ({n}, {n}) matrix (or its diagonal); got shape {M.shape}.")
    return 0.5 * (M + M.T)


def mpc_problem(model: CartPoleModel, params: CartPoleParams, stages: StageFunctions, *, Q=None, R=None,
                x_goal=None, u_goal=None, cart_margin: float = 0.1, rail_penalty: float = RAIL_PENALTY
                ) -> tuple[MPCProblem, LinearFeedback]:
    """The OCP of one MPC step and its upright LQR (the terminal cost's, and the safe action).

    ``x_goal`` (nx,) and ``u_goal`` (nu,) are the state ``[qpos, qvel]`` and ctrl held at the end (default the
    model's upright equilibrium ``x_eq``, ``u_eq``); ``Q``, ``R`` the stage weights (default the lab's),
    ``cart_margin`` m kept from each rail end.

    Returns ``(problem, lqr)``: ``lqr`` is ``u = u* - K e`` of ``dlqr(Ad, Bd, Q period, R period)`` on one period
    of the exact model at ``x_eq``, ``u_eq``, clipped to the ctrlranges, with ``S = P``.
    """
    nx, nu = model.nx, model.nu
    Q0, R0 = default_weights(model)
    Q = Q0 if Q is None else _matrix("Q", Q, nx)
    R = R0 if R is None else _matrix("R", R, nu)
    if np.linalg.eigvalsh(Q).min() < -1e-12 or np.linalg.eigvalsh(R).min() <= 0:
        raise NMPCError("Q must be positive semidefinite and R positive definite; give weights >= 0 on states and "
                        "> 0 on inputs.")
    x_goal = model.x_eq if x_goal is None else np.asarray(x_goal, dtype=float).ravel()
    u_goal = model.u_eq if u_goal is None else np.broadcast_to(np.asarray(u_goal, float), (nu,))
    if x_goal.shape != (nx,) or not np.all(np.isfinite(x_goal)):
        raise NMPCError(f"x_goal must be {nx} finite numbers [qpos, qvel]; got {np.asarray(x_goal).tolist()}.")
    if not rail_penalty > 0:
        raise NMPCError(f"rail_penalty {rail_penalty} must be positive (cost per m of rail violation).")
    period = stages.steps * model.dt
    _, A, B = stages.stage(model.x_eq, model.u_eq)
    lq = dlqr(np.asarray(A), np.asarray(B), Q * period, R * period)
    bounds = bounds_from_params(params, cart_margin=cart_margin)
    bounded = bounds.bounded_joints
    prob = MPCProblem(steps=stages.steps, N=stages.N, dt=float(model.dt), Qs=readonly(Q * period),
                      Rs=readonly(R * period), P=readonly(0.5 * (lq.S + lq.S.T)), x_goal=readonly(x_goal),
                      u_goal=readonly(np.array(u_goal, dtype=float)), hinges=tuple(model.hinges),
                      u_low=readonly(bounds.u_low), u_high=readonly(bounds.u_high), bounded=bounded,
                      q_low=readonly(bounds.q_low[list(bounded)]), q_high=readonly(bounds.q_high[list(bounded)]),
                      rho1=float(rail_penalty), rho2=10.0 * float(rail_penalty))
    lqr = LinearFeedback(lq.K, model.x_eq, model.u_eq, hinges=model.hinges, u_limits=np.asarray(params.ctrl_range),
                         S=prob.P)
    return prob, lqr


def _grid_guess(guess, prob: MPCProblem, x0) -> tuple[np.ndarray, np.ndarray]:
    """Initial shooting nodes (N+1, nx) and inputs (N, nu) from a guess: a Trajectory (sampled on the MPC grid,
    inputs the mean over each period), a ``(S, U)`` pair, or None (rest at ``x0``, else at ``x*``, with ``u*``)."""
    N, nx, nu = prob.N, prob.nx, prob.nu
    if guess is None:
        rest = prob.x_goal if x0 is None else x0
        return np.tile(rest, (N + 1, 1)), np.tile(prob.u_goal, (N, 1))
    if isinstance(guess, Trajectory):
        if guess.nx != nx or guess.nu != nu:
            raise NMPCError(f"The guess trajectory has nx={guess.nx}, nu={guess.nu}; the model needs {nx}, {nu}.")
        t = guess.t[0] + prob.period * np.arange(N + 1)
        S = guess.state(t)
        U = guess.input(t[:-1] + 0.5 * prob.period)
    else:
        try:
            S, U = (np.asarray(a, dtype=float) for a in guess)
        except (TypeError, ValueError):
            raise NMPCError("guess must be a Trajectory or a pair (S (N+1, nx), U (N, nu)).") from None
        U = U.reshape(N, nu) if U.size == N * nu else U
    if S.shape != (N + 1, nx) or U.shape != (N, nu) or not (np.all(np.isfinite(S)) and np.all(np.isfinite(U))):
        raise NMPCError(f"The guess must be finite with S ({N + 1}, {nx}) and U ({N}, {nu}); got {S.shape}, "
                        f"{U.shape}.")
    return np.array(S), np.clip(U, prob.u_low, prob.u_high)


class NMPCController:
    """Nonlinear MPC by real-time iteration, call shape ``u = controller(t, x)`` (see the module docstring).

    Parameters
    ----------
    model : CartPoleModel
        The planning model (any number of poles); its ``step`` at the MJCF's timestep is the shooting step (rebuilt
        at ``params.timestep`` when its ``dt`` differs). May differ from the MJCF on purpose.
    params : CartPoleParams
        The MJCF MuJoCo runs: timestep, ctrlranges, joint ranges.
    options : MPCOptions, optional
        The controller's settings (:class:`~cartpole.mpc.options.MPCOptions`: period, horizon, iterations, tol,
        init_iterations, cart_margin, rail_penalty, Q, R, qp_solver, prestabilize, compiled; meaning, units and
        defaults there); default ``MPCOptions()`` (a period of :data:`DEFAULT_PERIOD` when it gives none).
    x_goal : (nx,) array, optional
        Target state (default the upright equilibrium ``model.x_eq``); ``u_goal`` (nu,) target ctrl (default
        ``model.u_eq``).
    guess : Trajectory or (S (N+1, nx), U (N, nu)), optional
        First iterate; a Trajectory (e.g. an offline plan) is sampled on the MPC grid from its start. Default:
        rest at ``x0`` (else at ``x_goal``) with ``u_goal``: enough to balance near upright.
    x0 : (nx,) array, optional
        When given, the first iterate is converged for this start state before the loop, offline (that time is
        not in :attr:`solve_ms`): up to ``options.init_iterations`` full Gauss-Newton steps, and when they do not
        converge IPOPT on the same NLP from the same guess, then Gauss-Newton steps from its solution.

    With ``prestabilize`` the QP's unknowns are the input steps relative to the finite-horizon LQR's feedback (the
    Riccati gains ``K_k`` along the current iterate) on the predicted state corrections, ``du_k = -K_k ds_k +
    dv_k`` (the closed-loop paradigm), which keeps the condensed QP well conditioned over long horizons and fast
    chains of poles, at about twice the cost of a step; without, plain condensing in ``du``. The same QP, so the
    same solution, either way. By default it is on when the fastest unstable mode of the upright linearisation
    grows by more than :data:`GROWTH_LIMIT` over the horizon (single pole at 1.2 s: 260, plain; two poles: 6.7e3,
    pre-stabilised; three poles: 2e5, pre-stabilised).

    Attributes
    ----------
    options : MPCOptions
        The settings it was built with (period and horizon as given, before rounding).
    period, horizon : float
        s, after rounding.
    N, steps : int
        Stages; physics steps per stage.
    solve_ms : list of float
        Wall-clock ms of each control instant's solve (linearisation, condensing, QP, update), one per instant.
    step_c_ms : list of float
        With the C step: ms of each instant's step timed inside the C (``solve_ms`` adds the ctypes call).
    step_implementation : str
        ``"c"``: each instant runs the compiled C of ``cartpole/csrc/nmpc.c.jinja`` (:mod:`cartpole.mpc.nmpc_c`,
        the C ``cartpole export`` ships); ``"python"``: the Python step below (``options.c_step`` False, a
        ``qp_solver`` given, or no C compiler).
    failures : list of dict
        ``{"t", "reason", "action"}`` for each instant where the QP failed and the safe action was applied.
    qp_solver : str
        ``"daqp"`` or ``"qpoases"`` (the Python step's), ``"c"`` with the C step (its dual active-set solver,
        ``cartpole/csrc/qp_dual.c``).
    library : str or None
        The compiled stage library, None on the fallback.
    lqr : LinearFeedback
        The upright LQR of one period (terminal cost ``S``, safe action).
    init_info : dict
        The offline convergence: ``iterations`` (Gauss-Newton steps), ``converged`` (bool), ``step`` (last max
        |du|), ``method`` (``"gauss-newton"``, or ``"ipopt"`` with ``ipopt_iterations``).
    """

    #: Whether the compiled C step may replace this class's instant solve (a subclass that solves each instant
    #: otherwise, e.g. :class:`~cartpole.mpc.ipopt_baseline.IpoptMPC`, sets False).
    c_step_capable = True

    def __init__(self, model: CartPoleModel, params: CartPoleParams, *, options: MPCOptions | None = None,
                 x_goal=None, u_goal=None, guess=None, x0=None):
        options = MPCOptions() if options is None else options
        self.options = options
        period, iterations, tol = options.period, options.iterations, options.tol
        init_iterations, qp_solver, prestabilize = options.init_iterations, options.qp_solver, options.prestabilize
        if not isinstance(model, CartPoleModel) or not isinstance(params, CartPoleParams):
            raise NMPCError("NMPCController needs a CartPoleModel (planning) and the CartPoleParams MuJoCo runs.")
        if model.nx != 2 * params.nq or model.nu != params.nu:
            raise NMPCError(f"The planning model (nx={model.nx}, nu={model.nu}) does not match the MJCF "
                            f"(nx={2 * params.nq}, nu={params.nu}); plan with a model of the same cart.")
        dt = float(params.timestep)
        if abs(model.dt - dt) > 1e-15:
            model = model.rebuilt(dt=dt)
        period = DEFAULT_PERIOD if period is None else period  # the options checked the ranges
        if qp_solver is None:
            qp_solver = "daqp" if importlib.util.find_spec("daqp") is not None else "qpoases"
        self.qp_solver = qp_solver
        steps, N = mpc_grid(options, dt)  # refused when the period or horizon cannot be used as given
        if prestabilize is None:  # growth of the fastest upright mode over the horizon
            lam = float(np.linalg.eigvals(model.linearize()[0]).real.max())
            prestabilize = lam * N * steps * dt > np.log(GROWTH_LIMIT)
        self.prestabilize = bool(prestabilize)
        self.model = model
        self.params = params
        self.steps, self.N = steps, N
        self.period, self.horizon = steps * dt, N * steps * dt
        self.iterations = int(iterations)
        self.tol = float(tol)
        self.functions = stage_functions(model, steps, N, compiled=options.compiled, prestabilized=self.prestabilize)
        self.library = self.functions.library
        self.problem, self.lqr = mpc_problem(model, params, self.functions, Q=options.Q, R=options.R, x_goal=x_goal,
                                             u_goal=u_goal, cart_margin=options.cart_margin,
                                             rail_penalty=options.rail_penalty)
        self._plan = guess if isinstance(guess, Trajectory) else None
        if x0 is not None:
            x0 = np.asarray(x0, dtype=float).ravel()
            if x0.shape != (model.nx,) or not np.all(np.isfinite(x0)):
                raise NMPCError(f"x0 must be {model.nx} finite numbers [qpos, qvel].")
        S, U = _grid_guess(guess, self.problem, x0)
        self._setup_solver()
        self.init_info = {"iterations": 0, "converged": False, "step": float("nan")}
        if x0 is not None and init_iterations > 0:
            S, U = self._converge(x0, S, U, int(init_iterations))
        self._S0, self._U0 = S, U
        self._c = None
        self.reset()
        c_step = options.c_step if options.c_step is not None else (options.compiled and options.qp_solver is None)
        if c_step and self.c_step_capable:  # the C step from the same first iterate; None without a compiler
            self._c = compiled_nmpc(self, self._plan)
        self.step_implementation = "c" if self._c is not None else "python"
        if self._c is not None:
            self.qp_solver = "c"  # the dual active-set solver of cartpole/csrc/qp_dual.c

    # ---- state of a run -------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Start a new run: back to the first iterate, empty :attr:`solve_ms` and :attr:`failures`.

        Done automatically when called with an earlier time than the last call.
        """
        self._S, self._U = self._S0.copy(), self._U0.copy()
        self._k_plan = 0  # physics-step index at which self._S[0] is
        self._k_last = None  # physics-step index of the last solve
        self._u_hold = None
        self._age = 0  # instants since the stored plan was last solved
        self.solve_ms: list[float] = []
        self.step_c_ms: list[float] = []
        self.failures: list[dict] = []
        self._qp_warm = False
        if self._c is not None:
            self._c.reset()

    # ---- the QP ----------------------------------------------------------------------------------------------
    def _setup_solver(self) -> None:
        p = self.problem
        nzu = p.N * p.nu
        nz = nzu + 1
        nb = len(p.bounded)
        nr = p.N * nb
        nuc = nzu if self.prestabilize else 0  # pre-stabilised: the ctrl bounds are general rows in dv
        nc = nuc + 2 * nr  # rows: [u_k (nuc)], q_k - sigma <= q_high (nr), q_k + sigma >= q_low (nr)
        self._nuc = nuc
        self._qp_data = Buffered(self.functions.qp_data)
        self._rollout = Buffered(self.functions.rollout)
        self._qp_flag = 0
        self._H = np.zeros((nz, nz))
        self._H[nzu, nzu] = p.rho2
        self._h = np.zeros(nz)
        self._h[nzu] = p.rho1
        self._A = np.zeros((nc, nz))
        self._A[nuc:nuc + nr, nzu] = -1.0
        self._A[nuc + nr:, nzu] = 1.0
        self._lba = np.r_[np.zeros(nuc), np.full(nr, -np.inf), np.zeros(nr)]
        self._uba = np.r_[np.zeros(nuc), np.zeros(nr), np.full(nr, np.inf)]
        self._lbx = np.r_[np.full(nzu, -np.inf), 0.0]  # pre-stabilised: dv free; sigma >= 0
        self._ubx = np.full(nz, np.inf)
        self._q_low, self._q_high = np.tile(p.q_low, p.N), np.tile(p.q_high, p.N)
        self._u_low, self._u_high = np.tile(p.u_low, p.N), np.tile(p.u_high, p.N)
        if self.qp_solver == "qpoases":
            opts = {"printLevel": "none", "error_on_fail": False, "nWSR": QP_ITER_LIMIT}
            with _stdout_to_stderr():  # qpOASES prints its licence banner on stdout
                self._qpoases = ca.conic("nmpc_qp", "qpoases", {"h": ca.Sparsity.dense(nz, nz),
                                                                "a": ca.Sparsity.dense(nc, nz)}, opts)
        else:
            self._daqp = daqp.solve
            self._sense = np.zeros(nz + nc, dtype=np.int32)

    def _solve_qp(self, H, h, A, lba, uba, lbx, ubx):
        """The condensed QP ``min 1/2 z' H z + h' z, lbx <= z <= ubx, lba <= A z <= uba``: solution (nz,), or
        None when the solver reported failure."""
        if self.qp_solver == "qpoases":
            sol = self._qpoases(h=H, g=h, a=A, lba=lba, uba=uba, lbx=lbx, ubx=ubx)
            return np.asarray(sol["x"]).ravel() if self._qpoases.stats().get("success", False) else None
        upper = np.minimum(np.r_[ubx, uba], _BIG)
        lower = np.maximum(np.r_[lbx, lba], -_BIG)
        z, _, flag, _ = self._daqp(H, h, A, upper, lower, self._sense, iter_limit=QP_ITER_LIMIT)
        self._qp_flag = int(flag)
        return np.asarray(z) if flag in (1, 2) else None  # optimal, or optimal with soft constraints

    def _gn_step(self, x, S, U):
        """One Gauss-Newton step from nodes S (N+1, nx), inputs U (N, nu) with s_0 = x; returns (S, U, max|du|) or
        raises _StepFailed."""
        p = self.problem
        N, nx, nu = p.N, p.nx, p.nu
        nzu = N * nu
        # (N+1, nx) row-major is (nx, N+1) column-major: CasADi's layout, no copies
        out = self._qp_data(x, S, U, p.goal_near(S[-1]), p.u_goal, p.Qs, p.Rs, p.P)
        Hu, hu, g, G1 = out[:4]
        g = g.reshape(N + 1, nx)
        G1 = G1.reshape(N, nzu, nx)  # [k] = G_k+1' (stages 1..N; G_0 = 0)
        H, h = self._H, self._h
        H[:nzu, :nzu] = Hu.reshape(nzu, nzu)
        h[:nzu] = hu
        A_qp, lba, uba = self._A, self._lba, self._uba
        nuc = self._nuc
        if nuc:  # z = dv, du = fu + Fu dv: the ctrl bounds are rows
            Fu, fu = out[4].reshape(nzu, nzu).T, out[5]
            A_qp[:nzu, :nzu] = Fu
            u_now = U.ravel() + fu
            lba[:nzu] = self._u_low - u_now
            uba[:nzu] = self._u_high - u_now
            lbx, ubx = self._lbx, self._ubx
        else:  # z = du: the ctrl bounds are bounds
            lbx = np.r_[(p.u_low - U).ravel(), 0.0]
            ubx = np.r_[(p.u_high - U).ravel(), np.inf]
        nb = len(p.bounded)
        if nb:
            idx = list(p.bounded)
            nr = N * nb
            rows = G1[:, :, idx].transpose(0, 2, 1).reshape(nr, nzu)  # stage-major, bound-minor
            val = (S[1:, idx] + g[1:, idx]).ravel()
            A_qp[nuc:nuc + nr, :nzu] = rows
            A_qp[nuc + nr:, :nzu] = rows
            uba[nuc:nuc + nr] = self._q_high - val
            lba[nuc + nr:] = self._q_low - val
        z = self._solve_qp(H, h, A_qp, lba, uba, lbx, ubx)
        if z is None:
            raise _StepFailed(f"the QP solver ({self.qp_solver}) reported failure"
                              + (f" (exit flag {self._qp_flag})" if self.qp_solver == "daqp" else ""))
        dz = z[:nzu]
        if not np.all(np.isfinite(dz)):
            raise _StepFailed("the QP returned non-finite inputs")
        du = fu + Fu @ dz if nuc else dz
        ds = g.copy()
        ds[1:] += np.tensordot(G1, dz, axes=([1], [0]))
        S_new, U_new = S + ds, np.clip(U + du.reshape(N, nu), p.u_low, p.u_high)
        if not np.all(np.isfinite(S_new)):
            raise _StepFailed("the linearised prediction is not finite")
        return S_new, U_new, float(np.abs(du).max()) if du.size else 0.0

    def _reseed(self, x, U):
        """Nodes (N+1, nx) simulated from the measured ``x`` under the inputs ``U`` (N, nu) (rest at ``x`` where
        that simulation is not finite): a dynamically consistent iterate after a failure."""
        S = np.vstack([x, self._rollout(x, U)[0].reshape(self.N, self.problem.nx)])
        return S if np.all(np.isfinite(S)) and np.abs(S).max() < _RESEED_ABOVE else np.tile(x, (self.N + 1, 1))

    def _solve_instant(self, x, S, U):
        """The solve of one control instant from the shifted iterate: up to ``iterations`` Gauss-Newton steps, fewer
        once a step changes no input by more than ``tol``."""
        for _ in range(self.iterations):
            S, U, step = self._gn_step(x, S, U)
            if step <= self.tol:
                break
        return S, U

    def _align(self, x, S):
        """S with each hinge moved by whole turns so that its first node is nearest the measured ``x``."""
        h = list(self.problem.hinges)
        if h:
            turns = np.round((x[h] - S[0, h]) / (2 * np.pi))
            if np.any(turns):
                S = S.copy()
                S[:, h] += 2 * np.pi * turns
        return S

    def _converge(self, x0, S, U, iters):
        """The first iterate converged for ``x0``: full Gauss-Newton steps; when they do not converge within
        ``iters`` (full steps have no globalisation), IPOPT on the same NLP from the same guess
        (:class:`cartpole.mpc.ipopt_nlp.IpoptNLP`), then Gauss-Newton steps from its solution."""
        S, U = self._align(x0, S), np.array(U)
        S_gn, U_gn, step, i = S, U, float("nan"), 0
        try:
            for i in range(1, iters + 1):
                S_gn, U_gn, step = self._gn_step(x0, S_gn, U_gn)
                if step < 1e-6:
                    break
        except _StepFailed:
            step = float("nan")
        self.init_info = {"iterations": i, "converged": bool(step < 1e-6), "step": step, "method": "gauss-newton"}
        if self.init_info["converged"]:
            return S_gn, U_gn
        try:
            nlp = IpoptNLP(self.problem, self.functions.step_expr, {"ipopt.tol": 1e-10})
            S_ip, U_ip = nlp.solve(x0, S, U)
            ok = bool(nlp.stats.get("success", False))
            for j in range(1, iters + 1):
                S_ip, U_ip, step = self._gn_step(x0, S_ip, U_ip)
                if step < 1e-6:
                    break
        except _StepFailed as exc:
            raise NMPCError(f"The initial NMPC problem from x0 = {x0.tolist()} could not be solved ({exc}); give a "
                            "feasible guess or another start.") from None
        self.init_info = {"iterations": i + j, "converged": bool(ok and step < 1e-6), "step": step,
                          "method": "ipopt", "ipopt_iterations": int(nlp.stats.get("iter_count", 0))}
        return S_ip, U_ip

    # ---- shifting ----------------------------------------------------------------------------------------------
    def _tail_input(self, k_phys: int, s_last) -> np.ndarray:
        t = k_phys * self.problem.dt
        if self._plan is not None and self._plan.t[0] + t < self._plan.t[-1]:
            u = self._plan.input(self._plan.t[0] + t + 0.5 * self.period)
            return np.clip(u, self.problem.u_low, self.problem.u_high)
        return self.lqr(t, s_last)

    def _shift(self, n: int) -> None:
        """Move the stored plan forward by ``n`` stages, extending its tail."""
        for _ in range(min(n, self.N + 1)):
            k_end = self._k_plan + (self.N + 1) * self.steps  # physics index of the new last stage's start
            u_tail = self._tail_input(k_end - self.steps, self._S[-1])
            x_tail = np.asarray(self.functions.stage(self._S[-1], u_tail)[0]).ravel()
            self._S = np.vstack([self._S[1:], x_tail if np.all(np.isfinite(x_tail)) else self._S[-1]])
            self._U = np.vstack([self._U[1:], u_tail])
            self._k_plan += self.steps
            self._age += 1
        if n > self.N + 1:
            self._k_plan += (n - self.N - 1) * self.steps

    # ---- the loop ------------------------------------------------------------------------------------------------
    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s) for the measured state ``x`` (nx,); re-solves when a ``period`` has passed
        since the last solve (the first call, then every period after it), holds the last ctrl in between."""
        k = int(round(float(t) / self.problem.dt))
        if self._k_last is not None and k < self._k_last:
            self.reset()
        # re-solve once a period has passed since the last solve (instants may be offset by a loop's delay)
        if self._u_hold is not None and k - self._k_last < self.steps:
            return self._u_hold.copy()
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (self.problem.nx,):
            raise NMPCError(f"The state has {x.size} entries; the controller needs {self.problem.nx} [qpos, qvel].")
        if self._c is not None:
            return self._c_call(t, k, x)
        t0 = time.perf_counter()
        if k > self._k_plan:
            self._shift((k - self._k_plan) // self.steps)
        try:
            if not np.all(np.isfinite(x)):
                raise _StepFailed("the measured state is not finite")
            if not (np.all(np.isfinite(self._S)) and np.abs(self._S).max() < _RESEED_ABOVE):
                self._S = self._reseed(x, self._U)
            S, U = self._solve_instant(x, self._align(x, self._S), self._U)
            self._S, self._U, self._age = S, U, 0
            u = np.clip(U[0], self.problem.u_low, self.problem.u_high)
        except Exception as exc:  # noqa: BLE001 - never raise inside the loop: the documented safe action
            finite = bool(np.all(np.isfinite(x)))
            near = finite and np.all(np.abs(self.lqr.error(x)[list(self.problem.hinges)]) <= SAFE_LQR_ANGLE)
            if not near and self._age < self.N:
                u, action = np.clip(self._U[0], self.problem.u_low, self.problem.u_high), "previous plan"
            else:
                u, action = self.lqr(t, x) if finite else self.problem.u_goal.copy(), "upright LQR"
            u = np.where(np.isfinite(u), u, self.problem.u_goal)
            self.failures.append({"t": float(t), "reason": str(exc) or type(exc).__name__, "action": action})
            if np.all(np.isfinite(x)):  # next instant starts from a simulation of the plan's inputs from here
                try:
                    self._S = self._reseed(x, self._U)
                except Exception:  # noqa: BLE001 - keep the shifted plan
                    pass
        self.solve_ms.append(1e3 * (time.perf_counter() - t0))
        self._k_last = k
        self._u_hold = np.array(u, dtype=float)
        return self._u_hold.copy()

    def _c_call(self, t: float, k: int, x) -> np.ndarray:
        """One control instant by the compiled step (:mod:`cartpole.mpc.nmpc_c`): the same shift, Gauss-Newton
        step and safe action as the Python path, in the C the export ships."""
        t0 = time.perf_counter()
        _code, u, _action = self._c.step(t, x)
        self.solve_ms.append(1e3 * (time.perf_counter() - t0))
        solve = self._c.last_solve()
        self.step_c_ms.append(1e3 * solve.seconds)
        failure = solve.failure()
        if failure is not None:
            self.failures.append(failure)
        self._k_last = k
        self._u_hold = u
        return u.copy()

    @property
    def offline_plan(self) -> Trajectory | None:
        """The offline plan (the ``guess`` Trajectory) whose inputs extend the shifted tail, or None."""
        return self._plan

    @property
    def plan(self) -> tuple[np.ndarray, np.ndarray]:
        """The current iterate: shooting nodes (N+1, nx) and inputs (N, nu), copies."""
        if self._c is not None:
            return self._c.plan()
        return self._S.copy(), self._U.copy()


@contextlib.contextmanager
def _stdout_to_stderr():
    """File descriptor 1 sent to 2 for the duration (C libraries that print on stdout keep ``--json`` clean)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        yield
    finally:
        try:
            ctypes.CDLL(None).fflush(None)  # C stdio's buffer goes out while fd 1 is still stderr
        except (OSError, AttributeError):
            pass
        os.dup2(saved, 1)
        os.close(saved)


def nmpc_swingup(plant: Plant = None, x0=None, *, plan_model: CartPoleModel | None = None,
                 options: MPCOptions | None = None, plan=None) -> NMPCController:
    """A controller set up to swing up from ``x0`` and balance at ``model.x_eq``.

    The first iterate is an offline plan: :func:`cartpole.planning.trajopt.trajopt_swingup` from ``x0`` on the
    planning model, sampled on the MPC grid, then converged fully for ``x0`` before the loop (Gauss-Newton, or
    IPOPT where full Gauss-Newton steps do not converge; offline, not counted in ``solve_ms``). From then on every
    control instant is one real-time iteration; beyond the horizon the shifted tail follows the offline plan's
    inputs while it lasts. An RTI step from a cold guess (rest) over a 1.2 s horizon does not find a swing-up; this
    initialisation is what makes it one.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The MJCF MuJoCo runs (bounds, ctrlranges, timestep).
    x0 : (nx,) array, optional
        Start state (default the planning model's hanging rest ``x_hanging``).
    plan_model : CartPoleModel, optional
        The planning model (default the MJCF's own); may be wrong on purpose (``build_model(params.scaled_pole(1.2))``).
    options : MPCOptions, optional
        The controller's settings (:class:`~cartpole.mpc.options.MPCOptions`); default ``MPCOptions()``.
    plan : PlanOptions, optional
        The offline plan's settings (:class:`~cartpole.planning.options.PlanOptions`); default
        ``PlanOptions(cart_margin=options.cart_margin)``, the same rail as the controller's.

    Returns
    -------
    NMPCController
    """

    params = plant_params(plant)
    options = MPCOptions() if options is None else options
    plan = PlanOptions(cart_margin=options.cart_margin) if plan is None else plan
    model = plant_model(plant) if plan_model is None else plan_model
    x0 = model.x_hanging if x0 is None else np.asarray(x0, dtype=float).ravel()
    sp = trajopt_swingup(params, x0=x0, plan_model=model, options=plan)
    return NMPCController(model, params, options=options, guess=sp.trajectory, x0=x0)
