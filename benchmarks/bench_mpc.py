"""Nonlinear MPC per-control-step solve time over a single-pole swing-up in MuJoCo, against IPOPT re-solves.

Run: ``.venv/bin/python benchmarks/bench_mpc.py [--repeats 3] [--period 0.02] [--horizon 1.2] [--qp-solver daqp|qpoases]
[--no-baseline] [--no-two-pole] [--no-ddp] [--json]``.
"""
from __future__ import annotations

import argparse
import json

from cartpole.apps.bench.mpc import run_mpc_benchmark


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
    r = run_mpc_benchmark(a.mjcf, period=a.period, horizon=a.horizon, repeats=a.repeats, qp_solver=a.qp_solver,
                          baseline=not a.no_baseline, two_pole=not a.no_two_pole, ddp_two_pole=not a.no_ddp,
                          ddp=not a.no_ddp)
    if a.json:
        print(json.dumps(r, indent=2))
        return
    b = r["baseline"]
    print(f"NMPC (RTI, {r['qp_solver']}, compiled={r['compiled']}), period {r['period']:g} s, horizon "
          f"{r['horizon']:g} s (N = {r['N']}), single-pole swing-up in MuJoCo, {r['steps']} control steps:")
    print(f"  RTI      median {r['solve_ms_median']:.3f} ms, p99 {r['solve_ms_p99']:.3f} ms, "
          f"max {r['solve_ms_max']:.3f} ms, swing-up success {r['success']}, safe-action fallbacks {r['failures']}")
    if b is not None:
        print(f"  IPOPT    median {b['solve_ms_median']:.3f} ms, p99 {b['solve_ms_p99']:.3f} ms, "
              f"max {b['solve_ms_max']:.3f} ms, swing-up success {b['success']}, unconverged {b['unconverged']}")
        print(f"  speed-up (medians) {r['speedup_median']:.1f}x")
    if r["overhead"]:
        o = r["overhead"]
        print(f"  the C step {o['c_us_median']:.1f} us, the whole call {o['call_us_median']:.1f} us: Python's overhead "
              f"{o['python_us_median']:.1f} us (medians)")
    if r["two_pole"]:
        t = r["two_pole"]
        print(f"  two poles: RTI median {t['solve_ms_median']:.3f} ms, p99 {t['solve_ms_p99']:.3f} ms; IPOPT median "
              f"{t['baseline']['solve_ms_median']:.3f} ms; speed-up {t['speedup_median']:.1f}x")


if __name__ == "__main__":
    main()
