"""The swing-up plan's last stage by box-DDP on the exact discrete model (``PlanOptions(solver="ddp")``).

:func:`ddp_stage` solves the chosen objective at a fixed duration ``T`` with :class:`~cartpole.solvers.ddp.DDP` on
the MJCF's own step (one ``mj_step``), or on the exact model of the control period's hold: the same ctrl bounds
(less the ``u_margin`` kept for feedback), the rail and joint ranges and the terminal upright goal held by the
augmented Lagrangian, the running cost the collocation takes (``effort``, ``tracking``, the ``dmc_*`` rewards,
``MODULE:FUNCTION``; :class:`~cartpole.ocp.objectives.Objective`). It starts from the pipeline's guess (the
minimum-time collocation plan stretched onto ``T``, or padded with rest at upright), turned into a ctrl sequence
by TVLQR tracking that guess on the same discrete model (an open-loop replay of a stretched plan falls over). The
result is exact on the discrete model, so it is a :class:`~cartpole.planning.trajopt.DiscretePlan` that TVLQR
tracks directly, with a :class:`~cartpole.ocp.trajectory.Trajectory` through its states.

:func:`ddp_time_search` is the minimum-time objective for DDP: fixed-``T`` effort solves over a bisection on the
number of steps, between a duration at which a DDP converges and a shorter one at which it did not (a failure
there proves nothing; the reported ``T`` is the shortest at which DDP converged).

Every solve is an :class:`~cartpole.ocp.records.Attempt` (stage ``"<objective> (ddp)"``, guess, steps, status,
iterations, objective, T, wall time); the caller falls back to IPOPT when none converges.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, replace
from typing import ClassVar

import casadi as ca
import numpy as np

from cartpole.control.model_rollout import model_rollout
from cartpole.control.tvlqr import TVLQRController
from cartpole.control.linear import LinearFeedback
from cartpole.riccati import dlqr, default_weights, tvlqr
from cartpole.models import CartPoleModel
from cartpole.ocp.bounds import OCPBounds, OCPError
from cartpole.ocp.objectives import Objective, make_objective, tracking_cost
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory, step_grid_trajectory
from cartpole.options import StageOptions
from cartpole.planning.pumping import hanging_mode
from cartpole.solvers.ddp import DDP, DDPError, DDPOptions, DDPProblem

#: Most bisection steps of :func:`ddp_time_search` (each a fixed-T DDP solve; 2^-7 of the bracket is about one
#: MJCF step on the shipped carts' minimum-time brackets).
TIME_SEARCH_STEPS = 7
#: Fraction of the collocation's minimum time where the search's lower bracket starts (a discrete plan is not
#: much faster than the continuous one; DDP is not asked to prove anything below it).
TIME_SEARCH_LOW = 0.9


@dataclasses.dataclass(frozen=True, eq=False)
class DDPStageOptions(StageOptions):
    """Settings of :func:`ddp_stage` and :func:`ddp_time_search`, validated on creation.

    Attributes
    ----------
    steps : int
        MJCF steps per DDP step (>= 1: the control period's hold); default 1.
    u_margin : float
        Fraction in [0, 1) of each half ctrl range left free for feedback; default 0.
    Q, R : arrays or None
        TVLQR weights (nx, nx) and (nu, nu) of the initialisation, read-only; None: :func:`cartpole.riccati.
        default_weights` of the model.
    ddp : DDPOptions or None
        The DDP solver's settings (None: ``DDPOptions()``).

    Raises
    ------
    DDPError
        A value outside the ranges above.
    """

    steps: int = 1
    u_margin: float = 0.0
    Q: object = None
    R: object = None
    ddp: DDPOptions | None = None

    error: ClassVar[type] = DDPError
    SCALARS: ClassVar[tuple] = ("steps", "u_margin")

    def __post_init__(self):
        self.number("steps", low=1, integer=True)
        self.number("u_margin", low=0.0)
        if not self.u_margin < 1.0:
            raise DDPError(f"u_margin = {self.u_margin} must be a fraction in [0, 1) of each half ctrl range.")
        for name in ("Q", "R"):
            self.freeze_array(name)


@dataclass(frozen=True)
class DDPStage:
    """One converged (or the last failed) DDP solve of the plan's last stage.

    Attributes
    ----------
    trajectory : Trajectory
        Knots at every DDP step ``t_k = k h`` (s): the DDP's states (nx per knot), its held ctrl (the last one
        repeated at the end knot) and ``model.f`` there as ``xdot``.
    x : (N+1, nx) array
        The DDP's states on its step grid, an exact rollout of ``u`` on the discrete model.
    u : (N, nu) array
        ctrl held over each step.
    dt : float
        The DDP's step ``h`` in s (the MJCF timestep, or the control period).
    info : SolveInfo
        Status, success (converged with every constraint held), iterations, objective (the user's sign and units:
        ``integral u'u dt`` for effort, the reward's sum for a reward, T for time), wall time, ``solver="ddp"``.
    violation : float
        Largest constraint violation left (m or rad).
    defect_before : float
        Largest one-step defect ``|step(x_k, u_k) - x_k+1|`` (state units) of the guess on the DDP's grid (its
        stretched states and held ctrl; 0 for a start from rest): what the DDP made exact.
    margin : float
        The ``u_margin`` it was solved with.
    """

    trajectory: Trajectory | None
    x: np.ndarray | None
    u: np.ndarray | None
    dt: float
    info: SolveInfo
    violation: float
    defect_before: float = 0.0
    margin: float = 0.0


def _margin_bounds(bounds: OCPBounds, u_margin: float) -> tuple[np.ndarray, np.ndarray]:
    half = 0.5 * (np.asarray(bounds.u_high, float) - np.asarray(bounds.u_low, float))
    return bounds.u_low + u_margin * half, bounds.u_high - u_margin * half


def _initial_ctrl(model: CartPoleModel, dmodel, guess: Trajectory, steps: int, N: int, x0, Q, R,
                  u_lo, u_hi) -> tuple[np.ndarray, float]:
    """(N, nu) ctrl: TVLQR tracking ``guess`` stretched onto ``N h`` s (``h = steps * model.dt``), designed on the
    discrete model ``dmodel`` and run on ``model``'s step from ``x0``; the rollout's ctrl at the start of each DDP
    step, clipped into the box; and the guess's largest one-step defect on that grid (state units)."""
    h = float(model.dt) * steps
    scale = guess.duration / (N * h)
    tk = guess.t[0] + scale * h * np.arange(N + 1)
    xr = guess.state(tk).copy()
    xr[:, model.nq:] *= scale  # rates of the stretched motion
    ur = 0.5 * (guess.input(tk[:-1]) + guess.input(tk[1:]))
    ur = np.clip(ur, u_lo, u_hi)
    ref = Trajectory(t=h * np.arange(N + 1), x=xr, u=np.vstack([ur, ur[-1:]]),
                     xdot=np.zeros_like(xr))
    xn = np.asarray(dmodel.step.map(N)(xr[:-1].T, ur.T)).T
    defect = float(np.abs(xn - xr[1:]).max())
    gains = tvlqr(model, ref, Q, R, dt=h, reference=(xr, ur))
    A1, B1 = dmodel.linearize() if steps > 1 else model.linearize(discrete=True)
    catch = dlqr(A1, B1, Q * h, R * h)
    hold = LinearFeedback(catch.K, model.x_eq, model.u_eq, hinges=model.hinges, u_limits=np.c_[u_lo, u_hi])
    ctrl = TVLQRController(ref, gains, hold, u_limits=np.c_[u_lo, u_hi])
    xs, us = model_rollout(model, ctrl, x0, N * steps)
    us = np.asarray(us, float).reshape(N * steps, -1)[::steps]
    if not np.all(np.isfinite(us)):
        return np.clip(ur, u_lo, u_hi), defect
    return np.clip(us, u_lo, u_hi), defect


def ddp_stage(model: CartPoleModel, x0, guess: Trajectory | None, T: float, objective: Objective,
              bounds: OCPBounds, *, x_goal=None, guess_name: str = "given",
              options: DDPStageOptions | None = None) -> tuple[DDPStage, list]:
    """The objective at duration ``T`` by DDP on ``model``'s exact discrete step (held ``steps`` MJCF steps).

    Parameters
    ----------
    model : CartPoleModel
        The planning model at the MJCF timestep (its ``step`` is one ``mj_step``).
    x0 : (nx,) array
        Start state.
    guess : Trajectory or None
        The pipeline's plan to start from (stretched onto ``T``); None: zero ctrl clipped into the box.
    T : float
        Duration in s (rounded to whole DDP steps of ``steps * model.dt``).
    objective : Objective
        ``effort`` or a running cost (:func:`cartpole.ocp.objectives.make_objective`); not ``time``
        (:func:`ddp_time_search`).
    bounds : OCPBounds
        ctrl, rail and joint bounds (the collocation's).
    x_goal : (nx,) array, optional
        Terminal equality (hinge errors wrapped); default ``model.x_eq``.
    guess_name : str
        Name of the guess in the attempt record.
    options : DDPStageOptions, optional
        The hold (``steps``), the ctrl margin, the initialisation's TVLQR weights and the DDP's settings (default
        ``DDPStageOptions()``: every MJCF step, no margin, the default weights).

    Returns
    -------
    (DDPStage, [Attempt])
        The stage (``info.success`` says whether it converged) and its attempt record.
    """
    tic = time.perf_counter()
    options = DDPStageOptions() if options is None else options
    steps, u_margin = options.steps, options.u_margin
    Q0, R0 = default_weights(model)
    Q = Q0 if options.Q is None else np.asarray(options.Q, float)
    R = R0 if options.R is None else np.atleast_2d(np.asarray(options.R, float))
    h = float(model.dt) * steps
    N = max(1, int(round(float(T) / h)))
    dmodel = model if steps == 1 else model.hold(steps)
    u_lo, u_hi = _margin_bounds(bounds, float(u_margin))
    goal = np.asarray(model.x_eq if x_goal is None else x_goal, float)
    name = f"{objective.name} (ddp)"
    if objective.kind == "time":
        raise DDPError("DDP solves a fixed horizon: the minimum time is ddp_time_search's.")
    problem = DDPProblem(u_low=u_lo, u_high=u_hi, running=objective.running, q_low=bounds.q_low,
                         q_high=bounds.q_high, x_goal=goal, hinges=model.hinges)
    ddp = DDP(dmodel.step, h, N, problem, options=options.ddp)
    x0 = np.asarray(x0, float).ravel()
    defect = 0.0
    if guess is None:
        U0 = np.clip(np.zeros((N, model.nu)), u_lo, u_hi)
    else:
        U0, defect = _initial_ctrl(model, dmodel, guess, steps, N, x0, Q, R, u_lo, u_hi)
    try:
        r = ddp.solve(x0, U0)
    except DDPError:  # the first rollout blew up: from rest instead
        r = ddp.solve(x0, None)
    cost = float(r.cost)
    value = -cost if objective.is_reward else cost
    info = SolveInfo(status=r.status, success=bool(r.converged), iterations=int(r.iterations), objective=value,
                     solve_time_s=time.perf_counter() - tic, solver="ddp", T=N * h, guess=guess_name)
    traj = None
    if np.all(np.isfinite(r.x)):
        traj = step_grid_trajectory(model.f, h, r.x, r.u)
    att = Attempt.of(info, name, guess_name, N, chosen=info.success)
    return DDPStage(trajectory=traj, x=np.array(r.x), u=np.array(r.u), dt=h, info=info,
                    violation=float(r.violation), defect_before=defect, margin=float(u_margin)), [att]


def ddp_time_search(model: CartPoleModel, x0, guess: Trajectory, T_min: float, bounds: OCPBounds, *,
                    guess_name: str = "given", options: DDPStageOptions | None = None
                    ) -> tuple[DDPStage | None, list]:
    """The shortest duration at which an effort DDP (:func:`ddp_stage`) converges, by bisection on whole steps.

    ``x0`` (nx,) is the start ``[qpos, qvel]`` (m, rad, m/s, rad/s); ``model``, ``bounds``, ``guess_name`` and
    ``options`` (:class:`DDPStageOptions`: the hold ``steps``, ctrl margin, TVLQR weights, DDP settings) are
    :func:`ddp_stage`'s.

    The upper bracket starts at the collocation's minimum time ``T_min`` (s) rounded up to whole DDP steps and
    grows by 10 % (at most 5 times) until a DDP converges; the lower one at :data:`TIME_SEARCH_LOW` of it; then at
    most :data:`TIME_SEARCH_STEPS` bisections. Each solve starts from ``guess`` (the minimum-time plan) stretched
    onto its duration.

    Returns
    -------
    (DDPStage or None, [Attempt])
        The converged stage of the shortest duration (its ``info.objective`` is that T in s), or None when no
        duration converged; every solve's attempt (stage ``"time (ddp) T=..."``).
    """
    effort = make_objective(model, "effort")
    options = DDPStageOptions() if options is None else options
    h = float(model.dt) * options.steps
    attempts: list = []
    best: DDPStage | None = None

    def solve(n: int) -> DDPStage:
        st, tried = ddp_stage(model, x0, guess, n * h, effort, bounds, guess_name=guess_name, options=options)
        a = tried[0]
        attempts.append(Attempt(stage=f"time (ddp) T={n * h:.4g}", guess=a.guess, N=a.N, status=a.status,
                                success=a.success, iterations=a.iterations, objective=a.T, T=a.T,
                                solve_time_s=a.solve_time_s))
        return st

    hi = int(math.ceil(float(T_min) / h - 1e-9))
    for _ in range(6):
        st = solve(hi)
        if st.info.success:
            best = st
            break
        hi = int(math.ceil(hi * 1.1))
    if best is None:
        return None, attempts
    lo = max(1, int(math.floor(TIME_SEARCH_LOW * float(T_min) / h)))
    for _ in range(TIME_SEARCH_STEPS):
        if hi - lo <= 1:
            break
        mid = (lo + hi) // 2
        st = solve(mid)
        if st.info.success:
            hi, best = mid, st
        else:
            lo = mid
    attempts = [Attempt(**{**a.as_dict(), "chosen": a.success and abs(a.T - best.info.T) < 1e-12})
                for a in attempts]
    info = SolveInfo(status=best.info.status, success=True, iterations=best.info.iterations, objective=best.info.T,
                     solve_time_s=sum(a.solve_time_s for a in attempts), solver="ddp", T=best.info.T,
                     guess=guess_name)
    return replace(best, info=info), attempts


#: s: horizon of :func:`receding_swingup`'s DDP (the DDP MPC's on dm_control's acrobot, docs' NMPC page).
RECEDING_HORIZON = 2.0
#: rad, rad/s: :func:`receding_swingup` stops once every hinge is within this angle of upright (wrapped) and
#: every rate within :data:`RECEDING_RATE`: the rollout then ends all but at ``x_eq``, so the collocation's effort
#: problem onto ``x_eq`` at its duration starts next to a solution.
RECEDING_ANGLE = 0.02
RECEDING_RATE = 0.1
#: s of model time :func:`receding_swingup` rolls out at most by default. Longer rollouts (the acrobot from hanging
#: at rest: 11.5 s) made plans that TVLQR did not track in MuJoCo; the planner's other stages take those starts.
RECEDING_T_MAX = 6.0


#: DDP iterations of :func:`receding_swingup`'s first solution (converged offline, as the DDP MPC's first).
RECEDING_FIRST_ITERATIONS = 200


def _first_solution(model: CartPoleModel, ddp: DDP, x0, N: int, h: float, u_lo, u_hi, lqr) -> tuple[np.ndarray, int]:
    """The receding DDP's first (N, nu) ctrl from ``x0``: the best converged of three starts, the upright LQR's input
    and a bang-bang push at the hanging mode's frequency either way (near hanging the tracking cost is all but flat
    and the DDP from the LQR's input alone does not move); and the DDP iterations spent."""
    t = h * np.arange(N)
    omega = hanging_mode_frequency(model)
    starts = [np.array([lqr(0.0, model.x_eq)] * N, float)]
    if omega:
        half, mid = 0.5 * (u_hi - u_lo), 0.5 * (u_hi + u_lo)
        for sign in (1.0, -1.0):
            starts.append(mid + sign * np.outer(np.sign(np.sin(omega * t)), half))
    best, its = None, 0
    for U0 in starts:
        try:
            r = ddp.solve(x0, U0, max_iterations=RECEDING_FIRST_ITERATIONS, max_outer=1)
        except DDPError:
            continue
        its += int(r.iterations)
        if np.all(np.isfinite(r.u)) and (best is None or r.cost < best.cost):
            best = r
    return (starts[0] if best is None else np.array(best.u)), its


def hanging_mode_frequency(model: CartPoleModel) -> float | None:
    """rad/s: the slowest oscillation of the linearisation at hanging rest (:func:`cartpole.planning.pumping.
    hanging_mode`), None where hanging has no oscillating mode."""
    try:
        return float(hanging_mode(model)[0])
    except OCPError:
        return None


@dataclass(frozen=True)
class RecedingSwingup:
    """What :func:`receding_swingup` found.

    Attributes
    ----------
    trajectory : Trajectory or None
        Knots at every step ``t_k = k h`` (s) from the start to the first state near upright: the rollout's states,
        its held ctrl (the last repeated) and ``model.f`` there; None when no state near upright was reached.
    info : SolveInfo
        ``success`` (upright reached), ``status``, ``iterations`` (DDP iterations in all), ``T`` (s of model time
        rolled out), ``solve_time_s`` (wall time).
    """

    trajectory: Trajectory | None
    info: SolveInfo


def receding_swingup(model: CartPoleModel, x0, bounds: OCPBounds, *, horizon: float = RECEDING_HORIZON,
                     T_max: float = RECEDING_T_MAX, deadline_s: float | None = None, Q=None, R=None,
                     iterations: int = 1) -> RecedingSwingup:
    """A swing-up found by receding-horizon DDP on the model's exact discrete step, as the DDP MPC finds one in the
    loop: a guess for the planner where its multi-start finds none (the acrobot from dm_control's random starts).

    Each step ``h = model.dt`` the box-DDP of the MPC (the tracking cost ``2 (1 - cos e)`` on hinges, quadratic
    elsewhere, weights ``Q``, ``R``; the terminal cost the upright discrete LQR's ``S``; the rail and joint ranges as
    penalties) takes ``iterations`` iterations from its previous solution shifted by one step (the tail extended by
    that LQR's input), and its first input is applied to the exact discrete model. It stops at the first state with
    every hinge within :data:`RECEDING_ANGLE` rad of upright and every rate within :data:`RECEDING_RATE` rad/s.

    Parameters
    ----------
    model : CartPoleModel
        Planning model; its ``step`` is the exact discrete step (one MJCF step).
    x0 : (nx,) array
        Start ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    bounds : OCPBounds
        ctrl bounds, rail and joint ranges (the collocation's).
    horizon : float
        s, the DDP's horizon.
    T_max : float
        s of model time rolled out at most.
    deadline_s : float, optional
        s of wall time at most (the rollout stops unfinished after it).
    Q, R : arrays, optional
        Tracking weights (default :func:`cartpole.riccati.default_weights`).
    iterations : int
        DDP iterations per step.

    Returns
    -------
    RecedingSwingup
    """
    tic = time.perf_counter()
    Q0, R0 = default_weights(model)
    Q = Q0 if Q is None else np.asarray(Q, float)
    R = R0 if R is None else np.atleast_2d(np.asarray(R, float))
    h = float(model.dt)
    N = max(1, int(round(float(horizon) / h)))
    Ad, Bd = model.linearize(discrete=True)
    lq = dlqr(Ad, Bd, Q * h, R * h)
    u_lo, u_hi = np.asarray(bounds.u_low, float), np.asarray(bounds.u_high, float)
    lqr = LinearFeedback(lq.K, model.x_eq, model.u_eq, hinges=model.hinges, u_limits=np.c_[u_lo, u_hi])
    xs, us = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    running = ca.Function("receding_tracking", [xs, us], [tracking_cost(model, xs, us, np.diag(Q), np.diag(R))])
    problem = DDPProblem(u_low=u_lo, u_high=u_hi, running=running, q_low=bounds.q_low, q_high=bounds.q_high,
                         x_goal=model.x_eq, hinges=model.hinges, Qf=np.asarray(lq.S), goal_constraint=False)
    ddp = DDP(model.step, h, N, problem, options=DDPOptions(max_outer=1))
    hinges = list(model.hinges)
    rates = [model.nq + i for i in hinges]
    x = np.asarray(x0, float).ravel()
    U, its = _first_solution(model, ddp, x, N, h, u_lo, u_hi, lqr)
    X, Uapplied, status = [x.copy()], [], "T_max reached"
    for k in range(int(round(float(T_max) / h))):
        err = lqr.error(x)
        if np.all(np.abs(err[hinges]) <= RECEDING_ANGLE) and np.all(np.abs(x[rates]) <= RECEDING_RATE):
            status = "upright reached"
            break
        if deadline_s is not None and time.perf_counter() - tic > deadline_s:
            status = "deadline"
            break
        try:
            r = ddp.solve(x, U, max_iterations=int(iterations), max_outer=1)
        except DDPError:
            status = "DDP failed"
            break
        if not (np.all(np.isfinite(r.u)) and np.all(np.isfinite(r.x))):
            status = "DDP not finite"
            break
        its += int(r.iterations)
        U = np.array(r.u)
        u = np.clip(U[0], u_lo, u_hi)
        x = np.asarray(model.step(x, u), float).ravel()
        X.append(x.copy())
        Uapplied.append(u)
        U = np.vstack([U[1:], lqr(0.0, np.asarray(r.x)[-1])[None, :]])
    success = status == "upright reached" and len(Uapplied) > 0
    traj = None
    if success:
        traj = step_grid_trajectory(model.f, h, np.array(X), np.array(Uapplied))
    info = SolveInfo(status=status, success=success, iterations=its, objective=len(Uapplied) * h,
                     solve_time_s=time.perf_counter() - tic, solver="ddp", T=len(Uapplied) * h,
                     guess="receding-horizon DDP")
    return RecedingSwingup(trajectory=traj, info=info)
