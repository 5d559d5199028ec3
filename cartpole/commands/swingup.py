"""``cartpole swingup``: swing the pole up and hold it (energy shaping + LQR catch, or trajopt + TVLQR), in MuJoCo."""
from __future__ import annotations

import math
import statistics
import sys
from pathlib import Path

import cartpole.apps.swingup as swingup_app
from cartpole.apps.swingup import (
    ENERGY_DURATION, METHOD_CLASSES, MPC_DURATION, SwingupError, SwingupOptions, check_model_error, check_plan_size,
    check_push, check_upright_reachable, parse_push, plan_model_from, start_state)
from cartpole.commands._flags import as_flags, flag_words
from cartpole.commands._limits import add_limit_arguments, limit_keywords, limit_lines
from cartpole.commands._numbers import Numbers
from cartpole.commands._rig import (
    add_budget_argument, add_rig_arguments, check_budget, design_friction, friction_sentence, rig_fields,
    smoothed_friction_sentence)
from cartpole.commands._rollouts import rollout_doc
from cartpole.commands._view import add_view_arguments, live_view, web_summary
from cartpole.models import build_model
from cartpole.mpc.options import MPCOptions
from cartpole.ocp.objectives import make_objective
from cartpole.planning.options import PlanOptions
from cartpole.progress import stage
from cartpole.sim.budget import BATCHED
from cartpole.sim.disturbance import Knockdown, Throw
from cartpole.sim.options import LoopOptions
from cartpole.validation.basin import DEFAULTS
from cartpole.viz import VideoUnavailable, plot_swingup, render_video, swingup_modes
from cartpole.viz.estimation_plot import plot_estimation

HELP = ("swing the pole up and hold it upright in MuJoCo (energy shaping + LQR catch, trajopt + TVLQR, or "
        "nonlinear MPC), optionally pushed and with a wrong planning model")

#: Largest rollout log a run may hold in memory, bytes: (duration / timestep) steps, each 8 bytes for t, each of
#: the 2 nq state entries and the nu ctrl entries (256 MiB: for the shipped cart, 5 ms and nq = 2, nu = 1, about
#: 28 000 s of simulated time). Longer durations are refused before anything runs.
MAX_LOG_BYTES = 256 * 2**20


def add_arguments(parser) -> None:
    """``--method``, ``--objective``, ``--x0``, ``--duration``, ``--push``, ``--model-error``, ``--period``,
    ``--horizon``, ``--view``, ``--no-video``."""
    parser.add_argument("--method", choices=("auto", "energy", "trajopt", "mpc", "supervisor"), default="auto",
                        help="auto (default): what works for the model, tried in turn until one succeeds in MuJoCo "
                             "(energy shaping for one pole driven by the cart, else or when it fails the planner, "
                             "then the planner with --solver ddp when a plan does not hold; JSON methods_tried); "
                             "energy shaping with an LQR catch, direct collocation + TVLQR (trajopt), or nonlinear "
                             "MPC re-planning every control period (mpc); supervisor: catch, energy law or brake "
                             "and re-plan, again after every knockdown (the default with --knockdown or --throw)")
    parser.add_argument("--time-budget", type=float, default=None, metavar="S",
                        help="--method auto only: wall time in s for the methods tried (default 600): a further "
                             "method starts only while at least twice what the run before it took is left (the "
                             "method running is not interrupted)")
    parser.add_argument("--objective", default=None, metavar="OBJ",
                        help="trajopt (and mpc with --mpc-solver ddp: the MPC's running cost, its seed plan the "
                             "same; the RTI NMPC tracks upright only) : what the plan optimises: effort (default; minimum integral of "
                             "ctrl^2 over 1.2 x the minimum time), time (the minimum-time plan), tracking "
                             "(quadratic cost toward upright, 2 (1 - cos) per hinge error), a dm_control task "
                             "(dmc_cartpole_swingup (alias dmc_swingup), dmc_cartpole_swingup_sparse, "
                             "dmc_cartpole_balance, dmc_cartpole_balance_sparse, dmc_pendulum_swingup, "
                             "dmc_acrobot_swingup, "
                             "dmc_acrobot_swingup_sparse: its reward, or a smooth surrogate where sparse, maximised "
                             "over the minimum time + 1.5 s at the MJCF step; the run lasts at least the task's "
                             "episode and the JSON adds dm_control's exact 'return' over its 1000 control steps "
                             "and 'return_steps'), or MODULE:FUNCTION, a "
                             "function (x, u) -> scalar of CasADi symbols: a cost, or a reward to maximise when "
                             "wrapped with cartpole.ocp.objectives.reward")
    parser.add_argument("--x0", action=Numbers, default=None, metavar="V",
                        help="start state [qpos, qvel], 2 nq numbers in MuJoCo's joint order: every joint's "
                             "position (m or rad, 0 = upright as built), then every joint's rate; one pole: "
                             "X TH XD THD; default every pole hanging at rest (0 pi 0 0 for one pole)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="simulated seconds (default 10 for energy, plan + 3 for trajopt); the log must fit "
                             f"in {MAX_LOG_BYTES // 2**20} MiB (duration / timestep x (1 + 2 nq + nu) x 8 bytes)")
    add_budget_argument(parser)
    parser.add_argument("--push", action="append", default=None, metavar="T:F",
                        help="push the cart: a horizontal (world x) force of F newtons for 0.1 s from time T s, "
                             "through MuJoCo's xfrc_applied; repeatable; logged per physics step in the rollout's "
                             "'push', so the run replays exactly")
    parser.add_argument("--knockdown", default=None, metavar="AFTER:LENGTH[:SEED[:ENERGY]]",
                        help="knock the poles down each time they have been upright (every pole within 0.2 rad) "
                             "for AFTER s: random torques on the hinges, stronger than the motor, seeded, for at most "
                             "LENGTH s and at most ENERGY (default 1) times a random 0.5-1 of the model's swing-up "
                             "energy of work; "
                             "logged per physics step in the rollout's 'qfrc_applied', so the run replays exactly; "
                             "the JSON adds uptime, knockdowns and swingups; runs the supervisor by default")
    parser.add_argument("--throw", default=None, metavar="EVERY[:RATE[:SEED]]",
                        help="throw the state at random times whatever it is doing: every EVERY s on average, a "
                             "one-step impulse changing each hinge's rate by up to RATE rad/s (default 10), seeded")
    parser.add_argument("--model-error", type=float, default=None, metavar="S",
                        help="scale the planning model's pole masses and lengths by S (e.g. 1.2: 20 %% heavier and "
                             "longer); the controller is designed on that model, MuJoCo keeps the MJCF's")
    parser.add_argument("--plan-mjcf", default=None, metavar="PATH",
                        help="design the controller (plan, catch, TVLQR, NMPC) on this MJCF, e.g. one fitted by "
                             "`cartpole identify`, while MuJoCo runs --mjcf (the same joints, actuators and step)")
    parser.add_argument("--horizon", type=float, default=None, metavar="S",
                        help="mpc only: prediction horizon in s (default the controller's, 1.2 s)")
    parser.add_argument("--solver", choices=("auto", "ipopt", "fatrop", "sqp", "ddp"), default=None,
                        help="trajopt (and auto's planner) only: solver of the plan's last stage: auto (default: the collocation SQP for "
                             "every objective and for the minimum-time refinement before it; the coarse multi-start "
                             "stays IPOPT's), ipopt (every stage), fatrop, sqp (as auto) or ddp (box-DDP on the exact "
                             "discrete step, every objective; time by a search over T); IPOPT takes over when it does "
                             "not converge")
    parser.add_argument("--T-max", type=float, default=None, metavar="S", dest="T_max",
                        help="trajopt (and mpc's offline plan): the longest swing-up in s the pumping search tries "
                             "when no direct swing-up is found (default 40)")
    parser.add_argument("--search-s", type=float, default=None, metavar="S", dest="search_s",
                        help="trajopt (and mpc's offline plan): wall-time budget in s of that pumping search "
                             "(default 180; inf: none, the same search on any machine at any load)")
    parser.add_argument("--mpc-solver", choices=("rti", "ddp"), default=None,
                        help="mpc only: real-time iteration on the condensed QP (rti, the default) or warm-started "
                             "box-DDP on the exact held model (ddp)")
    parser.add_argument("--no-seed-plan", dest="seed_plan", action="store_false",
                        help="mpc with --mpc-solver ddp only: plan nothing offline; the MPC finds the swing-up "
                             "itself in the loop (as MuJoCo MPC does), its first solution converged from u*")
    add_rig_arguments(parser, period_help="control period in s, a whole number of MJCF steps (default one step; "
                      "mpc: the controller's, 0.02 s): the ctrl is held in between, the catch, TVLQR and NMPC are "
                      "designed for it")
    parser.add_argument("--ctrl-noise", type=float, default=None, metavar="FRACTION",
                        help="energy, trajopt and supervisor: design the catch (its R) and the estimator (its "
                             "process noise) so that the ctrl's standard deviation the sensors' noise and quantisation cause in the "
                             "hold, predicted from the loop at upright, stays below FRACTION of the ctrl range (needs "
                             "sensors and an estimator); default with sensors 0.02, the quietest design when none "
                             "holds; JSON ctrl_noise with the measured figure beside the predicted one")
    add_limit_arguments(parser)
    add_view_arguments(parser, "show the run live, in real time, as it is logged (desktop without a display: a "
                               "one-line note on stderr and the rest as usual)")
    parser.add_argument("--no-video", action="store_true", help="do not render videos/swingup_<method>.mp4")


def _marks(res) -> dict | None:
    """A knocked or thrown run's knockdowns, swing-ups and the supervisor's catches for the figure, else None."""
    m = res.metrics
    if "uptime" not in m:
        return None
    info = res.rollout.info if isinstance(res.rollout.info, dict) else {}
    decisions = (m.get("supervisor") or {}).get("decisions") or []
    return {"knockdowns": info.get("disturbances") or [], "swingups": m.get("swingup_times") or [],
            "catches": [d["t"] for d in decisions if d.get("kind") == "catch"]}


def disturbance_fields(args) -> dict:
    """``knockdown`` and ``throw`` of :class:`~cartpole.sim.options.LoopOptions` from ``--knockdown`` and ``--throw``
    (only those given)."""
    out = {}
    if getattr(args, "knockdown", None) is not None:
        out["knockdown"] = Knockdown.parse(args.knockdown)
    if getattr(args, "throw", None) is not None:
        out["throw"] = Throw.parse(args.throw)
    return out


def search_fields(args) -> dict:
    """``T_max`` and ``search_s`` of :class:`~cartpole.planning.options.PlanOptions` from ``--T-max`` and
    ``--search-s`` (only those given; ``--search-s inf`` is ``search_s=None``, no wall-time budget)."""
    fields = {k: getattr(args, k) for k in ("T_max", "search_s") if getattr(args, k, None) is not None}
    if fields.get("search_s") == math.inf:
        fields["search_s"] = None
    return fields


def methods_sentence(tried) -> str:
    """The prose line saying which methods the default tried, how each ended and whose run is shown (the last that
    ran): ``tried`` is :attr:`~cartpole.apps.swingup.SwingupResult.methods_tried`."""
    ran = [t.label for t in tried if t.outcome in ("success", "failed")]
    parts = []
    for t in tried:
        took = f" after {t.seconds:.0f} s" if t.outcome in ("success", "failed", "error") else ""
        parts.append(f"{t.label}: {t.outcome}{took}" + (f" ({t.reason})" if t.reason else ""))
    text = f"Methods tried (--method auto): {'; '.join(parts)}." + (f" Shown: the {ran[-1]} run." if ran else "")
    return as_flags(text)


def log_bytes(duration: float, params) -> float:
    """Bytes of the rollout log of ``duration`` s on ``params``: steps x (1 + 2 nq + nu) float64 (t, qpos, qvel,
    ctrl)."""
    steps = float(duration) / float(params.timestep)
    return steps * 8.0 * (1 + 2 * params.nq + params.nu)


def check_duration(duration, params, *, flag: str = "--duration") -> float | None:
    """``duration`` (s) if it is a positive finite number whose log fits in :data:`MAX_LOG_BYTES`, None if None.

    Raises
    ------
    SwingupError
        Not positive or not finite; or too long to hold (the sentence gives the largest duration accepted).
    """
    if duration is None:
        return None
    if not (math.isfinite(duration) and duration > 0):
        raise SwingupError(f"Duration {duration} s is not a positive number of seconds; give e.g. {flag} 8.")
    if log_bytes(duration, params) > MAX_LOG_BYTES:
        longest = MAX_LOG_BYTES / log_bytes(1.0, params)
        raise SwingupError(f"{flag} {duration:g} s is too long to hold in memory ({log_bytes(duration, params) / 2**20:.3g} "
                           f"MiB of log at the {params.timestep:g} s time step, more than "
                           f"{MAX_LOG_BYTES // 2**20} MiB); give at most {longest:.0f} s.")
    return float(duration)


def check_log_size(seconds: float, params, *, what: str) -> None:
    """Refuse, before anything runs, a command whose rollout logs (``seconds`` of simulated time in all, every run
    it keeps counted) exceed :data:`MAX_LOG_BYTES` at the MJCF's time step; ``what`` names those runs in the
    sentence (``"the lab's 5 runs of 6 s and its 10 s video clip"``).

    Raises
    ------
    SwingupError
        Too much log to hold (the sentence gives the time step that would fit).
    """
    need = log_bytes(seconds, params)
    if need > MAX_LOG_BYTES:
        step = float(params.timestep) * need / MAX_LOG_BYTES
        raise SwingupError(f"At the MJCF's {params.timestep:g} s time step {what} ({seconds:g} s simulated) log "
                           f"{need / 2**20:.3g} MiB, more than the {MAX_LOG_BYTES // 2**20} MiB limit; give the MJCF "
                           f"a time step of at least {step:.2g} s.")


class _Stages:
    """:func:`cartpole.apps.swingup.run_swingup`'s ``progress(stage, fraction)`` as :mod:`cartpole.progress` stages.

    The basin estimate reports itself (it is a stage of its own); ``trajopt`` and ``simulate`` open a stage on their
    first fraction and end it at 1.
    """

    LABELS = {"trajopt": "trajectory optimisation", "mpc": "NMPC set-up", "simulate": "MuJoCo rollout"}

    def __init__(self, sizes: dict | None = None):
        self.open = {}
        self.done = set()
        self.sizes = sizes or {}

    def __call__(self, name: str, fraction: float) -> None:
        if name not in self.LABELS:
            return
        st = self.open.get(name)
        if st is None:
            if fraction >= 1.0 and name in self.done:  # the closing 1.0 of a stage that reached 1 already
                return
            st = self.open[name] = stage(self.LABELS[name], size=self.sizes.get(name, ""))
            self.done.discard(name)
        st(fraction)
        if fraction >= 1.0:
            st.close()
            del self.open[name]
            self.done.add(name)


def _check_work(args, model, duration) -> None:
    """The swing-up's MuJoCo steps before it starts (:func:`cartpole.commands._rig.check_budget`): the run
    (``--duration``, else the method's default, 10 s for a plan's length unknown yet) and, for energy and trajopt,
    the catch basin's sampled runs (counted though a cached estimate costs none)."""
    T = duration if duration is not None else (MPC_DURATION if args.method == "mpc" else ENERGY_DURATION)
    parts = [(1, T, f"the {T:g} s run")]
    if args.method != "mpc":  # the catch basin's sampled runs
        parts.append((DEFAULTS["n"], DEFAULTS["duration"], "basin, unless cached,",
                      BATCHED))
    check_budget(args, model, parts, plans=0 if args.method == "energy" else 1)  # auto may plan after energy


def run(args) -> dict:
    """Validate the input, run the swing-up, write the figure (and video) and return the JSON document. Library
    errors name this command's options (:func:`cartpole.commands._flags.flag_words`)."""
    with flag_words():
        return _run(args)


def _run(args) -> dict:
    """:func:`run` without the flag words: everything validated before anything is computed or written."""
    model = build_model(args.mjcf)
    check_upright_reachable(model)
    model.contacts.check_swingup()  # a pair that touches on the way up: refused, named, before anything runs
    check_plan_size(model, args.method)
    x0 = start_state(args.x0, model.params, default=model.x_hanging)[0]
    duration = check_duration(args.duration, model.params)
    _check_work(args, model, duration)
    options, plan_model = swingup_options(args, model, duration)
    res = _swing_up(args, model, options, None if args.x0 is None else x0, plan_model)
    files = _write_files(args, res, model)
    doc = swingup_document(args, res, model, options, plan_model, files)
    if not args.json:
        _print_outcome(doc, res, model, x0, plan_model)
        _print_details(doc, res, files)
    return doc


def swingup_options(args, model, duration) -> tuple:
    """``(SwingupOptions, plan_model)`` from the command line: the loop (rig, ``--duration``, ``--period``,
    pushes, model error, disturbances), the planner's options (trajopt, auto with ``--objective`` or ``--solver``,
    the MPC's offline plan with ``--T-max``/``--search-s``), the MPC's, the bounds, the time budget and the
    ctrl-noise limit; the planning model of ``--plan-mjcf`` (or None).

    Raises
    ------
    SwingupError
        An option given to a method that does not have it, or a bad number, in the command line's words.
    """
    params = model.params
    push = check_push([parse_push(text) for text in (getattr(args, "push", None) or [])], params)
    model_error = check_model_error(getattr(args, "model_error", None))
    plan_mjcf = getattr(args, "plan_mjcf", None)
    plan_model = None
    if plan_mjcf is not None:
        if model_error != 1.0:
            raise SwingupError("--plan-mjcf and --model-error both choose the planning model; give one of them.")
        plan_model = plan_model_from(plan_mjcf, model)
    period, horizon = getattr(args, "period", None), getattr(args, "horizon", None)
    for flag, v in (("--period", period), ("--horizon", horizon)):
        if v is not None and args.method != "mpc" and flag == "--horizon":
            raise SwingupError(f"{flag} sets the NMPC's prediction horizon; use it with --method mpc.")
        if v is not None and not (math.isfinite(v) and v > 0):
            raise SwingupError(f"{flag} {v:g} s is not a positive number of seconds; give e.g. {flag} 0.02.")
    loop = LoopOptions(**{**rig_fields(args), "duration": duration, "period": period, "push": push,
                          "model_error": model_error, **disturbance_fields(args)})
    plan, mpc = _stage_options(args, model)
    time_budget = getattr(args, "time_budget", None)
    if time_budget is not None:
        if args.method != "auto":
            raise SwingupError("--time-budget bounds the tries of the default method; use it without --method (or "
                               "with --method auto).")
        if not (math.isfinite(time_budget) and time_budget > 0):
            raise SwingupError(f"--time-budget {time_budget:g} s is not a positive number of seconds; give e.g. "
                               "--time-budget 600.")
    options = SwingupOptions(plan=plan, loop=loop, mpc=mpc, time_budget=time_budget, ctrl_noise=args.ctrl_noise,
                             **limit_keywords(args))
    return options, plan_model


def _stage_options(args, model) -> tuple:
    """``(plan, mpc)``: the planner's and the MPC's options of ``--objective``, ``--solver``, ``--T-max``,
    ``--search-s``, ``--horizon``, ``--mpc-solver`` and ``--no-seed-plan``, each refused with a method that has no
    such stage."""
    objective = getattr(args, "objective", None)
    if objective is not None:
        if args.method not in ("auto", "trajopt", "mpc"):
            raise SwingupError("--objective chooses what the trajectory optimisation (or the MPC) optimises; use "
                               "it with --method trajopt or mpc.")
        make_objective(model, objective)  # a bad name or MODULE:FUNCTION ends here, before anything runs
    solver = getattr(args, "solver", None)
    plan = mpc = None
    if args.method == "trajopt" or (args.method == "auto" and (objective is not None or solver is not None)):
        plan = PlanOptions(objective=objective, **({} if solver is None else {"solver": solver}), **search_fields(args))
    elif solver is not None:
        raise SwingupError("--solver picks the trajectory optimisation's solver; use it with --method trajopt.")
    horizon = getattr(args, "horizon", None)
    if args.method == "mpc":
        mpc = MPCOptions(**({} if horizon is None else {"horizon": horizon}),
                         **({} if args.mpc_solver is None else {"solver": args.mpc_solver}),
                         **({} if objective is None else {"objective": objective}),
                         **({} if getattr(args, "seed_plan", True) else {"seed_plan": False}))
        if search_fields(args):  # the offline plan's search, at the MPC's own cart margin
            plan = PlanOptions(cart_margin=mpc.cart_margin, **search_fields(args))
    elif getattr(args, "mpc_solver", None) is not None:
        raise SwingupError("--mpc-solver picks the MPC's solver; use it with --method mpc.")
    if args.method == "energy" and search_fields(args):
        raise SwingupError("--T-max and --search-s set the planner's pumping search; use them with --method trajopt "
                           "or mpc.")
    if args.method != "mpc" and not getattr(args, "seed_plan", True):
        raise SwingupError("--no-seed-plan runs the DDP MPC without an offline plan; use it with --method mpc "
                           "--mpc-solver ddp.")
    return plan, mpc


def _swing_up(args, model, options, x0, plan_model):
    """The swing-up (:func:`cartpole.apps.swingup.run_swingup`) with the command's progress stages and live view."""
    duration = options.loop.duration
    default = METHOD_CLASSES[args.method].duration if args.method in ("energy", "mpc") else None
    sizes = {"simulate": f"{duration:g} s"} if duration is not None else (
        {"simulate": f"{default:g} s"} if default is not None else {})
    viewer = live_view("swingup", args)
    try:
        res = swingup_app.run_swingup(model, args.method, options, x0=x0, progress=_Stages(sizes), on_step=viewer,
                          plan_model=plan_model)
        if viewer is not None:
            viewer.finish()
    finally:
        if viewer is not None:
            viewer.close()
    return res, viewer


def _write_files(args, ran, model) -> dict:
    """The swing-up figure, the estimation figure (with an estimator) and the video (unless ``--no-video``):
    ``{"figure": Path, "estimation_figure": str or None, "video": video or None, "viewer": viewer}``."""
    res, viewer = ran
    params, out, method = model.params, Path(args.out), res.method
    marks = _marks(res)
    title = f"Swing-up ({method}) in MuJoCo: {'success' if res.success else 'FAILED'}"
    if marks is not None:  # knocked or thrown: how often, and how much of the run was upright
        m = res.metrics
        title = (f"{method} in MuJoCo: knocked {m['knockdowns']} times, {m['swingups']} swing-ups, uptime "
                 f"{m['uptime']:.2f}")
    fig = plot_swingup(res.rollout, params, out / "figures" / f"swingup_{method}.png", plan=res.plan,
                       caught_at=res.caught_at, handover_at=res.handover_at, model=model, marks=marks, title=title)
    est_fig = None
    if res.metrics.get("estimation"):
        est_fig = str(plot_estimation(res.rollout, params, out / "figures" / f"swingup_{method}_estimation.png",
                                      title=f"Swing-up ({method}): {res.metrics['estimation']['estimator']} "
                                            "estimate against MuJoCo").resolve())
    video = None
    if not args.no_video:
        seconds = float(res.rollout.t[-1])
        try:
            with stage("video", size=f"{seconds:g} s at 30 fps") as tick:
                video = render_video(params, res.rollout, out / "videos" / f"swingup_{method}.mp4",
                                     progress=tick, modes=swingup_modes(res), model=model)
        except VideoUnavailable as exc:
            print(f"cartpole swingup: no video ({exc})", file=sys.stderr)
    return {"figure": fig, "estimation_figure": est_fig, "video": video, "viewer": viewer, "result": res}


def swingup_document(args, ran, model, options, plan_model, files: dict) -> dict:
    """The JSON document of a swing-up (the fixed contract of ``cartpole swingup --json``, extended)."""
    res, viewer = ran
    params, m, method = model.params, res.metrics, res.method
    video = files["video"]
    doc = {"mjcf": params.mjcf, "method": method, "success": res.success, "caught_at": res.caught_at,
           "handover_at": res.handover_at,
           "methods_tried": [{**t.as_dict(), "reason": as_flags(t.reason)} for t in res.methods_tried],
           "diverged": bool(m["diverged"]), "diverged_at": m["diverged_at"], "rollout": rollout_doc(res.rollout),
           "time_to_upright": m["time_to_upright"], "figure": str(files["figure"].resolve()),
           "video": None if video is None else str(Path(video).resolve()),
           "metrics": {k: v for k, v in m.items()}, "basin": None if res.basin is None else res.basin.summary()}
    doc["model"] = {"contacts": model.contacts.to_dict()}
    doc["push"] = [list(p) for p in res.push]
    doc["rig"] = m.get("rig")
    doc["friction"] = m.get("friction")
    doc["smoothed_friction"] = design_friction(model, doc["friction"])
    doc["estimation"] = m.get("estimation")
    doc["estimation_figure"] = files["estimation_figure"]
    if method != "mpc":
        doc["period"] = params.timestep if options.loop.period is None else options.loop.period
    doc["model_error"] = res.model_error
    doc["limits"], doc["start_moved"] = m.get("limits"), m.get("start_moved", [])
    for key in ("ctrl_noise", "supervisor"):
        if key in m:
            doc[key] = m[key]
    if "uptime" in m:  # knocked down or thrown
        for key in ("uptime", "upright_band", "knockdowns", "swingups", "swingup_times", "recoveries",
                    "unrecovered_at"):
            doc[key] = m[key]
    doc["plan_mjcf"] = None if plan_model is None else plan_model.params.mjcf
    if method == "mpc":
        ctrl = res.controller
        doc["solve_ms"] = [float(v) for v in getattr(ctrl, "solve_ms", [])]
        doc["period"], doc["horizon"] = float(ctrl.period), float(ctrl.horizon)
        doc["failures"] = m.get("failures", 0)
    if method in ("mpc", "trajopt"):
        doc["objective"] = m.get("objective")
        if method == "trajopt":
            doc["plan"] = m.get("plan")
        if "return" in m:
            doc["return"], doc["return_steps"] = m["return"], m["return_steps"]
    if args.view:
        doc["viewer"] = None if viewer is None else {
            "frames": viewer.frames, "closed_early": viewer.closed, "wall_time": viewer.wall_time,
            "steps_shown": len(res.rollout.ctrl), **web_summary(viewer)}
    # the settings each stage ran with (PlanOptions, LoopOptions, MPCOptions .as_dict())
    doc["options"] = {name: opts.as_dict() for name, opts in res.options.items()}
    return doc


def _print_outcome(doc: dict, ran, model, x0, plan_model) -> None:
    """The prose lines of the outcome: the scenario and success, contacts, divergence, limits, methods tried, the
    catch, uptime and the supervisor."""
    res, _ = ran
    m, method = res.metrics, res.method
    print(f"MJCF: {model.params.mjcf}")
    scenario = "".join(f", pushed {F:+g} N at {T:g} s" for T, F in res.push) + (
        f", planning model's poles scaled by {res.model_error:g}" if res.model_error != 1.0 else "") + (
        f", designed on {plan_model.params.mjcf}" if plan_model is not None else "")
    print(f"Swing-up ({method}) from x0 = {list(map(float, x0))}{scenario}: "
          f"{'SUCCESS' if res.success else 'FAILED'} (upright and at rest for the last 1 s, cart off its "
          "limits, ctrl in range, no contact)")
    print(model.contacts.summary())
    if m.get("contact"):
        c = m["contact"]
        print(f"CONTACT: MuJoCo found geoms '{c['geom1']}' and '{c['geom2']}' touching at t = {c['t']:.3f} s "
              f"({c['steps']} step(s) in contact); the run is not a clean swing-up")
    if m["diverged"]:
        print(f"DIVERGED: MuJoCo warned that the simulation blew up ({m['diverged_warning']}) at "
              f"t = {m['diverged_at']:.3f} s and reset the state; the run stopped there")
    for line in limit_lines(doc["limits"], doc["start_moved"]):
        print(line)
    if len(res.methods_tried) > 1:
        print(methods_sentence(res.methods_tried))
    if res.caught_at is not None:
        catch = f"Caught at: {res.caught_at:.3f} s (handed over to the catch then; it held)"
    elif res.handover_at is not None:
        catch = f"Caught at: never (handed over to the catch at {res.handover_at:.3f} s; it did not hold)"
    else:
        catch = "Caught at: never (no hand-over to the catch)"
    upright = "never" if m["time_to_upright"] is None else f"{m['time_to_upright']:.3f} s"
    print(f"{catch}; time to upright (every |theta_i| < 0.05 rad for good): {upright}")
    if "uptime" in doc:
        print(f"Uptime: {doc['uptime']:.1%} of the run with every pole within {doc['upright_band']:g} rad of "
              f"upright; {doc['knockdowns']} knockdown(s), {doc['swingups']} swing-up(s) held 1 s, "
              f"{doc['recoveries']} knockdown(s) followed by a swing-up"
              + ("" if not doc["unrecovered_at"] else
                 f" (not after the one(s) at {', '.join(f'{t:.2f}' for t in doc['unrecovered_at'])} s)") + ".")
    if "supervisor" in doc:
        sv = doc["supervisor"]
        print(f"Supervisor: {sv['plans']} plan(s), {sv['plan_failures']} failed"
              + (f", planning {min(sv['plan_s']):.2f}-{max(sv['plan_s']):.2f} s each" if sv["plan_s"] else "")
              + f"; {len(sv['decisions'])} decisions (catch, swing-up law, brake, plan, track) in the JSON.")


def _print_details(doc: dict, ran, files: dict) -> None:
    """The prose lines of the details: ctrl and cart, the rig, friction, estimation, the ctrl-noise design, the
    basin, the NMPC's solve times, the plan, a dm_control return, the live view and the files."""
    res, viewer = ran
    m = res.metrics
    print(f"Peak |ctrl|: {m['peak_ctrl']:.3f}; cart range used: [{m['cart_min']:.3f}, {m['cart_max']:.3f}] m "
          f"(closest to a limit: {m['cart_clearance']:.3f} m)")
    if doc["rig"] is not None:
        r = doc["rig"]
        print(f"Rig: control period {r['period']:g} s, delay {r['delay']:g} s"
              f"{'' if r['delay_compensation'] else ' (not compensated)'}, estimator {r['estimator']}")
    if doc["friction"] is not None:
        print(friction_sentence(doc["friction"]))
    if doc["smoothed_friction"]:
        print(smoothed_friction_sentence(doc["smoothed_friction"], what="the swing-up's design model"))
    if doc["estimation"]:
        est = doc["estimation"]
        rms = ", ".join(f"{k} {v:.3g}" for k, v in est["rms_error"].items())
        print(f"Estimation error ({est['estimator']}, RMS over {est['samples']} control instants): {rms}; "
              f"{est['estimate_ms']['median']:.3f} ms a step (median)")
    if doc.get("ctrl_noise"):
        print(_ctrl_noise_sentence(doc["ctrl_noise"]))
    if res.basin is not None:
        print(f"Catch basin: e' S e < rho = {res.basin.rho:.4f} ({res.basin.n} MuJoCo samples, seed "
              f"{res.basin.seed}, safety factor {res.basin.safety_factor})")
    if res.method == "mpc" and doc["solve_ms"]:
        print(f"NMPC: period {doc['period']:g} s, horizon {doc['horizon']:g} s; solve per control step median "
              f"{statistics.median(doc['solve_ms']):.2f} ms, max {max(doc['solve_ms']):.2f} ms, "
              f"{doc['failures']} failure(s)")
    if m.get("plan"):
        pl = m["plan"]
        least = "" if pl["T_min"] is None else f" (minimum time {pl['T_min']:.3f} s)"
        print(f"Plan: T = {pl['T']:.3f} s{least}, {pl['solver']} {pl['status']}, guess '{pl['guess']}' won; "
              f"{len(pl['attempts'])} solver call(s), {pl['total_iterations']} iterations, {pl['plan_time_s']:.2f} s")
    if "return" in m:
        print(f"dm_control return (smooth swing-up reward): {m['return']:.1f} over {m['return_steps']} "
              "control steps")
    if viewer is not None:
        print(f"Live view: the run stepped in MuJoCo's viewer in real time ({viewer.frames} frames in "
              f"{viewer.wall_time:.1f} s{', window closed early' if viewer.closed else ''}); it is the run logged")
    video = files["video"]
    print(f"Figure: {files['figure']}")
    print(f"Video: {video.summary() if video is not None else 'not written'}")


def _ctrl_noise_sentence(cn: dict) -> str:
    """The prose line of the catch's ctrl-noise design (JSON ``ctrl_noise``)."""
    pn = "its default" if cn["process_noise"] is None else f"{cn['process_noise']:g}"
    measured = ("no hold to measure" if cn["measured_fraction"] is None else
                f"measured {', '.join(f'{100 * v:.2g} %' for v in cn['measured_fraction'])} over the last "
                f"{cn['measured_window_s']:.3g} s")
    return (f"Catch designed for the sensors (ctrl noise below {100 * cn['fraction']:g} % of the range"
            f"{'' if cn['met'] else ': not reached, the quietest design'}): R x {cn['factor']:g}, estimator "
            f"process noise {pn}; ctrl noise predicted "
            f"{', '.join(f'{100 * v:.2g} %' for v in cn['predicted_fraction'])}, {measured}")
