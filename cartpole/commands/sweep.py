"""``cartpole sweep``: robustness sweeps of the swing-up over a description (grids and seeded samples of starts, pushes,
model error and controller settings; :mod:`cartpole.apps.sweep`), one row per run, appended to a CSV results file as each
run finishes (so an interrupt or a crash keeps what finished; ``--resume`` goes on from there), on this machine's
processes or on a Dask distributed cluster, and a success map figure (with several ``--method``, also side by
side)."""
from __future__ import annotations

import argparse
from pathlib import Path

from cartpole._files import short
import cartpole.apps.sweep as sweep_app
from cartpole.apps.sweep import (
    MAX_RUNS, MAX_WORKERS, SweepError, SweepInterrupted, SweepRuns, axis, check_axes, check_settings,
    summary_line)
from cartpole.apps.sweep.plan import total_runs
from cartpole.apps.swingup import ENERGY_DURATION, MPC_DURATION, SwingupOptions, default_method, start_state
from cartpole.commands._flags import flag_words
from cartpole.commands._limits import add_limit_arguments, limit_keywords, limit_lines
from cartpole.commands._numbers import Numbers
from cartpole.commands._rig import add_budget_argument, add_rig_arguments, check_budget, loop_from_args
from cartpole.commands.swingup import check_duration, disturbance_fields
from cartpole.errors import Terminated
from cartpole.models import build_model, planning_limits, read_params
from cartpole.mpc.options import MPCOptions
from cartpole.planning.options import PlanOptions
from cartpole.sim.budget import BATCHED
from cartpole.validation.basin import DEFAULTS
from cartpole.viz.sweep_plot import plot_comparison

HELP = ("robustness sweep of the swing-up over starts, pushes, model error and controller settings (grids or "
        "seeded samples), in MuJoCo, one row per run")
DESCRIPTION = (HELP + ". Each run is `cartpole swingup` with its own start, push, model error and settings; a success "
               "swings up, holds and replays exactly. An axis option takes V (fixed), LO HI (a seeded uniform sample "
               "per run, --n of them) or LO HI K (a grid of K points); grid axes multiply. Without axis options: --n "
               "seeded starts around hanging rest. Runs on --workers processes of this machine, or on the workers of "
               "a running Dask distributed scheduler at --address tcp://HOST:PORT. Appends each finished run to "
               "sweeps/sweep_<method>.csv under --out (an interrupt keeps them; --resume skips them), then writes "
               "the success map figures/sweep_<method>.png (over the first two swept axes, or the start angle and "
               "rate); with two or more methods (--method trajopt mpc) each method's sweep, and their success maps "
               "side by side in figures/sweep_compare.png. No live view (--view is for one run, "
               "`cartpole swingup --view`).")

#: The results file and the success map under ``--out``; the side-by-side map of several methods.
RESULTS = Path("sweeps") / "sweep_{method}.csv"
FIGURE = Path("figures") / "sweep_{method}.png"
COMPARE = Path("figures") / "sweep_compare.png"
#: Runs without axes (and draws per grid cell with a sampled axis) when --n is not given.
DEFAULT_N = 20


def add_arguments(parser) -> None:
    """``--method``, ``--n``, ``--seed``, ``--workers``, ``--address``, ``--duration``, ``--jitter``, ``--resume``
    (and the hidden testing option ``--stop-after K``)."""
    add_rig_arguments(parser)
    add_budget_argument(parser)

    add_limit_arguments(parser)
    parser.add_argument("--method", nargs="+", choices=("energy", "trajopt", "mpc", "supervisor"), default=None,
                        metavar="M", help="swing-up of every run: energy (energy shaping + LQR catch), "
                                          "trajopt (collocation + TVLQR), mpc (nonlinear MPC) or supervisor (catch, "
                                          "energy law or brake and re-plan, again after every knockdown); two or "
                                          "more: the same sweep for each, and their success maps side by side; "
                                          "default the supervisor with --knockdown or --throw, else the method "
                                          "`cartpole swingup` tries first on the model: energy for one pole driven by "
                                          "the cart, else trajopt (no fall-back within a sweep)")
    parser.add_argument("--knockdown", default=None, metavar="AFTER:LENGTH[:SEED]",
                        help="every run knocked down each time its poles have been upright for AFTER s (as "
                             "`cartpole swingup --knockdown`); the table adds uptime, knockdowns and swingups")
    parser.add_argument("--throw", default=None, metavar="EVERY[:RATE[:SEED]]",
                        help="every run thrown at random times (as `cartpole swingup --throw`)")
    parser.add_argument("--n", type=int, default=None, metavar="N",
                        help=f"number of runs without axis options (default {DEFAULT_N}), or of seeded draws per "
                             f"grid cell when an axis is sampled (LO HI); at most {MAX_RUNS} runs in all")
    axis_help = "V (fixed), LO HI (seeded uniform sample) or LO HI K (grid of K points)"
    parser.add_argument("--push-force", nargs="+", type=str, default=None, metavar="F",
                        help=f"push force in N on the cart for 0.1 s (0: no push): {axis_help}")
    parser.add_argument("--push-time", nargs="+", type=str, default=None, metavar="T",
                        help=f"push start time in s (default 0.5 with --push-force): {axis_help}")
    parser.add_argument("--model-error", nargs="+", type=str, default=None, metavar="S",
                        help="scale of the planning model's pole masses and lengths (1: the MJCF's own; MuJoCo "
                             f"keeps the MJCF's): {axis_help}")
    parser.add_argument("--start", nargs="+", action="append", default=None, metavar="NAME V",
                        help="a start-state component: NAME a joint of the MJCF (its position, m or rad) or "
                             f"NAME_rate (its rate), then {axis_help}; repeatable; other components from --x0")
    parser.add_argument("--setting", nargs="+", action="append", default=None, metavar="NAME V",
                        help="a controller setting: for energy a scaling of the energy shaping (energy_gain, "
                             "overshoot, ...), for trajopt a numeric field of the planner's options (T, N, "
                             "cart_margin, ...), for mpc one of the NMPC's (horizon, ...), and for every method one "
                             "of the rig's (period, delay: rounded to whole MJCF steps; sensor_noise, encoder_cpr, "
                             "encoder_resolution, process_noise); then " + axis_help
                             + "; repeatable")
    parser.add_argument("--x0", action=Numbers, default=None, metavar="V",
                        help="with axis options: the start of every run where no --start sets a component, 2 nq "
                             "numbers [qpos, qvel] (default hanging at rest)")
    parser.add_argument("--objective", default=None, metavar="OBJ",
                        help="trajopt: what every plan optimises (as swingup's --objective); mpc: what the MPC minimises, "
                             "run by the DDP MPC (swingup's --mpc-solver ddp --objective); a dm_control task "
                             "(dmc_cartpole_swingup, dmc_cartpole_swingup_sparse, dmc_cartpole_balance, "
                             "dmc_cartpole_balance_sparse, "
                             "dmc_pendulum_swingup, dmc_acrobot_swingup, dmc_acrobot_swingup_sparse) runs its "
                             "episodes: the starts of its first N episodes seeded by --seed (numpy RandomState, as "
                             "dm_control's task_kwargs={'random': S}), each run's 'return', and their "
                             "'mean_return'")
    parser.add_argument("--horizon", type=float, default=None, metavar="S",
                        help="mpc only: every run's prediction horizon in s (swingup's --horizon)")
    parser.add_argument("--no-seed-plan", dest="seed_plan", action="store_false",
                        help="mpc only: run the DDP MPC without an offline seed plan (swingup's --no-seed-plan; "
                             "needs --objective)")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="seed of numpy's default_rng for the starts (and the jitter); default 0")
    parser.add_argument("--workers", type=int, default=1, metavar="W",
                        help=f"processes to spread the runs over, one model each (default 1, at most {MAX_WORKERS}); "
                             "the rows are the same for any W")
    parser.add_argument("--address", default=None, metavar="ADDR",
                        help="run on the Dask distributed scheduler at ADDR (tcp://host:port) instead of local "
                             "processes; one model per Dask worker; the same rows")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="simulated seconds per run (default 10 for energy, plan + 3 for trajopt)")
    parser.add_argument("--jitter", type=float, default=0.0, metavar="J",
                        help="energy only: relative jitter in [0, 1) of the energy-shaping gains per run (default 0)")
    parser.add_argument("--resume", action="store_true",
                        help="keep the runs already in the results file (the same sweep: method, N, seed, "
                             "duration, jitter, axes, x0, MJCF) and run only the others")
    parser.add_argument("--stop-after", type=int, default=None, help=argparse.SUPPRESS)  # testing: interrupt after K


def sweep_axes(args) -> tuple:
    """The sweep description of the command line's axis options, in a fixed order (``--push-force``,
    ``--model-error``, ``--push-time``, each ``--start``, each ``--setting``): the first grid axis varies slowest and
    the first two swept axes are the success map's x and y.

    Raises
    ------
    SweepError
        Bad numbers for an axis (:func:`cartpole.apps.sweep.axis`).
    """
    axes = []
    for flag, name in (("push_force", "push_force"), ("model_error", "model_error"), ("push_time", "push_time")):
        values = getattr(args, flag, None)
        if values is not None:
            axes.append(axis(name, *values))
    for flag, prefix in (("start", "start:"), ("setting", "setting:")):
        for item in getattr(args, flag, None) or []:
            if len(item) < 2:
                raise SweepError(f"--{flag} takes a name, then V, LO HI or LO HI K; got {' '.join(item)}.")
            axes.append(axis(prefix + item[0], *item[1:]))
    return tuple(axes)


def mpc_settings(args) -> dict:
    """The MPC fields every run of the sweep has from ``--horizon`` and ``--no-seed-plan`` (empty: the defaults)."""
    fixed = {} if getattr(args, "horizon", None) is None else {"horizon": float(args.horizon)}
    if not getattr(args, "seed_plan", True):
        fixed["seed_plan"] = False
    return fixed


def sweep_options(args, method: str, duration, loop):
    """The :class:`~cartpole.apps.swingup.SwingupOptions` every run of ``method``'s sweep starts from: the rig and
    disturbances ``loop`` with ``duration`` (s or None), ``--objective`` as the plan's (trajopt) or the DDP MPC's
    (mpc: the RTI NMPC tracks upright only), ``--horizon`` and ``--no-seed-plan`` as the MPC's.

    Raises
    ------
    SweepError
        ``--objective``, ``--horizon`` or ``--no-seed-plan`` with a method that has no such stage.
    """
    objective, fixed = getattr(args, "objective", None), mpc_settings(args)
    if fixed and method != "mpc":
        raise SweepError(f"--horizon and --no-seed-plan are the MPC's settings; use them with --method mpc (not "
                         f"{method}).")
    if objective is not None and method not in ("trajopt", "mpc"):
        raise SweepError(f"--objective chooses what the trajectory optimisation (or the DDP MPC) optimises; sweep it "
                         f"with --method trajopt or mpc (not {method}).")
    if method == "mpc" and not fixed.get("seed_plan", True) and objective is None:
        raise SweepError("--no-seed-plan runs the DDP MPC, which needs an objective to find the swing-up by itself; "
                         "give --objective (e.g. dmc_acrobot_swingup).")
    plan = PlanOptions(objective=objective) if method == "trajopt" and objective is not None else None
    mpc = None
    if method == "mpc" and (objective is not None or fixed):
        mpc = MPCOptions(**({} if objective is None else {"solver": "ddp", "objective": objective}), **fixed)
    return SwingupOptions(loop=loop.replace(duration=duration), plan=plan, mpc=mpc)


def _plan(args, params):
    """Validate everything before any run: the methods, n, workers, duration, axes and x0 for every method."""
    chosen = args.method
    if chosen is None and (getattr(args, "knockdown", None) is not None or getattr(args, "throw", None) is not None):
        chosen = ["supervisor"]  # knocked down: the controller that swings up again
    if chosen is None:  # the default: what `cartpole swingup` tries first on this model

        chosen = [default_method(build_model(params))]
    methods = list(dict.fromkeys(chosen if isinstance(chosen, list) else [chosen]))
    axes = sweep_axes(args)
    sampled = any(a.random for a in axes)
    if axes and not sampled and args.n is not None:
        cells = 1
        for a in axes:
            cells *= a.count
        raise SweepError(f"This sweep is a grid of {cells} run(s) and --n counts seeded draws; drop --n or give an "
                         "axis as LO HI to sample it.")
    if args.x0 is not None and not axes:
        raise SweepError("--x0 fixes the start of a sweep over axis options; without them the starts fill the start "
                         "box (give e.g. --push-force -20 20 5).")
    n = DEFAULT_N if args.n is None else args.n

    if axes and total_runs(axes, n) > MAX_RUNS:
        raise SweepError(f"This sweep description has {total_runs(axes, n)} runs, more than {MAX_RUNS}; use fewer "
                         "grid points or a smaller --n.")
    duration = check_duration(args.duration, params)
    for m in methods:
        check_settings(m, n, args.workers, args.jitter, seed=args.seed)
        # a push time checked against the run's length where it is known before any run (trajopt's is the plan's)
        ends = duration if duration is not None else {"energy": ENERGY_DURATION, "mpc": MPC_DURATION}.get(m)
        check_axes(axes, params, m, duration=ends)
    if args.stop_after is not None and args.stop_after < 1:
        raise SweepError(f"--stop-after needs at least 1 run (got {args.stop_after}).")

    model = build_model(params)
    # --x0 checked, else the hanging rest moved onto a range's edge it lies just outside (said), as every run starts
    x0, moves = start_state(args.x0, params, default=model.x_hanging)
    x0 = None if args.x0 is None else x0
    _check_work(args, model, methods, axes, n, duration)
    return methods, axes, n, duration, x0, moves


def _check_work(args, model, methods, axes, n: int, duration) -> None:
    """Every method's runs before any starts (:func:`cartpole.commands._rig.check_budget`): the runs times their
    length (``--duration``, else the method's default; 10 s for a plan's length unknown yet, as ``cartpole swingup``
    counts it), the catch basin of energy and trajopt, and a plan per trajopt run."""
    runs = total_runs(axes, n) if axes else n
    parts, plans = [], 0
    for m in methods:
        T = duration if duration is not None else (MPC_DURATION if m == "mpc" else ENERGY_DURATION)
        parts.append((runs, T, f"{runs} {m} runs of {T:g} s"))
        if m != "mpc":
            parts.append((DEFAULTS["n"], DEFAULTS["duration"], f"{m}'s basin, unless cached,", BATCHED))
        plans += runs if m == "trajopt" else (1 if m == "mpc" else 0)
    check_budget(args, model, parts, plans=plans)


def run(args) -> dict:
    """Run the sweep (one per ``--method``) and return the JSON document: for one method that of
    :func:`run_method`; for several ``mjcf``, ``methods``, ``sweeps`` (each method's document) and ``figure`` (the
    success maps side by side, :func:`cartpole.viz.sweep_plot.plot_comparison`). Library errors name this command's
    options (:func:`cartpole.commands._flags.flag_words`)."""
    with flag_words():
        return _run(args)


def _run(args) -> dict:
    """:func:`run` without the flag words."""
    params, limits = planning_limits(read_params(args.mjcf), **limit_keywords(args))  # every run plans within them
    methods, axes, n, duration, x0, moves = _plan(args, params)
    moved = [mv.to_dict() for mv in moves]
    if not args.json:
        for line in limit_lines(limits.to_dict(), moved):
            print(line)
    docs, results = [], []
    for m in methods:
        doc, result = run_method(args, params, m, axes=axes, n=n, duration=duration, x0=x0)
        doc["limits"], doc["start_moved"] = limits.to_dict(), moved
        docs.append(doc)
        results.append(result)
    if len(methods) == 1:
        return docs[0]

    figure = plot_comparison(results, params, Path(args.out) / COMPARE)
    if not args.json:
        print(f"Success maps side by side: {Path(figure).resolve()}")
    return {"mjcf": params.mjcf, "methods": methods, "sweeps": docs, "figure": str(Path(figure).resolve()),
            "limits": limits.to_dict(), "start_moved": moved}


def run_method(args, params, method: str, *, axes=(), n: int = DEFAULT_N, duration=None, x0=None):
    """Run one method's sweep on ``params`` (:func:`cartpole.apps.sweep.recorded_sweep`: each finished run appended
    to the CSV results under ``args.out``, which is then rewritten in run order, and the success map drawn), each
    run ``duration`` s (None: the method's default) from the fixed start ``x0`` (nx,) where no axis sets one; return
    ``(doc, SweepResult)``, the JSON document being: ``mjcf``, ``method``, ``n``, ``successes`` and the rest of
    :meth:`~cartpole.apps.sweep.SweepResult.summary`, ``rows`` (one per run, in run order: ``run``, ``start``,
    ``push``, ``model_error``, ``settings``, ``success``, ``replays``, ``time_to_upright``, ``caught_at``,
    ``cart_clearance``, ``peak_ctrl``, ``error``, ``failure``), ``results`` (the CSV's absolute path), ``figure``
    (the PNG's), ``sweep`` (the description's id) and ``resumed`` (runs taken from the file).

    Raises
    ------
    KeyboardInterrupt
        Interrupted: its one sentence says how many runs the results file kept and how to go on.
    """
    loop = loop_from_args(args).replace(**disturbance_fields(args))
    out = Path(args.out)
    options = sweep_options(args, method, duration, loop)
    runs = SweepRuns(n=n, seed=args.seed, axes=axes, x0=x0, gain_jitter=args.jitter)
    try:
        rec = sweep_app.recorded_sweep(params, method, options, runs=runs, workers=args.workers, address=args.address,
                             results=out / str(RESULTS).format(method=method),
                             figure=out / str(FIGURE).format(method=method), resume=args.resume,
                             stop_after=args.stop_after)
    except SweepInterrupted as stop:
        signum = stop.signum  # SIGTERM stays SIGTERM (exit status 143), Ctrl-C is KeyboardInterrupt (130)
        if stop.finished == 0 and not stop.path.exists():
            text = f"interrupted before any of the {stop.total} runs finished; nothing was written."
        else:
            again = "the same command with --resume" if not args.resume else "the same command again"
            text = (f"interrupted after {stop.finished} of {stop.total} runs, kept in {short(stop.path)}; run "
                    f"{again} to finish the others.")
        raise (KeyboardInterrupt(text) if signum is None else Terminated(signum, text)) from None
    result = rec.result
    doc = {**result.summary(), "rows": rec.rows, "results": str(rec.results.resolve()),
           "figure": str(rec.figure.resolve()), "sweep": rec.sweep, "resumed": rec.resumed,
           "loop": loop.as_dict()}
    if not args.json:
        print(summary_line(doc))
        if doc.get("uptime_mean") is not None:
            print(f"Knocked down {doc['knockdowns_total']} times in all, swung up {doc['swingups_total']} times; mean "
                  f"uptime {doc['uptime_mean']:.3f}")
        if doc.get("mean_return") is not None:
            print(f"{doc['objective']}: mean dm_control return {doc['mean_return']:.1f} over {doc['return_runs']} "
                  f"episodes of {doc['n']}")
        for r in doc["rows"]:
            t = "never" if r["time_to_upright"] is None else f"{r['time_to_upright']:.3f} s"
            start = " ".join(f"{v:+.3f}" for v in r["start"])
            scenario = "".join(f", push {F:+g} N at {T:g} s" for T, F in r["push"]) + (
                f", model error {r['model_error']:g}" if r["model_error"] != 1.0 else "") + "".join(
                f", {k} {v:g}" for k, v in r["settings"].items())
            why = f" ({r['error']})" if r["error"] else (f" ({r['failure']})" if r["failure"] else "")
            knocked = ("" if r.get("uptime") is None else
                       f", uptime {r['uptime']:.3f}, {r['knockdowns']} knockdown(s), {r['swingups']} swing-up(s)")
            print(f"  run {r['run']:3d}: start [{start}]{scenario}: {'success' if r['success'] else 'FAILED'}, "
                  f"time to upright {t}{knocked}{why}")
        if rec.resumed:
            print(f"Resumed: {rec.resumed} of {result.n} runs were already in the results file.")
        print(f"Results: {doc['results']}")
        print(f"Success map: {doc['figure']}")
    return doc, result
