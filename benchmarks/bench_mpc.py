"""Nonlinear MPC per-control-step solve time over a single-pole swing-up in MuJoCo (the compiled program as the loop
runs it), against IPOPT re-solves.

Run: ``.venv/bin/python benchmarks/bench_mpc.py [--repeats 3] [--period 0.02] [--horizon 1.2] [--qp-solver daqp|qpoases]
[--no-baseline] [--no-two-pole] [--no-ddp] [--json]``.
"""
from __future__ import annotations

import argparse
import json

from cartpole.apps.bench.mpc import MPCBenchOptions, mpc_lines, run_mpc_benchmark


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mjcf", default=None)
    ap.add_argument("--period", type=float, default=0.02)
    ap.add_argument("--horizon", type=float, default=1.2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--qp-solver", choices=["daqp", "qpoases"], default=None)
    ap.add_argument("--no-baseline", action="store_true", help="skip the IPOPT runs")
    ap.add_argument("--no-two-pole", action="store_true", help="skip the two-pole RTI and IPOPT runs")
    ap.add_argument("--no-ddp", action="store_true", help="skip the DDP MPC rows")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    r = run_mpc_benchmark(a.mjcf, MPCBenchOptions(period=a.period, horizon=a.horizon, repeats=a.repeats,
                                                  qp_solver=a.qp_solver, baseline=not a.no_baseline,
                                                  two_pole=not a.no_two_pole, ddp_two_pole=not a.no_ddp,
                                                  ddp=not a.no_ddp))
    if a.json:
        print(json.dumps(r, indent=2))
        return
    print("\n".join(mpc_lines(r)))

if __name__ == "__main__":
    main()
