"""The planner's own stages on 1, 2 and 3 poles, every objective, against the naive ``casadi.Opti`` script from
the same guess, in one run (``cartpole bench``'s ``trajopt.planner_stage`` rows).

The standard problem (:mod:`cartpole.apps.bench.trajopt`: T = 2 s from the first default guess) has no answer on the
shipped triple: T = 2 s is below its minimum time (2.3 s), and at longer T no solver converges from that guess. The
planner never starts there. It plans a minimum-time swing-up first and solves the objective's stage from that plan
(:func:`cartpole.planning.trajopt.trajopt_swingup`): these rows are those stages on every model. Per model (the
bench's bounds: |ctrl| <= 1, |cart| <= 1.4 m) the minimum-time plan on 60 intervals
(:func:`~cartpole.planning.trajopt.minimum_time`, not timed), then per objective the problem on N = 100 intervals from
that plan: ``effort`` at ``T = (1 + time_margin) T_min`` (the plan stretched onto T), ``time`` with T free (the plan
at its own pace, as the planner refines a coarse plan), a running objective over ``T_min +``
:data:`~cartpole.planning.trajopt.RUNNING_HOLD` (the plan, then rest at upright); each solved by the default
planner's solver (:func:`~cartpole.apps.bench.trajopt.default_planner_row`: the SQP, IPOPT behind it) and by the
naive script with that objective (:class:`~cartpole.apps.bench.trajopt.NaiveOptiBaseline`, hand-typed equations for
one pole, the model's ``f`` else) from the same guess. An objective the model cannot have is a row saying why.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cartpole.apps.bench.objectives import against_naive
from cartpole.apps.bench.trajopt import hand_typed_cartpole, shipped_plan_models
from cartpole.models import build_model, read_params
from cartpole.ocp.bounds import OCPError, bounds_from_model
from cartpole.ocp.collocation import OCPNotSolved
from cartpole.ocp.guess import stretched
from cartpole.ocp.trajectory import Trajectory
from cartpole.planning.options import PlanOptions
from cartpole.ocp.objectives import make_objective
from cartpole.planning.trajopt import RUNNING_HOLD, minimum_time, padded


#: The objectives of the planner-stage rows: the effort, a running cost, the minimum time and dm_control's cart-pole
#: rewards (``dmc_cartpole_balance`` pays the swing-up's reward: the same problem, not a row of its own). On two and
#: three poles dm_control's reward takes the least of the poles' rate tolerances, whose kink stalled both solvers
#: (the naive script 3000 iterations, 225 s) until the planning form smoothed it (:func:`cartpole.ocp.dmc.smooth_min`).
STAGE_OBJECTIVES = ("effort", "tracking", "time", "dmc_cartpole_swingup", "dmc_cartpole_swingup_sparse")


def planner_stage_benchmark(models=None, *, objectives=STAGE_OBJECTIVES, N: int = 100, repeats: int = 5,
                            progress=None) -> list[dict]:
    """One row per model and objective: the planner's stage by the default planner and by the naive script.

    Parameters
    ----------
    models : list of (label, MJCF path), optional
        Default the shipped 1-, 2- and 3-pole carts.
    objectives : sequence of str
        Objective names (default :data:`STAGE_OBJECTIVES`).
    N : int
        Intervals of each stage.
    repeats : int
        Timed solves of the naive script (medians; the default planner's repeated until they span as long).
    progress : callable, optional
        ``progress(message)`` as each measurement starts.

    Returns
    -------
    list of dict
        ``model``, ``mjcf``, ``objective`` (its name), ``T_min`` (s), ``T`` (s: the stage's, for ``time`` the guess's),
        ``N``, ``solver`` (whose plan the default's was), ``solve_ms_median``, ``iterations``, ``cost`` (what the
        script minimises: ctrl^2 s for effort, ``T + w effort`` for time, the running integral, a reward's
        negated), ``success``, ``baseline`` (``hand`` or ``generic``), ``baseline_solve_ms_median``,
        ``baseline_iterations``, ``baseline_cost``, ``baseline_success``, ``speedup`` (the script's time over ours;
        None unless both converged), ``cost_rel_diff``; or ``model``, ``mjcf``, ``objective`` and ``skipped`` (the
        sentence why) when the model has no minimum-time plan or cannot have the objective.
    """
    say = progress or (lambda msg: None)
    margin = PlanOptions().time_margin
    rows = []
    for label, mjcf in (shipped_plan_models() if models is None else models):
        params = read_params(mjcf)
        model = build_model(params)
        x0 = np.array(model.x_hanging)
        bounds = bounds_from_model(model, u_max=1.0, cart_max=1.4, cart_margin=0.0)
        say(f"planner stages, {label}: the minimum-time plan (not timed) ...")
        try:
            T_min, fast, _ = minimum_time(model, x0, N=60, bounds=bounds, sqp=True)
        except OCPNotSolved as exc:
            rows += [{"model": label, "mjcf": params.mjcf, "objective": name, "skipped": str(exc)}
                     for name in objectives]
            continue
        f_hand = hand_typed_cartpole(params)
        for name in objectives:
            try:
                obj = make_objective(model, name)
            except OCPError as exc:  # a task this model cannot have: said, not run
                rows.append({"model": label, "mjcf": params.mjcf, "objective": name, "skipped": str(exc)})
                continue
            case = _Case(label, params, model, x0, bounds, f_hand, T_min, fast)
            rows.append(_stage_row(case, obj, name, margin, N, repeats, say))
    return rows


class _Case(NamedTuple):
    """One model's shared part of its rows: its minimum-time plan ``fast`` of ``T_min`` s from ``x0`` in
    ``bounds``, and the hand-typed dynamics ``f_hand`` of the naive script."""
    label: str
    params: object
    model: object
    x0: np.ndarray
    bounds: object
    f_hand: object
    T_min: float
    fast: object


def _stage_row(case: _Case, obj, name: str, margin: float, N: int, repeats: int, say) -> dict:
    """One objective's stage from the minimum-time plan ``case.fast`` (module docstring), both solvers, one row."""
    label, params, model, x0, bounds, f_hand, T_min, fast = case
    if obj.kind == "effort":
        T, plan = (1.0 + margin) * T_min, fast
    elif obj.kind == "time":
        T, plan = fast.duration, fast
    else:
        T = T_min + RUNNING_HOLD
        plan = padded(fast, T)
    t = np.linspace(0.0, T, N + 1)
    x, u = stretched(plan, T, t, model.nq)
    guess = Trajectory(t=t, x=x, u=u, xdot=np.zeros_like(x))
    return {"model": label, "mjcf": params.mjcf, "objective": name, "T_min": T_min, "T": T, "N": N,
            **against_naive(model, obj, guess, bounds, x0, f_hand=f_hand, repeats=repeats, say=say,
                            label=f"planner stages, {label}, {name}")}


def print_planner_stage_table(rows: list[dict], file=None) -> None:
    """The rows of :func:`planner_stage_benchmark` as a table."""
    def w(line=""):
        print(line, file=file)

    w()
    w("The planner's stages (N = 100, from the minimum-time plan): default planner vs naive Opti")
    w(f"{'model':10s} {'objective':22s} {'T (s)':>7s} {'solver':>7s} {'ours ms':>9s} {'naive ms':>10s} "
      f"{'speed-up':>9s} {'iterations':>11s}")
    for r in rows:
        if "skipped" in r:
            w(f"{r['model']:10s} {r['objective']:22s} not measured: {r['skipped']}")
            continue
        ratio = f"{r['speedup']:.1f}x" if r["speedup"] is not None else "-"
        w(f"{r['model']:10s} {r['objective']:22s} {r['T']:7.3f} {str(r['solver']):>7s} {r['solve_ms_median']:9.1f} "
          f"{r['baseline_solve_ms_median']:10.1f} {ratio:>9s} {str(r['iterations']):>5s} / {r['baseline_iterations']}")
