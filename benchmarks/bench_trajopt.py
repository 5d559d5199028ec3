"""Swing-up collocation speed: ours vs the naive ``casadi.Opti`` baseline, TVLQR synthesis, batched replay.

The measurement lives in :mod:`cartpole.apps.bench.trajopt` (so ``cartpole bench`` runs the same code).

Run: ``python benchmarks/bench_trajopt.py`` (add ``--json`` for the JSON document, ``--no-replay`` to skip
the batched replay). Progress goes to stderr.
"""
from __future__ import annotations

import json
import sys

from cartpole.apps.bench.trajopt import print_table, run

if __name__ == "__main__":
    doc = run(repeats=7, replay="--no-replay" not in sys.argv,
              progress=lambda msg: print(msg, file=sys.stderr, flush=True))
    if "--json" in sys.argv:
        from cartpole.cli import to_jsonable

        print(json.dumps(to_jsonable(doc)))
    else:
        print_table(doc)
