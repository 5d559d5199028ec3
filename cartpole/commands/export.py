"""``cartpole export``: a controller and its estimator as standalone C99 (static memory, a Makefile, an example),
and with ``--verify`` its proof in the MuJoCo loop beside the Python controller."""
from __future__ import annotations

import math

import cartpole.apps.export as export_app
from cartpole.apps.export import VERIFY_DURATION
from cartpole.apps.swingup import MPC_DURATION, TRAJOPT_EXTRA
from cartpole.commands._limits import add_limit_arguments, limit_keywords, limit_lines
from cartpole.commands._numbers import Numbers
from cartpole.commands._rig import add_budget_argument, add_rig_arguments, check_budget, loop_from_args
from cartpole.commands._view import add_view_arguments, show_runs, view_mode
from cartpole.errors import CartPoleError
from cartpole.export import CONTROLLERS
from cartpole.models import build_model
from cartpole.planning.options import PlanOptions
from cartpole.sim.budget import BATCHED
from cartpole.validation.basin import DEFAULTS

HELP = ("write a controller (and its estimator) as standalone C99 for a rig or a microcontroller; --verify drives "
        "MuJoCo with it beside the Python controller")


def add_arguments(parser) -> None:
    """``--controller``, ``--float32``, ``--x0``, ``--verify``, ``--duration``, ``--mcu``, ``--max-steps`` and the
    rig's options."""
    parser.add_argument("--controller", choices=tuple(CONTROLLERS), default="lqr",
                        help="the law to export: lqr (balance, default), pid (cascaded PID balance), tvlqr "
                             "(trajopt swing-up + TVLQR + LQR catch), energy (energy shaping + LQR catch), nmpc "
                             "(real-time-iteration NMPC swing-up at its own 20 ms period)")
    parser.add_argument("--float32", action="store_true",
                        help="write the single-precision build (cp_real is float; for a Cortex-M4F's FPU); "
                             "default double")
    parser.add_argument("--x0", action=Numbers, default=None, metavar="V",
                        help="start state [qpos, qvel] of the verification run (and the swing-up's plan); default "
                             "the lab's first start for a balance, the hanging rest for a swing-up")
    parser.add_argument("--verify", action="store_true",
                        help="compile the double and the float build with -std=c99 -Wall -Wextra -Werror -pedantic, "
                             "load them through ctypes and drive MuJoCo with each beside the Python controller: C "
                             "ctrl = Python ctrl to 1e-9 (double), the run succeeds (both), it replays exactly")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="seconds of each verification run (default what the Python path runs: 5 for a balance, "
                             "10 for energy, the plan + 3 for tvlqr)")
    parser.add_argument("--mcu", action="store_true",
                        help="also compile the float32 build for a Cortex-M4F (arm-none-eabi-gcc -mcpu=cortex-m4 "
                             "-mfpu=fpv4-sp-d16 -mfloat-abi=hard -Os) and report its flash, RAM (arm-none-eabi-size) "
                             "and worst stack (-fstack-usage, -fcallgraph-info)")

    add_limit_arguments(parser)
    add_budget_argument(parser)

    add_view_arguments(parser, "with --verify: show the C build's MuJoCo runs live (double, then float32), in real "
                               "time, replayed from their logs (desktop without a display: a note on stderr and the "
                               "rest as usual)")
    add_rig_arguments(parser, period_help="control period in s, a whole number of MJCF steps (default one step): "
                      "CP_PERIOD, the period cp_step must be called at; the controller is designed for it")


def _check_work(args) -> None:
    """The export's MuJoCo steps before it starts (:func:`cartpole.commands._rig.check_budget`): with ``--verify`` two
    runs (double and float builds) of ``--duration`` s, else of the Python path's length (a plan's known only after
    it: at most the planner's longest plus the catch's hold); energy's catch basin; the swing-up's plan."""
    parts = []
    if args.verify:
        T = {"nmpc": MPC_DURATION, "tvlqr": PlanOptions().T_max + TRAJOPT_EXTRA}.get(
            args.controller, VERIFY_DURATION[CONTROLLERS.get(args.controller, "balance")])
        if args.duration is not None and math.isfinite(args.duration) and args.duration > 0:
            T = args.duration
        parts.append((2, T, f"2 verification runs of {'at most ' if args.duration is None else ''}{T:g} s"))
    if args.controller == "energy":
        parts.append((DEFAULTS["n"], DEFAULTS["duration"], "basin, unless cached,", BATCHED))
    check_budget(args, build_model(args.mjcf), parts, plans=int(args.controller in ("tvlqr", "nmpc")))


def run(args) -> dict:
    """Export (and verify); prose: the folder, its files and the verification's figures."""
    if getattr(args, "view", None) and not args.verify:
        raise CartPoleError("--view shows the C build's MuJoCo runs, which only --verify runs; add --verify, or drop "
                            "--view.")
    view = view_mode(args, "export")
    loop = loop_from_args(args)
    _check_work(args)
    runs: list = []
    options = export_app.ExportOptions(float32=args.float32, verify=args.verify, duration=args.duration, mcu=args.mcu,
                                       **limit_keywords(args))
    doc = export_app.run_export(args.mjcf, args.controller, options, loop=loop, x0=args.x0, out=args.out, runs=runs)
    if view and runs:
        show_runs(runs[0][0], [r for _, r in runs], view, args, command="export")
    if not args.json:
        for line in limit_lines(doc.get("limits"), doc.get("start_moved")):
            print(line)
        exp = doc["export"]
        print(f"Exported {doc['controller']} (estimator {doc['estimator']}, {doc['real']}, period {doc['period']:g} s, "
              f"delay {doc['delay']:g} s) to {doc['folder']}: {len(exp['files'])} files, {exp['bytes']} bytes.")
        print(f"Build it: make -C {doc['folder']}   (shared library: make -C {doc['folder']} shared)")
        if args.verify:
            print(f"Verified in MuJoCo: {'yes' if exp['verified'] else 'NO'}; max |C - Python| ctrl "
                  f"{exp['max_ctrl_diff']:.3g} (double), float32 run "
                  f"{'succeeded' if exp['float32']['success'] else 'FAILED'}; C step median "
                  f"{exp['step_us']['median']:.2f} us, max {exp['step_us']['max']:.2f} us (through ctypes).")
        if args.mcu:
            m = exp["mcu"]
            print(f"Cortex-M4F float32 build: flash {m['flash']} B, RAM {m['ram']} B, worst stack {m['stack']} B "
                  f"({' -> '.join(m['stack_chain'])}).")
    return doc
