"""Feedforward beside feedback: a planned swing-up played open loop, and the same plan tracked by TVLQR, in MuJoCo.

:func:`run_feedforward` plans the swing-up once by direct collocation (:func:`cartpole.planning.trajopt.trajopt_swingup`,
on the MJCF's own model) and once more on a deliberately wrong model (every pole link ``1 + mass_error`` times as
heavy, :meth:`~cartpole.models.CartPoleParams.scaled_pole`), then runs four controllers in MuJoCo on the true MJCF,
each from the model's hanging rest ``x_hanging`` for its plan's duration plus :data:`EXTRA` seconds:

``feedforward``
    the plan's ctrl alone, played open loop (:class:`PlanFeedforward`; after the plan, the upright rest input
    ``u_eq``);
``feedforward_tvlqr``
    the same feedforward plus TVLQR feedback along the plan, handing over to the LQR catch at the plan's end
    (the pipeline's :class:`~cartpole.control.tvlqr.TVLQRController`);
``wrong_mass_tvlqr``
    feedforward + TVLQR of the plan made on the wrong model (gains from the wrong model too);
``wrong_mass_feedforward``
    that wrong plan's ctrl alone, open loop.

Each run is judged by the toolkit's swing-up test (:func:`cartpole.validation.metrics.swingup_metrics` with the true
model's upright ``x_eq``: upright and at rest over the last 1 s, cart off its limits, ctrl in range) and measured
against the plan it follows: tracking errors over the plan's span ``0 <= t <= T`` (state error with the hinge entries
wrapped), the final wrapped angle error of every pole from ``x_eq``, the peak ctrl. Every rollout is checked to
replay exactly from its logged ctrl (:func:`cartpole.sim.replays_exactly`).

Why the open loop fails even on a perfect model: the plan satisfies the collocation's cubic/linear interpolation of
the dynamics, not MuJoCo's 5 ms semi-implicit Euler steps, so the rollout leaves the plan by a little; the upright
the plan ends at is unstable (the shipped pole's linearisation there has an eigenvalue of +4.6 1/s: an error grows
e-fold every 0.22 s), and nothing measures it. With a wrong model the feedforward is wrong from the
first step. The feedback measures the error and corrects it while it is small.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, ClassVar

import numpy as np

from cartpole._arrays import readonly
from cartpole.apps.swingup import start_state
from cartpole.control.friction import friction_design
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, CartPoleParams, bounded_model, build_model, planning_limits, plant_params
from cartpole.options import StageOptions
from cartpole.planning.options import PlanOptions
import cartpole.planning.trajopt as trajopt
from cartpole.progress import stage
from cartpole.sim import Rollout, SimOptions, replays_exactly, simulate
from cartpole.sim.rig import build_rig
from cartpole.validation.metrics import pole_angle_errors, swingup_metrics

#: Seconds simulated after each plan's end (the LQR catch must hold for the success test's last 1 s).
EXTRA = 2.0

#: Default relative error of the wrong planning model's pole mass (+10 %).
MASS_ERROR = 0.1

#: The four runs in the order they are reported: name -> one-line description.
RUNS = {
    "feedforward": "feedforward only (plan ctrl open loop)",
    "feedforward_tvlqr": "feedforward + TVLQR feedback",
    "wrong_mass_tvlqr": "feedforward + TVLQR, planned with the wrong pole mass",
    "wrong_mass_feedforward": "feedforward only, planned with the wrong pole mass",
}


def plan_options():
    """The study's default planner settings: ``PlanOptions(exact_discrete=False)``, the collocation plan's own
    feedforward inside TVLQR (not the exact-discrete re-solve)."""
    return PlanOptions(exact_discrete=False)


class FeedforwardError(CartPoleError):
    """Bad request for the feedforward study (a mass error that is not a number above -1, a bad duration)."""


def check_mass_error(mass_error) -> float:
    """``mass_error`` as a float, or one sentence: it must be a finite number from -0.9 to 9 (the pole keeps a
    mass; the scale ``1 + mass_error`` lies in the model error's [0.1, 10]); :class:`FeedforwardOptions` checks it.

    The wrong planning model's pole links weigh ``1 + mass_error`` times the MJCF's (0.1 = 10 % heavier).
    """
    return FeedforwardOptions(mass_error=mass_error).mass_error


@dataclass(frozen=True, eq=False)
class FeedforwardOptions(StageOptions):
    """The feedforward study's settings (:func:`run_feedforward`): how wrong the second plan's model is, how long
    each run goes on after its plan, the planner's and the loop's options, and the limits both plans keep to; the
    same field names as :class:`~cartpole.apps.swingup.SwingupOptions`. Keyword-only; every field has a default.

    Attributes
    ----------
    mass_error : float
        Relative error of the wrong planning model's pole mass (default :data:`MASS_ERROR`, 0.1: every pole link 10 %
        heavier; lengths unchanged), from -0.9 to 9 (:func:`check_mass_error`).
    extra : float
        Seconds simulated after each plan's end (default :data:`EXTRA`, 2 s), at least 1 s (the success test looks
        at the last 1 s).
    plan : PlanOptions or None
        The planner's settings for both plans (:class:`~cartpole.planning.options.PlanOptions`); None (default):
        :func:`plan_options`, the collocation plan tracked as it is (``exact_discrete=False``: this study is about
        that plan's own feedforward, not a re-solve on the exact discrete step).
    loop : LoopOptions or None
        The rig every run has (:class:`~cartpole.sim.options.LoopOptions`: control period, delay, sensors,
        estimator); the TVLQR is designed for its period. None (default): MuJoCo's exact state every physics step.
    u_max : float or tuple of float or None
        The ``|ctrl|`` bound the plans keep to; None (default): the file's, or a stated default where it has none
        (:func:`cartpole.models.planning_limits`).
    cart_max : float or None
        m: the cart's travel the plans keep to; None (default): likewise.

    Raises
    ------
    FeedforwardError
        A mass error or an ``extra`` time out of range (checked before anything is solved).
    """

    mass_error: float = MASS_ERROR
    extra: float = EXTRA
    plan: PlanOptions | None = None
    loop: object = None
    u_max: object = None
    cart_max: float | None = None

    error: ClassVar[type] = FeedforwardError
    SCALARS: ClassVar[tuple] = ("mass_error", "extra", "cart_max")

    def __post_init__(self):
        self.number("mass_error", low=-0.9, high=9.0,
                    hint="give a relative mass error such as `mass_error=0.1` (the planning model's pole weighs "
                         "1 + mass_error times the MJCF's, a model error of 0.1 to 10)")
        self.number("extra", low=1.0, unit="s",
                    hint="give the time after the plan e.g. `extra=2` (the success test looks at its last 1 s)")
        if self.plan is None:
            self.set_field("plan", plan_options())
        if isinstance(self.u_max, (list, np.ndarray)):  # one per actuator: kept as a tuple (read-only)
            self.set_field("u_max", tuple(np.ravel(self.u_max).tolist()))


class PlanFeedforward:
    """The plan's ctrl alone, ``u = u_ff(t)`` whatever the state: the feedforward part of the TVLQR controller.

    ``u_ff(t) = traj.input(min(t + shift, T))`` with ``shift = dt / 2`` for discrete TVLQR gains held over each
    simulator step of ``dt`` s (the mean of the plan's first-order-hold input over the step, exactly what
    :class:`~cartpole.control.tvlqr.TVLQRController` feeds forward), else 0. From the plan's end ``T`` on it
    gives ``u_rest`` (nu,), the input that keeps the plan's final state at rest (the planning model's upright
    ``u_eq``; default the last knot input, which collocation does not pin and which is generally not a rest
    input). Returns (nu,) ctrl, clipped to ``u_limits`` (nu, 2).
    """

    def __init__(self, traj, *, shift: float = 0.0, u_rest=None, u_limits=None):
        self.traj = traj
        self.shift = float(shift)
        self.T = float(traj.t[-1])
        self.u_rest = np.array(traj.u[-1] if u_rest is None else u_rest, dtype=float).ravel()
        self.u_limits = None if u_limits is None else np.asarray(u_limits, dtype=float).reshape(-1, 2)

    @classmethod
    def of_plan(cls, plan, params: CartPoleParams) -> "PlanFeedforward":
        """The feedforward of a :class:`~cartpole.planning.trajopt.SwingupPlan`: the shift its TVLQR gains use, its
        planning model's ``u_eq`` after the plan, the MJCF's ctrl ranges."""
        shift = 0.5 * plan.gains.dt if plan.gains.method == "discrete" else 0.0
        return cls(plan.trajectory, shift=shift, u_rest=plan.model.u_eq, u_limits=params.ctrl_range)

    def __call__(self, t: float, x=None) -> np.ndarray:
        """ctrl (nu,) at ``t`` s; ``x`` is ignored (open loop)."""
        t = float(t)
        if t >= self.T - 1e-12:
            u = self.u_rest
        else:
            u = np.asarray(self.traj.input(min(t + self.shift, self.T)), dtype=float).ravel()
        if self.u_limits is not None:
            u = np.clip(u, self.u_limits[:, 0], self.u_limits[:, 1])
        return u


@dataclass(frozen=True)
class FeedforwardRun:
    """One MuJoCo run of the study and its judgement.

    Attributes
    ----------
    name : str
        Key of :data:`RUNS`.
    label : str
        One-line description.
    rollout : Rollout
        Every physics step on the true MJCF: ``qpos`` (n+1, nq), ``qvel`` (n+1, nq), ``ctrl`` (n, nu).
    plan : Trajectory
        The plan the run follows (the true or the wrong one).
    success : bool
        :func:`~cartpole.validation.metrics.swingup_success` against the true model's ``x_eq``.
    time_to_upright : float or None
        s: every pole within 0.05 rad of upright from then to the end; None if never.
    final_angle_error : (n_hinges,) array, rad
        Wrapped angle error of each pole from ``x_eq`` in the last logged state.
    max_angle_tracking_error : float, rad
        Largest wrapped ``|theta_i - theta_i,plan|`` over every pole and every step with ``t <= T``.
    max_cart_tracking_error : float or None, m
        Largest ``|s - s_plan|`` over ``t <= T`` (None without a cart).
    peak_ctrl : float
        Largest ``|ctrl|`` applied (ctrl units; force = gear x ctrl).
    handover_time : float or None
        s: when the LQR catch took over (TVLQR runs), None for open-loop runs.
    replays_exactly : bool
        The logged ctrl replayed with ``mj_step`` from the first state reproduces every state bit for bit.
    metrics : dict
        All of :func:`~cartpole.validation.metrics.swingup_metrics`.
    """

    name: str
    label: str
    rollout: Rollout
    plan: object
    success: bool
    time_to_upright: float | None
    final_angle_error: np.ndarray
    max_angle_tracking_error: float
    max_cart_tracking_error: float | None
    peak_ctrl: float
    handover_time: float | None
    replays_exactly: bool
    metrics: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "final_angle_error", readonly(self.final_angle_error))

    def summary(self) -> dict:
        """JSON-ready dict of the judgement (no rollout)."""
        return {"label": self.label, "success": self.success, "time_to_upright": self.time_to_upright,
                "final_angle_error": self.final_angle_error.tolist(),
                "max_angle_tracking_error": self.max_angle_tracking_error,
                "max_cart_tracking_error": self.max_cart_tracking_error, "peak_ctrl": self.peak_ctrl,
                "handover_time": self.handover_time, "replays_exactly": self.replays_exactly}


@dataclass(frozen=True)
class FeedforwardStudy:
    """The two plans and the four runs of :func:`run_feedforward`.

    Attributes
    ----------
    params : CartPoleParams
        The MJCF MuJoCo ran.
    model : CartPoleModel
        Its own model (upright ``x_eq``, the reference of every judgement).
    plan : SwingupPlan
        Planned and tracked on the true model.
    wrong_plan : SwingupPlan
        Planned and tracked on the model whose pole mass is ``1 + mass_error`` times the MJCF's.
    mass_error : float
        Relative pole-mass error of the wrong model.
    runs : dict of str -> FeedforwardRun
        In the order of :data:`RUNS`.
    options : PlanOptions or None
        The planner settings both plans were made with.
    friction_compensation : bool
        The runs cancelled the driven joints' dry friction (:func:`~cartpole.control.friction.friction_design`).
    start_moves : tuple of StartMove
        The hanging start's positions moved onto a range's edge (:func:`cartpole.apps.swingup.start_state`).
    """

    params: CartPoleParams
    model: CartPoleModel
    plan: object
    wrong_plan: object
    mass_error: float
    runs: dict
    options: object = None
    friction_compensation: bool = False
    start_moves: tuple = ()

    @property
    def mjcf(self) -> str:
        """Absolute path of the MJCF ("" for parameters read from text)."""
        return self.params.mjcf


def judge(name: str, rollout: Rollout, plan, model: CartPoleModel, *, handover_time: float | None = None,
          label: str | None = None) -> FeedforwardRun:
    """Judge one MuJoCo ``rollout`` of the true MJCF against the true ``model`` and the ``plan`` it followed.

    Parameters
    ----------
    name : str
    rollout : Rollout
    plan : Trajectory
        The plan followed; tracking errors are taken over the steps with ``t <= plan.t[-1]``.
    model : CartPoleModel
        The MJCF's own model: ``x_eq``, hinges, slide, ranges for the success test.
    handover_time : float, optional
        s, recorded as given.
    label : str, optional
        Default ``RUNS[name]``.

    Returns
    -------
    FeedforwardRun
    """
    m = swingup_metrics(rollout, model)
    span = rollout.t <= plan.t[-1] + 1e-12
    err = model.state_error(rollout.x[span], plan.state(rollout.t[span]))
    hinges = list(model.hinges)
    final = pole_angle_errors(rollout.x[-1:], x_eq=model.x_eq, hinges=hinges)[0]
    return FeedforwardRun(
        name=name, label=RUNS.get(name, name) if label is None else label, rollout=rollout, plan=plan,
        success=bool(m["success"]), time_to_upright=m["time_to_upright"], final_angle_error=final,
        max_angle_tracking_error=float(np.abs(err[:, hinges]).max()) if hinges else 0.0,
        max_cart_tracking_error=None if model.slide is None else float(np.abs(err[:, model.slide]).max()),
        peak_ctrl=float(m["peak_ctrl"]), handover_time=handover_time,
        replays_exactly=replays_exactly(rollout, model.params), metrics=m)


def _run_all(params, model, plans, x0, extra: float, friction, rig, period, callback) -> dict:
    """The four MuJoCo runs of the study, judged: open-loop feedforward and TVLQR along the right plan, and both
    along the plan for the wrong mass (``plans`` = (right, wrong)), each ``extra`` s past its plan's end, from
    ``x0``, with the friction compensation and rig of the study. Returns name -> :func:`judge`'s record."""
    plan, wrong = plans
    controllers = {
        "feedforward": (PlanFeedforward.of_plan(plan, params), plan),
        "feedforward_tvlqr": (plan.controller, plan),
        "wrong_mass_tvlqr": (wrong.controller, wrong),
        "wrong_mass_feedforward": (PlanFeedforward.of_plan(wrong, params), wrong),
    }
    runs = {}
    seconds = max(plan.T, wrong.T) + extra
    with stage("MuJoCo rollouts", size=f"{len(controllers)} x {seconds:.1f} s", callback=callback) as tick:
        for i, (name, (ctrl, sp)) in enumerate(controllers.items()):
            if hasattr(ctrl, "reset"):
                ctrl.reset()
            watch = SimOptions(control_period=period, progress=lambda fr, i=i: tick((i + fr) / len(controllers)))
            rollout = simulate(params, friction.wrap(ctrl), x0, sp.T + extra,
                               rig=None if rig is None else rig.for_run(i), options=watch)
            runs[name] = judge(name, rollout, sp.trajectory, model,
                               handover_time=getattr(ctrl, "handover_time", None))
            tick((i + 1) / len(controllers))
    return runs


def run_feedforward(plant=None, options: FeedforwardOptions | None = None, *, plan=None, x0=None,
                    plan_model: CartPoleModel | None = None,
                    progress: Callable[[str, float], None] | None = None) -> FeedforwardStudy:
    """Plan the swing-up, then run feedforward alone and feedforward + TVLQR in MuJoCo, on a true and a wrong model.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole MuJoCo runs (default the shipped asset); any model the trajectory optimiser takes.
    options : FeedforwardOptions, optional
        The study's settings: the wrong model's ``mass_error``, the ``extra`` seconds after each plan, the planner's
        (``plan``) and the loop's (``loop``) options, the limits (``u_max``, ``cart_max``); default
        :class:`FeedforwardOptions` ``()``.
    plan : SwingupPlan, optional
        A plan already made on the MJCF's own model (skips that solve); it must be for this MJCF.
    x0 : (2 nq,) array, optional
        ``[qpos, qvel]`` (m, rad, m/s, rad/s) both plans and every run start from; default the hanging rest
        ``x_hanging``, moved onto a joint range's edge it lies just outside (:func:`cartpole.apps.swingup.start_state`).
    plan_model : CartPoleModel, optional
        Plan (and design the TVLQR of) the first plan on this model instead of the MJCF's own (e.g. a fitted MJCF);
        MuJoCo still runs ``plant``. The wrong-mass plan stays relative to ``plant``.
    progress : callable, optional
        ``progress(stage, fraction)`` with stage ``"plan"`` (both trajectory optimisations) or ``"simulate"`` (the four
        MuJoCo runs). Either is also a :func:`cartpole.progress.stage`, shown by the caller's reporter if any.

    Returns
    -------
    FeedforwardStudy

    Raises
    ------
    FeedforwardError
        ``options`` that are not a :class:`FeedforwardOptions` (a bad ``mass_error`` or ``extra`` is refused when the
        options are made, before anything is solved).
    MJCFError, OCPError
        An MJCF that is not a cart-pole; a swing-up the optimiser cannot plan (its one sentence).
    """
    study = FeedforwardOptions() if options is None else options
    if not isinstance(study, FeedforwardOptions):
        raise FeedforwardError(f"run_feedforward's options must be a FeedforwardOptions; got {study!r}.")
    f, extra, loop, options = study.mass_error, study.extra, study.loop, study.plan
    params = plant_params(plant)
    params, limits = planning_limits(params, u_max=study.u_max, cart_max=study.cart_max)  # stated defaults if unlimited
    plan_model = None if plan_model is None else bounded_model(plan_model, limits)
    # planned without the friction a compensation cancels, run with it (cartpole.control.friction)
    plant = build_model(params)
    friction = friction_design(plant, loop)
    model = friction.model
    period = None if loop is None else loop.period
    rig = build_rig(plant, loop, task="swingup")  # a bad period, delay or sensor ends here, before any solve
    # the runs' start, the hanging rest, on a range's edge where it lies just outside (said), else refused naming x0
    x0, moves = start_state(x0, params, default=model.x_hanging)
    start = None if np.array_equal(x0, model.x_hanging) else tuple(float(v) for v in x0)  # None: the planner's own

    def forward(name):
        return None if progress is None else (lambda frac: progress(name, frac))

    n_plans = 1 if plan is None else 0
    n_plans += 0 if f == 0.0 else 1
    with stage("trajectory optimisation", size=f"{n_plans} plan{'s' if n_plans != 1 else ''}",
               callback=forward("plan")) as tick:
        if plan is None:
            design = model if plan_model is None else plan_model
            plan = trajopt.trajopt_swingup(design.params, start, plan_model=design, options=options, period=period)
            tick(1.0 / max(n_plans, 1))
        wrong = plan if f == 0.0 else trajopt.trajopt_swingup(
            params, start, plan_model=friction_design(build_model(params.scaled_pole(1.0 + f, 1.0)), loop).model,
            options=options,
            period=period)
        tick(1.0)

    runs = _run_all(params, model, (plan, wrong), x0, extra, friction, rig, period, forward("simulate"))
    return FeedforwardStudy(params=params, model=model, plan=plan, wrong_plan=wrong, mass_error=f, runs=runs,
                            options=options, friction_compensation=friction.compensated, start_moves=moves)
