"""A sparse dm_control task's plan made fast from a stored one: into the task's box at the step the stored plan's rest
enters it, by one solve.

The sparse planner of :func:`~cartpole.planning.trajopt.trajopt_swingup` maximises the surrogate, then searches the
earliest box entry (:mod:`cartpole.planning.box_entry`: several IPOPT solves on the exact step): seconds to tens of
seconds a plan, longer than the swing-up it would shorten when planned in the loop. From a state near a knot of a
stored entry plan (a library's, :func:`cartpole.planning.library.cached_library` with ``exact=True``), the rest of
that plan already enters the box as early as the search found; :func:`box_tail_planner` keeps that entry step and
solves the one problem of :func:`~cartpole.planning.box_entry.box_entry_at` from the new start (the ctrl nearest the
stored plan's, on the exact step, :data:`STORED_MARGIN` inside the box as the stored plan; the box elastic,
:data:`ELASTIC`, so that a start that cannot enter at that step misses it by as little as it can instead of a refused
solve), later entries (:data:`ENTRY_SLACK`) only when
that solve does not converge, and tracks the plan with TVLQR on the exact step, handing over to the catch at its end,
as the planner's own entry plan is tracked.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from cartpole.control.tvlqr import TVLQRController
from cartpole.models import CartPoleModel, CartPoleParams
from cartpole.ocp.bounds import OCPError, bounds_from_params
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory, step_grid_trajectory
from cartpole.planning.box_entry import box_entry_at, entry_step
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import DiscretePlan, SwingupPlan, handover_catch
from cartpole.riccati import default_weights, tvlqr

#: Steps later than the stored plan's entry tried, in turn, when the entry at that step is refused from the new
#: start (each one IPOPT solve).
ENTRY_SLACK = (0, 2, 6)
#: IPOPT settings of the solve in the loop (:func:`~cartpole.planning.box_entry.entry_solver`'s ``fast``): expanded
#: to SX, a barrier starting low (the stored plan's rest is nearly the answer) and tolerances of 1e-8 (1e-9 on the
#: step's defects and the box, well inside its 1e-6 margin): 22 iterations, about 1 s on the loaded 2-core machine
#: (33 iterations, 2.1 s, with the search's own settings).
FAST_IPOPT = {"expand": True, "ipopt.tol": 1e-8, "ipopt.constr_viol_tol": 1e-9, "ipopt.mu_init": 1e-3}
#: The cost per unit of a box row missed (:func:`~cartpole.planning.box_entry.entry_solver`'s ``elastic``): from a
#: start that cannot enter at the stored step (the stored plan enters as early as its own start allows), the plan
#: misses the box by as little as it can for a step or two instead of a refused solve (a refusal costs IPOPT's
#: restoration, as long as a solve).
ELASTIC = 1e4
#: How far inside the box a stored entry plan keeps, and each plan made from it (:func:`kept_inside`; cosine, m): the
#: library's plan is followed by TVLQR from a start off its own while the first plan is made
#: (:class:`cartpole.supervise.lead_in.PlanLeadIn`), and a plan that comes later than predicted is tracked from a
#: state off it; a plan on the box's edge (the search's 1e-6) is left by the first error (seed 9 of swingup_sparse:
#: 792 with the edge, its plan 0.16 s late); 2e-3 in the cosine is about 0.01 rad at the box's 0.1 rad, and costs
#: one step of entry from hanging at rest (150 against 149).
STORED_MARGIN = 2e-3


def on_step_grid(traj: Trajectory, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``traj`` sampled every ``dt`` s from its start: ``x`` (n+1, nx) (its cubic-Hermite states, the last its end
    state), ``u`` (n, nu) (its inputs at the step starts), ``n = round(duration / dt)``."""
    n = max(1, int(round(traj.duration / float(dt))))
    t = float(traj.t[0]) + float(dt) * np.arange(n + 1)
    x = np.asarray(traj.state(t), dtype=float)
    x[-1] = np.asarray(traj.x[-1], dtype=float)
    return x, np.asarray(traj.input(t[:-1]), dtype=float).reshape(n, -1)


def kept_inside(model: CartPoleModel, name: str, x, u, bounds, margin: float = STORED_MARGIN):
    """The entry plan ``x`` (n+1, nx), ``u`` (n, nu) on the exact step (a sparse task's, on the box's edge) re-solved
    to keep ``margin`` inside the box from the first step it can (its own entry, then 2, 4, 8 and 16 steps later),
    the ctrl nearest its own: ``(x, u)``; the plan as it is when none converges."""
    x, u = np.asarray(x, float), np.asarray(u, float)
    K = entry_step(model, name, x, margin=0.0)
    for later in (0, 2, 4, 8, 16):
        if K is None or K + later > u.shape[0]:
            break
        found = box_entry_at(model, name, x[0], x, u, bounds, K + later, margin=margin)
        if found is not None:
            return found[0], found[1]
    return x, u


def box_tail_planner(params: CartPoleParams, model: CartPoleModel, objective: str, *, catch_R=None,
                     options: PlanOptions | None = None) -> Callable:
    """``planner(x0, guess=None, cold=True) -> SwingupPlan`` for the sparse task ``objective`` (module docstring):
    from ``x0`` (nx,) into the box at the step ``guess`` (the rest of a stored entry plan from near ``x0``, any
    knot grid: sampled on the MJCF's step) enters it (or :data:`ENTRY_SLACK` steps later), by one solve each.

    Parameters
    ----------
    params : CartPoleParams
        The MJCF MuJoCo runs (its step, ctrl and joint bounds).
    model : CartPoleModel
        The planning model; its ``step`` at the MJCF's step is the dynamics.
    objective : str
        A sparse ``dmc_*`` task (:func:`cartpole.ocp.dmc.sparse_box`).
    catch_R : (nu, nu) array or float, optional
        The catch's input weight (default the lab's weights').
    options : PlanOptions, optional
        Its ``cart_margin`` keeps the cart off the rail's ends (default ``PlanOptions()``).

    Returns
    -------
    callable
        The planner; it raises :class:`~cartpole.ocp.bounds.OCPError` without a guess (it never plans cold), or
        when every entry step is refused. The control period is the MJCF's step.
    """
    dt = float(params.timestep)
    dmodel = model if abs(float(model.dt) - dt) < 1e-15 else model.rebuilt(dt=dt)
    opts = PlanOptions() if options is None else options
    bounds = bounds_from_params(params, cart_margin=opts.cart_margin)
    Q, R = default_weights(model)
    catch = handover_catch(params, model, Q, R if catch_R is None else catch_R, steps=1)
    u_limits = np.asarray(params.ctrl_range, float)

    def tracked(found, k: int, K_ref: int, tried: tuple, tic: float) -> SwingupPlan:
        """The entry plan ``found`` (``(x, u, info)``, into the box at step ``k``) tracked by TVLQR on the exact step,
        the catch at its end."""
        x, u, info = found
        traj = step_grid_trajectory(dmodel.f, dt, x, u)
        gains = tvlqr(dmodel, traj, Q, R, dt=dt, reference=(x, u))
        exact = DiscretePlan(t=dt * np.arange(u.shape[0]), x=x, u=u, dt=dt, u_margin=0.0, status=info["status"],
                             iterations=info["iterations"], solve_time_s=info["solve_time_s"],
                             defect_before=float("nan"), defect_after=float("nan"),
                             box_entry={"K": int(k), "K_surrogate": int(K_ref), "solves": len(tried),
                                        "status": info["status"]})
        solve = SolveInfo(status=info["status"], success=True, iterations=info["iterations"], objective=float("nan"),
                          solve_time_s=info["solve_time_s"], solver="ipopt", T=traj.duration, guess="library plan",
                          attempts=tried)
        return SwingupPlan(trajectory=traj, gains=gains, solve_info=solve, catch=catch, model=dmodel,
                           controller=TVLQRController(traj, gains, catch, u_limits=u_limits), objective=objective,
                           plan_time_s=time.perf_counter() - tic, discrete=exact)

    def planner(x0, guess=None, cold=True):
        if guess is None:
            raise OCPError(f"The {objective} entry planner needs a stored plan's rest as its guess; it never plans "
                           "cold.")
        tic = time.perf_counter()
        x_ref, u_ref = on_step_grid(guess, dt)
        K = entry_step(dmodel, objective, x_ref, margin=0.5 * STORED_MARGIN)  # a stored plan lies on its margin
        if K is None:
            raise OCPError(f"The guess never stays in the {objective} box; give a stored entry plan's rest.")
        tried = []
        for slack in ENTRY_SLACK:
            k = min(K + slack, u_ref.shape[0])
            found = box_entry_at(dmodel, objective, np.asarray(x0, float), x_ref, u_ref, bounds, k,
                                 margin=STORED_MARGIN, fast=FAST_IPOPT, elastic=ELASTIC)
            if found is not None:  # where it enters, elastic as it is
                k = entry_step(dmodel, objective, found[0], margin=0.0)
            tried.append(Attempt(stage=f"warm box entry K={k}", guess="library plan", N=u_ref.shape[0],
                                 status="Solve_Succeeded" if found else "refused", success=found is not None,
                                 iterations=found[2]["iterations"] if found else 0, objective=float("nan"),
                                 T=u_ref.shape[0] * dt, solve_time_s=found[2]["solve_time_s"] if found else 0.0,
                                 chosen=found is not None))
            if found is not None:
                return tracked(found, k, K, tuple(tried), tic)
        raise OCPError(f"No {objective} plan entering the box within {ENTRY_SLACK[-1]} steps of the stored plan's "
                       f"entry (step {K}) was found from x0 after {len(tried)} solves; that proves nothing.")
    return planner
