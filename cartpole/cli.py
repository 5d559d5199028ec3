"""The ``cartpole`` command line: one subcommand per module in :mod:`cartpole.commands`.

Every subcommand takes ``--mjcf PATH`` (default: the shipped asset), ``--out DIR`` (default: the current
directory) and ``--json`` (print exactly one JSON document on stdout, nothing else). Bad input ends with
one sentence on stderr and exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import sys

from cartpole.errors import CartPoleError

#: Subcommand modules, in the order ``cartpole --help`` lists them.
COMMANDS = ("linearize", "lqr", "swingup", "bench")


def _load_commands():
    mods = {}
    for name in COMMANDS:
        try:
            mods[name] = importlib.import_module(f"cartpole.commands.{name}")
        except ModuleNotFoundError as exc:  # a subcommand not built in this checkout
            if exc.name != f"cartpole.commands.{name}":
                raise
    return mods


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand and the common options."""
    parser = argparse.ArgumentParser(prog="cartpole", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, mod in _load_commands().items():
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        p.add_argument("--mjcf", default=None, metavar="PATH",
                       help="cart-pole MJCF file (default: the shipped cartpole/assets/cartpole.xml)")
        p.add_argument("--out", default=".", metavar="DIR", help="directory for outputs (default: .)")
        p.add_argument("--json", action="store_true", help="print one JSON document on stdout instead of prose")
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def to_jsonable(obj):
    """Convert numpy arrays/scalars and paths inside ``obj`` to plain JSON types."""
    import numpy as np
    from pathlib import Path

    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating,)):
        obj = float(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def main(argv=None) -> int:
    """Entry point of the ``cartpole`` console script; returns the exit status."""
    # Headless rendering: MUJOCO_GL must be set before mujoco is first imported.
    os.environ.setdefault("MUJOCO_GL", "egl")
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        import mujoco  # noqa: F401  (MuJoCo 4 raises AttributeError, not ImportError, for a missing GL library)
    except Exception as exc:  # pragma: no cover - depends on the machine's GL libraries
        print(f"cartpole {args.command}: MuJoCo failed to load with MUJOCO_GL={os.environ.get('MUJOCO_GL')} "
              f"({type(exc).__name__}); set MUJOCO_GL=egl (or unset it) and try again.", file=sys.stderr)
        return 2
    try:
        doc = args._run(args)
    except CartPoleError as exc:
        print(f"cartpole {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"cartpole {args.command}: interrupted.", file=sys.stderr)
        return 130
    if args.json:
        sys.stdout.write(json.dumps(to_jsonable(doc)) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
