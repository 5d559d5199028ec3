"""Swing-up by trajectory optimisation: collocation -> Trajectory -> TVLQR -> controller, in one call.

``trajopt_swingup`` plans with a symbolic model (by default the MJCF's own; optionally a deliberately wrong
one, to test robustness), tracks the plan with TVLQR on the exact discrete model at the simulator's step,
and hands over to the LQR catch (the discrete LQR of the lab's weight pattern at the model's upright equilibrium
``x_eq``, ``u_eq``) when the plan ends. Any model shape: a cart with a chain of poles, several motors. The plan's
duration, unless given, is the minimum time the bounds allow times ``1 + time_margin``: the faster the
better, but a plan that saturates the actuator everywhere leaves TVLQR no authority to correct errors.

No hand-holding: the stages and the mesh are the code's. (0) On a chain driven at a hinge (the acrobot), a
receding-horizon DDP rollout (:func:`~cartpole.planning.ddp_plan.receding_swingup`) to near upright, re-solved as the
effort and then the free-time problem; the stages below only when it finds none. (1) :func:`minimum_time`: a deterministic multi-start
of named guesses (:func:`cartpole.ocp.guess.named_guesses`: pumping and straight-line shapes towards the nearest
upright angles, for one pole an energy-shaping rollout first; ``starts=4`` adds the routes in which every link
loops once more) on a coarse mesh (N = 30), each capped at :data:`EXPLORE_MAX_ITER` iterations, the fastest converged one
refined on N = 60 (the next if that refinement fails); from near upright each guess first goes through the
fixed-time effort problem (a homotopy in T). (2) The chosen objective at its T on N = 100 (or the file's step
for the ``dmc_*`` tasks), started from the minimum-time plan stretched (or padded with rest) onto T; the default guesses
only if that fails. Every solver call of every stage is in ``plan.solve_info.attempts`` (guess, N, iterations,
status, objective, which were kept), and ``plan.plan_time_s`` is the wall time of the whole call
(``benchmarks/bench_swingup_chains.py`` measures it on the shipped carts; the docs' benchmarks page states it).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from cartpole._arrays import readonly
from cartpole.control.linear import LinearFeedback
from cartpole.control.model_rollout import model_rollout
from cartpole.control.tvlqr import TVLQRController
from cartpole.riccati import TVLQRGains, default_weights, tvlqr
from cartpole.riccati.tvlqr import reference as _on_step_grid
from cartpole.models import (CartPoleModel, CartPoleParams, Plant, plant_model, plant_params,
                             steps_per_period)
from cartpole.ocp.bounds import OCPError, bounds_from_params, shooting_bounds
from cartpole.ocp.collocation import CollocationOptions, DirectCollocation, OCPInfeasible, OCPNotSolved
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.guess import named_guesses
from cartpole.ocp.dmc import is_sparse_task, is_task
from cartpole.ocp.objectives import make_objective
from cartpole.planning import ddp_plan
from cartpole.planning.box_entry import box_entry_plan
from cartpole.planning.ddp_plan import RECEDING_T_MAX, receding_swingup
from cartpole.planning.energy_ceiling import energy_ceiling
from cartpole.planning.options import DEFAULT_N, U_MARGIN, PlanOptions
from cartpole.planning.pumping import pumping_search
from cartpole.solvers.sqp import CollocationSQP, SQPError, SQPOptions
from cartpole.ocp.trajectory import Trajectory


@dataclass(frozen=True)
class SwingupPlan:
    """Everything ``trajopt_swingup`` produced.

    Attributes
    ----------
    trajectory : Trajectory
        The optimised plan (its ``duration`` is the chosen T in s).
    gains : TVLQRGains
        TVLQR along the plan at the simulator's step.
    controller : TVLQRController
        ``u = controller(t, x)``: TVLQR tracking, then the catch; use it with ``cartpole.sim.simulate``.
    solve_info : SolveInfo
        The collocation solve of the returned plan.
    catch : LinearFeedback
        The LQR catch (K, S of ``dlqr(Ad, Bd, Q dt, R dt)`` at the planning model's ``x_eq``, ``u_eq``, one MJCF
        step of the planning model; hinge errors wrapped; clipped to the MJCF's ctrlranges).
    model : CartPoleModel
        The model used for planning and TVLQR (may differ from the MJCF MuJoCo runs).
    T_min : float or None
        Minimum swing-up time in s found for the bounds (None when T was given, or the plan came from a warm start,
        which skips the minimum-time search).
    objective : str
        Name of the objective the plan optimised (``effort``, ``time``, ``tracking``, ``dmc_swingup`` or the user
        function's name).
    plan_time_s : float
        Wall time in s of the whole :func:`trajopt_swingup` call that made this plan: every guess of the
        multi-start, every stage, building (and compiling, on a cold cache) the solvers, and TVLQR.
    discrete : DiscretePlan or None
        The plan re-solved on the exact discrete model (:func:`exact_discrete_plan`) that TVLQR tracks, or None
        when TVLQR tracks ``trajectory`` itself (``exact_discrete=False``, or the re-solve failed).
    options : PlanOptions or None
        The planner settings the plan was made with.
    """

    trajectory: Trajectory
    gains: TVLQRGains
    controller: TVLQRController
    solve_info: SolveInfo
    catch: LinearFeedback
    model: CartPoleModel
    T_min: float | None = None
    objective: str = "effort"
    plan_time_s: float = float("nan")
    discrete: "DiscretePlan | None" = field(default=None, compare=False)
    options: PlanOptions | None = field(default=None, compare=False)

    @property
    def T(self) -> float:
        """Duration of the plan in s."""
        return self.trajectory.duration


@dataclass(frozen=True)
class DiscretePlan:
    """A plan that is an exact solution of the MJCF's own discrete step (``model.step`` = one ``mj_step``).

    Attributes
    ----------
    t : (n,) array, s
        Step starts ``t0 + k dt``.
    x : (n+1, nx) array
        States at ``t0 + k dt``; ``x[k+1] = model.step(x[k], u[k])`` to the solver's tolerance.
    u : (n, nu) array
        ctrl held over each step.
    dt : float
        s, the MJCF's timestep.
    u_margin : float
        Fraction of each actuator's half ctrl range kept free on both sides (0: the full range).
    status : str
        IPOPT's return status (DDP's with ``solver="ddp"``: ``converged``).
    iterations : int
    solve_time_s : float
        Wall time of building and solving the problem in s.
    defect_before : float
        Largest one-step defect ``|model.step(x_k, u_k) - x_k+1|`` of the collocation plan on the same grid
        (what TVLQR would have had to absorb every step), in state units.
    defect_after : float
        The same for this plan.
    box_entry : dict or None
        A sparse dm_control task's plan (:mod:`cartpole.planning.box_entry`): ``K`` (the first control step from
        which it stays in the task's box), ``K_surrogate`` (the surrogate plan's), ``solves``, ``status``; None
        otherwise.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    dt: float
    u_margin: float
    status: str
    iterations: int
    solve_time_s: float
    defect_before: float
    defect_after: float
    box_entry: dict | None = None

    def __post_init__(self):
        for name in ("t", "x", "u"):
            object.__setattr__(self, name, readonly(np.asarray(getattr(self, name), float)))

    @property
    def t_final(self) -> float:
        """End of the plan in s."""
        return float(self.t[0] + self.dt * self.t.size)

    def as_dict(self) -> dict:
        """JSON-ready summary (no arrays)."""
        return {"steps": int(self.t.size), "dt": self.dt, "u_margin": self.u_margin, "status": self.status,
                "iterations": self.iterations, "solve_time_s": self.solve_time_s,
                "defect_before": self.defect_before, "defect_after": self.defect_after,
                **({} if self.box_entry is None else {"box_entry": dict(self.box_entry)})}




def _sparse_entry(model: CartPoleModel, name: str, x0, traj: Trajectory, exact, bounds, dt: float):
    """The sparse task's earliest-entry plan (:func:`cartpole.planning.box_entry.box_entry_plan`) from the exact
    plan (else the collocation plan on the step grid), as a :class:`DiscretePlan`, or None when it found none
    earlier."""
    dmodel = model if abs(model.dt - dt) < 1e-15 else model.rebuilt(dt=dt)
    if exact is not None:
        t, xr, ur = np.asarray(exact.t), np.asarray(exact.x), np.asarray(exact.u)
    else:
        t, xr, ur = _on_step_grid(traj, dt)
    found = box_entry_plan(dmodel, name, x0, xr, ur, xr[-1] if exact is not None else traj.x[-1], bounds)
    if found is None:
        return None
    x, u, K, K_ref, info = found
    before = exact.defect_before if exact is not None else _defects(dmodel, xr, ur)
    return DiscretePlan(t=t, x=x, u=u, dt=dt, u_margin=0.0, status=info["status"], iterations=info["iterations"],
                        solve_time_s=info["solve_time_s"], defect_before=before, defect_after=_defects(dmodel, x, u),
                        box_entry={"K": int(K), "K_surrogate": int(K_ref), "solves": int(info["solves"]),
                                   "status": info["status"]})


def _defects(model: CartPoleModel, x, u) -> float:
    n = u.shape[0]
    xn = np.asarray(model.step.map(n)(np.asarray(x[:-1]).T, np.asarray(u).reshape(n, -1).T)).T
    return float(np.abs(xn - x[1:]).max())


#: rad: largest hinge-angle deviation from the collocation plan, predicted for TVLQR on the exact discrete step,
#: that ``trajopt_swingup(exact_discrete="auto")`` accepts without re-solving the plan on that step. Why 0.1: the
#: plans from hanging on the shipped carts are predicted well inside it, and the failures it must catch (the triple
#: re-planned with the cart off centre) stray by a radian and more (the swing-up page's claims measure both).
TRACK_TOL = 0.1


def predicted_tracking_error(model: CartPoleModel, controller, traj: Trajectory, x0) -> float:
    """Largest hinge-angle deviation in rad from ``traj`` of ``controller`` run on ``model.step`` (the planning
    model's exact discrete step, one MJCF step each; :func:`cartpole.control.model_rollout.model_rollout`) from
    ``x0`` over the plan's duration; inf when the state leaves the finite numbers. Cheap (one CasADi call and one
    controller call a step): a prediction of the MuJoCo run, exact when ``model`` is the MJCF's own."""
    n = int(round(traj.duration / model.dt))
    t0 = float(traj.t[0])
    x, _ = model_rollout(model, controller, x0, n, t0=t0)
    if not np.all(np.isfinite(x)):
        return float("inf")
    hinges = list(model.hinges)
    if not hinges or n == 0:
        return 0.0
    ends = (t0 + np.arange(n) * model.dt) + model.dt  # the end of each step, as the plan's time
    return float(np.abs(x[1:, hinges] - traj.state(ends)[:, hinges]).max())


def exact_discrete_plan(model: CartPoleModel, traj: Trajectory, x0, bounds, *, dt: float | None = None,
                        u_margin: float = U_MARGIN, x_goal=None, max_iter: int = 100) -> DiscretePlan | None:
    """Re-solve a collocation plan on the exact discrete model: the closest motion MuJoCo can follow exactly.

    The collocation plan satisfies the continuous dynamics; MuJoCo steps the MJCF's integrator (semi-implicit
    Euler at 5 ms on the shipped carts), whose local error per step is what TVLQR must absorb all along the plan.
    On the shipped three-pole cart that one-step defect is large on the last hinge rate (whatever the collocation
    mesh: it is the integrator's, not the mesh's) and the plan run open loop in the discrete model drifts by a
    tenth of a radian within the swing (the swing-up page states the measured figures, with their commands). This solves, by IPOPT,

        min  sum_k |u_k - u_plan,k|^2 dt
        s.t. x_0 = x0,  x_k+1 = model.step(x_k, u_k),  x_n = x_goal,
             u_low + m <= u_k <= u_high - m  (m = u_margin * half each ctrl range),  joint bounds on every x_k,

    on the plan's step grid (``n = round(T / dt)`` steps), started from the plan itself (its zero-order-hold
    inputs, :func:`cartpole.riccati.tvlqr.reference`), so the result is as near the plan as the exact discrete
    dynamics allow and leaves feedback a ctrl margin.

    Parameters
    ----------
    model : CartPoleModel
        Planning model; its discrete step at ``dt`` is the constraint (rebuilt at ``dt`` when it differs).
    traj : Trajectory
        The collocation plan.
    x0 : (nx,) array
        Start state.
    bounds : OCPBounds
        ctrl and joint bounds (as the collocation's).
    dt : float, optional
        Step in s; default ``model.dt``.
    u_margin : float
        Fraction in [0, 1) of each actuator's half ctrl range kept free on each side.
    x_goal : (nx,) array, optional
        Final state; default the plan's last knot.
    max_iter : int
        IPOPT iteration cap.

    Returns
    -------
    DiscretePlan, or None when IPOPT did not converge (the caller keeps the collocation plan).
    """
    tic = time.perf_counter()
    dt = float(model.dt if dt is None else dt)
    if not 0.0 <= u_margin < 1.0:
        raise OCPError(f"u_margin = {u_margin} must be a fraction in [0, 1) of each half ctrl range.")
    dmodel = model if abs(model.dt - dt) < 1e-15 else model.rebuilt(dt=dt)
    t, xr, ur = _on_step_grid(traj, dt)
    n, nx, nu = t.size, dmodel.nx, dmodel.nu
    x0 = np.asarray(x0, float).ravel()
    x_goal = np.asarray(traj.x[-1] if x_goal is None else x_goal, float).ravel()
    before = _defects(dmodel, xr, ur)
    X = ca.MX.sym("X", nx, n + 1)
    U = ca.MX.sym("U", nu, n)
    gap = ca.vec(dmodel.step.map(n)(X[:, :-1], U) - X[:, 1:])
    cost = ca.sumsqr(U - ur.T) * dt
    half = 0.5 * (bounds.u_high - bounds.u_low)
    u_lo, u_hi = bounds.u_low + u_margin * half, bounds.u_high - u_margin * half
    lw, hw = shooting_bounds(bounds, nx, n, x0, x_goal, u_lo, u_hi)
    w0 = np.clip(np.r_[xr.ravel(), ur.ravel()], lw, hw)
    solver = ca.nlpsol("exact_discrete", "ipopt", {"x": ca.veccat(X, U), "f": cost, "g": gap},
                       {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                        "ipopt.max_iter": int(max_iter), "ipopt.tol": 1e-10, "ipopt.constr_viol_tol": 1e-10})
    sol = solver(x0=w0, lbx=lw, ubx=hw, lbg=0.0, ubg=0.0)
    stats = solver.stats()
    if not stats.get("success", False):
        return None
    w = np.asarray(sol["x"], float).ravel()
    x = w[:nx * (n + 1)].reshape(n + 1, nx)
    u = w[nx * (n + 1):].reshape(n, nu)
    return DiscretePlan(t=t, x=x, u=u, dt=dt, u_margin=float(u_margin), status=str(stats["return_status"]),
                        iterations=int(stats["iter_count"]), solve_time_s=time.perf_counter() - tic,
                        defect_before=before, defect_after=_defects(dmodel, x, u))


#: IPOPT iterations allowed to each start of the coarse minimum-time multi-start: a start that has not converged
#: by then counts as failed (a converging start needs 30 to 200 on the shipped carts).
EXPLORE_MAX_ITER = 250
#: Duration in s of the initial guesses of a minimum-time multi-start (a free-time solve moves it).
GUESS_T = 2.0
#: s: the longest plan the minimum-time multi-start allows (:class:`~cartpole.ocp.collocation.DirectCollocation`'s
#: default ``T_range``); beyond it the pumping search takes over, up to ``PlanOptions.T_max``.
MINIMUM_TIME_T_MAX = 10.0
#: s of plan per collocation interval when the planner re-solves a receding-horizon DDP swing-up (at least ``N``).
RECEDING_KNOT_S = 0.04


def minimum_time(model: CartPoleModel, x0=None, x_goal=None, *, N: int = 60, solver: str = "ipopt",
                 starts: int | None = None, coarse_N: int | None = None, sqp: bool = False, **bounds
                 ) -> tuple[float, Trajectory, SolveInfo]:
    """The shortest motion from ``x0`` to ``x_goal`` the bounds allow: a free-final-time Hermite-Simpson solve.

    Any model. A deterministic multi-start on a coarse mesh, then a refinement: every guess of
    :func:`cartpole.ocp.guess.named_guesses` is solved on ``coarse_N`` intervals (default ``N // 2``, at most
    :data:`EXPLORE_MAX_ITER` iterations each); the converged ones, fastest first, are refined on ``N`` intervals
    until one converges (a coarse mesh can admit a motion the fine one does not); if none does, the guesses are
    solved on ``N`` intervals directly. From near upright (every hinge within a quarter turn of the goal) each
    guess first goes through the fixed-time effort problem at :data:`GUESS_T` (a homotopy in T: a free-time solve
    from a guess there tends to shrink T to its lower bound and stop, locally infeasible). ``info.attempts`` lists
    every solve, ``info.guess`` names the guess that won.

    Parameters
    ----------
    model : CartPoleModel
    x0, x_goal : (nx,) arrays, optional
        Start (default hanging rest ``model.x_hanging``) and goal (default upright ``model.x_eq``).
    N : int
        Intervals of the returned plan.
    solver : str
        ``ipopt`` (the only solver for a free final time).
    starts : int, optional
        Guesses of the multi-start, the first ``starts`` of :func:`~cartpole.ocp.guess.named_guesses`; default
        those towards the nearest upright angles (pumping and straight-line shapes, and for one pole the
        energy-shaping rollout first). 4 (5 for one pole) adds the shapes in which every link loops once more
        relative to its parent (one turn the other way for one pole): on the shipped two-pole cart that route is
        faster in the plan but TVLQR tracks it less well, so it is not among the defaults (the swing-up page
        gives the figures).
    coarse_N : int, optional
        Intervals of the multi-start; ``coarse_N >= N`` solves the multi-start on ``N`` directly.
    sqp : bool
        Refine each coarse plan by :class:`~cartpole.solvers.sqp.CollocationSQP` first (its time scale; at most
        :data:`SQP_MAX_ITER` iterations, attempt stage ``"time N=<N> (sqp)"``), IPOPT when it does not converge (the
        planner's ``solver="auto"``). The multi-start itself stays IPOPT's: from the named guesses, far from any
        plan, its interior point finds plans the SQP's line search does not.
    bounds
        Passed to :class:`DirectCollocation` (``u_max``, ``cart_max``, ``cart_margin`` or ``bounds``).

    Returns
    -------
    (T_min (s), Trajectory, SolveInfo)

    Raises
    ------
    OCPNotSolved
        No guess converged (its ``attempts`` are every solve; the message names the bound a relaxed solve widened, a
        local figure). :func:`trajopt_swingup` goes on to the pumping search, and refuses as infeasible only with a
        proof.
    """
    N = int(N)
    Nc = max(2, N // 2) if coarse_N is None else int(coarse_N)
    explore_options = CollocationOptions(solver=solver, solver_options={"ipopt": {"max_iter": EXPLORE_MAX_ITER}})
    ocp = DirectCollocation(model, N=N, T=None, objective="time", options=explore_options, **bounds)
    x0 = ocp._check_state("start state", model.x_hanging if x0 is None else x0)
    x_goal = ocp._check_state("goal state", model.x_eq if x_goal is None else x_goal)

    # near upright: each guess is first made dynamically feasible at a fixed T (see the docstring)
    near = all(abs((x0[i] - x_goal[i] + np.pi) % (2 * np.pi) - np.pi) < 0.5 * np.pi for i in model.hinges)
    attempts: list = []

    def explore(target: DirectCollocation):
        n = target.N
        named = named_guesses(model, x0, x_goal, GUESS_T, n, bounds=target.bounds, count=starts or 10,
                              second_goal=starts is not None)
        if near:
            eff = DirectCollocation(model, N=n, T=GUESS_T, options=explore_options, **bounds)
            feasible, tried = eff.multistart(x0, x_goal, named, stage=f"effort T={GUESS_T:g} N={n}")
            attempts.extend(tried)
            named = [(f"{info.guess} via effort", traj) for traj, info in sorted(feasible, key=lambda s: s[1].start)]
        sols, tried = target.multistart(x0, x_goal, named, stage=f"time N={n}")
        attempts.extend(tried)
        return sols

    if Nc < N:
        coarse = DirectCollocation(model, N=Nc, T=None, objective="time", options=explore_options, **bounds)
        # refine the coarse solutions, fastest first: a coarse mesh can admit a motion the fine one does not
        for traj, info in explore(coarse):
            if sqp:
                found = _sqp_attempt(ocp, x0, x_goal, traj, f"{info.guess} refined", f"time N={N}", attempts)
                if found is not None:
                    return found[1].T, found[0], replace(found[1], attempts=tuple(attempts))
            sols, tried = ocp.multistart(x0, x_goal, [(f"{info.guess} refined", traj)], stage=f"time N={N}")
            attempts.extend(tried)
            if sols:
                return sols[0][1].T, sols[0][0], replace(sols[0][1], attempts=tuple(attempts))
    sols = explore(ocp)
    if sols:
        return sols[0][1].T, sols[0][0], replace(sols[0][1], attempts=tuple(attempts))
    raise ocp.diagnose(x0, x_goal, named_guesses(model, x0, x_goal, GUESS_T, N, bounds=ocp.bounds, count=1)[0][1],
                       None, attempts=tuple(attempts))


def _sqp_attempt(ocp: DirectCollocation, x0, x_goal, guess: Trajectory, name: str, stage: str, attempts: list
                 ) -> tuple[Trajectory, SolveInfo] | None:
    """``ocp`` by :class:`~cartpole.solvers.sqp.CollocationSQP` from ``guess`` (at most :data:`SQP_MAX_ITER`
    iterations); the try appended to ``attempts`` (stage ``"<stage> (sqp)"``); the plan if it converged, else None
    (also when the SQP does not take the problem)."""
    try:
        sqp = CollocationSQP(ocp, options=SQPOptions(max_iter=SQP_MAX_ITER, max_unsettled=SQP_MAX_UNSETTLED))
        traj, info = sqp.solve_once(x0, x_goal, guess=guess)
    except SQPError:
        return None
    info = replace(info, guess=name)
    attempts.append(Attempt.of(info, f"{stage} (sqp)", name, ocp.N, chosen=info.success))
    return (traj, info) if info.success else None


def _swingup_time_plan(model: CartPoleModel, params: CartPoleParams, x0, *, N: int, bounds, options: PlanOptions,
                       sqp: bool = False) -> tuple[float | None, Trajectory, SolveInfo, tuple | None]:
    """The time stage of the planner: on a chain of two or more links driven at a hinge (no cart: the acrobot) first
    a receding-horizon DDP swing-up (:func:`_receding_plan`, within ``search_s`` s of wall time), which found the
    acrobot's swing-up from dm_control's random starts in seconds where the stages below found none; then (or on
    any other model first) :func:`minimum_time`; when no guess of it converges, the refusal at once if
    :func:`infeasibility_proof` proves upright out of reach, else (a weak actuator that must pump)
    :func:`~cartpole.planning.pumping.pumping_search` (``restarts`` guesses per duration, random ones from ``seed``)
    up to ``T_max`` s within ``search_s`` s of wall time, whose
    fixed-time effort plan then seeds the free-time problem (same mesh, ``T <= T_max``): ``(T_min, time plan, info,
    (pump plan, its info))``, or ``(None, pump plan, info, None)`` when that refinement does not converge; when the
    search finds nothing either, the refusal (:func:`refusal`: no proof, so "no swing-up found"). From ``options``
    (:class:`~cartpole.planning.options.PlanOptions`): ``starts``, ``T_max``, ``search_s`` and the pumping search's
    ``pump_restarts`` (``restarts``) and ``pump_seed`` (``seed``)."""
    starts, T_max, search_s = options.starts, options.T_max, options.search_s

    if params.slide is None and len(model.hinges) > 1:  # a chain driven at a hinge (the acrobot): the receding-
        # horizon DDP first (seconds, where the multi-start took minutes and found nothing from dm_control's starts)
        found = _receding_plan(model, x0, N=N, bounds=bounds, T_max=T_max, search_s=search_s, tried=())
        if found[1] is not None:
            return found
        first_attempts = found[2].attempts
    else:
        first_attempts = ()
    try:
        return (*minimum_time(model, x0, N=N, starts=starts, bounds=bounds, sqp=sqp), None)
    except OCPNotSolved as exc:
        first = exc
    first = OCPNotSolved(str(first), tuple(first_attempts) + tuple(first.attempts))
    proof = infeasibility_proof(params, model, x0, bounds)
    if proof.proven:  # no need to search
        raise refusal(params, model, x0, bounds, first.attempts, T_max=T_max, proof=proof)
    try:
        traj, info, tried = pumping_search(model, x0, model.x_eq, bounds, T_max=T_max, deadline_s=search_s,
                                           seeds=options.pump_restarts, seed=options.pump_seed)
    except OCPError:  # nothing to pump (no oscillating hanging mode)
        traj, info, tried = None, None, []
    attempts = tuple(first.attempts) + tuple(tried)
    if traj is not None:
        ocp = DirectCollocation(model, N=traj.N, T=None, objective="time", T_range=(0.2, T_max), bounds=bounds,
                                options=CollocationOptions(solver_options={"ipopt": {"max_iter": 500}}))
        fast, tinfo = ocp.solve_once(x0, model.x_eq, guess=traj)
        kept = Attempt.of(tinfo, "time from the pumping plan", info.guess, traj.N, chosen=tinfo.success)
        attempts = attempts + (kept,)
        pump = (traj, replace(info, attempts=attempts))
        if tinfo.success:
            return tinfo.T, fast, replace(tinfo, guess=f"{info.guess} -> time", attempts=attempts), pump
        return None, traj, replace(info, attempts=attempts), None
    # the longest plan searched: the minimum-time stage's upper bound on T, or the pumping search's longest
    T_searched = max([MINIMUM_TIME_T_MAX] + [a.T for a in tried if a.stage.startswith("pump")])
    raise refusal(params, model, x0, bounds, attempts, T_max=T_searched, proof=proof)


def _receding_plan(model: CartPoleModel, x0, *, N: int, bounds, T_max: float, search_s: float | None,
                   tried: tuple) -> tuple:
    """The time stage from a receding-horizon DDP swing-up (:func:`~cartpole.planning.ddp_plan.receding_swingup`,
    within ``search_s`` s of wall time): its rollout, near upright at its end, solved as the effort problem at its
    duration onto ``x_eq`` (:func:`warm_stage`), then the free-time problem from that plan (``T <= T_max``).
    ``(T_min, time plan, info, (effort plan, its info))`` like :func:`_swingup_time_plan`, ``(None, effort plan,
    info, None)`` when the free-time solve does not converge (the rollout itself when the effort problem does not
    either), or ``(None, None, info, None)`` when no swing-up was found (``info.attempts`` then holds every try, after
    ``tried``)."""
    rec = receding_swingup(model, x0, bounds, T_max=min(T_max, RECEDING_T_MAX), deadline_s=search_s)
    attempts = tuple(tried) + (Attempt.of(rec.info, "receding-horizon DDP", rec.info.guess,
                                          int(round(rec.info.T / float(model.dt))), chosen=rec.info.success),)
    if rec.trajectory is None:
        return None, None, replace(rec.info, attempts=attempts), None
    n = max(int(N), int(math.ceil(rec.info.T / RECEDING_KNOT_S)))
    traj, info, warm = warm_stage(model, x0, rec.trajectory, N=n, bounds=bounds, name=rec.info.guess)
    attempts = attempts + tuple(warm)
    if traj is None:  # the rollout itself: exact on the model's step, ending all but at x_eq
        return None, rec.trajectory, replace(rec.info, attempts=attempts), None
    ocp = DirectCollocation(model, N=n, T=None, objective="time", T_range=(0.2, T_max), bounds=bounds,
                            options=CollocationOptions(solver_options={"ipopt": {"max_iter": 500}}))
    fast, tinfo = ocp.solve_once(x0, model.x_eq, guess=traj)
    attempts = attempts + (Attempt.of(tinfo, "time from the receding-horizon plan", info.guess, n,
                                      chosen=tinfo.success),)
    pump = (traj, replace(info, attempts=attempts))
    if tinfo.success:
        return tinfo.T, fast, replace(tinfo, guess=f"{info.guess} -> time", attempts=attempts), pump
    return None, traj, replace(info, attempts=attempts), None


def _pumped_effort(model, x0, fast: Trajectory, tinfo: SolveInfo, pump: tuple, *, N: int, bounds, margin: float,
                   solver: str, solver_options) -> tuple[Trajectory, SolveInfo]:
    """The effort plan of a pumping swing-up: at ``(1 + margin) T_min`` from the minimum-time plan ``fast`` stretched,
    then at half and a quarter of that margin (a pumping plan does not stretch far), else the pumping search's own
    fixed-time plan ``pump`` (plan, info). Every solve joins the attempts."""
    attempts = tuple(tinfo.attempts)
    for m in (margin, 0.5 * margin, 0.25 * margin):
        T = (1.0 + m) * tinfo.T
        ocp = DirectCollocation(model, N=N, T=T, bounds=bounds,
                                options=CollocationOptions(solver=solver, solver_options=solver_options))
        traj, info = ocp.solve_once(x0, model.x_eq, guess=fast, T=T)
        attempts = attempts + (Attempt.of(info, f"effort T={T:.3g}", f"time plan ({tinfo.guess})", N,
                                          chosen=info.success),)
        if info.success:
            return traj, replace(info, guess=f"time plan ({tinfo.guess})", attempts=attempts)
    traj, info = pump
    return traj, replace(info, attempts=attempts)


def infeasibility_proof(params: CartPoleParams, model: CartPoleModel, x0, bounds):
    """:func:`~cartpole.planning.energy_ceiling.energy_ceiling` of the start ``x0`` (nx,) with the cart inside the
    bounds' slide range (the plan's, the file's rail shrunk by the margin): an
    :class:`~cartpole.planning.energy_ceiling.EnergyCeiling` whose ``proven`` says upright is out of reach."""
    cart = None
    if model.slide is not None:
        cart = (float(bounds.q_low[model.slide]), float(bounds.q_high[model.slide]))
    return energy_ceiling(params, np.asarray(x0, float), cart_range=cart)


def refusal(params: CartPoleParams, model: CartPoleModel, x0, bounds, attempts, *, T_max: float,
            proof=None) -> OCPError:
    """What the planner says when it found no swing-up: :class:`~cartpole.ocp.collocation.OCPInfeasible` with the
    proof (:func:`~cartpole.planning.energy_ceiling.energy_ceiling`: from a start at rest, the most energy the
    actuator can pump in against the damping stays below upright's, with the cart inside the bounds' slide range)
    when there is one, else :class:`~cartpole.ocp.collocation.OCPNotSolved` ("no swing-up found within T <= ... after
    K attempts", with how far the search got). Returned, not raised.

    Parameters
    ----------
    params : CartPoleParams
    model : CartPoleModel
        The planning model (its ``x_eq`` is the goal).
    x0 : (nx,) array
        The start.
    bounds : OCPBounds
    attempts : sequence of Attempt
        Every solve of the search.
    T_max : float
        s, the longest plan searched.
    proof : EnergyCeiling, optional
        :func:`infeasibility_proof` already made (made here when not given).
    """
    ec = infeasibility_proof(params, model, x0, bounds) if proof is None else proof
    if ec.proven:
        return OCPInfeasible(f"The swing-up is infeasible: {ec.sentence()}.")
    k = len(attempts)
    pumped = [a for a in attempts if a.stage.startswith("pump effort") and a.success]
    if pumped:
        best = min(pumped, key=lambda a: (float(a.stage.rsplit("x", 1)[-1]), a.T))
        how = (f"the pumping search got as far as a plan with the ctrl bound relaxed to {best.stage.rsplit('x', 1)[-1]}"
               f" times the file's half range at T = {best.T:.3g} s")
    else:
        how = "no pumping plan converged even with the ctrl bound relaxed"
    walls = [(params.joints[h].name, *params.joints[h].range) for h in params.hinges
             if np.all(np.isfinite(params.joints[h].range)) and np.ptp(params.joints[h].range) < 2 * np.pi - 1e-9]
    wall = "".join(f"; hinge '{name}' is limited to [{lo:.6g}, {hi:.6g}] rad, less than a full turn, so a pole "
                   "cannot swing through the rest of it (widen that range, or limited=\"false\")"
                   for name, lo, hi in walls)
    return OCPNotSolved(f"No swing-up found within T <= {T_max:.3g} s after {k} attempts ({how}){wall}; that proves "
                        "nothing: give a longer T_max or search_s (--T-max, --search-s on the command line), or more actuator "
                        "force (a wider ctrlrange, or --u-max where the file has none).", attempts)


#: Seconds of the horizon beyond the minimum swing-up time for the running objectives (tracking, dmc_swingup,
#: user functions) when T is not given: long enough to arrive and hold, so the plan is scored on holding too.
RUNNING_HOLD = 1.5


def padded(traj: Trajectory, T: float) -> Trajectory:
    """``traj`` followed by resting at its final state until ``T`` s (exact when that state is an equilibrium):
    a feasible initial guess for a longer horizon."""
    if T <= traj.duration + 1e-9:
        return traj
    n = max(2, int(np.ceil((T - traj.duration) / (traj.duration / traj.N))))
    tp = np.linspace(traj.t[-1], traj.t[0] + T, n + 1)[1:]
    return Trajectory(t=np.r_[traj.t, tp], x=np.vstack([traj.x, np.repeat(traj.x[-1:], n, 0)]),
                      u=np.vstack([traj.u, np.repeat(traj.u[-1:], n, 0)]),
                      xdot=np.vstack([traj.xdot, np.zeros((n, traj.nx))]))


#: SQP iterations the fixed-time stage is given (``solver="auto"`` or ``"sqp"``) before IPOPT takes over (from the
#: time plan the shipped one- and two-pole carts' effort stage converges in 7; a running objective from the bench's
#: guess in 20 to 40).
SQP_MAX_ITER = 60
#: QPs the SQP's Riccati active set may hand to DAQP (feasible ones it could not settle) before the stage goes to
#: IPOPT: a stage that needs them again and again is cheaper by IPOPT (the shipped carts need none from the time
#: plan).
SQP_MAX_UNSETTLED = 3


def _continue_from(ocp: DirectCollocation, x0, name: str, guess: Trajectory, stage: str, *, sqp: bool = False
                   ) -> tuple[Trajectory, SolveInfo]:
    """``ocp`` solved from ``guess`` (an earlier stage's plan); if that fails, from its default guesses (and
    their diagnosis when all fail). The returned info's attempts include the failed first try. ``sqp``: first
    by :class:`~cartpole.solvers.sqp.CollocationSQP` (at most :data:`SQP_MAX_ITER` iterations; its attempt's stage is
    ``"<stage> (sqp)"``), then as before with IPOPT if it does not converge or does not handle the problem."""
    sqp_tried: list = []
    if sqp:
        found = _sqp_attempt(ocp, x0, None, guess, name, stage, sqp_tried)
        if found is not None:
            return found[0], replace(found[1], attempts=tuple(sqp_tried))
    tried = tuple(sqp_tried)
    traj, info = ocp.solve_once(x0, guess=guess)
    first = Attempt.of(info, stage, name, ocp.N, chosen=info.success)
    if info.success:
        return traj, replace(info, guess=name, attempts=tried + (first,))
    traj, info = ocp.solve(x0, stage=stage)
    return traj, replace(info, start=info.start + 1, attempts=tried + (first,) + info.attempts)


def handover_catch(plant: Plant = None, plan_model: CartPoleModel | None = None, Q=None, R=None, *,
                   steps: int = 1) -> LinearFeedback:
    """The LQR that takes over when a trajopt plan ends: ``dlqr(Ad, Bd, Q dt, R dt)`` of one MJCF step
    (``dt`` the plant's MJCF ``timestep``), or of ``steps`` MJCF steps with the ctrl held (``dt = steps *
    timestep``, a control period), of ``plan_model`` (default the plant's own model) at its ``x_eq``, ``u_eq``; hinge errors wrapped, ctrl
    clipped to the MJCF's ctrlranges; ``Q``, ``R`` default :func:`cartpole.riccati.default_weights`. Designed without
    the model's dry friction (:meth:`~cartpole.models.CartPoleModel.without_friction`).

    The catch basin ``cartpole swingup --method trajopt`` reports is this controller's. Designed by the one
    constructor of the upright LQR, :meth:`~cartpole.control.linear.LinearFeedback.for_model` (``discrete=True``
    over the period, on the planning model at the MJCF's step, clipped to the MJCF's ctrl ranges).
    """
    params = plant_params(plant)
    model = plant_model(plant) if plan_model is None else plan_model
    tv_model = model if abs(model.dt - params.timestep) < 1e-15 else model.rebuilt(dt=params.timestep)
    return LinearFeedback.for_model(tv_model, Q, R, discrete=True, period=params.timestep * steps,
                                    u_limits=np.asarray(params.ctrl_range, float))


def trajopt_swingup(plant: Plant = None, x0=None, *,
                    plan_model: CartPoleModel | None = None, options: PlanOptions | None = None,
                    period: float | None = None, catch_R=None, guess: Trajectory | None = None,
                    cold: bool = True) -> SwingupPlan:
    """Plan a swing-up by direct collocation and build its TVLQR tracking controller.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (default the shipped asset), any number of poles and motors; its ctrlranges and joint
        ranges bound the plan, its timestep is the TVLQR step.
    x0 : (nx,) array, optional
        Start state ``[qpos, qvel]`` (default hanging at rest, the planning model's ``x_hanging``). The plan
        ends at the planning model's upright equilibrium ``x_eq`` (hinge angles shifted by whole turns to the
        nearest).
    plan_model : CartPoleModel, optional
        Model used for planning and TVLQR; default the MJCF's own. Give a deliberately wrong one (e.g.
        ``build_model(params.scaled_pole(1.1, 0.9))``) to test robustness while MuJoCo runs the MJCF.
    options : PlanOptions, optional
        The planner's settings (:class:`~cartpole.planning.options.PlanOptions`: objective, T, N, time_margin,
        cart_margin, u_margin, solver, solver_options, starts, exact_discrete, Q, R, Qf; their meaning, units and
        defaults are documented there); default ``PlanOptions()``.
    period : float, optional
        The loop's control period in s, a whole number ``m`` of MJCF steps (default one step). With ``m > 1`` the
        TVLQR and the catch are designed on the exact discrete model over the hold, and the plan is tracked as
        collocated (its re-solve on the exact discrete step, ``exact_discrete``, is for a controller that acts
        every physics step).
    catch_R : (nu, nu) array or float, optional
        Input weight (MuJoCo ctrl) of the hand-over catch alone (:func:`handover_catch`), e.g. one that respects
        the rig's sensors (:func:`cartpole.apps.margins.noise_limited_catch`); default the plan's ``R``. The
        plan and its TVLQR keep ``options.R``.
    guess : Trajectory, optional
        A warm start: a swing-up plan from a start near ``x0`` (e.g. :meth:`cartpole.planning.library.PlanLibrary.
        guess_for`), ending upright. With the ``effort`` objective or a running one (``tracking``, the ``dmc_*``
        tasks: on their step grid, by IPOPT) and no ``T`` given, that objective at the guess's duration is solved from
        it first (:func:`warm_stage`, attempt stage ``"warm effort T=..."``, ``"warm dmc_cartpole_swingup T=..."``),
        skipping the minimum-time search; when it does not converge the planner goes on cold. Ignored by ``time``, a
        given ``T`` and ``solver="ddp"``.
    cold : bool
        With a ``guess`` whose warm start does not converge: plan cold (True, default), or raise
        :class:`~cartpole.ocp.bounds.OCPError` at once (False: a caller with other warm starts to try, or a deadline).

    With ``solver="ddp"`` the last stage (every objective; ``time`` by a search over T) is made by box-DDP on the
    exact discrete step held over ``period`` (:mod:`cartpole.planning.ddp_plan`) from the minimum-time plan; the
    result is ``plan.discrete``, which TVLQR tracks as it is; IPOPT's stage when DDP does not converge.
    With ``solver="sqp"`` the fixed-time effort plan is made by :class:`~cartpole.solvers.sqp.CollocationSQP` from
    the minimum-time plan, IPOPT when it does not converge in :data:`SQP_MAX_ITER` iterations (the first use per
    cart and N compiles its QP library); other objectives and a given ``T`` use IPOPT. With
    ``exact_discrete="auto"`` TVLQR tracking the collocation plan is first predicted on the planning model's exact
    discrete step (the step MuJoCo takes, so for the MJCF's own model this is the MuJoCo run) and the plan is
    re-solved on that step (:func:`exact_discrete_plan`) only when the prediction strays more than
    :data:`TRACK_TOL` from the plan in any hinge angle (:func:`predicted_tracking_error`). If the re-solve fails
    (with ``u_margin``, then with no margin), TVLQR tracks the collocation plan.

    Returns
    -------
    SwingupPlan
        ``plan.solve_info.attempts`` lists every solver call of every stage; ``plan.plan_time_s`` their wall time;
        ``plan.options`` the options it was made with.

    Raises
    ------
    PlanOptionsError, OCPError
        Bad settings; a swing-up the optimiser cannot plan (its one sentence).
    """
    opts = PlanOptions() if options is None else options
    return _plan(plant, x0, plan_model=plan_model, options=opts, period=period, catch_R=catch_R, guess=guess,
                 cold=cold)


def warm_stage(model: CartPoleModel, x0, guess: Trajectory, *, N: int, bounds, solver: str = "ipopt",
               solver_options=None, sqp: bool = False, name: str = "library plan", objective=None
               ) -> tuple[Trajectory | None, SolveInfo | None, tuple]:
    """The effort problem (or ``objective``, a running one: :func:`cartpole.ocp.objectives.make_objective`'s) at
    ``guess``'s duration from ``x0`` (nx,), started from ``guess`` (a plan from a nearby start): ``(plan, info,
    attempts)``, plan and info None when it did not converge. ``sqp``: by :class:`~cartpole.solvers.sqp.CollocationSQP`
    first, IPOPT when it does not converge; ``N`` intervals; ``name`` the guess's name in the attempt records (stage
    ``"warm <objective> T=..."``)."""
    T = float(guess.duration)
    stage = f"warm {'effort' if objective is None else getattr(objective, 'name', objective)} T={T:.3g}"
    ocp = DirectCollocation(model, N=N, T=T, bounds=bounds, objective=objective,
                            options=CollocationOptions(solver=solver, solver_options=solver_options))
    tried: list = []
    if sqp:
        found = _sqp_attempt(ocp, x0, None, guess, name, stage, tried)
        if found is not None:
            return found[0], replace(found[1], attempts=tuple(tried)), tuple(tried)
    traj, info = ocp.solve_once(x0, guess=guess)
    tried.append(Attempt.of(info, stage, name, ocp.N, chosen=info.success))
    if not info.success:
        return None, None, tuple(tried)
    return traj, replace(info, guess=name, attempts=tuple(tried)), tuple(tried)


@dataclass(frozen=True)
class _Planning:
    """One planner call's fixed inputs, made once from its options (:func:`_planning`): the settings, the MJCF's
    parameters, the planning model and that model at the MJCF's step (TVLQR's and DDP's), the start (nx,), the
    MJCF's bounds, the objective, the tracking weights, the MJCF steps per control period, and the solvers chosen."""
    options: PlanOptions
    params: CartPoleParams
    model: CartPoleModel
    tv_model: CartPoleModel
    x0: np.ndarray
    bounds: object
    obj: object
    Q: np.ndarray
    R: np.ndarray
    steps: int
    solver: str  # the collocation's NLP solver
    solver_options: dict | None
    use_sqp: bool
    use_ddp: bool

    @property
    def dt(self) -> float:
        """The control period in s: ``steps`` MJCF steps."""
        return self.params.timestep * self.steps

    @property
    def collocation(self) -> CollocationOptions:
        """The collocation's solver settings."""
        return CollocationOptions(solver=self.solver, solver_options=self.solver_options)


@dataclass
class _Stages:
    """What the planner's stages made (:func:`_last_stage`): the plan and its info (None while DDP's stands), the
    minimum time (s, None when not solved or a pumping plan), DDP's converged stage (or None), the attempts made
    before DDP's and DDP's own."""
    traj: Trajectory | None = None
    info: SolveInfo | None = None
    T_min: float | None = None
    by_ddp: object = None
    attempts_before: tuple = ()
    ddp_tried: list = field(default_factory=list)


def _plan(source, x0, *, plan_model: CartPoleModel | None, options: PlanOptions,
          period: float | None = None, catch_R=None, guess: Trajectory | None = None, cold: bool = True
          ) -> SwingupPlan:
    """:func:`trajopt_swingup` with its options made."""
    tic = time.perf_counter()
    p = _planning(source, x0, plan_model, options, period)
    st = _last_stage(p, guess, cold)
    traj, info = st.traj, st.info
    exact, exact_discrete = None, options.exact_discrete
    by_ddp = st.by_ddp
    if by_ddp is not None:  # the plan is DDP's, exact on the discrete step: TVLQR tracks it as it is
        traj = by_ddp.trajectory
        info = replace(by_ddp.info, attempts=tuple(st.attempts_before) + tuple(st.ddp_tried))
        dstep = p.tv_model.hold(p.steps) if p.steps > 1 else p.tv_model
        exact = DiscretePlan(t=by_ddp.dt * np.arange(by_ddp.u.shape[0]), x=by_ddp.x, u=by_ddp.u, dt=by_ddp.dt,
                             u_margin=by_ddp.margin, status=by_ddp.info.status, iterations=by_ddp.info.iterations,
                             solve_time_s=by_ddp.info.solve_time_s, defect_before=by_ddp.defect_before,
                             defect_after=_defects(dstep, by_ddp.x, by_ddp.u))
        exact_discrete = False
    elif st.ddp_tried:  # DDP did not converge: IPOPT's plan, every attempt in the order made
        done = tuple(info.attempts)
        k = len(st.attempts_before) if done[:len(st.attempts_before)] == tuple(st.attempts_before) else 0
        info = replace(info, attempts=done[:k] + tuple(st.ddp_tried) + done[k:])
    return _tracked(p, traj, info, exact, exact_discrete, T_min=st.T_min, catch_R=catch_R, tic=tic)


def _planning(source, x0, plan_model: CartPoleModel | None, options: PlanOptions, period: float | None) -> _Planning:
    """The planner's fixed inputs (:class:`_Planning`) from its arguments."""
    solver = options.solver
    solver_options = None if options.solver_options is None else dict(options.solver_options)
    use_sqp = solver == "sqp" or (solver == "auto" and solver_options is None)
    use_ddp = solver == "ddp"
    solver = "ipopt" if solver in ("auto", "sqp", "ddp") else solver
    params = plant_params(source)
    plan_model = plan_model if plan_model is not None else plant_model(source)
    Q0, R0 = default_weights(plan_model)
    Q = Q0 if options.Q is None else np.asarray(options.Q, float)
    R = R0 if options.R is None else np.atleast_2d(np.asarray(options.R, float))
    x0 = plan_model.x_hanging if x0 is None else np.asarray(x0, dtype=float)
    # Bounds are the MJCF's (the real actuators and track), whatever model plans.
    bounds = bounds_from_params(params, cart_margin=options.cart_margin)
    obj = make_objective(plan_model, "effort" if options.objective is None else options.objective, Q=Q, R=R)
    # TVLQR (and DDP) at the MJCF's step, on the planning model's exact discrete step, held over the period.
    tv_model = plan_model if abs(plan_model.dt - params.timestep) < 1e-15 else plan_model.rebuilt(dt=params.timestep)
    return _Planning(options=options, params=params, model=plan_model, tv_model=tv_model, x0=x0, bounds=bounds,
                     obj=obj, Q=Q, R=R, steps=steps_per_period(period, params.timestep), solver=solver,
                     solver_options=solver_options, use_sqp=use_sqp, use_ddp=use_ddp)


def _last_stage(p: _Planning, guess: Trajectory | None, cold: bool = True) -> _Stages:
    """The planner's stages up to its last (module docstring): from ``guess`` (a nearby start's plan, effort at the
    default T only), else by the objective: minimum time itself, effort at a given T, or the objective at its T from
    the minimum-time plan."""
    st = _Stages()
    warm, warm_tried = None, ()
    if guess is not None and p.obj.kind in ("effort", "running") and p.options.T is None and not p.use_ddp:
        running = p.obj.kind == "running"  # at the guess's duration, on the task's step grid as the cold stage's
        N = p.options.N or (max(2, int(round(guess.duration / p.params.timestep))) if running and is_task(p.obj.name)
                            else DEFAULT_N)
        warm_traj, warm_info, warm_tried = warm_stage(p.model, p.x0, guess, N=N, bounds=p.bounds, solver=p.solver,
                                                      solver_options=p.solver_options, sqp=p.use_sqp and not running,
                                                      objective=p.obj if running else None)
        if warm_traj is not None:
            warm = (warm_traj, warm_info)
        elif not cold:
            raise OCPError(f"The warm start (T = {guess.duration:.3g} s) did not converge from x0 and cold=False "
                           "asks for no cold plan.")
    if warm is not None:
        st.traj, st.info = warm
    elif p.obj.kind == "time":
        _time_stage(p, st)
    elif p.obj.kind == "effort" and p.options.T is not None:
        if p.use_ddp:  # no earlier stage to start from: DDP from rest (zero ctrl clipped into the box)
            st.by_ddp, st.attempts_before = _ddp_last_stage(p, st, None, p.options.T, "rest"), ()
        if st.by_ddp is None:
            ocp = DirectCollocation(p.model, N=p.options.N or DEFAULT_N, T=p.options.T, bounds=p.bounds,
                                    options=p.collocation)
            st.traj, st.info = ocp.solve(p.x0)
    else:
        _stage_from_time_plan(p, st)
    if warm is None and warm_tried:  # the warm start did not converge: its try first, then the cold plan's
        st.info = replace(st.info, attempts=tuple(warm_tried) + tuple(st.info.attempts))
    return st


def _ddp_last_stage(p: _Planning, st: _Stages, guess, T_use: float, gname: str):
    """The last stage by DDP (with the ctrl margin, then without), its attempts added to ``st.ddp_tried``; the
    converged DDPStage or None."""
    for margin in dict.fromkeys((float(p.options.u_margin), 0.0)):
        settings = ddp_plan.DDPStageOptions(steps=p.steps, u_margin=margin, Q=p.Q, R=p.R)
        stage, tried = ddp_plan.ddp_stage(p.tv_model, p.x0, guess, T_use, p.obj, p.bounds, guess_name=gname,
                                          options=settings)
        st.ddp_tried.extend(replace(a, stage=f"{a.stage} u_margin={margin:g}") for a in tried)
        if stage.info.success:
            return replace(stage, margin=margin)
    return None


def _time_stage(p: _Planning, st: _Stages) -> None:
    """The minimum-time objective: the time stage's plan, or DDP's search over T from it."""
    T_min, traj, info, _ = _swingup_time_plan(p.model, p.params, p.x0, N=p.options.N or DEFAULT_N, bounds=p.bounds,
                                              options=p.options, sqp=p.use_sqp)
    st.T_min, st.traj, st.info = T_min, traj, info
    if p.use_ddp:
        st.by_ddp, tried = ddp_plan.ddp_time_search(p.tv_model, p.x0, traj,
                                                    T_min if T_min is not None else traj.duration,
                                                    p.bounds, guess_name=f"time plan ({info.guess})",
                                                    options=ddp_plan.DDPStageOptions(steps=p.steps, Q=p.Q, R=p.R))
        st.ddp_tried.extend(tried)
        st.attempts_before = info.attempts


def _stage_from_time_plan(p: _Planning, st: _Stages) -> None:
    """Effort at ``(1 + time_margin) T_min`` or a running objective at its T, from the minimum-time plan stretched
    (or padded with rest at upright), by DDP or the collocation; a pumping plan is the effort plan at its own T."""
    options, obj, x0 = p.options, p.obj, p.x0
    T, N = options.T, options.N
    T_min, fast, tinfo, pump = _swingup_time_plan(p.model, p.params, x0,
                                                  N=60 if obj.kind == "running" else min(N or DEFAULT_N, 60),
                                                  bounds=p.bounds, options=options, sqp=p.use_sqp)
    st.T_min, st.attempts_before = T_min, tinfo.attempts
    ocp = first = None
    if obj.kind == "effort" and T_min is None:  # a pumping plan: already the effort plan at its T
        st.traj, st.info = fast, tinfo
        if p.use_ddp:
            st.by_ddp = _ddp_last_stage(p, st, fast, fast.duration, f"pumping plan ({tinfo.guess})")
    elif obj.kind == "effort":
        T = (1.0 + options.time_margin) * T_min
        ocp = DirectCollocation(p.model, N=N or DEFAULT_N, T=T, bounds=p.bounds, options=p.collocation)
        first = fast  # the minimum-time plan, stretched onto T
    else:
        if T is None:
            T = (fast.duration if T_min is None else T_min) + RUNNING_HOLD
        if N is None:
            N = max(2, int(round(T / p.params.timestep))) if is_task(obj.name) else DEFAULT_N
        ocp = DirectCollocation(p.model, N=N, T=T, objective=obj, bounds=p.bounds, options=p.collocation)
        first = padded(fast, T) if T > fast.duration else fast  # then rest at upright
    if p.use_ddp and not (obj.kind == "effort" and T_min is None):
        st.by_ddp = _ddp_last_stage(p, st, first, T, f"time plan ({tinfo.guess})")
    if st.by_ddp is not None:
        return
    if obj.kind == "effort" and pump is not None:  # a pumping plan: the margin shrunk if need be, else itself
        st.traj, st.info = _pumped_effort(p.model, x0, fast, tinfo, pump, N=N or DEFAULT_N, bounds=p.bounds,
                                          margin=options.time_margin, solver=p.solver,
                                          solver_options=p.solver_options)
    elif not (obj.kind == "effort" and T_min is None):
        try:
            traj, info = _continue_from(ocp, x0, f"time plan ({tinfo.guess})", first, obj.name,
                                        sqp=p.use_sqp and obj.kind in ("effort", "running"))
            st.traj, st.info = traj, replace(info, attempts=tinfo.attempts + info.attempts)
        except OCPNotSolved as exc:
            if obj.kind != "running":
                raise
            # a swing-up exists (the time stage's plan) though the running objective converged from no guess:
            # that plan, resting at upright until T, every attempt kept and the status saying what it is
            st.traj = first
            st.info = replace(tinfo, status=f"{obj.name} not converged from any guess: the time plan kept",
                              attempts=tuple(tinfo.attempts) + tuple(exc.attempts))


def _tracked(p: _Planning, traj: Trajectory, info: SolveInfo, exact, exact_discrete, *, T_min, catch_R,
             tic: float) -> SwingupPlan:
    """The plan ``traj`` tracked: the catch, the exact discrete plan when asked (or needed: ``"auto"``) or given
    (``exact``, DDP's), the sparse task's box-entry plan, TVLQR along it; the :class:`SwingupPlan`."""
    # The catch is the discrete LQR of that same step and weights (dlqr(Ad, Bd, Q dt, R dt)) at the model's
    # upright equilibrium: TVLQR's default terminal cost is its S, so at the hand-over both the cost-to-go and
    # the gain continue without a jump (the continuous lab gain is ~15 % larger at 5 ms for one pole because
    # the fastest closed-loop pole is -51 1/s).
    tv_model, steps, dt, Q, R, Qf = p.tv_model, p.steps, p.dt, p.Q, p.R, p.options.Qf
    if steps > 1:
        exact_discrete = False
    u_limits = np.asarray(p.params.ctrl_range, float)  # (nu, 2): the MJCF's actuators
    catch = handover_catch(p.params, p.model, Q, R if catch_R is None else catch_R, steps=steps)
    gains = None
    if exact_discrete == "auto":
        gains = tvlqr(tv_model, traj, Q, R, Qf=Qf, dt=dt)
        err = predicted_tracking_error(tv_model, TVLQRController(traj, gains, catch, u_limits=u_limits), traj, p.x0)
        exact_discrete = not err <= TRACK_TOL
    if exact_discrete:
        for margin in dict.fromkeys((float(p.options.u_margin), 0.0)):
            exact = exact_discrete_plan(tv_model, traj, p.x0, p.bounds, dt=dt, u_margin=margin)
            if exact is not None:
                break
    if is_sparse_task(p.obj.name) and steps == 1:
        # the indicator's own plan: into its box as early as the exact step allows (cartpole.planning.box_entry)
        boxed = _sparse_entry(tv_model, p.obj.name, p.x0, traj, exact, p.bounds, dt)
        if boxed is not None:
            exact = boxed
    if exact is None:
        gains = gains if gains is not None else tvlqr(tv_model, traj, Q, R, Qf=Qf, dt=dt)
    else:
        gains = tvlqr(tv_model, traj, Q, R, Qf=Qf, dt=dt, reference=(exact.x, exact.u))
    controller = TVLQRController(traj, gains, catch, u_limits=u_limits)
    return SwingupPlan(trajectory=traj, gains=gains, controller=controller, solve_info=info, catch=catch,
                       model=p.model, T_min=T_min, objective=p.obj.name, plan_time_s=time.perf_counter() - tic,
                       discrete=exact, options=p.options)
