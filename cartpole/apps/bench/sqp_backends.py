"""Each QP back-end of the collocation SQP (:class:`~cartpole.solvers.sqp.CollocationSQP`) on the SQP problems the
planner poses for the shipped 1-, 2- and 3-pole swing-ups (``benchmarks/bench_sqp_backends.py`` runs this).

The problems are recorded, not rebuilt: :func:`cartpole.planning.trajopt.trajopt_swingup` plans each cart's swing-up
(the planner's defaults, ``solver="auto"``) while every SQP problem it hands to the SQP (the minimum-time refinement,
the fixed-time stage after it) is kept with its start, goal and guess (:func:`planner_sqp_problems`). Each problem is
then solved from its guess by the SQP with each back-end in ``backends`` (the planner's iteration and hand-over
limits), first once to build (not timed), then ``repeats`` times: median wall time, iterations, status, and the QPs
each solver of the chain took (``qp_counts``: which fallback ran, and how often).
"""
from __future__ import annotations

from contextlib import contextmanager

from cartpole.apps.bench.trajopt import median_ms, shipped_plan_models
from cartpole.planning import trajopt as _trajopt
from cartpole.planning.options import PlanOptions
from cartpole.solvers.sqp import QP_SOLVERS, CollocationSQP, SQPError, SQPOptions


@contextmanager
def _recording(problems: list):
    """While open, every SQP problem the planner solves is appended to ``problems`` as ``(stage, ocp, x0, x_goal,
    guess)`` (the planner's SQP still solves it): the planner's ``CollocationSQP`` is this recording subclass."""
    class Recording(CollocationSQP):
        def solve_once(self, x0, x_goal=None, *, guess=None, T=None, start=0):
            stage = f"{self.ocp.objective_spec.kind} N={self.ocp.N}"
            problems.append((stage, self.ocp, x0, x_goal, guess))
            return super().solve_once(x0, x_goal, guess=guess, T=T, start=start)

    original = _trajopt.CollocationSQP
    _trajopt.CollocationSQP = Recording
    try:
        yield problems
    finally:
        _trajopt.CollocationSQP = original


def planner_sqp_problems(mjcf, *, objective: str = "effort") -> list[tuple]:
    """The SQP problems the planner solves for one swing-up from hanging rest.

    Parameters
    ----------
    mjcf : str or Path
        The cart's MJCF.
    objective : str
        The plan's objective (default the planner's, ``effort``).

    Returns
    -------
    list of tuple
        ``(stage, ocp, x0, x_goal, guess)`` in the order the planner solved them: the attempt's stage name, the
        :class:`~cartpole.ocp.collocation.DirectCollocation`, the start and goal (nx,) (``x_goal`` None: the
        model's upright) and the guess :class:`~cartpole.ocp.trajectory.Trajectory`.
    """
    problems: list = []
    with _recording(problems):
        _trajopt.trajopt_swingup(mjcf, options=PlanOptions(objective=objective, exact_discrete=False))
    return problems


def _solve_row(ocp, x0, x_goal, guess, backend: str, repeats: int) -> dict:
    """One problem by one back-end: built and solved once untimed, then ``repeats`` timed solves."""
    try:
        solver = CollocationSQP(ocp, options=SQPOptions(qp_solver=backend, max_iter=_trajopt.SQP_MAX_ITER,
                                                        max_unsettled=_trajopt.SQP_MAX_UNSETTLED))
    except SQPError as exc:
        return {"backend": backend, "refused": str(exc)}
    solver.solve_once(x0, x_goal, guess=guess)  # builds the QP solvers (not timed)
    ms, (_, info) = median_ms(lambda: solver.solve_once(x0, x_goal, guess=guess), repeats)
    return {"backend": backend, "solve_ms_median": ms, "iterations": info.iterations, "status": info.status,
            "success": info.success, "objective": info.objective, "qp_counts": dict(solver.qp_counts),
            "qp_soft": solver.qp_soft}


def sqp_backend_benchmark(models=None, *, objectives=("effort",), backends=QP_SOLVERS, repeats: int = 5,
                          progress=None) -> list[dict]:
    """One row per recorded SQP problem: each back-end's time, iterations, success and QP counts.

    Parameters
    ----------
    models : list of (label, MJCF path), optional
        Default the shipped 1-, 2- and 3-pole carts.
    objectives : sequence of str
        The plans' objectives (default the planner's ``effort``).
    backends : sequence of str
        ``qp_solver`` values of :class:`~cartpole.solvers.sqp.CollocationSQP` (default all of them).
    repeats : int
        Timed solves per problem and back-end (medians).
    progress : callable, optional
        ``progress(message)`` as each measurement starts.

    Returns
    -------
    list of dict
        ``model``, ``objective``, ``stage``, ``N``, ``results`` (one dict per back-end: ``backend`` and either
        ``refused`` (the SQP's sentence) or ``solve_ms_median`` (ms), ``iterations``, ``status``, ``success``,
        ``objective``, ``qp_counts``, ``qp_soft``).
    """
    say = progress or (lambda msg: None)
    rows = []
    for label, mjcf in (shipped_plan_models() if models is None else models):
        for objective in objectives:
            say(f"{label}, {objective}: planning (recording the SQP's problems) ...")
            for stage, ocp, x0, x_goal, guess in planner_sqp_problems(mjcf, objective=objective):
                results = []
                for backend in backends:
                    say(f"{label}, {objective}, {stage}: {backend}, {repeats} solves ...")
                    results.append(_solve_row(ocp, x0, x_goal, guess, backend, repeats))
                rows.append({"model": label, "objective": objective, "stage": stage, "N": ocp.N, "results": results})
    return rows


def print_sqp_backend_table(rows: list[dict], file=None) -> None:
    """The rows of :func:`sqp_backend_benchmark` as a table (one line per problem and back-end)."""
    print(f"{'model':8s} {'objective':9s} {'stage':24s} {'backend':8s} {'ms':>8s} {'it':>4s} {'status':28s} "
          "QPs by solver (soft)", file=file)
    for r in rows:
        for res in r["results"]:
            head = f"{r['model']:8s} {r['objective']:9s} {r['stage'][:24]:24s} {res['backend']:8s}"
            if "refused" in res:
                print(f"{head} refused: {res['refused']}", file=file)
                continue
            counts = ", ".join(f"{k} {v}" for k, v in res["qp_counts"].items() if v)
            print(f"{head} {res['solve_ms_median']:8.1f} {res['iterations']:4d} {res['status']:28s} {counts} "
                  f"({res['qp_soft']})", file=file)
