"""A first plan in a freshly forked planning worker, cold and warm, against a plan in the caller's thread.

The supervisor plans in a child process (:class:`cartpole.supervise.worker.PlanWorker`) that is killed at the plan
budget; the next plan forks a new child. A child is as warm as its parent was at the fork: this measures, in one
process and on one cart, the wall time of

* ``cold_child_s``: the first plan in a child forked from a parent that has built nothing for the planner (each
  child a new fork of the same cold parent, so every one is cold);
* ``prepare_s``: the warm-up in the parent (:meth:`cartpole.supervise.Supervisor.prepare`: one plan made and
  discarded, which builds the solvers and loads the compiled C);
* ``thread_s``: a plan in the caller's thread of the warmed parent;
* ``warm_child_s``: the first plan in a child forked from the warmed parent (each a new fork, as after a kill);

each from the hanging state through the supervisor's own planner (:func:`cartpole.supervise.supervisor_for`),
medians of ``--repeats`` runs, and the ratios ``warm_child_s / thread_s`` (1 when a fresh child starts warm) and
``cold_child_s / warm_child_s`` (what the warm-up saves each child). The compile cache on disk is whatever the
machine has (run once before to measure with it filled, as a user's second run would).

Run: ``python benchmarks/bench_plan_worker.py [--poles 1,3] [--repeats 3] [--json]``.
"""
from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from cartpole.models import build_model, read_params
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.supervise import Supervisor, SupervisorOptions, supervisor_for
from cartpole.supervise.worker import run_planner

ASSETS = Path(__file__).resolve().parents[1] / "cartpole" / "assets"
#: The shipped cart of each number of poles.
CARTS = {1: "cartpole.xml", 2: "cartpole_two_pole.xml", 3: "cartpole_three_pole.xml"}
#: s: the budget a child's plan is given here (generous: what is measured is the time, not the bound).
BUDGET = 900.0


def _timed(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def measure(poles: int, repeats: int) -> dict:
    """The row of one cart: medians (s) of each kind of plan, their ratios, and every run's time."""
    params = read_params(str(ASSETS / CARTS[poles]))
    model = build_model(params)
    sup = _planning_supervisor(params, model)
    x0 = np.asarray(model.x_hanging, dtype=float)

    def plan():
        return sup.planner(x0)

    cold = [_timed(lambda: run_planner(plan, BUDGET)) for _ in range(repeats)]  # parent still cold
    prepare_s = sup.prepare(again=True)
    thread = [_timed(plan) for _ in range(repeats)]
    warm = [_timed(lambda: run_planner(plan, BUDGET)) for _ in range(repeats)]
    med = {k: statistics.median(v) for k, v in (("cold_child_s", cold), ("thread_s", thread), ("warm_child_s", warm))}
    return {"poles": poles, "mjcf": CARTS[poles], "repeats": repeats, "prepare_s": prepare_s, **med,
            "warm_child_over_thread": med["warm_child_s"] / med["thread_s"],
            "cold_child_over_warm_child": med["cold_child_s"] / med["warm_child_s"],
            "runs": {"cold_child_s": cold, "thread_s": thread, "warm_child_s": warm}}


def _planning_supervisor(params, model):
    """supervisor_for's supervisor, or on one pole (whose supervisor runs the energy law and never plans) one with
    the same catch and brake that plans with :func:`~cartpole.planning.trajopt.trajopt_swingup`."""
    base = supervisor_for(params, model)
    if base.planner is not None:
        return base

    def planner(x0, guess=None, cold=True):
        return trajopt_swingup(params, x0=tuple(x0), plan_model=model, guess=guess, cold=cold)
    return Supervisor(model, base.catch, base.rho, base.brake, planner=planner,
                      options=SupervisorOptions(plan_in_worker=True))


def main(argv: list[str]) -> dict:
    """The benchmark's JSON document for the command line ``argv`` (``--poles``, ``--repeats``)."""
    repeats = int(argv[argv.index("--repeats") + 1]) if "--repeats" in argv else 3
    poles = [int(a) for a in argv[argv.index("--poles") + 1].split(",")] if "--poles" in argv else [1, 3]
    return {"plan_worker": [measure(p, repeats) for p in poles]}


if __name__ == "__main__":
    doc = main(sys.argv[1:])
    if "--json" in sys.argv:
        print(json.dumps(doc))
    else:
        for row in doc["plan_worker"]:
            print(f"{row['poles']} pole(s): cold child {row['cold_child_s']:.2f} s, warm-up {row['prepare_s']:.2f} s, "
                  f"caller's thread {row['thread_s']:.2f} s, warm child {row['warm_child_s']:.2f} s; warm child / "
                  f"thread {row['warm_child_over_thread']:.2f}, cold child / warm child "
                  f"{row['cold_child_over_warm_child']:.2f} (medians of {row['repeats']})")
