"""Swing-up plan time for carts with 1, 2 and 3 poles, from a fresh process to a verified MuJoCo rollout.

Each run is a new Python process (as ``cartpole swingup --method trajopt`` is): import, read the MJCF, plan, one
MuJoCo rollout from hanging rest checked for exact replay and success; medians per cart. The measurement and what
each figure means live in :mod:`cartpole.apps.bench.swingup_chains`. The compile cache is whatever the machine has:
run once before to measure warm.

Run: ``python benchmarks/bench_swingup_chains.py [--repeats 5] [--poles 1,2,3] [--baseline ROOT] [--json]``;
``--baseline`` runs another checkout's code (e.g. ``git archive <commit> cartpole | tar -x -C ROOT``) the same way,
alternating with ours run by run, so both see the same machine load.
"""
from __future__ import annotations

import json
import sys

from cartpole.apps.bench.swingup_chains import print_chains_table, swingup_chains_benchmark


def main(argv: list[str]) -> dict:
    """The benchmark's JSON document for the command line ``argv`` (``--repeats``, ``--poles``, ``--baseline``)."""
    repeats = int(argv[argv.index("--repeats") + 1]) if "--repeats" in argv else 5
    baseline = argv[argv.index("--baseline") + 1] if "--baseline" in argv else None
    poles = [int(a) for a in argv[argv.index("--poles") + 1].split(",")] if "--poles" in argv else None
    return swingup_chains_benchmark(poles, repeats=repeats, baseline=baseline)


if __name__ == "__main__":
    doc = main(sys.argv[1:])
    if "--json" in sys.argv:
        print(json.dumps(doc))
    else:
        print_chains_table(doc)
