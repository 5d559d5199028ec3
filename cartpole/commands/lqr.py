"""``cartpole lqr``: the LQR balance lab with its true numbers, figure, video and metrics row (the file names are
the lab's, :mod:`cartpole.apps.lab`)."""
from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

import cartpole.apps.lab as lab
from cartpole._files import check_replaceable
from cartpole.apps.lab import (ESTIMATION_FIGURE, FIGURE, LAB_DURATION, METRICS, PID_FIGURE, START_SCALES, VIDEO,
                               compare_pid, lab_friction, view_first_run)
from cartpole.apps.metrics_csv import append_metrics, metrics_row
from cartpole.apps.swingup import plan_model_from
from cartpole.commands._flags import as_flags
from cartpole.commands._margins import add_margins_argument, ctrl_noise_weights, run_margins
from cartpole.commands._numbers import Numbers
from cartpole.commands._rig import (add_budget_argument, add_rig_arguments, check_budget, friction_sentence,
                                    loop_from_args, rig_doc, smoothed_friction_sentence)
from cartpole.commands._state import state_labels, state_sentence
from cartpole.commands._view import add_view_arguments, live_sentence, view_mode, view_web as _view_web
from cartpole.commands.swingup import check_duration, check_log_size
from cartpole.control.friction import friction_summary
from cartpole.control.pid import PIDError
from cartpole.errors import CartPoleError
from cartpole.models import ContactReport, build_model
from cartpole.progress import stage
from cartpole.sim import simulate
from cartpole.viz import VideoUnavailable, plot_lab, render_video
from cartpole.viz.estimation_plot import plot_estimation
from cartpole.viz.lab_plot import plot_pid_vs_lqr
from cartpole.viz.margin_plot import plot_margin
from cartpole.viz.viewer import ViewerUnavailable, watch

HELP = ("the LQR balance lab: K, settling times from 5 initial conditions in MuJoCo, figure, 10 s video "
        "and a metrics row")

DELAY_MARGIN_FIGURE = Path("figures") / "delay_margin.png"
NOISE_MARGIN_FIGURE = Path("figures") / "noise_margin.png"
VIDEO_SECONDS = 10.0


def add_arguments(parser) -> None:
    """``--no-video``, ``--duration``, ``--max-steps``, ``--discrete``, ``--Q``, ``--R``, ``--compare-pid`` and
    ``--view``."""
    parser.add_argument("--no-video", action="store_true", help="skip rendering the 10 s video")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="seconds each of the five MuJoCo runs lasts (default 6, the handout's): a model whose "
                             "closed loop is slow needs longer to settle")
    add_budget_argument(parser)
    parser.add_argument("--compare-pid", action="store_true",
                        help="also run the cascaded PID baseline (cartpole.control.pid) from the same five starts "
                             "in MuJoCo and print one table and one figure of both (one pole on a cart only; "
                             "elsewhere a note on stderr and the LQR lab as usual)")
    add_view_arguments(parser, "show the first start's LQR run live (desktop: the run logged is the run shown; web: a "
                               "live run of its own, pushed and tuned from the page, in the JSON's live)",
                       live_seconds=True)
    parser.add_argument("--plan-mjcf", default=None, metavar="PATH",
                        help="design K on this MJCF (e.g. one fitted by `cartpole identify`) while MuJoCo runs "
                             "--mjcf (the same joints, actuators and step)")
    parser.add_argument("--discrete", action="store_true",
                        help="design K with dlqr on (Ad, Bd), one step of the MJCF's integrator, instead of "
                             "lqr on the continuous (A, B)")
    parser.add_argument("--Q", action=Numbers, default=None, metavar="V",
                        help="state weights: 2 nq numbers (the diagonal, in the state's order) or (2 nq)^2 (the "
                             "matrix, row by row); default 1 per slide, 10 per hinge angle, 0.1 per rate (the "
                             "lab's 1 10 0.1 0.1 for one pole)")
    parser.add_argument("--R", action=Numbers, default=None, metavar="V",
                        help="ctrl weights: nu numbers (the diagonal) or nu^2 (the matrix); default 0.1 per input")
    add_rig_arguments(parser)
    parser.add_argument("--delay-margin", type=float, default=None, metavar="MAX",
                        help="instead of one lab: the largest delay (whole MJCF steps up to MAX s) at which the lab's "
                             "LQR (and with --compare-pid the PID) still balances all five starts on this rig; "
                             "prints it and writes figures/delay_margin.png")
    parser.add_argument("--noise-margin", type=float, default=None, metavar="MAX",
                        help="instead of one lab: the largest sensor noise (std in m or rad; 0 and MAX halved nine "
                             "times to MAX) at which the LQR through the estimator (default kf; with --compare-pid "
                             "also the PID on the measurements) still balances all five starts on this rig; prints "
                             "it and writes figures/noise_margin.png")
    add_margins_argument(parser)


#: Largest magnitude of a --Q or --R entry (and 1 / it the smallest nonzero one): far outside it SciPy's Riccati solver
#: overflows or loses every digit.
MAX_WEIGHT = 1e12


def weight_matrix(values, n: int, flag: str, order: str) -> np.ndarray:
    """``--Q``/``--R`` numbers as an (n, n) matrix: n numbers are the diagonal, n*n the matrix row by row.

    Raises
    ------
    CartPoleError
        Any other count, naming the two counts accepted and the order of the entries; an entry beyond
        :data:`MAX_WEIGHT` in magnitude, or a nonzero one below its inverse.
    """
    v = np.asarray(values, dtype=float)
    if v.size not in (n, n * n):
        raise CartPoleError(f"{flag} has {v.size} number(s); give {n} (the diagonal, for {order}) or {n * n} "
                            "(the whole matrix, row by row).")
    big = v[np.isfinite(v)]
    if big.size and np.abs(big).max() > MAX_WEIGHT:
        raise CartPoleError(f"{flag} holds {np.abs(big).max():g}, beyond the {MAX_WEIGHT:g} limit of a weight (the "
                            "Riccati equation overflows long before); scale the weights down together, only their "
                            "ratios matter.")
    nonzero = np.abs(big[big != 0])
    if nonzero.size and nonzero.min() < 1.0 / MAX_WEIGHT:
        raise CartPoleError(f"{flag} holds {nonzero.min():g}, below the {1.0 / MAX_WEIGHT:g} limit of a nonzero "
                            "weight; scale the weights up together (only their ratios matter) or give 0.")
    return np.diag(v) if v.size == n else v.reshape(n, n)


class _Inputs(NamedTuple):
    """What ``cartpole lqr`` checked before any work: the model, the weights, the run length and the rig."""
    model: object
    Q: object
    R: object
    duration: float
    loop: object


def _checked_inputs(args) -> _Inputs:
    """The model, weights, duration and rig of ``args``, and the work they ask for checked against the budget (one
    sentence on bad input, before anything runs)."""
    model = build_model(args.mjcf)
    names = state_labels(model.params)
    Q = None if args.Q is None else weight_matrix(args.Q, model.nx, "--Q", "x = [" + ", ".join(names) + "]")
    R = None if args.R is None else weight_matrix(
        args.R, model.nu, "--R", "u = [" + ", ".join(a.name for a in model.params.actuators) + "]")

    duration = LAB_DURATION if args.duration is None else check_duration(args.duration, model.params)
    loop = loop_from_args(args, **({} if args.duration is None else {"duration": duration}))
    runs = 5 * (2 if args.compare_pid else 1)  # every start's rollout is kept (and the PID's beside)
    clip = 0.0 if args.no_video else VIDEO_SECONDS
    check_log_size(runs * duration + clip, model.params,
                   what=f"the lab's {runs} runs of {duration:g} s" + (f" and its {clip:g} s video clip" if clip
                                                                    else ""))
    # the work, before any: the runs kept, the start-scale search's (up to len(START_SCALES) sets of five at the
    # lab's 6 s), and the video clip; a model too ill-conditioned to simulate or design on is refused here too
    search = 5 * (len(START_SCALES) - (1 if duration == LAB_DURATION else 0)) * LAB_DURATION
    check_budget(args, model, [(runs, duration, f"{runs} lab runs"), (1, search, "start search, at most,"),
                               (1, clip, "video")])
    if args.delay_margin is not None and args.noise_margin is not None:
        raise CartPoleError("--delay-margin and --noise-margin are two searches; give one at a time.")
    return _Inputs(model, Q, R, duration, loop)


def run(args) -> dict:
    """Run the lab on ``args.mjcf``, write its outputs under ``args.out`` and return the JSON document."""
    # Everything that can fail on bad input happens before the first file is written.
    model, Q, R, duration, loop = _checked_inputs(args)
    if args.margins or args.margins_mujoco:
        return run_margins(args, model, loop, Q, R)
    for key in MARGINS:
        if getattr(args, key) is not None:
            return _margin(args, model, loop, key)

    check_replaceable(Path(args.out) / METRICS)  # a read-only metrics.csv is refused before the lab runs
    plan_model = None
    if getattr(args, "plan_mjcf", None) is not None:
        plan_model = plan_model_from(args.plan_mjcf, model)
    R, ctrl_noise = ctrl_noise_weights(args, model, loop, Q, R)
    view = view_mode(args, "lqr")
    if view == "web":
        check_log_size(args.live_seconds, model.params, what=f"the live run of {args.live_seconds:g} s")
    result = lab.run_lab(model, Q=Q, R=R, discrete=args.discrete, loop=loop, plan_model=plan_model, duration=duration)
    live = None
    if view == "desktop":
        result = _view(result)
    pid = skipped = None
    if args.compare_pid:
        try:
            pid = compare_pid(result, model)
        except PIDError as exc:
            skipped = str(exc)
            print(f"cartpole lqr: --compare-pid skipped: {skipped}", file=sys.stderr)
    if view == "web":  # after the PID's lab, which then runs live after the LQR
        live = _view_web(result, args, pid=pid)
    files = _write_outputs(args, result, model, pid)
    doc = _lab_doc(result, model, plan_model, files)
    if args.compare_pid:
        doc["pid"] = {"skipped": skipped} if pid is None else _pid_doc(pid, files["pid_figure"])
    if ctrl_noise is not None:
        doc["ctrl_noise"] = ctrl_noise
    if live is not None:
        doc["live"] = live
    if not args.json:
        _print_prose(result, doc, pid)
        if live is not None:
            print(live_sentence(live))
    return doc


def _write_outputs(args, result, model, pid) -> dict:
    """The lab's files under ``args.out``: the figure, the estimator's and the PID's figures when there are
    those, the video (unless ``--no-video``; a missing GL backend is a note on stderr) and the metrics row.
    Returns their paths (``figure``, ``estimation_figure``, ``pid_figure``, ``video``, ``metrics``) and
    ``video_render_s``."""
    out = Path(args.out)
    figure = plot_lab(result, out / FIGURE).resolve()
    est_figure = None
    if result.estimation is not None:
        est_figure = str(plot_estimation(result.rollouts[0], result.params, out / ESTIMATION_FIGURE,
                                         title=f"IC 1: {result.rig.estimator} estimate against MuJoCo").resolve())
    pid_figure = None
    if pid is not None:
        pid_figure = plot_pid_vs_lqr(result, pid, out / PID_FIGURE).resolve()
    video = video_render_s = None
    if not args.no_video:
        clip = simulate(result.params, result.controller(), result.x0s[0], VIDEO_SECONDS,
                        rig=None if result.rig is None else result.rig.for_run(0))
        try:
            with stage("video", size=f"{VIDEO_SECONDS:g} s at 30 fps") as tick:
                info = render_video(result.params, clip, out / VIDEO, progress=tick, modes=[(0.0, "LQR")],
                                    model=model)
            video, video_render_s = info.resolve(), float(info.render_s)
        except VideoUnavailable as exc:
            print(f"cartpole lqr: no video: {as_flags(str(exc))}", file=sys.stderr)

    metrics = append_metrics(out / METRICS, metrics_row(result)).resolve()
    return {"figure": figure, "estimation_figure": est_figure, "pid_figure": pid_figure, "video": video,
            "video_render_s": video_render_s, "metrics": metrics}


def _lab_doc(result, model, plan_model, files: dict) -> dict:
    """The JSON document of a lab run (without its ``pid``, ``ctrl_noise`` and ``live`` parts)."""
    return {
        "mjcf": result.mjcf,
        "plan_mjcf": None if plan_model is None else plan_model.params.mjcf,
        "discrete": result.discrete,
        "A": result.A, "B": result.B,
        "Q": result.Q, "R": result.R,
        "K": result.K,
        "closed_loop_eigenvalues": {"real": result.E.real, "imag": result.E.imag},
        "x_eq": result.x_eq,
        "u_eq": result.u_eq,
        "initial_conditions": result.x0s,
        "start_scale": result.start_scale,
        "duration": result.duration,
        "settling_times_seed": result.settling_times_seed,
        "settling_times": result.settling_times,
        "settling_definition": ("settling_times_seed: t of the sample after the last with some |theta_i - theta_i*| "
                                "> 0.05 rad (every hinge, wrapped); settling_times: first t after which every "
                                "entry of x - x* (hinges wrapped) stays within 0.01 (m, rad, m/s, rad/s) to the "
                                "end; null = never"),
        "mean_settling_time_seed": result.mean_settling_time_seed,
        "std_settling_time_seed": result.std_settling_time_seed,
        "settled": list(result.settled),
        "counted": list(result.counted),
        "not_settled": [None if w is None else w.to_dict() for w in result.not_settled],
        "slowest_time_constant_s": result.slowest_time_constant,
        "start_scale_reason": result.start_scale_reason,
        "diverged": [m.diverged for m in result.metrics],
        "diverged_at": [m.diverged_at for m in result.metrics],
        "rollouts": [_rollout_dict(r) for r in result.rollouts],
        "peak_ctrl": result.peak_ctrl,
        "cart_excursion": result.cart_excursion,
        "residual_error": result.residual_error,
        "saturation_fraction": [m.saturation_fraction for m in result.metrics],
        "track_margin": [m.track_margin for m in result.metrics],
        "figure": str(files["figure"]),
        "video": None if files["video"] is None else str(files["video"]),
        "video_render_s": files["video_render_s"],
        "metrics": str(files["metrics"]),
        **rig_doc(result.rig, result.period),
        "friction": friction_summary(result.params, result.friction_compensation),
        "smoothed_friction": lab_friction(model, result.friction_compensation),
        "estimation": result.estimation,
        "estimation_figure": files["estimation_figure"],
        "model": {"contacts": model.contacts.to_dict()},
    }


class _Margin(NamedTuple):
    setting: str       # the LoopOptions field searched
    figure: Path       # under --out
    what: str          # in sentences
    unit: str
    zero_ok: bool      # 0 is a value to search from (a delay), else the largest value must be > 0
    example: float     # for the refusal's "give e.g."
    search: str        # the cartpole.apps.lab function
    limit: str         # its keyword for the largest value


#: ``--delay-margin`` / ``--noise-margin``, by JSON key.
MARGINS = {"delay_margin": _Margin("delay", DELAY_MARGIN_FIGURE, "a delay", "s", True, 0.1, "delay_margin",
                                   "max_delay"),
           "noise_margin": _Margin("sensor_noise", NOISE_MARGIN_FIGURE, "a sensor noise", "m or rad", False, 0.01,
                                   "noise_margin", "max_noise")}


def _margin(args, model, loop, key: str) -> dict:
    """``--delay-margin MAX`` or ``--noise-margin MAX``: JSON ``mjcf``, ``period`` (s), ``rig`` (the rest of the
    rig), ``delay_margin`` or ``noise_margin`` (:func:`cartpole.apps.lab.rig_margin`: ``lqr``,
    ``lqr_first_failure``, ``lqr_runs`` and the ``pid`` ones with ``--compare-pid``), ``figure``."""
    spec = MARGINS[key]
    setting, path, what, unit = spec.setting, spec.figure, spec.what, spec.unit
    flag = "--" + key.replace("_", "-")
    top = getattr(args, key)
    if not (math.isfinite(top) and (top >= 0 if spec.zero_ok else top > 0)):
        raise CartPoleError(f"{flag} {top:g} is not {what} in {unit} {'>=' if spec.zero_ok else '>'} 0; "
                            f"give e.g. {flag} {spec.example}.")
    if setting == "sensor_noise" and loop.estimator_for("balance") == "none":
        loop = loop.replace(estimator="kf")  # noise on the sensors needs an estimator between them and the LQR
    search = getattr(lab, spec.search)
    limit = {spec.limit: top}
    with stage(key.replace("_", " "), size=f"{setting.replace('_', ' ')} up to {top:g} {unit}") as tick:
        found = search(model, loop=loop, pid=args.compare_pid, progress=tick, **limit)
    period = model.dt if loop.period is None else loop.period
    figure = plot_margin(found, Path(args.out) / path)
    doc = {"mjcf": model.params.mjcf, "period": float(period), "rig": loop.as_dict(), key: found,
           "figure": str(figure.resolve())}
    if not args.json:
        for name in ("lqr", "pid"):
            if name in found:
                m, f = found[name], found[f"{name}_first_failure"]
                print(f"{name.upper()}: balances all five starts up to {what} of "
                      f"{'none at all' if m is None else f'{m:g} {unit}'}"
                      + (f"; fails at {f:g} {unit}" if f is not None else f" (every value tried, to {top:g} {unit})"))
        print(f"Wrote {doc['figure']}")
    return doc


def _contacts_line(doc) -> str:
    """The prose line about the file's contacts (its pairs by reachability) and any run that touched."""
    line = ContactReport.sentence(doc["model"]["contacts"])
    touched = [i for i, r in enumerate(doc["rollouts"], 1) if r.get("contact")]
    if touched:
        line += f" MuJoCo found contacts in the run(s) from IC {', '.join(map(str, touched))}."
    return line


def _rollout_dict(run) -> dict:
    """A rollout in the swing-up's JSON contract: ``t``, ``qpos``, ``qvel``, ``ctrl`` and ``push`` (zeros: the lab
    pushes nothing), so it replays with ``mj_step``; ``contact`` (MuJoCo's first contact) only when the run touched."""
    d = run.to_dict()
    d.setdefault("push", [0.0] * int(run.ctrl.shape[0]))
    contact = run.info.get("contact") if isinstance(run.info, dict) else None
    if contact is not None:  # only a run that touched has the key
        d["contact"] = contact
    return d


def _pid_doc(pid, figure) -> dict:
    """The JSON ``pid`` object: the LQR side's keys for the PID runs, its gains and its figure."""
    return {
        "gains": pid.gains.to_dict(),
        "initial_conditions": pid.x0s,
        "duration": pid.duration,
        "settling_times_seed": pid.settling_times_seed,
        "settling_times": pid.settling_times,
        "mean_settling_time_seed": pid.mean_settling_time_seed,
        "std_settling_time_seed": pid.std_settling_time_seed,
        "settled": list(pid.settled),
        "diverged": [m.diverged for m in pid.metrics],
        "diverged_at": [m.diverged_at for m in pid.metrics],
        "peak_ctrl": pid.peak_ctrl,
        "cart_excursion": pid.cart_excursion,
        "saturation_fraction": [m.saturation_fraction for m in pid.metrics],
        "track_margin": [m.track_margin for m in pid.metrics],
        "rollouts": [_rollout_dict(r) for r in pid.rollouts],
        "figure": str(figure),
    }


def _view(result):
    """``--view``: the first start's LQR run shown live (:func:`cartpole.viz.viewer.watch`) and logged as shown
    (:func:`cartpole.apps.lab.view_first_run`); without a display, the viewer's sentence on stderr and ``result``
    unchanged."""
    try:
        result, shown = view_first_run(result, watch)
    except ViewerUnavailable as exc:
        print(f"cartpole lqr: {as_flags(str(exc))}", file=sys.stderr)
        return result
    if shown.info.get("closed_early"):
        print(f"cartpole lqr: the viewer was closed at t = {shown.t[-1]:.2f} s; the logged run of IC 1 is the "
              "full run, of which the window showed the first part (checked identical).", file=sys.stderr)
    return result


def _start_text(result, x0) -> str:
    """``theta0 = 5.00 deg, x0 = +0.00 m`` for one start: the first pole's angle from upright (named by its joint
    for a chain) and the cart's position."""
    p = result.params
    parts = []
    if p.hinges:
        h = p.hinges[0]
        which = "theta0" if len(p.hinges) == 1 else f"{p.joints[h].name}"
        parts.append(f"{which} = {np.rad2deg(x0[h] - result.x_eq[h]):6.2f} deg")
    if p.slide is not None:
        parts.append(f"x0 = {x0[p.slide]:+.2f} m")
    return ", ".join(parts)


def _rig_sentence(rig) -> str:
    """One line: the rig the runs had (period, delay, estimator, sensors)."""
    comp = "predicted over the delay" if rig.compensate else "not compensated"
    text = f"Rig: control period {rig.period:g} s, delay {rig.delay:g} s ({comp}), estimator {rig.estimator}"
    if rig.spec is not None:
        parts = []
        for s in rig.spec.sensors:
            q = f", {s.resolution:.3g} {s.units} a count" if s.resolution else ""
            n = f", noise {s.noise_std:.3g}" if s.noise_std else ""
            parts.append(f"{s.name} ({s.kind}{q}{n})")
        text += "; sensors " + "; ".join(parts)
    return text + "."


def _print_prose(result, doc, pid=None) -> None:
    q = ", ".join(f"{v:g}" for v in np.diag(result.Q))
    r = ", ".join(f"{v:g}" for v in np.diag(result.R))
    steps = int(round(result.period / result.params.timestep)) if result.period else 1
    if steps > 1:
        kind = f"dlqr on (Ad, Bd) over the {result.period:g} s control period, {steps} MJCF steps with the ctrl held"
    else:
        kind = "dlqr on (Ad, Bd), one MJCF integrator step" if result.discrete else "lqr on the continuous (A, B)"
    p = result.params
    with np.printoptions(precision=4, suppress=True, linewidth=100):
        print(f"MJCF: {result.mjcf}")
        print(state_sentence(p))
        print(_contacts_line(doc))
        print("Upright equilibrium: x* =", result.x_eq, " u* =", result.u_eq)
        print("Linearized system at upright rest (exact, symbolic): d(x - x*)/dt = A (x - x*) + B (u - u*)")
        print("A =\n", result.A)
        print("B =\n", result.B)
        off = "" if np.count_nonzero(result.Q - np.diag(np.diag(result.Q))) == 0 else " (plus off-diagonal terms)"
        print(f"LQR ({kind}), Q = diag({q}){off}, R = diag({r}), law u = u* - K (x - x*):")
        print("K =", result.K)
        print("Closed-loop eigenvalues:", result.E)
        print(_time_constant_sentence(result))
        if result.rig is not None:
            print(_rig_sentence(result.rig))
        if doc["friction"] is not None:
            print(friction_sentence(doc["friction"], smooth=False))
        smoothed = smoothed_friction_sentence(doc.get("smoothed_friction") or [], what="the LQR design")
        if smoothed:
            print(smoothed)
        if result.start_scale != 1.0:
            why = f" ({result.start_scale_reason})" if result.start_scale_reason else ""
            print(f"The lab's starts are too large for this model's ctrl limit{why}: all five are scaled "
                  f"by {result.start_scale:g}, the largest of 1, 1/2, 1/4, ... at which the ctrl limit keeps no start "
                  "from settling under the lab's own LQR (cartpole.apps.lab.lab_start_scale).")
        what = ("offsets from x* on the first pole's angle and the cart, the other poles at x*, at rest"
                if len(p.hinges) > 1 else "offsets from x* on the pole's angle and the cart, at rest")
        print(f"Settling from {len(result.x0s)} initial conditions ({what}), {result.duration:g} s each in MuJoCo "
              "(handout's definition: every |theta_i - theta_i*| stays <= 0.05 rad; strict: whole state within "
              "0.01 of x*):")
        for i, (x0, ts, st, counted, why) in enumerate(zip(result.x0s, doc["settling_times_seed"],
                                                          doc["settling_times"], result.counted,
                                                          result.not_settled), 1):
            seed = f"settling time {ts:.2f} s" if counted else "inside the 0.05 rad band from the start (not counted)"
            print(f"  IC {i}: {_start_text(result, x0)}: {seed}, strict {st:.2f} s, "
                  f"{'settled' if why is None else _not_settled_text(result, why)}")
    print(_mean_sentence(result))
    longer = _longer_run(result)
    if longer is not None:
        print(longer)
    if doc.get("estimation"):
        est = doc["estimation"]
        rms = ", ".join(f"{k} {v:.3g}" for k, v in est["rms_error"].items())
        print(f"Estimation error ({est['estimator']}, RMS over {est['samples']} control instants): {rms}; "
              f"{est['estimate_ms']['median']:.3f} ms a step (median)")
    if pid is not None:
        _print_pid_table(result, pid)
    print(f"Wrote {doc['figure']}")
    if doc.get("estimation_figure"):
        print(f"Wrote {doc['estimation_figure']}")
    if pid is not None:
        print(f"Wrote {doc['pid']['figure']}")
    if doc["video"]:
        print(f"Wrote {doc['video']} (rendered in {doc['video_render_s']:.1f} s)")
    print(f"Appended a row to {doc['metrics']}")


def _time_constant_sentence(result) -> str:
    """The slowest closed-loop time constant and the run's length in those units."""
    tau = result.slowest_time_constant
    if not np.isfinite(tau):
        return "Slowest closed-loop time constant: none finite (a mode on the stability boundary)."
    return (f"Slowest closed-loop time constant: {tau:.3g} s (1 / the smallest decay rate of the eigenvalues); each "
            f"run lasts {result.duration:g} s, {result.duration / tau:.3g} of them.")


def _not_settled_text(result, why) -> str:
    """``NOT settled: ...``: the reason of one start (:class:`cartpole.apps.lab.NotSettled`) and by how much."""
    labels = state_labels(result.params)
    left = (f"|theta - theta*| {why.final_angle_error:.3g} rad at the end, the largest error {why.final_error:.3g} "
            f"on {labels[why.final_error_state]}")
    if why.reason == "slow":
        t = why.linear_settling_time
        need = f"needs {t:.3g} s" if np.isfinite(t) else "does not settle within 30 time constants either"
        return (f"NOT settled in {result.duration:g} s ({left}): the run is too short, the LQR's own linear loop "
                f"{need} from this start")
    if why.reason == "ctrl_limit":
        return (f"NOT settled ({left}): the ctrl limit, the ctrl at its limit {100 * why.saturation_fraction:.0f} % "
                "of the run")
    if why.reason == "cart_limit":
        return f"NOT settled ({left}): the cart reached the end of its rail"
    if why.reason == "diverged":
        return "NOT settled: MuJoCo's simulation blew up"
    return f"NOT settled ({left}): the error does not decay (friction, a model error, the rig's sensors or delay)"


def _mean_sentence(result) -> str:
    """``Mean settling time: ...`` over the counted starts only (none counted: said so, no number)."""
    n = sum(result.counted)
    skipped = len(result.x0s) - n
    if n == 0:
        return (f"Mean settling time: none: all {len(result.x0s)} starts begin inside the 0.05 rad band, where the "
                "handout's settling time is 0 whatever the controller does, so none is counted.")
    out = f" ({skipped} more inside the 0.05 rad band from the start, not counted)" if skipped else ""
    return (f"Mean settling time: {result.mean_settling_time_seed:.2f} s ± {result.std_settling_time_seed:.2f} s "
            f"across {n} initial conditions{out}")


def _longer_run(result) -> str | None:
    """The advice for starts the run was too short to settle: ``--duration`` with a length that would."""
    slow = [w for w in result.not_settled if w is not None and w.reason == "slow"]
    if not slow:
        return None
    tau = result.slowest_time_constant
    need = max(w.linear_settling_time for w in slow)
    if np.isfinite(need):
        give = float(np.ceil(1.2 * need))
        return (f"{len(slow)} start(s) did not settle because the closed loop's slowest time constant, {tau:.3g} s, "
                f"is long for a {result.duration:g} s run; give a longer run: --duration {give:g}.")
    return (f"{len(slow)} start(s) did not settle because the closed loop's slowest time constant, {tau:.3g} s, is "
            f"long for a {result.duration:g} s run; give a longer run with --duration, or heavier --Q weights for "
            "a faster loop.")


#: Rows of the PID-beside-LQR table: attribute of LabResult / PIDLabResult, label, number format.
PID_TABLE_ROWS = (
    ("settling_times_seed", "settling time, handout (s)", "{:.3f}"),
    ("settling_times", "settling time, strict (s)", "{:.3f}"),
    ("peak_ctrl", "peak |ctrl|", "{:.3f}"),
    ("cart_excursion", "cart excursion (m)", "{:.3f}"),
)


def _print_pid_table(lqr, pid) -> None:
    """One table of both controllers: a row per metric and controller, a column per start and the mean."""
    g = pid.gains
    n = len(lqr.rollouts)
    print(f"PID beside LQR: the same {n} starts, {lqr.duration:g} s each in MuJoCo, the PID reset for each.")
    print(f"  cascaded PID (cartpole.control.pid.tune_pid): kp = {g.kp:.4g}, ki = {g.ki:.4g}, kd = {g.kd:.4g}, "
          f"kp_cart = {g.kp_cart:.4g}, kd_cart = {g.kd_cart:.4g}, rate filter {g.filter_tau * 1e3:.3g} ms, "
          f"tilt limit {g.tilt_limit:.3g} rad")
    print("  settling: handout = every |theta_i - theta_i*| stays <= 0.05 rad, strict = whole state within 0.01 "
          "of x*; cart excursion = max |cart - x*_cart|")
    head = f"{'':28s} {'':4s}" + "".join(f"{f'IC {i}':>8s}" for i in range(1, n + 1)) + f"{'mean':>8s}"
    print(head)
    for key, label, fmt in PID_TABLE_ROWS:
        for j, (name, res) in enumerate((("LQR", lqr), ("PID", pid))):
            vals = np.asarray(getattr(res, key), dtype=float)
            cells = [fmt.format(v) if np.isfinite(v) else "never" for v in vals]
            if key == "settling_times_seed":  # starts inside the band from the outset are not in the mean
                cells = [c if k else "in band" for c, k in zip(cells, res.counted)]
                vals = vals[list(res.counted)]
            mean = fmt.format(vals.mean()) if vals.size and np.all(np.isfinite(vals)) else "n/a"
            print(f"{label if j == 0 else '':28s} {name:4s}" + "".join(f"{c:>8s}" for c in cells + [mean]))
