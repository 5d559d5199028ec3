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

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from cartpole.control.model_rollout import model_rollout
from cartpole.control.tvlqr import TVLQRController
from cartpole.control.linear import LinearFeedback
from cartpole.riccati import dlqr, tvlqr
from cartpole.models import CartPoleModel
from cartpole.ocp.bounds import OCPBounds
from cartpole.ocp.objectives import Objective
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory
from cartpole.solvers.ddp import DDP, DDPError, DDPOptions

#: Most bisection steps of :func:`ddp_time_search` (each a fixed-T DDP solve; 2^-7 of the bracket is about one
#: MJCF step on the shipped carts' minimum-time brackets).
TIME_SEARCH_STEPS = 7
#: Fraction of the collocation's minimum time where the search's lower bracket starts (a discrete plan is not
#: much faster than the continuous one; DDP is not asked to prove anything below it).
TIME_SEARCH_LOW = 0.9


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
              bounds: OCPBounds, *, steps: int = 1, u_margin: float = 0.0, x_goal=None, Q=None, R=None,
              guess_name: str = "given", options: DDPOptions | None = None) -> tuple[DDPStage, list]:
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
    steps : int
        MJCF steps per DDP step (the control period's hold).
    u_margin : float
        Fraction in [0, 1) of each half ctrl range left free for feedback.
    x_goal : (nx,) array, optional
        Terminal equality (hinge errors wrapped); default ``model.x_eq``.
    Q, R : arrays, optional
        TVLQR weights of the initialisation (default :func:`cartpole.riccati.lab_weights`).
    guess_name : str
        Name of the guess in the attempt record.
    options : DDPOptions, optional

    Returns
    -------
    (DDPStage, [Attempt])
        The stage (``info.success`` says whether it converged) and its attempt record.
    """
    from cartpole.riccati import lab_weights

    tic = time.perf_counter()
    Q0, R0 = lab_weights(model)
    Q = Q0 if Q is None else np.asarray(Q, float)
    R = R0 if R is None else np.atleast_2d(np.asarray(R, float))
    steps = int(steps)
    h = float(model.dt) * steps
    N = max(1, int(round(float(T) / h)))
    dmodel = model if steps == 1 else model.hold(steps)
    u_lo, u_hi = _margin_bounds(bounds, float(u_margin))
    goal = np.asarray(model.x_eq if x_goal is None else x_goal, float)
    name = f"{objective.name} (ddp)"
    if objective.kind == "time":
        raise DDPError("DDP solves a fixed horizon: the minimum time is ddp_time_search's.")
    ddp = DDP(dmodel.step, h, N, running=objective.running, u_low=u_lo, u_high=u_hi, q_low=bounds.q_low,
              q_high=bounds.q_high, x_goal=goal, hinges=model.hinges, options=options)
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
        xdot = np.asarray(model.f.map(N + 1)(r.x.T, np.vstack([r.u, r.u[-1:]]).T)).T
        traj = Trajectory(t=h * np.arange(N + 1), x=r.x, u=np.vstack([r.u, r.u[-1:]]), xdot=xdot)
    att = Attempt.of(info, name, guess_name, N, chosen=info.success)
    return DDPStage(trajectory=traj, x=np.array(r.x), u=np.array(r.u), dt=h, info=info,
                    violation=float(r.violation), defect_before=defect, margin=float(u_margin)), [att]


def ddp_time_search(model: CartPoleModel, x0, guess: Trajectory, T_min: float, bounds: OCPBounds, *,
                    steps: int = 1, u_margin: float = 0.0, Q=None, R=None, guess_name: str = "given",
                    options: DDPOptions | None = None) -> tuple[DDPStage | None, list]:
    """The shortest duration at which an effort DDP (:func:`ddp_stage`) converges, by bisection on whole steps.

    ``x0`` (nx,) is the start ``[qpos, qvel]`` (m, rad, m/s, rad/s); ``model``, ``bounds``, ``steps``, ``u_margin``,
    ``Q``, ``R``, ``guess_name`` and ``options`` are :func:`ddp_stage`'s.

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
    from cartpole.ocp.objectives import make_objective

    effort = make_objective(model, "effort")
    h = float(model.dt) * int(steps)
    attempts: list = []
    best: DDPStage | None = None

    def solve(n: int) -> DDPStage:
        st, tried = ddp_stage(model, x0, guess, n * h, effort, bounds, steps=steps, u_margin=u_margin, Q=Q, R=R,
                              guess_name=guess_name, options=options)
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
