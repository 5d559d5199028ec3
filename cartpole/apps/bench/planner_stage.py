"""The planner's own fixed-time stage on 1, 2 and 3 poles, against the naive ``casadi.Opti`` script from the same
guess, in one run (``cartpole bench``'s ``trajopt.planner_stage`` rows).

The standard problem (:mod:`cartpole.apps.bench.trajopt`: T = 2 s from the first default guess) has no answer on the
shipped triple: T = 2 s is below its minimum time (2.3 s), and at longer T no solver converges from that guess. The
planner never starts there. It plans a minimum-time swing-up first and solves the effort problem at
``(1 + time_margin) T_min`` from that plan (:func:`cartpole.planning.trajopt.trajopt_swingup`): this row is that
stage on every model. Per model (the bench's bounds: |ctrl| <= 1, |cart| <= 1.4 m): the minimum-time plan on 60
intervals (:func:`~cartpole.planning.trajopt.minimum_time`, not timed), then the effort problem on N = 100 intervals
at ``T = (1 + time_margin) T_min`` from that plan stretched onto T, solved by the default planner's solver
(:func:`~cartpole.apps.bench.trajopt.default_planner_row`: the SQP, IPOPT behind it) and by the naive script
(:class:`~cartpole.apps.bench.trajopt.NaiveOptiBaseline`, hand-typed equations for one pole, the model's ``f`` else)
from the same guess.
"""
from __future__ import annotations

import numpy as np

from cartpole.apps.bench.trajopt import (NaiveOptiBaseline, default_planner_row, hand_typed_cartpole, median_ms,
                                         shipped_plan_models)
from cartpole.models import build_model, read_params
from cartpole.ocp.bounds import bounds_from_model
from cartpole.ocp.collocation import DirectCollocation, OCPNotSolved
from cartpole.ocp.guess import stretched
from cartpole.ocp.trajectory import Trajectory
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import minimum_time


def planner_stage_benchmark(models=None, *, N: int = 100, repeats: int = 5, progress=None) -> list[dict]:
    """One row per model: the planner's effort stage by the default planner and by the naive script.

    Parameters
    ----------
    models : list of (label, MJCF path), optional
        Default the shipped 1-, 2- and 3-pole carts.
    N : int
        Intervals of the effort stage.
    repeats : int
        Timed solves of the naive script (medians; the default planner's repeated until they span as long).
    progress : callable, optional
        ``progress(message)`` as each measurement starts.

    Returns
    -------
    list of dict
        ``model``, ``mjcf``, ``T_min`` (s), ``T`` (s), ``N``, ``solver`` (whose plan the default's was),
        ``solve_ms_median``, ``iterations``, ``objective`` (ctrl^2 s), ``success``, ``baseline`` (``hand`` or
        ``generic``), ``baseline_solve_ms_median``, ``baseline_iterations``, ``baseline_objective``,
        ``baseline_success``, ``speedup`` (the script's time over ours; None unless both converged),
        ``objective_rel_diff``; or ``model``, ``mjcf``, ``skipped`` (the sentence why) when no minimum-time plan.
    """
    say = progress or (lambda msg: None)
    margin = PlanOptions().time_margin
    rows = []
    for label, mjcf in (shipped_plan_models() if models is None else models):
        params = read_params(mjcf)
        model = build_model(params)
        x0 = np.array(model.x_hanging)
        bounds = bounds_from_model(model, u_max=1.0, cart_max=1.4, cart_margin=0.0)
        say(f"planner stage, {label}: the minimum-time plan (not timed) ...")
        try:
            T_min, fast, _ = minimum_time(model, x0, N=60, bounds=bounds, sqp=True)
        except OCPNotSolved as exc:
            rows.append({"model": label, "mjcf": params.mjcf, "skipped": str(exc)})
            continue
        T = (1.0 + margin) * T_min
        t = np.linspace(0.0, T, N + 1)
        x, u = stretched(fast, T, t, model.nq)
        guess = Trajectory(t=t, x=x, u=u, xdot=np.zeros_like(x))
        f_hand = hand_typed_cartpole(params)
        say(f"planner stage, {label}: the naive Opti script, {repeats} solves ...")
        base = NaiveOptiBaseline(model, N, T, bounds, x0, f=f_hand)
        base.solve(guess)  # builds IPOPT (not timed)
        b_ms, (b_obj, b_it, b_ok) = median_ms(lambda: base.solve(guess), repeats)
        say(f"planner stage, {label}: the default planner's solver ...")
        ocp = DirectCollocation(model, N=N, T=T, bounds=bounds)
        row = default_planner_row(ocp, x0, guess, repeats, b_ms)
        ok = row["default_success"]
        both = ok and b_ok
        rows.append({"model": label, "mjcf": params.mjcf, "T_min": T_min, "T": T, "N": N,
                     "solver": row["default_solver"], "solve_ms_median": row["default_solve_ms_median"],
                     "iterations": row["default_iterations"], "objective": row["default_objective"], "success": ok,
                     "baseline": "hand" if f_hand is not None else "generic", "baseline_solve_ms_median": b_ms,
                     "baseline_iterations": b_it, "baseline_objective": b_obj, "baseline_success": b_ok,
                     "speedup": b_ms / row["default_solve_ms_median"] if both else None,
                     "objective_rel_diff": abs(row["default_objective"] - b_obj) / abs(b_obj) if both else None})
    return rows


def print_planner_stage_table(rows: list[dict], file=None) -> None:
    """The rows of :func:`planner_stage_benchmark` as a table."""
    def w(line=""):
        print(line, file=file)

    w()
    w("The planner's effort stage (T = 1.2 T_min, N = 100, from the minimum-time plan): default planner vs naive Opti")
    w(f"{'model':10s} {'T (s)':>7s} {'solver':>7s} {'ours ms':>9s} {'naive ms':>10s} {'speed-up':>9s} "
      f"{'iterations':>11s}")
    for r in rows:
        if "skipped" in r:
            w(f"{r['model']:10s} not measured: {r['skipped']}")
            continue
        ratio = f"{r['speedup']:.1f}x" if r["speedup"] is not None else "-"
        w(f"{r['model']:10s} {r['T']:7.3f} {str(r['solver']):>7s} {r['solve_ms_median']:9.1f} "
          f"{r['baseline_solve_ms_median']:10.1f} {ratio:>9s} {str(r['iterations']):>5s} / {r['baseline_iterations']}")
