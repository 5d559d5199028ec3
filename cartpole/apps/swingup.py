"""Swing the poles up and hold them, proven in MuJoCo: ``run_swingup(plant, method="auto" | "energy" | "trajopt" |
"mpc" | "supervisor", SwingupOptions(...))``.

* ``auto`` (the default): what works for the model, tried in turn until one succeeds in MuJoCo
  (:func:`auto_methods`): energy shaping for one pole driven by the cart, the planner for chains and hinge-driven
  models and after energy shaping failed, and the planner with DDP on the exact discrete step when a plan does not
  hold; ``result.methods_tried`` says what was tried and how each ended (:class:`MethodTry`);

* ``energy``: energy shaping (:class:`~cartpole.control.energy.EnergyShapingController`) until the state enters
  the LQR catch's basin ``e' S e < rho`` (``rho`` estimated in MuJoCo by :func:`~cartpole.validation.basin.
  estimate_basin`), then an LQR catch (the lab's Q with R = 1,
  :meth:`~cartpole.control.linear.LinearFeedback.for_model` with ``R =``
  :data:`~cartpole.control.switching.SWINGUP_CATCH_R`, whose verified basin is about five times the lab LQR's), with
  hysteresis (:class:`~cartpole.control.switching.SwitchingController`). One pole on a cart driven by the cart
  only: any other model is refused with the controller's one sentence, before anything runs;
* ``trajopt``: direct collocation + TVLQR (:func:`cartpole.planning.trajopt.trajopt_swingup`) for the chosen
  ``objective`` (:mod:`cartpole.ocp.objectives`), handing over to the LQR hold after the plan; any model the
  planner takes. The basin reported is the hand-over LQR's (:func:`cartpole.planning.trajopt.handover_catch`), the
  controller that actually takes over; with a dm_control task as objective (``dmc_cartpole_swingup``, ...) the metrics add dm_control's
  ``return`` of the logged run (:func:`~cartpole.validation.metrics.dmc_return`, the exact reward) and its
  ``return_steps``.

* ``mpc``: nonlinear MPC re-planning every control period (:func:`cartpole.mpc.nmpc.nmpc_swingup`), MuJoCo holding
  each ctrl for the controller's ``period``; no catch, no basin.

Each method is a class (:class:`EnergySwingup`, :class:`TrajoptSwingup`, :class:`NMPCSwingup`, :class:`DDPMPCSwingup`,
:class:`SupervisorSwingup`, all :class:`SwingupMethod`): it designs its controller, and the closed loop they share
(the rig around the plant, friction compensation, MuJoCo, the metrics) is written once, in :meth:`SwingupMethod.run`.
A run's settings are one value, :class:`SwingupOptions` (what a sweep's runs take too), each stage's inside it:
``plan`` :class:`~cartpole.planning.options.PlanOptions` (trajopt, and mpc's offline plan), ``mpc``
:class:`~cartpole.mpc.options.MPCOptions`, ``energy`` :class:`~cartpole.control.energy.EnergyOptions` and for every
method ``loop`` :class:`~cartpole.sim.options.LoopOptions`, the closed loop's scenario: ``push=((T, F), ...)`` (a
horizontal force of F N on the cart body for :data:`PUSH_SECONDS` from time T s, through MuJoCo's ``xfrc_applied``;
logged per physics step in ``rollout.info["push"]``, so the run still replays exactly) and ``model_error=S`` (the
*planning* model's pole masses and lengths scaled by S, :meth:`~cartpole.models.CartPoleParams.scaled_pole`; MuJoCo keeps the file's). With
model error, energy shaping and its catch (energy), the plan and its TVLQR (trajopt) or the NMPC's model (mpc) are
built on the scaled model; the catch basin is still measured in MuJoCo on the MJCF (the basin of the catch as built).

The start state is ``[qpos, qvel]`` in MuJoCo's order (``2 nq`` numbers; default the model's hanging rest
``x_hanging``). Either way MuJoCo runs the controller on the MJCF and every physics step is logged (``qpos``
(n+1, nq), ``qvel`` (n+1, nq), ``ctrl`` (n, nu)), so the result replays exactly
(:func:`~cartpole.sim.rollout.replays_exactly`).
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field, replace
from typing import Callable, ClassVar

import numpy as np

from cartpole._arrays import readonly
from cartpole.apps.lab import state_names
from cartpole.apps.live import paced_supervisor
from cartpole.apps.margins import noise_limited_catch
from cartpole.control.energy import (EnergyOptions, EnergyShapingController, EnergyShapingError, check_single_pole,
                                     default_gains)
from cartpole.control.energy import energy_options as as_energy_options
from cartpole.control.friction import friction_design, friction_summary
from cartpole.control.linear import LinearFeedback
from cartpole.control.switching import SWINGUP_CATCH_R, SwitchingController
from cartpole.export.inloop import in_loop
from cartpole.errors import CartPoleError, first_line
from cartpole.models import (CartPoleModel, CartPoleParams, bounded_model, build_model, planning_limits, plant_params,
                             read_params, start_on_range, steps_per_period)
from cartpole.mpc.ddp_mpc import ddp_mpc_swingup, seed_plan_options
from cartpole.mpc.nmpc import nmpc_swingup
from cartpole.mpc.options import MPCOptions, mpc_grid
from cartpole.ocp.bounds import OCPError
from cartpole.ocp.dmc import is_task, task
from cartpole.options import StageOptions
from cartpole.planning import trajopt
from cartpole.planning.options import PLAN_SOLVERS, PlanOptions, PlanOptionsError
from cartpole.riccati import default_weights
from cartpole.sim import Rollout, SimOptions, simulate
from cartpole.sim.options import (PUSH_SECONDS, LoopError, LoopOptions, check_model_error, check_push,
                                  check_push_times, push_force)
from cartpole.sim.rig import build_rig
from cartpole.supervise import supervisor_for
from cartpole.validation.basin import BasinCache
from cartpole.validation.estimation import estimation_summary
from cartpole.validation.metrics import (EPISODE, catch_held, dmc_rewards, failure_reason, swingup_metrics,
                                         uptime_metrics)

#: Re-exported from :mod:`cartpole.sim.options`, where the closed loop's settings live (the command line and the
#: sweep import them from here).
__all__ = ["AUTO", "AUTO_NEXT_FACTOR", "AUTO_TIME_BUDGET", "DDPMPCSwingup", "DEFAULT_OPTIONS", "ENERGY_DURATION",
           "EnergySwingup", "METHODS", "METHOD_CLASSES", "MethodTry", "MPC_DURATION", "NMPCSwingup", "PUSH_SECONDS",
           "SupervisorSwingup", "SwingupMethod", "SwingupOptions", "TRAJOPT_EXTRA", "TrajoptSwingup", "LoopError",
           "SwingupError", "SwingupResult", "auto_methods", "check_model_error", "default_method", "check_push",
           "check_plan_size", "check_start", "check_upright_reachable", "method_class", "method_list",
           "own_duration", "parse_push", "plan_model_from", "plan_report", "planning_model", "push_force",
           "run_swingup"]

METHODS = ("energy", "trajopt", "mpc", "supervisor")
#: The default method: the methods :func:`auto_methods` chooses for the model, tried in turn until one succeeds.
AUTO = "auto"
#: s of wall time within which the default method tries its methods: a further method starts only while the budget
#: left is at least :data:`AUTO_NEXT_FACTOR` times what the run before it took (the one running is not interrupted).
#: An acrobot's collocation plan takes minutes on a busy machine and its DDP re-plan (1500 steps at 10 ms) many
#: more; a default run should not take much longer than the first plan.
AUTO_TIME_BUDGET = 600.0
#: A further method is expected to take at least this many times as long as the run before it (a DDP re-plan is
#: slower than the collocation plan it follows): it starts only when that much of the budget is left.
AUTO_NEXT_FACTOR = 2.0

#: Default simulated time in s after the start (energy, mpc) or after the plan's end (trajopt).
ENERGY_DURATION = 10.0
TRAJOPT_EXTRA = 3.0
MPC_DURATION = 8.0
#: s a supervisor run lasts when no duration is given: long enough for several knockdowns and swing-ups.
SUPERVISOR_DURATION = 30.0


class SwingupError(CartPoleError):
    """Bad swing-up request: unknown method, start state not finite or outside the joint range, a stage's options
    given to a method that has no such stage. (Bad closed-loop settings, pushes and model error, are
    :class:`~cartpole.sim.options.LoopError`; bad planner or NMPC settings
    :class:`~cartpole.planning.options.PlanOptionsError`, :class:`~cartpole.mpc.options.NMPCError`; all are
    :class:`~cartpole.errors.CartPoleError`.)"""


@dataclass(frozen=True)
class SwingupResult:
    """What a swing-up did in MuJoCo.

    Attributes
    ----------
    method : str
        "energy", "trajopt" or "mpc".
    success : bool
        :func:`~cartpole.validation.metrics.swingup_success` of the rollout.
    caught_at : float or None
        s: when the LQR catch took over and held (``handover_at`` when the run ends upright and at rest from then on,
        :func:`~cartpole.validation.metrics.catch_held`); None when it never took over, did not hold (the run ends
        away from upright) or the run diverged (MuJoCo reset a blown-up state: never a catch).
    rollout : Rollout
        Every physics step MuJoCo took.
    plan : Trajectory or None
        The optimised trajectory (trajopt), else None.
    basin : BasinEstimate or None
        The catch basin estimate used (energy) or checked against at the handover (trajopt).
    metrics : dict
        :func:`~cartpole.validation.metrics.swingup_metrics` plus ``switches`` (list of
        ``{"t", "mode", "cost"}``) and, for trajopt, ``handover_cost`` (``e' S e`` at the handover).
    push : tuple of (float, float)
        The pushes ``(T [s], F [N])`` the run had (each :data:`PUSH_SECONDS` long).
    model_error : float
        Scale of the planning model's pole masses and lengths (1: the MJCF's own).
    controller : object
        The controller MuJoCo ran (for mpc: its ``solve_ms``, ``period``, ``horizon``, ``failures``).
    handover_at : float or None
        s: when the controller handed over to the LQR catch, whether or not the catch then held (energy: the last
        switch into the basin; trajopt: the end of the plan's tracking, once the run reached it); None without a
        hand-over (mpc, or a run that ended first).
    methods_tried : tuple of MethodTry
        Every method considered, in order, with its outcome: one entry for an explicit method; for ``"auto"`` (or a
        sequence) also the methods that did not apply, failed or were skipped.
    options : dict of str -> options object
        The settings of each stage the method ran, as run: ``"plan"``
        (:class:`~cartpole.planning.options.PlanOptions`; trajopt, and mpc's offline plan), ``"loop"``
        (:class:`~cartpole.sim.options.LoopOptions`; every method), ``"mpc"`` (:class:`~cartpole.mpc.options.
        MPCOptions`; mpc, its period the loop's when it gave none).
    """

    method: str
    success: bool
    caught_at: float | None
    rollout: Rollout
    plan: object = None
    basin: object = None
    metrics: dict = field(default_factory=dict)
    push: tuple = ()
    model_error: float = 1.0
    controller: object = field(default=None, compare=False, repr=False)
    options: dict = field(default_factory=dict, compare=False)
    handover_at: float | None = None
    methods_tried: tuple = field(default=(), compare=False)


@dataclass(frozen=True)
class MethodTry:
    """One swing-up method to try and, once tried, what came of it (:attr:`SwingupResult.methods_tried`).

    Attributes
    ----------
    method : str
        "energy", "trajopt" or "mpc".
    solver : str or None
        trajopt: the solver of the plan's last stage (:attr:`~cartpole.planning.options.PlanOptions.solver`; "ddp":
        box-DDP on the exact discrete step); None: the plan options' own (trajopt), or none (energy, mpc).
    outcome : str
        "" (not tried yet), "success", "failed" (ran in MuJoCo and did not end upright at rest), "error" (the
        planner found no plan), "not applicable" (the method does not take this model or these settings) or
        "skipped" (not started: an earlier method succeeded, the time budget was spent, ...).
    reason : str
        Why, in a few words.
    seconds : float
        Wall time of the try in s (0 when it did not run).
    """

    method: str
    solver: str | None = None
    outcome: str = ""
    reason: str = ""
    seconds: float = 0.0

    @property
    def label(self) -> str:
        """The method in words: ``"energy"``, ``"trajopt"``, ``"trajopt (ddp)"``."""
        return self.method if self.solver in (None, "auto") else f"{self.method} ({self.solver})"

    @property
    def arguments(self) -> str:
        """The arguments that run this method alone, as a sentence names them (each in backticks):
        ``method='trajopt'`` and, with a solver, ``solver='ddp'`` (the command line writes them as its options)."""
        return f"`method='{self.method}'`" + ("" if self.solver in (None, "auto") else f" (`solver='{self.solver}'`)")

    def as_dict(self) -> dict:
        """JSON-ready: ``method``, ``solver`` (or None), ``outcome``, ``reason``, ``seconds``."""
        return {"method": self.method, "solver": self.solver, "outcome": self.outcome, "reason": self.reason,
                "seconds": float(self.seconds)}


def method_list(method) -> tuple:
    """The methods to try, in order, as :class:`MethodTry` entries: one method's name, or a sequence of names and
    :class:`MethodTry` (a trajopt entry may name its plan's ``solver``). ``"auto"`` is :func:`auto_methods`'s.

    Raises
    ------
    SwingupError
        An unknown method, an empty sequence, a solver on a method without a plan or a solver the planner does
        not have.
    """
    names = ", ".join((AUTO,) + METHODS)
    items = [method] if isinstance(method, (str, MethodTry)) else list(method) if method is not None else []
    if not items:
        raise SwingupError(f"No swing-up method given; choose one of {names}.")
    out = []
    for m in items:
        t = m if isinstance(m, MethodTry) else MethodTry(str(m))
        if t.method not in METHODS:
            raise SwingupError(f"Unknown swing-up method '{t.method}'; choose one of {names}.")
        if t.solver is not None and (t.method != "trajopt" or t.solver not in PLAN_SOLVERS):
            raise SwingupError(f"Solver '{t.solver}' of method '{t.method}' is not a planner's; a trajopt entry "
                               f"takes one of {', '.join(PLAN_SOLVERS)}.")
        out.append(replace(t, outcome="", reason="", seconds=0.0))
    return tuple(out)


def default_method(model: CartPoleModel) -> str:
    """The first method the default (:func:`auto_methods`) would run on ``model``: ``"energy"`` for one pole driven
    by the cart, else ``"trajopt"`` (for a chain too long to plan too: :func:`check_plan_size` refuses it in one
    sentence). A sweep's default, one method for every run with no fall-back (a sweep of runs that each try
    several methods would cost several sweeps)."""
    pending = [t.method for t in auto_methods(model) if not t.outcome]
    return pending[0] if pending else "trajopt"


def _without_advice(text: str) -> str:
    """An energy-shaping refusal without its closing advice to use the planner (the default runs it next)."""
    return re.sub(r"(;| or) use `--method trajopt` instead$", "", first_line(text))


def auto_methods(model: CartPoleModel, *, plan=None, objective=None, energy_options=None) -> tuple:
    """The methods the default (``method="auto"``) tries on ``model``, in order (:class:`MethodTry` entries, those
    that do not apply already marked "not applicable" with the reason).

    1. ``energy``: energy shaping with the LQR catch, for one pole driven by the cart
       (:func:`~cartpole.control.energy.check_single_pole`, a ctrl range to scale its gains by) when no planner
       setting was given;
    2. ``trajopt``: the planner (trajectory optimisation + TVLQR) with ``plan``'s solver, for every model of at
       most :data:`MAX_PLAN_POLES` poles: chains, hinge-driven models, and after energy shaping failed;
    3. ``trajopt`` with ``solver="ddp"``: the plan's last stage by box-DDP on the exact discrete step, tracked as it
       is, when the first plan did not hold in MuJoCo (unless the first was DDP already).

    Parameters
    ----------
    model : CartPoleModel
        The planning model.
    plan : PlanOptions, optional
        Planner settings given by the caller: they make the planner the first method.
    objective : str, optional
        An objective given by the caller (the planner's): as ``plan``.
    energy_options : EnergyOptions or dict, optional
        Energy shaping's settings (checked here: bad ones raise).

    Returns
    -------
    tuple of MethodTry

    Raises
    ------
    EnergyShapingError
        Bad ``energy_options``.
    """
    opts = as_energy_options(energy_options)
    if plan is not None or objective is not None:
        energy = MethodTry("energy", outcome="not applicable",
                           reason="planner settings (an objective or a solver) were given and energy shaping has "
                                  "no plan")
    else:
        try:
            check_single_pole(model)
            default_gains(model, opts)
            energy = MethodTry("energy")
        except EnergyShapingError as exc:
            energy = MethodTry("energy", outcome="not applicable", reason=_without_advice(str(exc)))
    solver = None if plan is None else plan.solver
    n = len(model.hinges)
    if n > MAX_PLAN_POLES:
        why = (f"plans for at most {MAX_PLAN_POLES} poles and this chain has {n} (its generated code grows steeply "
               "with every pole)")
        return (energy, MethodTry("trajopt", solver, "not applicable", why))
    planners = (MethodTry("trajopt", solver),) + (() if solver == "ddp" else (MethodTry("trajopt", "ddp"),))
    return (energy,) + planners


def _state_order(params: CartPoleParams) -> str:
    """The state's order in words, from the MJCF's joint names: ``"slider (m), hinge (rad), then their rates"``."""
    pos = ", ".join(f"{j.name} ({'m' if j.kind == 'slide' else 'rad'})" for j in params.joints)
    return f"{pos}, then their rates in the same order"


#: Largest start rate accepted, in each joint's units (m/s, rad/s): a faster start only blows MuJoCo up.
MAX_START_RATE = 100.0
#: Largest start hinge angle accepted, rad (about 160 turns; MuJoCo's angles never wrap).
MAX_START_ANGLE = 1000.0


def check_start(x0, params: CartPoleParams) -> np.ndarray:
    """Validate a start state against the MJCF: ``2 nq`` finite numbers, every joint inside its range.

    Parameters
    ----------
    x0 : array-like
        ``[qpos, qvel]`` in MuJoCo's order; one pole: ``[s (m), theta (rad), s_dot (m/s), theta_dot (rad/s)]``.
    params : CartPoleParams

    Returns
    -------
    (2 nq,) float array

    Raises
    ------
    SwingupError
        Wrong count (the sentence names the expected count and the order, from the MJCF's joint names), not
        finite, a slide not strictly inside its range or a hinge outside its range, a rate beyond
        :data:`MAX_START_RATE` or a hinge angle beyond :data:`MAX_START_ANGLE`.
    """
    n = 2 * params.nq
    try:
        x = np.asarray(x0, dtype=float).ravel()
    except (TypeError, ValueError):
        raise SwingupError(f"The start state {x0!r} is not numeric; give {n} numbers: {_state_order(params)}.") \
            from None
    if x.size != n:
        raise SwingupError(f"The start state has {x.size} number(s); give exactly {n}: {_state_order(params)}.")
    if not np.all(np.isfinite(x)):
        raise SwingupError(f"The start state {x.tolist()} is not finite; give {n} finite numbers.")
    for i, j in enumerate(params.joints):
        rate, unit = x[params.nq + i], "m/s" if j.kind == "slide" else "rad/s"
        if abs(rate) > MAX_START_RATE:
            raise SwingupError(f"The start rate {rate:g} {unit} of joint '{j.name}' is beyond the {MAX_START_RATE:g} "
                               f"{unit} limit; give a rate of at most {MAX_START_RATE:g} in magnitude.")
        if j.kind == "hinge" and abs(x[i]) > MAX_START_ANGLE:
            raise SwingupError(f"The start angle {x[i]:g} rad of hinge '{j.name}' is beyond the {MAX_START_ANGLE:g} "
                               "rad limit; give the angle within a few turns of upright.")
        lo, hi = (float(v) for v in j.range)
        if j.kind == "slide" and not lo < x[i] < hi:
            raise SwingupError(f"The start position {x[i]} m of slide '{j.name}' is outside its joint range "
                               f"[{lo}, {hi}] m; give a start `x0` with the cart strictly inside it.")
        if j.kind == "hinge" and not lo <= x[i] <= hi:
            raise SwingupError(f"The start angle {x[i]} rad of hinge '{j.name}' is outside its joint range "
                               f"[{lo}, {hi}] rad; give a start `x0` inside it.")
    return x


def start_state(x0, params: CartPoleParams, *, default) -> tuple[np.ndarray, tuple]:
    """The state a run starts from, the same way for every command that starts one (swingup, sweep, export,
    feedforward): ``x0`` as given, or else ``default`` with each joint position that lies outside its range by at most
    :data:`cartpole.models.limits.START_SNAP` moved onto the range's edge (a hinge limited to +-3.14159 hanging at
    pi; :func:`cartpole.models.start_on_range`, said in each :class:`~cartpole.models.limits.StartMove`); either way
    checked by :func:`check_start` (farther outside a range: a sentence naming ``x0``, ``--x0``).

    Parameters
    ----------
    x0 : (2 nq,) array-like or None
        ``[qpos, qvel]`` given by the user (m, rad, m/s, rad/s), None for ``default``. A given start is never moved.
    params : CartPoleParams
    default : (2 nq,) array-like
        The command's own start (the hanging rest ``x_hanging`` for a swing-up).

    Returns
    -------
    x : (2 nq,) float array
    moves : tuple of StartMove
        The default's positions moved onto a range's edge (empty for a given start).

    Raises
    ------
    SwingupError
        As :func:`check_start`.
    """
    x, moves = start_on_range(default, params) if x0 is None else (x0, ())
    return check_start(x, params), moves


#: Most poles a trajectory optimisation (trajopt, and the NMPC's plan) is built for: its generated C grows steeply with
#: every pole (see :data:`cartpole.codegen.LARGE_SOURCE`); a longer chain is refused before anything is built.
MAX_PLAN_POLES = 3


def check_plan_size(model: CartPoleModel, method: str) -> None:
    """Refuse, before anything is built, a chain too long for ``method``'s planner (:data:`MAX_PLAN_POLES`).

    Raises
    ------
    SwingupError
        ``method`` is trajopt, mpc or auto (:data:`AUTO`, whose other method, energy shaping, drives one pole) and
        the model has more hinges than :data:`MAX_PLAN_POLES`.
    """
    n = len(model.hinges)
    if method == AUTO and n > MAX_PLAN_POLES:  # energy shaping drives one pole only: nothing to run
        raise SwingupError(f"This MJCF has a chain of {n} poles and the planner plans for at most {MAX_PLAN_POLES} "
                           "(its generated code grows steeply with every pole and would not build in reasonable "
                           f"time); use a chain of at most {MAX_PLAN_POLES} poles.")
    if method in ("trajopt", "mpc") and n > MAX_PLAN_POLES:
        raise SwingupError(f"This MJCF has a chain of {n} poles and `method='{method}'` plans for at most "
                           f"{MAX_PLAN_POLES} (its generated code grows steeply with every pole and would not build "
                           f"in reasonable time); use a chain of at most {MAX_PLAN_POLES} poles.")


def check_upright_reachable(model: CartPoleModel) -> None:
    """Refuse a model whose hinge ranges exclude upright (``model.x_eq``): no swing-up can end there (the lab's
    ``cartpole lqr`` refuses it in the same words).

    Raises
    ------
    SwingupError
        A hinge's range does not contain its upright angle.
    """
    x_eq = np.asarray(model.x_eq, float)
    for h in model.hinges:
        j = model.params.joints[h]
        lo, hi = (float(v) for v in j.range)
        if not lo < x_eq[h] < hi:
            raise SwingupError(f"The range [{lo:g}, {hi:g}] rad of hinge '{j.name}' does not contain the upright "
                               f"angle {x_eq[h]:g} rad; a swing-up ends upright, so widen the hinge range.")


def parse_push(text: str) -> tuple[float, float]:
    """``"T:F"`` (the command line's ``--push``) as ``(T [s], F [N])``.

    Raises
    ------
    SwingupError
        Not two numbers separated by a colon.
    LoopError
        A bad pair (:func:`~cartpole.sim.options.check_push`).
    """
    parts = str(text).split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        pair = (float(parts[0]), float(parts[1]))
    except ValueError:
        raise SwingupError(f"The push {text!r} is not T:F (a start time in s and a force in N); give e.g. "
                           "1.5:20 for 20 N on the cart for 0.1 s from t = 1.5 s.") from None
    return check_push([pair])[0]  # a bad pair: LoopError


def planning_model(model: CartPoleModel, model_error: float = 1.0) -> CartPoleModel:
    """The model a controller is designed on: ``model`` itself for ``model_error == 1``, else
    ``build_model(model.params.scaled_pole(S, S))`` (pole masses and lengths scaled by ``S``)."""
    S = check_model_error(model_error)
    return model if S == 1.0 else build_model(model.params.scaled_pole(S, S))


def plan_model_from(path, model: CartPoleModel) -> CartPoleModel:
    """The model of the MJCF at ``path`` to design a controller on while MuJoCo runs ``model``'s (``--plan-mjcf``:
    e.g. design on a fitted MJCF, run on the rig's), after checking the two describe the same machine: the same
    joints and actuators by name and order, the same time step and integrator.

    Parameters
    ----------
    path : path
        The planning MJCF.
    model : CartPoleModel
        The model MuJoCo runs.

    Returns
    -------
    CartPoleModel

    Raises
    ------
    SwingupError
        Joints, actuators, time step or integrator that differ.
    MJCFError
        A planning MJCF that is not a cart-pole.
    """
    pm = build_model(read_params(path))
    a, b = pm.params, model.params
    same = (a.joint_names == b.joint_names and [x.name for x in a.actuators] == [x.name for x in b.actuators]
            and a.timestep == b.timestep and a.integrator == b.integrator)
    if not same:
        raise SwingupError(f"The planning MJCF {a.mjcf} is not the same machine as {b.mjcf} (joints "
                           f"{', '.join(a.joint_names)} vs {', '.join(b.joint_names)}, actuators, time step "
                           f"{a.timestep:g} vs {b.timestep:g} s or integrator {a.integrator} vs {b.integrator} "
                           "differ); give a planning MJCF (`path`) fitted to or edited from the plant's.")
    return pm


def _stage(progress, name):
    return None if progress is None else (lambda f: progress(name, f))


def plan_report(sp) -> dict:
    """What the trajectory optimisation did, JSON-ready: ``plan_time_s`` (s, wall time of the whole plan, every
    guess and stage included), ``T_min`` and ``T`` (s), ``solver``, ``status``, ``iterations`` (of the kept plan),
    ``total_iterations``, ``guess`` (the initial guess that won) and ``attempts`` (every solver call: stage, guess,
    N, status, success, iterations, objective, T, solve time, whether it was kept) and ``discrete`` (the re-solve on
    the exact discrete step that TVLQR tracks, :func:`cartpole.planning.trajopt.exact_discrete_plan`, or None)."""
    info = sp.solve_info
    attempts = getattr(info, "attempts", None) or ()
    return {"plan_time_s": float(getattr(sp, "plan_time_s", float("nan"))),
            "T_min": None if sp.T_min is None else float(sp.T_min), "T": float(sp.T), "solver": info.solver,
            "status": info.status, "iterations": int(info.iterations),
            "total_iterations": int(getattr(info, "total_iterations", info.iterations)),
            "guess": getattr(info, "guess", None), "attempts": [a.as_dict() for a in attempts],
            "discrete": None if getattr(sp, "discrete", None) is None else sp.discrete.as_dict()}


@dataclass(frozen=True, eq=False)
class SwingupOptions(StageOptions):
    """Every setting of a swing-up as one value: what :func:`run_swingup` takes for one run and
    :func:`~cartpole.apps.sweep.swingup_sweep` for each of its runs (each stage's own options object inside).

    Attributes
    ----------
    plan : PlanOptions, optional
        trajopt, the supervisor's plans and mpc's offline plan: the planner's settings
        (:class:`~cartpole.planning.options.PlanOptions`, its ``objective`` among them); default ``PlanOptions()``
        (mpc: ``PlanOptions(cart_margin=mpc.cart_margin)``). With ``"auto"``, planner settings make the planner the
        first method (energy shaping has no plan).
    loop : LoopOptions
        The closed loop (:class:`~cartpole.sim.options.LoopOptions`): ``duration`` (s; None: each method's own,
        :attr:`SwingupMethod.duration`, the plan's horizon + :data:`TRAJOPT_EXTRA` for trajopt, with a ``dmc_*`` task
        at least dm_control's episode), ``period`` (s; mpc: the NMPC re-plans at it), ``push``, ``model_error``
        (the planning model is :func:`planning_model` of it; MuJoCo keeps the MJCF's), the rig and the
        disturbances. Default ``LoopOptions()``.
    mpc : MPCOptions, optional
        mpc only: the controller's settings (:class:`~cartpole.mpc.options.MPCOptions`; ``solver="ddp"`` runs
        :class:`DDPMPCSwingup`); its period, when None, is the loop's.
    energy : EnergyOptions or dict, optional
        energy (and the default's energy try): :class:`~cartpole.control.energy.EnergyOptions`, or a dict of its
        field names; default its defaults.
    catch_weights : (Q, R), optional
        energy only: LQR weights of the catch; default the default ``Q`` with ``R =``
        :data:`~cartpole.control.switching.SWINGUP_CATCH_R` (trajopt hands over to
        :func:`cartpole.planning.trajopt.handover_catch`).
    u_max : float or (nu,) array, optional
        ``|ctrl| <= u_max`` the swing-up plans and runs within; default each actuator's ctrlrange, or a stated
        default where the file has none (:func:`cartpole.models.planning_limits`).
    cart_max : float, optional
        m: the cart keeps ``|s - centre| <= cart_max``; default the slide's range, or a stated default.
    time_budget : float, optional
        s of wall time after which a sequence of methods starts no further one; default :data:`AUTO_TIME_BUDGET`.
    ctrl_noise : float, optional
        energy and trajopt: design the catch (its ``R``) and the estimator (its process noise) so that the ctrl
        noise the sensors cause in the hold stays below this fraction of the ctrl range
        (:func:`cartpole.apps.margins.noise_limited_catch`). Default: with sensors and an estimator,
        :data:`DEFAULT_CTRL_NOISE`; without, none.

    Raises
    ------
    SwingupError
        A stage given an object of the wrong type, a time budget that is not a positive number of seconds.
    """

    error: ClassVar[type] = SwingupError

    plan: PlanOptions | None = None
    loop: LoopOptions | None = None
    mpc: MPCOptions | None = None
    energy: EnergyOptions | None = None
    catch_weights: tuple | None = None
    u_max: object = None
    cart_max: float | None = None
    time_budget: float | None = None
    ctrl_noise: float | None = None

    def __post_init__(self):
        self.set_field("loop", LoopOptions() if self.loop is None else self.loop)
        for name, kind in (("plan", PlanOptions), ("loop", LoopOptions), ("mpc", MPCOptions)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise SwingupError(f"SwingupOptions.{name} must be a {kind.__name__}; got {value!r}.")
        if self.energy is not None:
            self.set_field("energy", as_energy_options(self.energy))
        if self.catch_weights is not None:
            Q, R = self.catch_weights
            self.set_field("catch_weights", (None if Q is None else readonly(Q), None if R is None else readonly(R)))
        budget = self.time_budget
        if budget is not None and not (isinstance(budget, (int, float)) and math.isfinite(budget) and budget > 0):
            raise SwingupError(f"The time budget {budget!r} s is not a positive number of seconds; give e.g. "
                               f"`time_budget={AUTO_TIME_BUDGET:g}`.")

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        return self.as_dict() == other.as_dict()

    __hash__ = StageOptions.__hash__


#: Default of :func:`run_swingup`'s options.
DEFAULT_OPTIONS = SwingupOptions()


@dataclass(frozen=True)
class _Context:
    """What every method's run shares: the file's model and parameters, the planning model (``pm``, designed
    without the friction a compensation cancels) and the plant it stands for, the closed loop and its push force,
    the start state, the progress and step hooks, ``basin_of(catch)``, the bounds planned within
    (:class:`~cartpole.models.PlanningLimits`) and the start's moves onto the joint ranges."""

    params: CartPoleParams
    model: CartPoleModel
    pm: CartPoleModel
    plant: CartPoleModel
    friction: object
    loop: LoopOptions
    x0: np.ndarray
    force: object
    progress: object
    on_step: object
    basin_of: Callable
    limits: object = None
    moves: tuple = ()
    ctrl_noise: float | None = None

    def report(self, stage: str, fraction: float) -> None:
        """``progress(stage, fraction)`` when a progress hook was given."""
        if self.progress is not None:
            self.progress(stage, fraction)

    def duration(self, own: float) -> float:
        """s the run lasts: the loop's duration, else ``own`` (the method's), its pushes checked against it."""
        T = own if self.loop.duration is None else self.loop.duration
        check_push_times(self.loop.push, T)
        return T


@dataclass(frozen=True)
class _Design:
    """What a method built for one run, before MuJoCo runs it: the controller, the simulated seconds, the loop it
    runs in, the catch basin (or None), the plan (or None), the options of its stages as run and its ctrl-noise
    design (or None)."""

    controller: object
    duration: float
    loop: LoopOptions
    basin: object = None
    plan: object = None
    options: dict = field(default_factory=dict)
    noise: dict | None = None


class SwingupMethod:
    """One swing-up method: :meth:`design` builds its controller for a run, :meth:`run` (shared, written once)
    runs it in the closed loop (the rig around the plant, friction compensation outermost, MuJoCo; :func:`_simulate`)
    and measures it (:func:`~cartpole.validation.metrics.swingup_metrics`, the rig's, estimation, friction; then
    :meth:`measure`, the method's own).

    Subclasses set :attr:`name` (the JSON ``method``) and :attr:`duration` and implement :meth:`design`; they
    override :meth:`measure` to add their own metrics and the hand-over to the catch.

    Parameters
    ----------
    options : SwingupOptions
        The swing-up's settings.
    entry : MethodTry
        The entry that chose this method (a trajopt entry may name its plan's solver).
    """

    #: The method's name, as :attr:`SwingupResult.method` and the JSON ``method``.
    name: ClassVar[str] = ""
    #: s simulated when the loop gives no duration (trajopt: after the plan's end, :data:`TRAJOPT_EXTRA`).
    duration: ClassVar[float] = ENERGY_DURATION
    #: Whether the method designs a catch for the rig's sensors (``ctrl_noise``).
    designs_catch: ClassVar[bool] = False

    def __init__(self, options: SwingupOptions, entry: MethodTry | None = None):
        self.options = options
        self.entry = MethodTry(self.name) if entry is None else entry

    def check(self, pm: CartPoleModel, timestep: float) -> None:
        """Refuse, before anything runs, settings this method cannot run on the planning model ``pm`` (the file
        stepping ``timestep`` s); nothing by default."""

    def design(self, ctx: _Context) -> _Design:
        """The controller for this run and how long it runs (every subclass)."""
        raise NotImplementedError

    def measure(self, ctx: _Context, design: _Design, rollout: Rollout, ran) -> tuple:
        """``(handover_at, extra)``: when the method handed over to its catch (s or None) and its own metrics;
        ``ran`` is the controller as it ran (the compiled C's, when there was a compiler: its switches and hand-over
        are read from the C)."""
        return None, {"switches": []}

    def run(self, ctx: _Context) -> SwingupResult:
        """Design, run in the closed loop, measure: the :class:`SwingupResult` of one run."""
        d = self.design(ctx)
        try:
            controller, rig, rollout = _simulate(ctx, d.controller, d.duration, loop=d.loop)
        finally:
            self.release(d)
        handover_at, extra = self.measure(ctx, d, rollout, controller)
        if d.noise is not None:
            extra["ctrl_noise"] = _noise_measured(d.noise, rollout, handover_at, ctx.pm.u_high - ctx.pm.u_low)
        return _finish(ctx, self.name, _Ran(rollout, controller, rig, d.basin, d.plan, handover_at, extra,
                                            d.options))

    def release(self, design: _Design) -> None:
        """After the MuJoCo run, or an exception in it: end what the design holds (nothing here)."""


class EnergySwingup(SwingupMethod):
    """Energy shaping (:class:`~cartpole.control.energy.EnergyShapingController`) until the state enters the LQR
    catch's MuJoCo-estimated basin, then the catch, switching with hysteresis
    (:class:`~cartpole.control.switching.SwitchingController`). One pole on a cart driven by the cart: any other
    model is refused in the energy shaping's one sentence when the method is made."""

    name = "energy"
    duration = ENERGY_DURATION
    designs_catch = True

    def __init__(self, options: SwingupOptions, entry: MethodTry | None = None, *, pm: CartPoleModel):
        super().__init__(options, entry)
        self.energy = EnergyShapingController(pm, as_energy_options(options.energy))

    def design(self, ctx: _Context) -> _Design:
        """The switching controller, the catch's basin, the loop (its estimator designed for the sensors)."""
        Q, R = self.options.catch_weights or (None, None)
        R0 = SWINGUP_CATCH_R * np.eye(ctx.pm.nu) if R is None else R
        loop, R, noise = _sensor_design(
            ctx, lambda r: LinearFeedback.for_model(ctx.pm, Q, r, period=ctx.loop.period).K, R0)
        catch = LinearFeedback.for_model(ctx.pm, Q, R, period=ctx.loop.period)
        basin = ctx.basin_of(catch)
        switching = SwitchingController(self.energy, catch, basin.rho)
        return _Design(switching, ctx.duration(self.duration), loop, basin,
                       options={"energy": self.energy.options, "loop": loop}, noise=noise)

    def measure(self, ctx: _Context, design: _Design, rollout: Rollout, ran) -> tuple:
        """The last switch into the catch, and every switch (``switches``)."""
        switches = ran.switches  # the C's when it ran
        handovers = [s.t for s in switches if s.mode == "catch"]
        extra = {"switches": [{"t": s.t, "mode": s.mode, "cost": s.cost} for s in switches]}
        return (handovers[-1] if handovers else None), extra


class TrajoptSwingup(SwingupMethod):
    """Direct collocation (or DDP, the plan's ``solver``) + TVLQR (:func:`cartpole.planning.trajopt.trajopt_swingup`)
    handing over to the LQR hold after the plan; the basin reported is the hand-over catch's."""

    name = "trajopt"
    duration = TRAJOPT_EXTRA
    designs_catch = True

    def plan_options(self) -> PlanOptions:
        """The planner's options: the swing-up's (default ``PlanOptions()``), with the entry's solver when it names
        one."""
        plan = self.options.plan or PlanOptions()
        return plan if self.entry.solver is None else plan.replace(solver=self.entry.solver)

    def design(self, ctx: _Context) -> _Design:
        """The plan, its TVLQR and the hand-over catch; the run lasts the plan + :data:`TRAJOPT_EXTRA` (at least a
        dm_control task's episode) unless the loop says."""
        plan = self.plan_options()
        ctx.report("trajopt", 0.0)
        R0 = default_weights(ctx.pm)[1] if plan.R is None else plan.R
        steps = steps_per_period(ctx.loop.period, ctx.params.timestep)
        loop, R, noise = _sensor_design(ctx, lambda r: trajopt.handover_catch(ctx.params, ctx.pm, plan.Q, r,
                                                                              steps=steps).K, R0)
        self.sp = sp = trajopt.trajopt_swingup(ctx.params, x0=tuple(ctx.x0), plan_model=ctx.pm, options=plan,
                                               period=ctx.loop.period, catch_R=None if noise is None else R)
        ctx.report("trajopt", 1.0)
        self.T_plan = float(sp.trajectory.t[-1] - sp.trajectory.t[0])
        own = max(self.T_plan + self.duration, _episode_seconds(sp.objective, ctx.params.timestep))
        return _Design(sp.controller, ctx.duration(own), loop, ctx.basin_of(sp.catch), sp.trajectory,
                       {"plan": plan, "loop": loop}, noise)

    def measure(self, ctx: _Context, design: _Design, rollout: Rollout, ran) -> tuple:
        """The end of the plan's tracking (once the run reached it), its cost-to-go, the plan's report, and a
        dm_control task's return."""
        sp = self.sp
        handover = getattr(ran, "handover_time", self.T_plan)  # the C's when it ran
        handover_at = float(handover) if handover is not None and rollout.t[-1] >= handover else None
        k = int(np.searchsorted(rollout.t, handover_at)) if handover_at is not None else None
        cost = None if k is None else sp.catch.cost_to_go(rollout.x[k])
        extra = {"switches": [] if k is None else [{"t": handover_at, "mode": "catch", "cost": cost}],
                 "handover_cost": cost, "objective": sp.objective, "plan": plan_report(sp)}
        extra.update(_episode_return(rollout, ctx.model, sp.objective))
        return handover_at, extra


class NMPCSwingup(SwingupMethod):
    """Nonlinear MPC by SQP-RTI (:func:`cartpole.mpc.nmpc.nmpc_swingup`) re-planning every control period, MuJoCo
    holding each ctrl; no catch, no basin. ``mpc.solver="ddp"`` is :class:`DDPMPCSwingup`."""

    name = "mpc"
    duration = MPC_DURATION
    def mpc_options(self, loop: LoopOptions, timestep: float) -> MPCOptions:
        """The NMPC's options, its period the loop's when it gives none (one sentence when both are given and
        differ); a horizon too long to solve or a period it would round away refused."""
        mpc = _mpc_period(self.options.mpc or MPCOptions(), loop, timestep)
        mpc_grid(mpc, timestep)
        return mpc

    def check(self, pm: CartPoleModel, timestep: float) -> None:
        """The NMPC's options refused now (:meth:`mpc_options`)."""
        self.mpc_options(self.options.loop, timestep)

    def plan_options(self, mpc: MPCOptions) -> PlanOptions:
        """The offline plan's options: the swing-up's, default ``PlanOptions(cart_margin=mpc.cart_margin)``."""
        return PlanOptions(cart_margin=mpc.cart_margin) if self.options.plan is None else self.options.plan

    def build(self, ctx: _Context, mpc: MPCOptions, plan: PlanOptions):
        """The controller (:func:`~cartpole.mpc.nmpc.nmpc_swingup`)."""
        return nmpc_swingup(ctx.params, x0=ctx.x0, plan_model=ctx.pm, options=mpc, plan=plan)

    def design(self, ctx: _Context) -> _Design:
        """The NMPC, run at its own period; 8 s (at least a dm_control task's episode) unless the loop says."""
        mpc = self.mpc_options(ctx.loop, ctx.params.timestep)
        plan = self.plan_options(mpc)
        ctx.report("mpc", 0.0)
        nmpc = self.build(ctx, mpc, plan)
        ctx.report("mpc", 1.0)
        own = max(self.duration, _episode_seconds(mpc.objective, ctx.params.timestep))
        T = own if ctx.loop.duration is None else ctx.loop.duration
        return _Design(nmpc, T, ctx.loop.replace(period=float(nmpc.period)),
                       options={"plan": plan, "loop": ctx.loop, "mpc": mpc})

    def measure(self, ctx: _Context, design: _Design, rollout: Rollout, ran) -> tuple:
        """``period``, ``horizon``, ``failures`` (the C's, read after each ``cp_step``, when the compiled program
        ran: :class:`~cartpole.export.inloop.CompiledNMPCLaw`), ``objective`` and a dm_control task's return."""
        nmpc = design.controller
        extra = {"switches": [], "period": float(nmpc.period), "horizon": float(nmpc.horizon),
                 "failures": _count(getattr(ran if hasattr(ran, "failures") else nmpc, "failures", 0)), "objective": getattr(nmpc, "objective", "tracking")}
        extra.update(_episode_return(rollout, ctx.model, extra["objective"]))
        return None, extra


class DDPMPCSwingup(NMPCSwingup):
    """MPC by box-DDP on any running objective (:func:`cartpole.mpc.ddp_mpc.ddp_mpc_swingup`, ``mpc.solver="ddp"``),
    its offline seed plan following the MPC's objective."""

    def plan_options(self, mpc: MPCOptions) -> PlanOptions:
        """The seed plan's options (:func:`~cartpole.mpc.ddp_mpc.seed_plan_options`)."""
        return seed_plan_options(super().plan_options(mpc), mpc)

    def build(self, ctx: _Context, mpc: MPCOptions, plan: PlanOptions):
        """The controller (:func:`~cartpole.mpc.ddp_mpc.ddp_mpc_swingup`)."""
        return ddp_mpc_swingup(ctx.params, x0=ctx.x0, plan_model=ctx.pm, options=mpc, plan=plan)


class SupervisorSwingup(SwingupMethod):
    """The supervisor (:class:`~cartpole.supervise.Supervisor`): the catch in its verified basin, the energy law on
    one pole driven by the cart, else a passive brake and a plan from the state predicted over the planning
    latency, TVLQR along it; again whenever the state is knocked out of the basin."""

    name = "supervisor"
    duration = SUPERVISOR_DURATION
    designs_catch = True

    def design(self, ctx: _Context) -> _Design:
        """The supervisor for the whole run."""
        plan = self.options.plan or PlanOptions()
        loop, R, noise = _sensor_design(  # the catch (and the estimator) designed for the rig's sensors, as energy's
            ctx, lambda r: LinearFeedback.for_model(ctx.pm, R=r, period=ctx.loop.period).K,
            SWINGUP_CATCH_R * np.eye(ctx.pm.nu))
        sup = supervisor_for(ctx.params, ctx.pm, period=ctx.loop.period, plan=plan, basin_of=ctx.basin_of,
                             catch_R=None if noise is None else R)
        if getattr(ctx.on_step, "realtime", False):  # a live view paced in real time: plans made while it runs
            sup = paced_supervisor(sup)
        return _Design(sup, ctx.duration(self.duration), loop, sup.basin, options={"plan": plan, "loop": loop},
                       noise=noise)

    def release(self, design: _Design) -> None:
        """End the supervisor's planning worker (no child process left, whatever ended the run)."""
        design.controller.close()

    def measure(self, ctx: _Context, design: _Design, rollout: Rollout, ran) -> tuple:
        """The last catch, and the supervisor's summary (``supervisor``)."""
        sup = design.controller
        catches = [d.t for d in sup.decisions if d.kind == "catch"]
        return (catches[-1] if catches else None), {"supervisor": sup.summary()}


#: The class of each method name (:func:`method_class`).
METHOD_CLASSES = {"energy": EnergySwingup, "trajopt": TrajoptSwingup, "mpc": NMPCSwingup,
                  "supervisor": SupervisorSwingup}


def method_class(name: str, mpc: MPCOptions | None = None) -> type:
    """The :class:`SwingupMethod` subclass that runs method ``name`` (one of :data:`METHODS`): mpc with
    ``mpc.solver == "ddp"`` is :class:`DDPMPCSwingup`.

    Raises
    ------
    SwingupError
        An unknown method.
    """
    if name not in METHOD_CLASSES:
        raise SwingupError(f"Unknown swing-up method '{name}'; choose one of {', '.join((AUTO,) + METHODS)}.")
    if name == "mpc" and mpc is not None and mpc.solver == "ddp":
        return DDPMPCSwingup
    return METHOD_CLASSES[name]


def run_swingup(plant=None, method="auto", options: SwingupOptions | None = None, *, x0=None,
                plan_model: CartPoleModel | None = None, progress: Callable[[str, float], None] | None = None,
                basin_cache=None, on_step=None) -> SwingupResult:
    """Swing up from ``x0`` and hold upright, in MuJoCo on the MJCF.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The model (None = shipped asset): one pole on a cart for ``energy``, any chain for ``trajopt``.
    method : {"auto", "energy", "trajopt", "mpc", "supervisor"} or sequence of str or MethodTry
        ``"auto"`` (default): the methods :func:`auto_methods` chooses for the model, tried in turn until one
        succeeds in MuJoCo (energy shaping for one pole driven by the cart; the planner, then the planner with DDP
        on the exact discrete step, for chains, hinge-driven models and after a method that failed); with a loop
        that knocks or throws the pole, the supervisor. One name runs that method alone (its class:
        :func:`method_class`). A sequence (of names or :class:`MethodTry`, a trajopt entry naming its ``solver``) is
        tried in its order in the same way.
    options : SwingupOptions, optional
        Every setting: each stage's options (``plan``, ``loop``, ``mpc``, ``energy``), the catch's weights, the
        bounds planned within, the time budget, the ctrl-noise limit; default :data:`DEFAULT_OPTIONS`.
    x0 : (2 nq,) array, optional
        Start state ``[qpos, qvel]`` (m, rad, m/s, rad/s); default the model's hanging rest ``x_hanging``, a
        position just outside its range moved onto the edge (:func:`start_state`).
    plan_model : CartPoleModel, optional
        The planning model itself (a fitted file's, or built once by a caller that runs many swing-ups); default
        :func:`planning_model` of ``options.loop.model_error``.
    progress : callable, optional
        ``progress(stage, fraction)`` with stage "basin", "trajopt", "mpc" or "simulate".
    basin_cache : BasinCache, optional
        Where basin estimates are looked up and kept; default ``BasinCache.on_disk()`` (the user cache directory,
        ``$CARTPOLE_CACHE_DIR`` honoured), so a second run with the same model and catch does not estimate again.
    on_step : callable, optional
        ``on_step(m, d)`` during the MuJoCo run (e.g. :class:`cartpole.viz.viewer.LiveViewer`, to watch it live);
        returning False ends the run (see :func:`cartpole.sim.rollout.simulate`) and tries no further method.

    Returns
    -------
    SwingupResult
        The run of the method that ran last (the first that succeeded, else the last one tried);
        ``result.methods_tried`` lists every method considered, ``result.options`` the options of each stage of
        the method that ran, as run.

    Raises
    ------
    SwingupError, MJCFError
        Bad method or start state; a stage's options given to methods without that stage (``plan`` to energy,
        ``mpc`` to anything but mpc, ``ctrl_noise`` to mpc or the supervisor); an MJCF that is not a cart-pole;
        ``"auto"`` on a model no method takes (the sentence gives each method's reason).
    LoopError, PlanOptionsError, NMPCError
        Bad loop, planner or NMPC settings (a push, a model error, a duration...).
    EnergyShapingError
        ``energy`` on a model energy shaping does not drive (more than one pole, a motor on a hinge), raised
        before the basin estimate or any simulation.
    OCPError
        The planner found no swing-up (or proved none exists) and no method before it ran in MuJoCo.
    """
    options = DEFAULT_OPTIONS if options is None else options
    if not isinstance(options, SwingupOptions):
        raise SwingupError(f"run_swingup takes its settings as options=SwingupOptions(...); got {options!r}.")
    tries = None if isinstance(method, str) and method == AUTO else method_list(method)
    model, params, limits = _planned_model(plant, options)
    plan_model = None if plan_model is None else bounded_model(plan_model, limits)
    for t in tries or ():
        check_plan_size(model, t.method)
    x0, moves = start_state(x0, params, default=model.x_hanging)
    loop = options.loop
    check_push(loop.push, params)  # a push needs a cart
    pm = plan_model if plan_model is not None else planning_model(model, loop.model_error)
    if tries is None:  # knocked down or thrown: the controller that swings up again, for the whole run
        tries = (MethodTry("supervisor"),) if loop.disturbed else auto_methods(pm, plan=options.plan,
                                                                                energy_options=options.energy)
    friction = friction_design(pm, loop)  # designed without the friction a compensation cancels, run with it
    methods = _methods(tries, options, friction.model, params.timestep)
    cache = BasinCache.on_disk() if basin_cache is None else basin_cache
    ctx = _Context(params=params, model=model, pm=friction.model, plant=pm, friction=friction, loop=loop, x0=x0,
                   force=loop.push_force(params.timestep), progress=progress, on_step=on_step,
                   basin_of=lambda catch: cache.get(params, catch, progress=_stage(progress, "basin")),
                   limits=limits, moves=tuple(moves), ctrl_noise=options.ctrl_noise)
    if len(tries) == 1:
        t0 = time.perf_counter()
        res = methods[0].run(ctx)
        return replace(res, methods_tried=(_outcome(tries[0], res, time.perf_counter() - t0),))
    budget = AUTO_TIME_BUDGET if options.time_budget is None else options.time_budget
    return _run_in_turn(tries, methods, ctx, budget)


def _planned_model(plant, options: SwingupOptions) -> tuple:
    """``(model, params, limits)``: the plant's model within the bounds planned within
    (:func:`~cartpole.models.planning_limits` of ``options.u_max``, ``options.cart_max``), refused when upright is out
    of a hinge's range or geoms touch on the way up."""
    if isinstance(plant, CartPoleModel):
        model, params = plant, plant.params
    else:
        model, params = None, plant_params(plant)
    params, limits = planning_limits(params, u_max=options.u_max, cart_max=options.cart_max)
    model = model if model is not None and model.params is params else build_model(params)
    check_upright_reachable(model)
    model.contacts.check_swingup()  # geoms that touch on the way up (cartpole.models.contacts): refused, named
    return model, params, limits


def _methods(tries: tuple, options: SwingupOptions, pm: CartPoleModel, timestep: float) -> list:
    """The :class:`SwingupMethod` of each pending entry of ``tries`` (None for the others), after refusing, before
    anything runs, settings no pending method has a stage for, and each method's own refusals."""
    names = [t.method for t in tries if not t.outcome]
    if not names:
        raise SwingupError("No swing-up method takes this model: "
                           + "; ".join(f"{t.label} {t.reason}" for t in tries) + ".")
    loop = options.loop
    if loop.duration is not None:
        check_push_times(loop.push, loop.duration)
    elif names[0] != "trajopt":  # trajopt's length is known after the plan (checked there, before simulating)
        check_push_times(loop.push, method_class(names[0], options.mpc).duration)
    if options.ctrl_noise is not None and not any(method_class(n, options.mpc).designs_catch for n in names):
        raise SwingupError("`ctrl_noise` designs the catch of the energy, trajopt and supervisor swing-ups; use it "
                           "with `method='energy'`, `method='trajopt'` or `method='supervisor'`.")
    if options.mpc is not None and "mpc" not in names:
        raise SwingupError("`mpc` options set the NMPC; use them with `method='mpc'`.")
    if options.plan is not None and not {"trajopt", "mpc", "supervisor"} & set(names):
        raise SwingupError("`plan` options set the trajectory optimisation; use them with `method='trajopt'` or "
                           "`method='mpc'`.")
    out = []
    for t in tries:
        if t.outcome:
            out.append(None)
            continue
        cls = method_class(t.method, options.mpc)
        # energy shaping refuses a model it cannot drive with its own sentence, before any basin estimate runs
        m = cls(options, t, pm=pm) if cls is EnergySwingup else cls(options, t)
        m.check(pm, timestep)
        out.append(m)
    return out


def own_duration(result: SwingupResult) -> float:
    """s: the duration a run of ``result``'s method lasts when none is given: :data:`ENERGY_DURATION` (energy),
    :data:`MPC_DURATION` (mpc), the plan's horizon + :data:`TRAJOPT_EXTRA` (trajopt), at least a dm_control task's
    episode."""
    objective = result.metrics.get("objective")
    timestep = float(result.rollout.t[1] - result.rollout.t[0]) if len(result.rollout.t) > 1 else 0.0
    episode = _episode_seconds(objective, timestep) if objective is not None and timestep > 0 else 0.0
    if result.method == "trajopt" and result.plan is not None:
        return max(float(result.plan.t[-1] - result.plan.t[0]) + TRAJOPT_EXTRA, episode)
    return max(METHOD_CLASSES[result.method].duration, episode)


def _run_in_turn(tries: tuple, methods: list, ctx: _Context, budget: float) -> SwingupResult:
    """Run the pending entries of ``tries`` (:class:`MethodTry`, their ``methods``) in turn until one succeeds; the
    result of the last run, with every entry (its outcome, reason and wall time) in ``methods_tried``. A planner that
    raised (:class:`~cartpole.ocp.bounds.OCPError` other than bad settings: no plan found, or none exists) ends the
    planners after it; no method starts with less than :data:`AUTO_NEXT_FACTOR` times the time of the run before
    it left of ``budget`` s; a run stopped by ``ctx.on_step`` (the live view closed), or cut short by a given
    duration below its method's own (:func:`own_duration`: its failure says nothing of the method) ends the turn.
    Re-raises the last planner error when nothing ran in MuJoCo."""
    start = time.perf_counter()
    done, result, error = [], None, None
    last = 0.0  # s the run before took
    stop = None  # why every later method is skipped
    no_plan = None  # why every later planner is skipped
    for t, method in zip(tries, methods):
        elapsed = time.perf_counter() - start
        if t.outcome:  # not applicable to this model
            done.append(t)
            continue
        if stop is None and last > 0 and budget - elapsed < AUTO_NEXT_FACTOR * last:
            stop = (f"{elapsed:.1f} s of the {budget:g} s time budget were spent and the run before took "
                    f"{last:.1f} s; raise the `time_budget` or run {t.arguments} alone")
        why = stop or (no_plan if t.method == "trajopt" else None)
        if why is not None:
            done.append(replace(t, outcome="skipped", reason=why))
            continue
        t0 = time.perf_counter()
        try:
            res = method.run(ctx)
        except OCPError as exc:
            if isinstance(exc, PlanOptionsError):
                raise
            error = exc
            last = time.perf_counter() - t0
            done.append(replace(t, outcome="error", reason=first_line(exc), seconds=last))
            no_plan = "the planner before it found no plan, and every planner starts from the same search"
            continue
        result = res
        last = time.perf_counter() - t0
        done.append(_outcome(t, res, last))
        stop = stop or _turn_ends(ctx, res, done)
    if result is None:
        raise error
    return replace(result, methods_tried=tuple(done))


def _turn_ends(ctx: _Context, res: SwingupResult, done: list) -> str | None:
    """Why no method runs after ``res`` (None: the turn goes on); a run cut short by the loop's duration says so
    in its own entry, the last of ``done``."""
    duration = ctx.loop.duration
    short = not res.success and duration is not None and duration < own_duration(res)
    if short:
        done[-1] = replace(done[-1], reason=f"{done[-1].reason}; the run of {duration:g} s was shorter than the "
                                            f"method's own {own_duration(res):.3g} s")
    if res.success:
        return "an earlier method succeeded"
    if getattr(ctx.on_step, "closed", False) or getattr(ctx.on_step, "interrupted", False):
        return "the live view was closed or interrupted"
    if short:
        return (f"the run before it was cut short by the duration given ({duration:g} s); give a longer "
                "`duration`, or none")
    return None


def _outcome(t: MethodTry, res: SwingupResult, seconds: float) -> MethodTry:
    """``t`` with the outcome of its run ``res``: "success" or "failed", and why in a few words."""
    solver = t.solver
    if res.method == "trajopt" and solver is None:
        solver = res.options["plan"].solver
    if res.success:
        reason = "upright and at rest over the last second" + (
            f", caught at {res.caught_at:.2f} s" if res.caught_at is not None else "")
    else:
        reason = failure_reason(res.metrics) + (
            f"; handed over to the catch at {res.handover_at:.2f} s, it did not hold"
            if res.handover_at is not None else "")
    return replace(t, solver=solver, outcome="success" if res.success else "failed", reason=reason,
                   seconds=float(seconds))


@dataclass(frozen=True)
class _Ran:
    """One method's MuJoCo run before the shared metrics: the rollout, the controller that ran, its rig, the catch
    basin (or None), the plan (or None), the hand-over time to the catch (s or None), the method's own metrics and
    the options of its stages as run."""

    rollout: Rollout
    controller: object
    rig: object
    basin: object
    plan: object
    handover_at: float | None
    extra: dict
    options: dict


def _simulate(ctx: _Context, controller, T: float, *, loop=None) -> tuple:
    """The closed loop every method shares: the rig for ``loop`` (default the context's) around the plant, the
    friction compensation outermost, MuJoCo for ``T`` s at the loop's period; ``(controller as run, rig,
    rollout)``."""
    loop = ctx.loop if loop is None else loop
    rig = build_rig(ctx.plant, loop, task="swingup")
    # the controller that runs, friction compensation outermost; the one implementation: the export's compiled C
    # (law, estimator, delay prediction, clip) when there is a compiler, its state read from the C
    controller = ctx.friction.wrap(controller)
    controller, rig = in_loop(ctx.model, controller, rig)
    force = ctx.force
    attach = getattr(ctx.on_step, "attach", None)
    if attach is not None:  # the web page: it shows this law's state, its pushes join the logged push column
        force = attach(controller, push=force)
    disturbance = loop.disturbance(ctx.params, x_eq=ctx.model.x_eq, hinges=ctx.model.hinges, model=ctx.model)
    watch = SimOptions(control_period=loop.period, progress=_stage(ctx.progress, "simulate"), on_step=ctx.on_step)
    rollout = simulate(ctx.params, controller, ctx.x0, T, push=force, rig=rig, disturbance=disturbance, options=watch)
    if disturbance is not None:
        rollout.info["disturbances"] = disturbance.events
    ctx.report("simulate", 1.0)
    return controller, rig, rollout


#: The ctrl noise (fraction of the ctrl range, standard deviation) a swing-up's catch is designed for by default on
#: a rig with sensors and an estimator (:func:`_sensor_design`). Measured on the shipped two-pole cart from
#: 2048-count encoders, period and delay 10 ms: the hinge rates MuJoCo's true state shows in the hold stay below
#: the success test's rest tolerance (0.1 rad/s) with 1.6 % and not with 3 %; so 2 %, not the 10 % a motor survives.
DEFAULT_CTRL_NOISE = 0.02
#: Seconds at the end of the hold over which the measured ctrl noise is taken (shorter when the hold is).
CTRL_NOISE_WINDOW = 4.0


def _sensor_design(ctx: _Context, gain, R0):
    """``(loop, R, doc)``: the loop to run (its estimator's process noise chosen), the catch's ``R`` and the JSON
    ``ctrl_noise`` design (None, with ``ctx.loop`` and ``R0``, on a rig without sensors when no limit is asked):
    :func:`cartpole.apps.margins.noise_limited_catch` of ``ctx.ctrl_noise`` or :data:`DEFAULT_CTRL_NOISE` with
    ``gain(R) -> K`` the method's catch."""
    sensed = ctx.loop.sensed and ctx.loop.estimator_for("swingup") != "none"
    if ctx.ctrl_noise is None and not sensed:
        return ctx.loop, R0, None
    asked = ctx.ctrl_noise is not None
    found = noise_limited_catch(ctx.pm, ctx.loop, ctx.ctrl_noise if asked else DEFAULT_CTRL_NOISE, gain, R0,
                                required=asked)
    loop = ctx.loop.replace(process_noise=found["process_noise"])
    doc = {"fraction": found["fraction"], "default": not asked, "met": found["met"], "factor": found["factor"],
           "R": np.asarray(found["R"]).tolist(), "process_noise": found["process_noise"],
           "predicted_std": found["predicted_std"].tolist(),
           "predicted_fraction": found["predicted_fraction"].tolist(),
           "predicted_state_std": found["predicted_state_std"].tolist()}
    return loop, found["R"], doc


def _noise_measured(doc: dict, rollout, handover_at: float | None, span) -> dict:
    """``doc`` with the ctrl noise MuJoCo measured: ``measured_std`` and ``measured_fraction`` (per input, ctrl units
    and of the ctrl range's width) and ``measured_state_std`` (nx, the true state's, beside ``predicted_state_std``)
    over the last ``measured_window_s`` s of the hold (:data:`CTRL_NOISE_WINDOW`, less when the hold after
    ``handover_at`` is shorter); None without a hand-over. ``span`` (nu,): the ctrl ranges' widths."""
    t, u = rollout.t, rollout.ctrl
    window = 0.0 if handover_at is None else min(CTRL_NOISE_WINDOW, float(t[-1]) - float(handover_at))
    if window <= 0:
        return {**doc, "measured_std": None, "measured_fraction": None, "measured_state_std": None,
                "measured_window_s": None}
    std = u[t[1:] > t[-1] - window].std(axis=0)
    return {**doc, "measured_std": std.tolist(), "measured_fraction": (std / span).tolist(),
            "measured_state_std": rollout.x[t > t[-1] - window].std(axis=0).tolist(), "measured_window_s": window}


def _finish(ctx: _Context, method: str, ran: _Ran) -> SwingupResult:
    """The shared metrics of a run (:func:`~cartpole.validation.metrics.swingup_metrics`, the method's own, the
    rig's, estimation and friction) and its result: ``caught_at`` is the hand-over only when the catch held
    (:func:`~cartpole.validation.metrics.catch_held`)."""
    rollout, rig, params = ran.rollout, ran.rig, ctx.params
    metrics = {**swingup_metrics(rollout, ctx.model, rig=rig), **ran.extra}  # at rest to the rig's sensors
    handover_at = None if metrics["diverged"] else ran.handover_at  # MuJoCo reset a blown-up run: never caught
    caught_at = handover_at if catch_held(rollout, ctx.model, handover_at, rig=rig) else None
    metrics["handover_at"] = handover_at
    events = rollout.info.get("disturbances") if isinstance(rollout.info, dict) else None
    if events is not None:  # knocked or thrown: how much of the run was upright, how often it swung up again
        requested = ctx.loop.duration if ctx.loop.duration is not None else float(rollout.t[-1])
        metrics.update(uptime_metrics(rollout, ctx.model, events=events, duration=requested))
    if rig is not None and rig.estimator != "none":
        metrics["estimation"] = estimation_summary(rollout, rig.estimator, params.hinges, state_names(params))
    metrics["rig"] = None if rig is None else rig.to_dict()
    metrics["friction"] = friction_summary(params, ctx.friction.compensated)
    metrics["limits"] = ctx.limits.to_dict()
    metrics["start_moved"] = [mv.to_dict() for mv in ctx.moves]
    return SwingupResult(method=method, success=bool(metrics["success"]), caught_at=caught_at, rollout=rollout,
                         plan=ran.plan, basin=ran.basin, metrics=metrics, push=ctx.loop.push,
                         model_error=ctx.loop.model_error, controller=ran.controller, options=ran.options,
                         handover_at=handover_at)


def _episode_seconds(objective, timestep: float) -> float:
    """s of a dm_control task's episode (its control steps times its control step) on a file stepping ``timestep``
    s; 0 for any other objective."""
    if not is_task(objective):
        return 0.0
    t = task(objective)
    return t.steps(timestep) * t.control_dt(timestep)


def _episode_return(rollout, model, objective) -> dict:
    """``return`` and ``return_steps``: dm_control's exact reward summed over its episode of the logged run, for a
    dm_control task's objective; empty for any other."""
    if not is_task(objective):
        return {}
    rewards = dmc_rewards(rollout, model, objective=objective, steps=EPISODE)
    return {"return": float(np.sum(rewards)), "return_steps": int(rewards.size)}


def _mpc_period(mpc, loop: LoopOptions, timestep: float):
    """``mpc`` with its period the loop's when it has none; one sentence when both are given and differ by a
    physics step or more (``timestep``, s)."""
    if loop.period is None:
        return mpc
    if mpc.period is None:
        return mpc.replace(period=loop.period)
    if round(mpc.period / timestep) != round(loop.period / timestep):
        raise SwingupError(f"The loop's period {loop.period:g} s and the NMPC's {mpc.period:g} s differ; give the "
                           "control period once.")
    return mpc


def _count(failures) -> int:
    """A controller's ``failures`` as a count (it may keep a number or a list of what failed)."""
    return int(failures) if isinstance(failures, (int, np.integer)) else len(failures or ())
