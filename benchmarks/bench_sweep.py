"""Sweep throughput on 1 and 2 local workers (and Dask), and the machine's parallel capacity beside it: a thin
command-line caller of :mod:`cartpole.apps.bench.sweep` (see it for what is timed and how).

    python benchmarks/bench_sweep.py --n 24 --rounds 7 --where 1 2 --fresh 5   # the worker start-up figure
    python benchmarks/bench_sweep.py --n 100 --rounds 3 [--method energy] [--json]
"""
from cartpole.apps.bench.sweep import main

if __name__ == "__main__":
    raise SystemExit(main())
