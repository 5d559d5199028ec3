"""``cartpole library``: build a library of swing-up plans on disk (cold plans from a grid of starts, stored with the
model's hash), or say what is stored; the supervisor's and the planner's warm starts
(:mod:`cartpole.planning.library`)."""
from __future__ import annotations

import time
from pathlib import Path

from cartpole.codegen import model_key
from cartpole.commands.swingup import search_fields
from cartpole.models import build_model, read_params
from cartpole.planning.library import PlanLibrary, PlanLibraryError, build_plan_library, library_path, library_starts
from cartpole.planning.options import PlanOptions

HELP = ("build a library of swing-up plans from a grid of starts, stored with the model's hash (the supervisor's "
        "warm starts), or list the one stored")

#: The library goes to the user cache (where the supervisor looks) or to --file, never to --out.
WRITES_FILES = False


def add_arguments(parser) -> None:
    """``--build N``, ``--file PATH``, ``--search-s S``, ``--period S``."""
    parser.add_argument("--build", type=int, default=None, metavar="N",
                        help="plan cold from N starts (the chain at rest, its first hinge at N evenly spaced angles "
                             "about hanging) and add them to the library; without it, only list what is stored")
    parser.add_argument("--file", default=None, metavar="PATH",
                        help="the library file (default: the user cache's file of the model's hash, where "
                             "`cartpole swingup --knockdown` looks)")
    parser.add_argument("--search-s", type=float, default=None, metavar="S", dest="search_s",
                        help="wall-time budget of each start's pumping search, s (default the planner's, 180; inf: "
                             "none)")
    parser.add_argument("--period", type=float, default=None, metavar="S",
                        help="control period the plans' TVLQR is designed over (default every MJCF step)")


def run(args) -> dict:
    """Build (``--build N``) or read the plan library of ``args.mjcf``'s model.

    JSON: ``mjcf``, ``file`` (the library's path), ``key`` (the model's hash), ``plans`` (stored after the run),
    ``built`` (plans added by this run), ``failed`` (each start no plan was found from: ``x0``, ``reason``),
    ``starts`` (one object per stored plan: ``x0``, ``T`` s, ``plan_s`` wall time of its cold plan), ``build_s``
    (wall time of the build, s).
    """
    if args.build is not None and not 1 <= args.build <= 64:
        raise PlanLibraryError(f"--build {args.build} must be a whole number of starts from 1 to 64; give e.g. --build 3.")
    if args.search_s is not None and not args.search_s > 0:
        raise PlanLibraryError(f"--search-s {args.search_s} must be a positive number of seconds (inf: no budget); "
                               "give e.g. --search-s 180.")
    params = read_params(args.mjcf)
    model = build_model(params)
    path = Path(args.file).expanduser().resolve() if args.file else library_path(_key(model))
    if args.file and not path.parent.is_dir():
        raise PlanLibraryError(f"The folder of --file {args.file} does not exist; create it or give another --file.")
    lib = PlanLibrary.load(model, path)
    before = len(lib)
    tic = time.perf_counter()
    if args.build is not None:
        options = PlanOptions(**search_fields(args))  # --search-s inf: no wall-time budget
        progress = None if args.json else (lambda done, total: print(f"  planned {done}/{total}", flush=True))
        lib = build_plan_library(params, model, library_starts(model, args.build), options=options,
                                 period=args.period, library=lib, progress=progress)
        try:
            lib.save(path)
        except OSError as exc:
            raise PlanLibraryError(f"The library cannot be written to {path} ({exc.strerror}); give a writable --file.") from None
    doc = {"mjcf": params.mjcf, "file": str(path), "key": lib.key, "plans": len(lib), "built": len(lib) - before,
           "failed": [{"x0": [float(v) for v in x0], "reason": why} for x0, why in lib.failed],
           "starts": [{"x0": [float(v) for v in p.x0], "T": float(p.trajectory.duration), "plan_s": p.plan_s}
                      for p in lib.plans],
           "build_s": time.perf_counter() - tic}
    if not args.json:
        print(f"Plan library of {params.mjcf}: {len(lib)} plan(s) in {path}"
              + (f" ({doc['built']} built in {doc['build_s']:.1f} s)" if args.build is not None else ""))
        for s in doc["starts"]:
            print(f"  from {[round(v, 3) for v in s['x0']]}: a {s['T']:.2f} s swing-up")
        for f in doc["failed"]:
            print(f"  no plan from {[round(v, 3) for v in f['x0']]}: {f['reason']}")
    return doc


def _key(model) -> str:
    return model_key(model)
