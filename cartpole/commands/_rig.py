"""The rig's command-line options, one definition for every command that runs MuJoCo (``--period``, ``--delay``,
``--estimator``, ``--encoder-cpr``, ``--encoder-resolution``, ``--sensor-noise``, ``--process-noise``,
``--mhe-horizon``, ``--noise-seed``, ``--no-delay-compensation``, ``--no-friction-compensation``), and the :class:`~cartpole.sim.options.LoopOptions`
they make."""
from __future__ import annotations

import math

from cartpole.errors import CartPoleError
from cartpole.models import friction_treatment
from cartpole.planning.options import DEFAULT_N, PlanOptions
from cartpole.progress import current
from cartpole.sim.budget import (ANNOUNCE_STEPS, DEFAULT_MAX_STEPS, check_conditioning, check_work, estimate_work,
                                 plan_size)
from cartpole.sim.options import ESTIMATORS, LoopOptions

#: argparse destination -> LoopOptions field, for the rig's options.
RIG_FIELDS = {"period": "period", "delay": "delay", "estimator": "estimator", "encoder_cpr": "encoder_cpr",
              "encoder_resolution": "encoder_resolution", "sensor_noise": "sensor_noise",
              "process_noise": "process_noise", "mhe_horizon": "mhe_horizon", "noise_seed": "seed"}


def add_rig_arguments(parser, *, period_help: str | None = None) -> None:
    """Add the rig's options to a subcommand's parser (``period_help`` replaces ``--period``'s help text)."""
    parser.add_argument("--period", type=float, default=None, metavar="S",
                        help=period_help or "control period in s, a whole number of MJCF steps (default one step): "
                             "the ctrl is held in between and the controller is designed on the exact discrete "
                             "model over the hold")
    parser.add_argument("--delay", type=float, default=None, metavar="S",
                        help="time from sampling the sensors to the ctrl taking effect, whole MJCF steps, may "
                             "exceed the period (default 0); compensated by predicting the estimate through the "
                             "model unless --no-delay-compensation")
    parser.add_argument("--estimator", choices=ESTIMATORS, default=None,
                        help="what the controller acts on: none (MuJoCo's exact state), kf (steady-state Kalman "
                             "filter, with LQR = LQG), ekf (extended Kalman filter), mhe (moving-horizon "
                             "estimation); default none, or with a sensor option kf for balancing and ekf for a "
                             "swing-up")
    parser.add_argument("--encoder-cpr", type=float, default=None, metavar="N",
                        help="counts per revolution of every hinge encoder (e.g. 2048); default not quantised")
    parser.add_argument("--encoder-resolution", type=float, default=None, metavar="M",
                        help="metres per count of every slide encoder (e.g. 0.001); default not quantised")
    parser.add_argument("--sensor-noise", type=float, default=None, metavar="STD",
                        help="standard deviation of every sensor's noise in its units (rad, m, ...); default the "
                             "MJCF's sensor noise attribute, else 0")
    parser.add_argument("--process-noise", type=float, default=None, metavar="STD",
                        help="standard deviation of the unknown acceleration per joint the estimator allows "
                             "(m/s^2, rad/s^2); default the estimator's")
    parser.add_argument("--mhe-horizon", type=float, default=None, metavar="S",
                        help="the MHE's window in s, a whole number of periods (default 10 periods)")
    parser.add_argument("--noise-seed", type=int, default=None, metavar="N",
                        help="seed of the sensor noise (default 0); every run draws its own stream from it")
    parser.add_argument("--no-delay-compensation", action="store_true",
                        help="act on the estimate at the sample instant, not predicted over the delay (what the "
                             "delay costs)")
    parser.add_argument("--no-friction-compensation", action="store_true",
                        help="on an MJCF whose driven joints have frictionloss: design on the smooth friction "
                             "model and add no ctrl cancelling it (default: design without that friction and "
                             "cancel it, see docs/rig.md)")


def rig_fields(args) -> dict:
    """The LoopOptions fields the rig's options on ``args`` set (those given only)."""
    out = {}
    for dest, name in RIG_FIELDS.items():
        v = getattr(args, dest, None)
        if v is not None:
            out[name] = v
    if getattr(args, "no_delay_compensation", False):
        out["delay_compensation"] = False
    if getattr(args, "no_friction_compensation", False):
        out["friction_compensation"] = False
    return out


def loop_from_args(args, **fields):
    """``LoopOptions(**rig_fields(args), **fields)``; its one-sentence :class:`~cartpole.sim.options.LoopError` on
    bad values."""
    return LoopOptions(**{**rig_fields(args), **fields})


def rig_doc(rig, period: float) -> dict:
    """The JSON ``period`` (s) and ``rig`` objects of a run (``rig`` None for MuJoCo's exact state every step)."""
    return {"period": float(period), "rig": None if rig is None else rig.to_dict()}


def friction_sentence(friction: dict, *, smooth: bool = True) -> str:
    """The prose line for a run's JSON ``friction`` (:func:`cartpole.control.friction.friction_summary`);
    ``smooth=False`` for a design that leaves all friction out (the lab's LQR, linearised at rest)."""
    loss = ", ".join(f"{name} {v:g}" for name, v in friction["frictionloss"].items())
    how = ("designed without the driven joints' friction, which a feedforward cancels (--no-friction-compensation "
           "to design on the smooth friction model instead)" if friction["compensation"] else
           "designed on the smooth friction model, nothing cancelled" if smooth else "nothing cancelled")
    return f"Friction (frictionloss {loss}): {how}."


def add_budget_argument(parser) -> None:
    """``--max-steps N``: the budget of MuJoCo steps a command runs before it refuses (:mod:`cartpole.sim.budget`)."""
    parser.add_argument("--max-steps", type=float, default=None, metavar="N",
                        help=f"most MuJoCo steps the command may run in all (default {DEFAULT_MAX_STEPS:.0e}); "
                             "beyond it the command refuses before it starts, naming its estimate")


def check_budget(args, model, parts, *, plans: int = 0, intervals: int | None = None) -> object:
    """Estimate a command's work before it starts and refuse it beyond ``--max-steps``; refuse a numerically singular
    model (:func:`cartpole.sim.budget.check_conditioning`); announce large work on the progress reporter.

    Parameters
    ----------
    args : argparse.Namespace
        Its ``max_steps`` (None: the default budget).
    model : CartPoleModel
    parts : iterable of tuples
        Runs, seconds each, what they are, and optionally the weight of a step
        (:func:`cartpole.sim.budget.estimate_work`).
    plans : int
        Swing-up plans the command solves (at most), said with their size in the estimate
        (:func:`cartpole.sim.budget.plan_size`).
    intervals : int, optional
        Their collocation intervals (default the planner's, :func:`plan_intervals`).

    Returns
    -------
    Work
    """
    top = getattr(args, "max_steps", None)
    if top is not None and not (math.isfinite(top) and top >= 1):
        raise CartPoleError(f"--max-steps {top:g} is not a number of steps >= 1; give e.g. --max-steps "
                            f"{DEFAULT_MAX_STEPS:.0e}.")
    check_conditioning(model)
    plan = plan_size(plans=plans, intervals=plan_intervals() if intervals is None else intervals, nx=model.nx,
                     nu=model.nu, poles=len(model.hinges))
    work = check_work(estimate_work(parts, model.dt, plan=plan), max_steps=DEFAULT_MAX_STEPS if top is None else top,
                      option="--max-steps")
    rep = current()
    if rep is not None and work.cost > ANNOUNCE_STEPS:
        rep.write(f"{rep.prefix + ': ' if rep.prefix else ''}about {work.describe()}")
    return work


def plan_intervals() -> int:
    """Collocation intervals of a default swing-up plan (:class:`cartpole.planning.options.PlanOptions` ``N``, its
    default when unset)."""
    n = PlanOptions().N
    return int(DEFAULT_N if n is None else n)


def smoothed_friction_sentence(entries: list, *, what: str = "the design") -> str | None:
    """The prose line for a JSON ``smoothed_friction`` (:func:`cartpole.models.friction_treatment`), None when empty:
    which joints' dry friction (MuJoCo sticks them) the design holds as the smooth model, leaves out or cancels."""
    if not entries:
        return None
    parts = []
    for e in entries:
        slide = e.get("kind") == "slide"
        force, damp = ("N", "N s/m") if slide else ("N m", "N m s/rad")
        how = {"smooth": f"as the smooth -{e['frictionloss']:g} tanh(qvel/{e['width']:g}), a damping of "
                         f"{e.get('damping_at_rest', 0.0):.3g} {damp} at rest",
               "omitted": "left out (linearised at rest without it)",
               "cancelled": "left out and cancelled by a feedforward"}[e["design"]]
        parts.append(f"{e['joint']} {e['frictionloss']:g} {force} {how}")
    return f"Dry friction (MuJoCo's frictionloss, which sticks a joint at rest) in {what}: " + "; ".join(parts) + "."


def design_friction(model, friction: dict | None) -> list:
    """JSON ``smoothed_friction`` of a command that designs on the symbolic model with its smooth friction (a
    swing-up's planner and controllers, :func:`cartpole.control.friction.friction_design`): every joint with
    frictionloss held as the smooth model, except the driven ones a compensation cancels.

    Parameters
    ----------
    model : CartPoleModel
        The model MuJoCo runs.
    friction : dict or None
        The run's JSON ``friction`` (:func:`cartpole.control.friction.friction_summary`): its ``compensation``.
    """
    p = model.params
    cancelled = p.driven_joints if friction and friction.get("compensation") else ()
    return friction_treatment(p, width=model.friction_width, cancelled=cancelled)
