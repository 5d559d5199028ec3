"""``cartpole feedforward``: a planned swing-up's ctrl played open loop beside the same plan tracked by TVLQR, on the
true model and on one whose pole mass is wrong, in MuJoCo; one table, one figure (and a video per run)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import cartpole.apps.feedforward as feedforward_app
from cartpole.apps.feedforward import EXTRA, check_mass_error, plan_options
from cartpole.apps.lab import state_names
from cartpole.apps.swingup import plan_model_from
from cartpole.commands._flags import as_flags, flag_words
from cartpole.commands._limits import add_limit_arguments, limit_keywords, limit_lines
from cartpole.commands._numbers import Numbers
from cartpole.commands._rig import add_budget_argument, add_rig_arguments, check_budget, loop_from_args, rig_doc
from cartpole.commands._rollouts import rollout_doc
from cartpole.commands._view import add_view_arguments, show_runs, view_mode
from cartpole.control.friction import friction_summary
from cartpole.models import bounded_model, build_model, planning_limits, read_params
from cartpole.progress import stage
from cartpole.sim.rig import build_rig
from cartpole.validation.estimation import estimation_summary
from cartpole.viz import VideoUnavailable, render_video
from cartpole.viz.feedforward_plot import plot_feedforward

HELP = ("feedforward beside feedback: the trajopt swing-up's ctrl open loop vs feedforward + TVLQR, also planned "
        "with a wrong pole mass, in MuJoCo")


def add_arguments(parser) -> None:
    """``--mass-error``, ``--no-video``, ``--x0``, ``--plan-mjcf``, the view's, the limits' and the rig's options."""
    parser.add_argument("--mass-error", type=str, default="0.1", metavar="F",
                        help="relative error of the wrong planning model's pole mass (default 0.1: 10 %% heavier; "
                             "a finite number from -0.9 to 9)")
    parser.add_argument("--no-video", action="store_true",
                        help="do not render videos/feedforward_<run>.mp4")
    parser.add_argument("--x0", action=Numbers, default=None, metavar="V",
                        help="start state [qpos..., qvel...] in MuJoCo's joint order, both plans' and every run's "
                             "(default the hanging rest, moved onto a joint range's edge it lies just outside)")
    parser.add_argument("--plan-mjcf", default=None, metavar="PATH",
                        help="plan the first swing-up (and its TVLQR) on this MJCF, e.g. one fitted by `cartpole "
                             "identify`, while MuJoCo runs --mjcf (the same joints, actuators and step)")

    add_view_arguments(parser, "show each run live, in real time, one after the other, replayed from its log (desktop "
                               "without a display: a note on stderr and the rest as usual)")

    add_limit_arguments(parser)
    add_rig_arguments(parser)
    add_budget_argument(parser)


def _fmt(v, spec: str, unit: str = "") -> str:
    return "never" if v is None else f"{v:{spec}}{unit}"


def run(args) -> dict:
    """Validate the input, plan, run the four controllers, write the figure (and videos), return the JSON document.
    Library errors name this command's options (:func:`cartpole.commands._flags.flag_words`)."""
    with flag_words():
        return _run(args)


def _run(args) -> dict:
    """:func:`run` without the flag words."""
    params, limits, loop, plan_model, mass_error = _inputs(args)
    view = view_mode(args, "feedforward")
    options = feedforward_app.FeedforwardOptions(mass_error=mass_error, loop=loop)
    study = feedforward_app.run_feedforward(params, options, plan_model=plan_model,  # reports through cartpole.progress
                                            x0=args.x0)
    if view:
        show_runs(params, [r.rollout for r in study.runs.values()], view, args, command="feedforward")
    names = _run_names(mass_error)
    fig = _figure(args, study, params, plan_model, names, mass_error)
    videos = None if args.no_video else _videos(args, study, params)
    doc = _document(study, params, loop, limits, plan_model, mass_error)
    doc["figure"], doc["videos"] = str(fig.resolve()), videos
    if not args.json:
        _print(doc, study, params, names, mass_error, fig)
    return doc


def _inputs(args) -> tuple:
    """``(params, limits, loop, plan_model, mass_error)``, everything validated before anything is solved or written
    (the work too: two plans, four runs of at most the longest plan + :data:`~cartpole.apps.feedforward.EXTRA` s;
    a numerically singular model is refused there)."""
    mass_error = check_mass_error(args.mass_error)
    params, limits = planning_limits(read_params(args.mjcf), **limit_keywords(args))  # defaults where unlimited
    n_plans = 1 if mass_error == 0.0 else 2
    longest = plan_options().T_max + EXTRA
    model = build_model(params)
    check_budget(args, model, [(4, longest, f"4 runs of at most {longest:g} s")], plans=n_plans)
    loop = loop_from_args(args)
    plan_model = None
    if getattr(args, "plan_mjcf", None) is not None:
        plan_model = bounded_model(plan_model_from(args.plan_mjcf, model), limits)
    return params, limits, loop, plan_model, mass_error


def _run_names(mass_error: float) -> dict:
    """Each run's name in words."""
    pct = f"{100 * mass_error:+g} %"
    return {"feedforward": "feedforward only", "feedforward_tvlqr": "feedforward + TVLQR",
            "wrong_mass_tvlqr": f"feedforward + TVLQR, pole mass {pct}",
            "wrong_mass_feedforward": f"feedforward only, pole mass {pct}"}


def _figure(args, study, params, plan_model, names: dict, mass_error: float):
    """The figure of the plans and the four runs (``figures/feedforward.png`` under ``--out``)."""
    pct = f"{100 * mass_error:+g} %"
    true_label = (f"plan (MJCF's model), T = {study.plan.T:.2f} s" if plan_model is None else
                  f"plan ({Path(plan_model.params.mjcf).name}), T = {study.plan.T:.2f} s")
    plans = {true_label: study.plan.trajectory}
    if study.wrong_plan is not study.plan:
        plans[f"plan (pole mass {pct}), T = {study.wrong_plan.T:.2f} s"] = study.wrong_plan.trajectory
    runs = {f"{names[n]}: {'success' if r.success else 'FAILED'}": r.rollout for n, r in study.runs.items()}
    return plot_feedforward(runs, plans, params, Path(args.out) / "figures" / "feedforward.png", model=study.model,
                            title=f"Feedforward beside feedback in MuJoCo ({Path(params.mjcf).name or 'MJCF text'})")


def _videos(args, study, params) -> dict | None:
    """One video per run (``videos/feedforward_<run>.mp4``), their absolute paths; None when no video can be made
    (a sentence on stderr)."""
    videos = {}
    seconds = max(float(r.rollout.t[-1]) for r in study.runs.values())
    with stage("videos", size=f"{len(study.runs)} x {seconds:.1f} s at 30 fps") as tick:
        for i, (name, r) in enumerate(study.runs.items()):
            try:
                path = render_video(params, r.rollout, Path(args.out) / "videos" / f"feedforward_{name}.mp4",
                                    progress=lambda f, i=i: tick((i + f) / len(study.runs)))
            except VideoUnavailable as exc:
                tick.close(ok=False)   # the stage failed: its line is not printed, the sentence below is
                print(f"cartpole feedforward: no videos ({as_flags(str(exc))})", file=sys.stderr)
                return None
            videos[name] = str(path.resolve())
    return videos


def _document(study, params, loop, limits, plan_model, mass_error: float) -> dict:
    """The JSON document (without ``figure`` and ``videos``)."""
    rig = build_rig(study.model, loop, task="swingup")
    return {"mjcf": params.mjcf, "mass_error": mass_error,
            **rig_doc(rig, params.timestep if loop.period is None else loop.period),
            "plan_mjcf": None if plan_model is None else plan_model.params.mjcf,
            "plan": {"T": study.plan.T, "T_min": study.plan.T_min, "N": study.plan.trajectory.N},
            "wrong_plan": {"T": study.wrong_plan.T, "T_min": study.wrong_plan.T_min,
                           "N": study.wrong_plan.trajectory.N, "pole_mass_factor": 1.0 + mass_error},
            "runs": {n: {**r.summary(), "rollout": rollout_doc(r.rollout), "estimation": _estimation(r.rollout, rig)}
                     for n, r in study.runs.items()},
            "friction": friction_summary(params, study.friction_compensation),
            "options": {"plan": study.options.as_dict()}, "limits": limits.to_dict(),
            "start_moved": [mv.to_dict() for mv in study.start_moves]}


def _print(doc: dict, study, params, names: dict, mass_error: float, fig) -> None:
    """The prose: the plans, the table of runs, the replay check and the files."""
    joints = [params.joints[h].name for h in study.model.hinges]
    print(f"MJCF: {params.mjcf}")
    for line in limit_lines(doc["limits"], doc["start_moved"]):
        print(line)
    print(f"Plans (Hermite-Simpson, minimum time + 20 %): the MJCF's own model T = {study.plan.T:.3f} s; "
          f"pole mass {100 * mass_error:+g} % T = {study.wrong_plan.T:.3f} s. Each run starts hanging at rest and "
          "lasts its plan + 2 s in MuJoCo on the true MJCF.")
    print("Success: upright and at rest for the last 1 s, cart off its limits, ctrl in range. Tracking errors "
          "over the plan's span; final angle error wrapped, from upright.")
    head = (f"{'run':<44} {'success':>7} {'upright at':>10} {'final angle':>12} {'max |dtheta|':>12} "
            f"{'max |ds|':>9} {'peak |u|':>8}")
    print(head)
    print("-" * len(head))
    for n, r in study.runs.items():
        fin = np.rad2deg(np.abs(r.final_angle_error)).max() if r.final_angle_error.size else 0.0
        print(f"{names[n]:<44} {'yes' if r.success else 'NO':>7} "
              f"{_fmt(r.time_to_upright, '.3f', ' s'):>10} {fin:>10.2f} ° "
              f"{np.rad2deg(r.max_angle_tracking_error):>10.2f} ° "
              f"{_fmt(r.max_cart_tracking_error, '.3f', ' m'):>9} {r.peak_ctrl:>8.3f}")
    if len(joints) > 1:
        print(f"(angles: the largest over the poles {', '.join(joints)})")
    print(f"Every rollout replays exactly from its logged ctrl: "
          f"{all(r.replays_exactly for r in study.runs.values())}")
    print(f"Figure: {fig}")
    videos = doc["videos"]
    print("Videos: " + ("not written" if not videos else ", ".join(videos.values())))


def _estimation(rollout, rig):
    """A run's JSON ``estimation`` (:func:`~cartpole.validation.estimation.estimation_summary`); None without an
    estimator."""
    if rig is None or rig.estimator == "none":
        return None

    params = rig.model.params
    return estimation_summary(rollout, rig.estimator, params.hinges, state_names(params))
