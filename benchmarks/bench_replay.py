"""Closed-loop MuJoCo replay throughput (issue 3): a batch of LQR rollouts stepped in lockstep.

Prints the figures of :func:`cartpole.apps.bench.replay.replay_benchmark`: physics steps per second of 256
closed-loop LQR rollouts of 2 s from random starts (``simulate_batch_linear``: one threaded
``mujoco.rollout`` call per physics step over the whole batch, feedback vectorised in numpy), next to MuJoCo's
own open-loop ``mujoco.rollout.rollout`` of the same batch in the same run, and (``--python-loop``) the naive
per-rollout Python ``mj_step`` loop.

Run: ``python benchmarks/bench_replay.py [--json] [--python-loop] [--rollouts 256] [--seconds 2] [--repeats 5]``.
"""
from __future__ import annotations

import argparse
import json
import sys


def main(argv=None) -> int:
    """Run the benchmark and print it (prose or ``--json``)."""
    from cartpole.apps.bench.replay import replay_benchmark

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mjcf", default=None, help="cart-pole MJCF (default: the shipped asset)")
    p.add_argument("--rollouts", type=int, default=256)
    p.add_argument("--seconds", type=float, default=2.0)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--python-loop", action="store_true", help="also time the per-rollout Python mj_step loop")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    r = replay_benchmark(a.mjcf, rollouts=a.rollouts, seconds=a.seconds, repeats=a.repeats,
                         python_loop=a.python_loop)
    if a.json:
        print(json.dumps(r))
        return 0
    print(f"{r['rollouts']} rollouts x {r['seconds_each']:g} s ({r['physics_steps']} physics steps), "
          f"{r['nthread']} thread(s), medians of {a.repeats}:")
    print(f"  closed-loop LQR, batched lockstep : {r['steps_per_s']:12,.0f} steps/s")
    print(f"  open-loop mujoco.rollout.rollout  : {r['open_loop_steps_per_s']:12,.0f} steps/s")
    print(f"  ratio closed / open               : {r['ratio']:12.2f}")
    if "python_loop_steps_per_s" in r:
        print(f"  closed-loop Python mj_step loop   : {r['python_loop_steps_per_s']:12,.0f} steps/s "
              f"({r['python_loop_steps_per_s'] / r['open_loop_steps_per_s']:.2f} of open loop)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
