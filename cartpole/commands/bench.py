"""``cartpole bench``: trajectory-optimisation, TVLQR and batched-replay speed, measured in one run."""
from __future__ import annotations

import sys

HELP = ("time the swing-up collocation solve (ours vs the naive casadi.Opti baseline), TVLQR synthesis "
        "and batched MuJoCo replay")


def add_arguments(parser) -> None:
    """``--quick`` (fewer repeats and rollouts, for tests), ``--repeats``, ``--no-replay``."""
    parser.add_argument("--quick", action="store_true",
                        help="few repeats and a small replay batch (smoke test; figures are not for publishing)")
    parser.add_argument("--repeats", type=int, default=None, metavar="K",
                        help="timed solves per method, medians reported (default 7; --quick 2)")
    parser.add_argument("--no-replay", action="store_true", help="skip the batched replay benchmark")


def run(args) -> dict:
    """Run :func:`cartpole.benchmark.run` on ``args.mjcf``; print a table unless ``--json``."""
    from cartpole.benchmark import print_table
    from cartpole.benchmark import run as bench_run
    from cartpole.errors import CartPoleError

    repeats = args.repeats if args.repeats is not None else (2 if args.quick else 7)
    if repeats < 1:
        raise CartPoleError(f"--repeats {repeats} is not positive; give at least 1 (5 or more to publish).")
    doc = bench_run(args.mjcf, repeats=repeats, replay=not args.no_replay,
                    replay_repeats=1 if args.quick else repeats, replay_rollouts=16 if args.quick else 256,
                    progress=lambda msg: print(f"cartpole bench: {msg}", file=sys.stderr, flush=True))
    doc["quick"] = bool(args.quick)
    if not args.json:
        print_table(doc)
    return doc
