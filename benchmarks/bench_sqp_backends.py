"""The collocation SQP's QP back-ends on the SQP problems the planner poses for the shipped 1-, 2- and 3-pole
swing-ups: median solve time, iterations, status and the QPs each fallback took, per problem and back-end.

The measurement lives in :mod:`cartpole.apps.bench.sqp_backends`. Run: ``python benchmarks/bench_sqp_backends.py
[--repeats 5] [--objective effort ...] [--json]``. Progress goes to stderr.
"""
from __future__ import annotations

import argparse
import json
import sys

from cartpole.apps.bench.sqp_backends import print_sqp_backend_table, sqp_backend_benchmark
from cartpole.solvers.sqp import QP_SOLVERS

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--objective", nargs="+", default=["effort"])
    ap.add_argument("--backend", nargs="+", default=list(QP_SOLVERS), choices=QP_SOLVERS)
    ap.add_argument("--poles", nargs="+", type=int, default=[1, 2, 3], choices=[1, 2, 3])
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    from cartpole.apps.bench.trajopt import shipped_plan_models

    models = [m for i, m in enumerate(shipped_plan_models(), start=1) if i in a.poles]
    rows = sqp_backend_benchmark(models, objectives=a.objective, backends=a.backend, repeats=a.repeats,
                                 progress=lambda msg: print(msg, file=sys.stderr, flush=True))
    if a.json:
        print(json.dumps(rows))
    else:
        print_sqp_backend_table(rows)
