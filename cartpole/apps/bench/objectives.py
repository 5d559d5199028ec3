"""The default planner on every objective of the standard problem, against the naive ``casadi.Opti`` script with
the same objective, in one run (``cartpole bench``'s ``trajopt.objectives`` rows).

The standard problem of :mod:`cartpole.apps.bench.trajopt` (from hanging to upright, N = 100 Hermite-Simpson
intervals, |ctrl| <= 1, |cart| <= 1.4 m, the same guess), with each objective the swing-up command takes: ``effort``
(T = 2 s), ``tracking`` and ``dmc_cartpole_swingup`` (running objectives over the same T), ``time`` (T free, from
the guess's 2 s). Ours is what ``cartpole swingup`` runs for that stage by default (``solver="auto"``): the
collocation SQP with IPOPT behind it, for every objective (time by the SQP's time scale). The baseline is the naive
script (:class:`~cartpole.apps.bench.trajopt.NaiveOptiBaseline`) with the same objective written into it (a running
cost's SX Function called per knot and midpoint; ``T`` a variable for time), on the hand-typed one-pole equations
where they apply (:func:`~cartpole.apps.bench.trajopt.hand_typed_cartpole`), else the model's ``f``.
"""
from __future__ import annotations

import sys

import numpy as np

from cartpole.apps.bench.trajopt import NaiveOptiBaseline, default_planner_row, hand_typed_cartpole, median_ms
from cartpole.models import build_model, plant_params
from cartpole.ocp.bounds import OCPError, bounds_from_model
from cartpole.ocp.collocation import DirectCollocation
from cartpole.ocp.guess import initial_guesses
from cartpole.ocp.hermite_simpson import simpson_effort_terms
from cartpole.ocp.objectives import make_objective

#: The objectives measured, in order.
OBJECTIVES = ("effort", "tracking", "dmc_cartpole_swingup", "time")


def objective_benchmark(plant=None, *, objectives=OBJECTIVES, N: int = 100, T: float = 2.0, repeats: int = 5,
                        progress=None) -> list[dict]:
    """Per objective (module docstring), ours against the naive script, medians of ``repeats`` solves each.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        Cart MJCF (default the shipped one), any number of poles.
    objectives : sequence of str
        Objective names (default :data:`OBJECTIVES`).
    N, T : int, float
        Intervals and duration in s (the initial duration for ``time``).
    repeats : int
        Timed solves per method.
    progress : callable, optional
        ``progress(message)``.

    Returns
    -------
    list of dict
        Per objective: ``objective``, ``solver`` (whose plan ours is: ``sqp`` or ``ipopt``), ``solve_ms_median``,
        ``iterations``, ``success``, ``cost`` (the minimised quantity: the effort, the running cost's integral, a
        reward's negated, or ``T + w effort`` for time), ``baseline`` (``hand`` or ``generic``),
        ``baseline_solve_ms_median``, ``baseline_iterations``, ``baseline_cost``, ``baseline_success``,
        ``speedup`` (baseline / ours; None unless both converged) and ``cost_rel_diff``; for an objective the model
        cannot have (``dmc_cartpole_swingup`` without a cart) only ``objective`` and ``skipped``, the sentence why.
    """
    say = progress or (lambda msg: None)
    params = plant_params(plant)
    model = build_model(params)
    x0 = np.array(model.x_hanging)
    bounds = bounds_from_model(model, u_max=1.0, cart_max=1.4, cart_margin=0.0)
    guess = initial_guesses(model, x0, model.x_eq, T, N, bounds=bounds, count=1)[0]
    f_hand = hand_typed_cartpole(params)
    rows = []
    for name in objectives:
        try:
            obj = make_objective(model, name)
        except OCPError as exc:  # a task this model cannot have (a cart-pole reward on a pendulum): said, not run
            rows.append({"objective": name, "skipped": str(exc)})
            continue
        rows.append({"objective": name, **against_naive(model, obj, guess, bounds, x0, f_hand=f_hand, repeats=repeats,
                                                         say=say, label=f"objective {name}")})
    return rows


def against_naive(model, obj, guess, bounds, x0, *, f_hand=None, repeats: int = 5, say=None, label: str = "") -> dict:
    """One objective ``obj`` (:class:`~cartpole.ocp.objectives.Objective`) on ``guess``'s knots (``guess.N``
    intervals over its duration ``T`` s; for ``time`` the guess of T) from ``guess`` (a Trajectory), by the naive
    script with it
    (:class:`~cartpole.apps.bench.trajopt.NaiveOptiBaseline`; ``f_hand`` its dynamics where given, else the model's)
    and by the default planner's solver (:func:`~cartpole.apps.bench.trajopt.default_planner_row`), ``repeats``
    timed solves each; ``x0`` (nx,) the start, ``bounds`` the problem's.

    Returns
    -------
    dict
        ``solver``, ``solve_ms_median``, ``iterations``, ``success``, ``cost`` (what the script minimises: ctrl^2 s
        for effort, ``T + w effort`` for time, the running integral, a reward as the reward), ``baseline`` (``hand``
        or ``generic``), ``baseline_solve_ms_median``, ``baseline_iterations``, ``baseline_cost``,
        ``baseline_success``, ``speedup`` and ``cost_rel_diff`` (None unless both converged).
    """
    say = say or (lambda msg: None)
    N, T = guess.N, guess.duration
    say(f"{label}: the naive Opti script, {repeats} solves ...")
    base = NaiveOptiBaseline(model, N, T, bounds, x0, f=f_hand, objective=obj)
    base.solve(guess)  # builds IPOPT (not timed)
    b_ms, (b_cost, b_it, b_ok) = median_ms(lambda: base.solve(guess), repeats)
    say(f"{label}: ours (the default planner's solver), {repeats} solves ...")
    ocp = DirectCollocation(model, N=N, T=None if obj.kind == "time" else T, bounds=bounds, objective=obj)
    # the planner's SQP, IPOPT behind it (time: T_0 the guess's duration, the script's initial T)
    row = default_planner_row(ocp, x0, guess, repeats, b_ms)
    ms, ok = row["default_solve_ms_median"], row["default_success"]
    cost = row["default_objective"]
    if ok and obj.kind == "time":  # what the script minimises
        cost = row["trajectory"].duration + ocp.time_effort_weight * plan_effort(row["trajectory"])
    elif ok and obj.is_reward:  # reported as the reward: the script minimises its negative
        cost = -cost
    both = ok and b_ok
    return {"solver": row["default_solver"], "solve_ms_median": ms, "iterations": row["default_iterations"],
            "success": ok, "cost": cost, "baseline": "hand" if f_hand is not None else "generic",
            "baseline_solve_ms_median": b_ms, "baseline_iterations": b_it, "baseline_cost": b_cost,
            "baseline_success": b_ok, "speedup": b_ms / ms if both else None,
            "cost_rel_diff": abs(cost - b_cost) / max(abs(b_cost), 1e-12) if both else None}


def plan_effort(traj) -> float:
    """``integral u'u dt`` of a Hermite-Simpson plan (ctrl^2 s), Simpson on its first-order-hold inputs."""
    h = np.diff(traj.t)[:, None]
    return float(np.sum(h / 6 * simpson_effort_terms(traj.u[:-1], traj.u[1:])))


def print_objective_table(rows: list[dict], file=None) -> None:
    """Prose table of :func:`objective_benchmark` rows."""
    w = (sys.stdout if file is None else file).write
    w(f"\n{'objective (standard problem)':28s} {'ours':>8s} {'ms':>8s} {'naive Opti ms':>14s} {'speed-up':>9s} "
      f"{'cost rel. diff':>15s}\n")
    for r in rows:
        if "skipped" in r:
            w(f"{r['objective']:28s} not measured: {r['skipped']}\n")
            continue
        sp = "-" if r["speedup"] is None else f"{r['speedup']:.1f}x"
        rd = "-" if r["cost_rel_diff"] is None else f"{r['cost_rel_diff']:.1e}"
        w(f"{r['objective']:28s} {str(r['solver']):>8s} {r['solve_ms_median']:8.1f} "
          f"{r['baseline_solve_ms_median']:14.1f} {sp:>9s} {rd:>15s}\n")
