"""The Python overhead of the one compiled implementation in the MuJoCo loop (issue 39).

For the LQR with a Kalman filter on the one-pole cart (10 ms period, 2048-count encoders) and the EKF variant, the
measurements of a MuJoCo run are replayed, in one process, through:

* ``c_us``: the compiled ``cp_step`` timed inside C (``cartpole.export.timing``: the fastest of several replays of
  each step), the time the rig spends;
* ``loop_us``: the same library called from Python as the MuJoCo loop calls it
  (:class:`cartpole.export.inloop.InLoopController`: ``step`` then ``estimate``, through ``ctypes``);
* ``python_us``: the Python reference classes on the same inputs (estimator update, then the law).

``overhead_us`` = ``loop_us - c_us`` (medians) is what calling the C from the Python loop costs per step.
Nothing here is asserted: timings vary with the machine and its load.

Run: ``python benchmarks/bench_inloop.py`` (add ``--json`` for machine-readable output).
"""
from __future__ import annotations

import json
import sys
import time

import numpy as np

from cartpole.export import design_export, run_lockstep
from cartpole.export.inloop import compile_program
from cartpole.export.make import export_files
from cartpole.export.timing import time_steps
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions

CASES = {"lqr+kf": ("lqr", "kf"), "lqr+ekf": ("lqr", "ekf"), "pid+kf": ("pid", "kf")}


def _median_us(fn, rounds: int = 5) -> np.ndarray:
    best = None
    for _ in range(rounds):
        times = fn()
        best = times if best is None else np.minimum(best, times)
    return best


def case(method: str, estimator: str, duration: float = 2.0) -> dict:
    """Per-step medians (microseconds) of the compiled step inside C, from the Python loop, and of the Python
    reference, for ``method`` with ``estimator`` on the one-pole cart."""
    model = build_model(None)
    loop = LoopOptions(period=0.01, estimator=estimator, encoder_cpr=2048)
    design = design_export(model, method, loop)
    ctl = compile_program(design)
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += 0.1
    run = run_lockstep(design, ctl, x0, duration)
    t, y = np.asarray(run.t, float), np.asarray(run.y, float)
    c_us = time_steps(export_files(design), t, y, repeats=20)["step_us"]

    def loop_pass():
        out = np.empty(len(t))
        ctl.reset()
        for k in range(len(t)):
            t0 = time.perf_counter_ns()
            ctl.step(t[k], y[k])
            ctl.estimate()
            out[k] = 1e-3 * (time.perf_counter_ns() - t0)
        return out

    loop_us = _median_us(loop_pass)
    c_med, loop_med = float(np.median(c_us)), float(np.median(loop_us))
    return {"c_us": c_med, "loop_us": loop_med, "overhead_us": loop_med - c_med,
            "python_us": float(np.median(run.python_us)), "steps": int(len(t))}


def run() -> dict:
    """Every case of :data:`CASES`."""
    return {name: case(*spec) for name, spec in CASES.items()}


if __name__ == "__main__":
    res = run()
    if "--json" in sys.argv:
        print(json.dumps(res))
    else:
        print(f"{'case':10s} {'C step':>10s} {'from loop':>10s} {'overhead':>10s} {'Python':>10s}  (us, medians)")
        for name, r in res.items():
            print(f"{name:10s} {r['c_us']:10.2f} {r['loop_us']:10.2f} {r['overhead_us']:10.2f} {r['python_us']:10.2f}")
