"""``cartpole bench``: trajectory-optimisation, TVLQR and batched-replay speed, measured in one run."""
from __future__ import annotations

import math
from pathlib import Path

import cartpole.apps.bench.trajopt as bench_trajopt
from cartpole.apps.bench.crocoddyl import crocoddyl_benchmark, print_crocoddyl
from cartpole.apps.bench.estimation import estimation_benchmark, print_estimation_table
from cartpole.apps.bench.export import export_benchmark, print_export_table
from cartpole.apps.bench.identify import identify_benchmark, print_identify_table
from cartpole.apps.bench.objectives import OBJECTIVES, objective_benchmark, print_objective_table
from cartpole.apps.bench.plan_library import plan_library_benchmark, print_plan_library_table
from cartpole.apps.bench.planner_stage import STAGE_OBJECTIVES, planner_stage_benchmark, print_planner_stage_table
from cartpole.apps.bench.mpc import mpc_benchmark, print_mpc_table
from cartpole.apps.bench.trajopt import plan_benchmark, print_plan_table, print_table, shipped_plan_models
from cartpole.apps.swingup import ENERGY_DURATION
from cartpole.commands._limits import add_limit_arguments, limit_keywords, limit_lines
from cartpole.commands._rig import add_budget_argument, check_budget
from cartpole.errors import CartPoleError
from cartpole.models import build_model
from cartpole.progress import stage
from cartpole.sim.budget import BATCHED

HELP = ("time the swing-up collocation solve (ours vs naive casadi.Opti baselines), TVLQR synthesis, batched "
        "MuJoCo replay, the swing-up plan on 1, 2 and 3 poles and NMPC in the loop")

#: bench prints its figures and writes no files, so it takes no --out (an old --out is accepted and ignored).
WRITES_FILES = False


#: Most timed repeats a benchmark runs (medians settle long before).
MAX_REPEATS = 100


def add_arguments(parser) -> None:
    """``--quick`` (fewer repeats and rollouts, for tests), ``--repeats``, ``--no-replay``."""
    parser.add_argument("--quick", action="store_true",
                        help="few repeats and a small replay batch (smoke test; figures are not for publishing)")
    parser.add_argument("--repeats", type=int, default=None, metavar="K",
                        help="timed solves per method, medians reported (default 7; --quick 2)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="the standard problem's duration T in s (default 2; the three-pole cart needs at least "
                             "its minimum time, 2.3 s)")
    parser.add_argument("--no-replay", action="store_true", help="skip the batched replay benchmark")
    parser.add_argument("--no-plan", action="store_true",
                        help="skip the swing-up plan times (default: the shipped 1-, 2- and 3-pole carts, or the "
                             "--mjcf given; --quick: one pole, one plan)")
    parser.add_argument("--no-mpc", action="store_true", help="skip the NMPC-in-the-loop benchmark")

    add_limit_arguments(parser)  # the swing-up plans on --mjcf (the standard problem keeps its own fixed bounds)

    add_budget_argument(parser)
    parser.add_argument("--no-crocoddyl", action="store_true",
                        help="skip Crocoddyl's double-pendulum example (our DDP, and Crocoddyl's FDDP when installed)")
    parser.add_argument("--no-objectives", action="store_true",
                        help="skip the default planner on every objective of the standard problem against the naive "
                             "script with that objective (--quick: effort and time only)")
    parser.add_argument("--no-planner-stage", action="store_true",
                        help="skip the planner's stages (from its minimum-time plan: effort, tracking, time, "
                             "dm_control's cart-pole rewards) on the shipped 1-, 2- and 3-pole carts, or the --mjcf "
                             "given, against the naive script (--quick: one pole, effort and time)")
    parser.add_argument("--no-library", action="store_true",
                        help="skip the plan library's rows: plans warm-started from the nearest stored plan against "
                             "cold ones from the same starts (the shipped 1- and 2-pole carts and the acrobot, or the "
                             "--mjcf given; --quick: one pole, one start)")
    parser.add_argument("--no-identify", action="store_true",
                        help="skip the system-identification fit times (one- and two-pole carts, IPOPT beside)")


class _Steps:
    """The benchmark's ``progress(message)`` (one message as each measurement starts) as progress stages: each
    message ends the previous stage and opens the next (``bench: baseline (Opti, no expand): 7 solves in 1.4 s``)."""

    def __init__(self):
        self.current = None

    def __call__(self, message: str) -> None:
        self.close()
        self.current = stage(message.rstrip(" .").rstrip())
        self.current(0.0)

    def close(self) -> None:
        if self.current is not None:
            self.current.close()
            self.current = None


def _check_work(args, repeats: int) -> None:
    """The benchmark's MuJoCo steps on ``--mjcf`` before it starts (:func:`cartpole.commands._rig.check_budget`): the
    batched replay (its rollouts of 2 s each repeat), the NMPC runs (4 s each, three without ``--quick``), the
    swing-up plans' runs (each at most 10 s, as ``cartpole swingup`` counts a plan's run before its length is known)
    and their plans. The other parts (the standard problem's solves, Crocoddyl, identification, the export) run the
    shipped carts, whatever the file."""
    model = build_model(args.mjcf)
    parts = []
    if not args.no_replay:
        rollouts, reps = (16, 1) if args.quick else (256, repeats)
        parts.append((rollouts * reps, 2.0, f"replay of {rollouts} x {reps} rollouts", BATCHED))
    if not args.no_mpc and len(model.hinges) == 1:
        parts.append((1 if args.quick else 3, 4.0, "NMPC runs"))
    plans = 0
    if not args.no_plan and args.mjcf is not None:
        plans = 1 if args.quick else 3
        parts.append((plans, ENERGY_DURATION, "swing-up runs, at most,"))
    check_budget(args, model, parts, plans=plans)


def run(args) -> dict:
    """Run :func:`cartpole.apps.bench.trajopt.run` on ``args.mjcf``; print a table unless ``--json``."""
    repeats = args.repeats if args.repeats is not None else (2 if args.quick else 7)
    if repeats < 1:
        raise CartPoleError(f"--repeats {repeats} is not positive; give at least 1 (5 or more to publish).")
    if repeats > MAX_REPEATS:
        raise CartPoleError(f"--repeats {repeats} is more than the {MAX_REPEATS} limit (each repeat solves every "
                            "benchmark again); give at most that, 7 is the default.")
    T = 2.0 if args.duration is None else float(args.duration)
    if not (math.isfinite(T) and 0.1 <= T <= 60.0):
        raise CartPoleError(f"--duration {args.duration} is not a duration from 0.1 to 60 s; give one (2 is the "
                            "standard problem's).")
    _check_work(args, repeats)
    steps = _Steps()
    doc = bench_trajopt.run(args.mjcf, T=T, repeats=repeats, replay=not args.no_replay,
                    replay_repeats=1 if args.quick else repeats, replay_rollouts=16 if args.quick else 256,
                    progress=steps)

    doc["trajopt"]["objectives"] = None
    if not args.no_objectives:
        names = ("effort", "time") if args.quick else OBJECTIVES
        doc["trajopt"]["objectives"] = objective_benchmark(args.mjcf, objectives=names, T=T, repeats=repeats,
                                                           progress=steps)
    doc["trajopt"]["planner_stage"] = None
    if not args.no_planner_stage:
        stage_models = [(Path(args.mjcf).stem, args.mjcf)] if args.mjcf is not None else (
            shipped_plan_models()[:1] if args.quick else None)
        stage_objectives = ("effort", "time") if args.quick else STAGE_OBJECTIVES
        doc["trajopt"]["planner_stage"] = planner_stage_benchmark(stage_models, objectives=stage_objectives,
                                                                  repeats=repeats, progress=steps)
    doc["plan"] = None
    if not args.no_plan:
        if args.mjcf is not None:
            models = [(Path(args.mjcf).stem, args.mjcf)]
        else:
            models = shipped_plan_models()[:1] if args.quick else shipped_plan_models()
        doc["plan"] = plan_benchmark(models, repeats=1 if args.quick else 3, command=not args.quick,
                                     progress=steps, **limit_keywords(args))
    doc["plan_library"] = None
    if not args.no_library:
        lib_models = [(Path(args.mjcf).stem, args.mjcf)] if args.mjcf is not None else (
            [("1 pole", shipped_plan_models()[0][1])] if args.quick else None)
        doc["plan_library"] = plan_library_benchmark(lib_models, angles=1 if args.quick else 3,
                                                     probes=1 if args.quick else 3, progress=steps)
    doc["mpc"] = None if args.no_mpc else mpc_benchmark(args.mjcf, quick=args.quick, progress=steps,
                                                        **limit_keywords(args))

    doc["estimation"] = estimation_benchmark(args.mjcf, quick=args.quick)

    doc["crocoddyl"] = None if args.no_crocoddyl else crocoddyl_benchmark(repeats=1 if args.quick else repeats)
    doc["identify"] = None
    if not args.no_identify:
        doc["identify"] = identify_benchmark(quick=args.quick)

    doc["export"] = export_benchmark(args.mjcf, quick=args.quick)
    steps.close()
    doc["quick"] = bool(args.quick)
    if not args.json:
        print_table(doc)
        if doc["trajopt"]["objectives"]:
            print_objective_table(doc["trajopt"]["objectives"])
        if doc["trajopt"]["planner_stage"]:
            print_planner_stage_table(doc["trajopt"]["planner_stage"])
        if doc["plan"]:
            print_plan_table(doc["plan"])
        if doc["plan_library"]:
            print_plan_library_table(doc["plan_library"])
        if doc["mpc"]:
            print_mpc_table(doc["mpc"])

        said = [line for part in [*(doc["plan"] or []), doc["mpc"] or {}] for line in limit_lines(part.get("limits"))]
        for line in dict.fromkeys(said):  # the defaults the swing-up plans on --mjcf used, each once
            print(line)
        print_estimation_table(doc["estimation"])
        if doc["crocoddyl"]:
            print_crocoddyl(doc["crocoddyl"])
        if doc["identify"]:
            print_identify_table(doc["identify"])
        print_export_table(doc["export"])
    return doc
