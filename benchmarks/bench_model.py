"""Model readiness and linearisation speed (issue 2).

Times, as medians of several runs in one process: reading the MJCF + building every CasADi Function, and one
evaluation of the exact ``A, B`` - next to the baseline people use without a symbolic model, MuJoCo's own
finite-difference ``mjd_transitionFD`` (discrete Jacobians) and a central difference of ``mj_forward`` (continuous).
The measurement lives in :mod:`cartpole.apps.bench.model`.

Run: ``python benchmarks/bench_model.py`` (add ``--json`` for machine-readable output).
"""
from __future__ import annotations

import json
import sys

from cartpole.apps.bench.model import print_model_table, shipped_model_benchmarks


def run() -> dict:
    """Benchmark figures (seconds, microseconds) and ratios against MuJoCo finite differences, per shipped cart."""
    return shipped_model_benchmarks()


if __name__ == "__main__":
    res = run()
    if "--json" in sys.argv:
        print(json.dumps(res))
    else:
        print_model_table(res)
