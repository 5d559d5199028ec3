"""Swing the poles up and hold them, proven in MuJoCo: ``run_swingup(mjcf, method="energy" | "trajopt")``.

* ``energy``: energy shaping (:class:`~cartpole.control.energy.EnergyShapingController`) until the state enters
  the LQR catch's basin ``e' S e < rho`` (``rho`` estimated in MuJoCo by :func:`~cartpole.validation.basin.
  estimate_basin`), then an LQR catch (the lab's Q with R = 1,
  :func:`~cartpole.control.switching.swingup_catch`, whose verified basin is about five times the lab LQR's), with
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

Each stage takes its settings as one value: ``plan=`` :class:`~cartpole.planning.options.PlanOptions` (trajopt, and
mpc's offline plan), ``mpc=`` :class:`~cartpole.mpc.options.MPCOptions`, and for every method ``loop=``
:class:`~cartpole.sim.options.LoopOptions`, the closed loop's scenario: ``push=((T, F), ...)`` (a horizontal force
of F N on the cart body for :data:`PUSH_SECONDS` from time T s, through MuJoCo's ``xfrc_applied``; logged per physics
step in ``rollout.info["push"]``, so the run still replays exactly) and ``model_error=S`` (the *planning* model's pole
masses and lengths scaled by S, :meth:`~cartpole.models.CartPoleParams.scaled_pole`; MuJoCo keeps the file's). With
model error, energy shaping and its catch (energy), the plan and its TVLQR (trajopt) or the NMPC's model (mpc) are
built on the scaled model; the catch basin is still measured in MuJoCo on the MJCF (the basin of the catch as built).

The start state is ``[qpos, qvel]`` in MuJoCo's order (``2 nq`` numbers; default the model's hanging rest
``x_hanging``). Either way MuJoCo runs the controller on the MJCF and every physics step is logged (``qpos``
(n+1, nq), ``qvel`` (n+1, nq), ``ctrl`` (n, nu)), so the result replays exactly
(:func:`~cartpole.sim.rollout.replays_exactly`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from cartpole.control.friction import friction_design, friction_summary
from cartpole.errors import CartPoleError
from cartpole.models import (CartPoleModel, CartPoleParams, bounded_model, build_model, planning_limits, read_params,
                             start_on_range)
from cartpole.sim import Rollout, simulate
from cartpole.sim.options import (PUSH_SECONDS, LoopError, LoopOptions, check_model_error, check_push,
                                  check_push_times, push_force)

#: Re-exported from :mod:`cartpole.sim.options`, where the closed loop's settings live (the command line and the
#: sweep import them from here).
__all__ = ["ENERGY_DURATION", "METHODS", "MPC_DURATION", "PUSH_SECONDS", "TRAJOPT_EXTRA", "LoopError", "SwingupError",
           "SwingupResult", "check_model_error", "check_push", "check_plan_size", "check_start", "check_upright_reachable",
           "parse_push", "plan_model_from", "plan_report",
           "planning_model", "push_force", "run_swingup"]

METHODS = ("energy", "trajopt", "mpc")

#: Default simulated time in s after the start (energy, mpc) or after the plan's end (trajopt).
ENERGY_DURATION = 10.0
TRAJOPT_EXTRA = 3.0
MPC_DURATION = 8.0


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
        s: when the LQR catch took over for good (energy: last switch into the basin; trajopt: the plan's
        handover time), None if it never did or the run diverged (MuJoCo reset a blown-up state: never a catch).
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
                               f"[{lo}, {hi}] m; give a start (x0, --x0 on the command line) with the cart "
                               "strictly inside it.")
        if j.kind == "hinge" and not lo <= x[i] <= hi:
            raise SwingupError(f"The start angle {x[i]} rad of hinge '{j.name}' is outside its joint range "
                               f"[{lo}, {hi}] rad; give a start (x0, --x0 on the command line) inside it.")
    return x


#: Most poles a trajectory optimisation (trajopt, and the NMPC's plan) is built for: its generated C grows steeply with
#: every pole (see :data:`cartpole.codegen.LARGE_SOURCE`); a longer chain is refused before anything is built.
MAX_PLAN_POLES = 3


def check_plan_size(model: CartPoleModel, method: str) -> None:
    """Refuse, before anything is built, a chain too long for ``method``'s planner (:data:`MAX_PLAN_POLES`).

    Raises
    ------
    SwingupError
        ``method`` is trajopt or mpc and the model has more hinges than :data:`MAX_PLAN_POLES`.
    """
    n = len(model.hinges)
    if method in ("trajopt", "mpc") and n > MAX_PLAN_POLES:
        raise SwingupError(f"This MJCF has a chain of {n} poles and --method {method} plans for at most "
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
        raise SwingupError(f"--push {text!r} is not T:F (a start time in s and a force in N); give e.g. --push "
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
        raise SwingupError(f"The planning MJCF {a.mjcf} is not the same machine as --mjcf {b.mjcf} (joints "
                           f"{', '.join(a.joint_names)} vs {', '.join(b.joint_names)}, actuators, time step "
                           f"{a.timestep:g} vs {b.timestep:g} s or integrator {a.integrator} vs {b.integrator} "
                           "differ); give a --plan-mjcf fitted to or edited from the --mjcf file.")
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


#: The keywords ``run_swingup`` took before the options objects, and the stage each one sets (a compatibility layer).
LEGACY_KEYWORDS = {"duration": "loop", "push": "loop", "model_error": "loop", "objective": "plan", "period": "mpc",
                   "horizon": "mpc"}


def run_swingup(mjcf=None, *, method: str = "energy", x0=None, plan=None, loop: LoopOptions | None = None,
                mpc=None, energy_options=None, catch_weights: tuple | None = None,
                plan_model: CartPoleModel | None = None, progress: Callable[[str, float], None] | None = None,
                basin_cache=None, on_step=None, u_max=None, cart_max: float | None = None,
                **legacy) -> SwingupResult:
    """Swing up from ``x0`` and hold upright, in MuJoCo on the MJCF.

    Parameters
    ----------
    mjcf : path, CartPoleParams, CartPoleModel or None
        The model (None = shipped asset): one pole on a cart for ``energy``, any chain for ``trajopt``.
    method : {"energy", "trajopt", "mpc"}
    x0 : (2 nq,) array, optional
        Start state ``[qpos, qvel]``; default the model's hanging rest ``x_hanging`` (``[0, pi, 0, 0]`` for the
        shipped cart).
    plan : PlanOptions, optional
        ``trajopt`` and ``mpc`` (its offline plan): the planner's settings
        (:class:`~cartpole.planning.options.PlanOptions`); default ``PlanOptions()`` (mpc:
        ``PlanOptions(cart_margin=mpc.cart_margin)``).
    loop : LoopOptions, optional
        The closed loop (:class:`~cartpole.sim.options.LoopOptions`): ``duration`` (s; None: 10 s energy, 8 s mpc,
        the plan's horizon + 3 s trajopt, with a ``dmc_*`` task at least dm_control's episode (1000 control steps) so
        the return counts all of them), ``period`` (s; ``mpc`` only: the NMPC re-plans at it), ``push`` and
        ``model_error`` (the planning model is :func:`planning_model` of it; MuJoCo keeps the MJCF's).
    mpc : MPCOptions, optional
        ``mpc`` only: the controller's settings (:class:`~cartpole.mpc.options.MPCOptions`); its period, when None,
        is the loop's, else the controller's default.
    energy_options : EnergyOptions or dict, optional
        ``energy`` only: the energy shaping's settings (:class:`~cartpole.control.energy.EnergyOptions`, or a dict
        of its field names); default its defaults.
    catch_weights : (Q, R), optional
        LQR weights of the catch; default the lab's ``Q`` with ``R = 1``
        (:func:`~cartpole.control.switching.swingup_catch`; the lab's ``R = 0.1`` gives a much smaller basin).
        Pass ``(cartpole.Q_LAB, cartpole.R_LAB)`` for the lab's LQR. Energy method only: the trajopt hand-over is
        :func:`cartpole.planning.trajopt.handover_catch`.
    plan_model : CartPoleModel, optional
        The planning model itself, built once by a caller that runs many swing-ups (a sweep); default
        :func:`planning_model` of ``loop.model_error``.
    progress : callable, optional
        ``progress(stage, fraction)`` with stage "basin", "trajopt", "mpc" or "simulate".
    basin_cache : BasinCache, optional
        Where basin estimates are looked up and kept; default ``BasinCache.on_disk()`` (the user cache directory,
        ``$CARTPOLE_CACHE_DIR`` honoured), so a second run with the same model and catch does not estimate again.
    on_step : callable, optional
        ``on_step(m, d)`` during the MuJoCo run (e.g. :class:`cartpole.viz.viewer.LiveViewer`, to watch it live);
        returning False ends the run (see :func:`cartpole.sim.rollout.simulate`).
    u_max : float or (nu,) array, optional
        ``|ctrl| <= u_max`` the swing-up plans and runs within; default each actuator's ctrlrange, or where the
        file has none a stated default (:func:`cartpole.models.planning_limits`; ``metrics["limits"]`` says which).
    cart_max : float, optional
        m: the cart keeps ``|s - centre| <= cart_max``; default the slide's range, or a stated default when the
        file's slide is unlimited.
    **legacy
        A compatibility layer for the keywords this function took before the options objects
        (:data:`LEGACY_KEYWORDS`): ``duration``, ``push``, ``model_error`` (fields of ``loop``), ``objective``
        (``plan`` for trajopt; for mpc the MPC's own objective, ``mpc.objective``), ``period``, ``horizon`` (``mpc``; mpc only). Each replaces that field of the
        stage's options (None leaves it as it is) and does nothing else.

    Returns
    -------
    SwingupResult
        ``result.options`` holds the options of each stage as run.

    Raises
    ------
    SwingupError, MJCFError
        Bad method or start state; a stage's options given to a method without that stage (``plan`` to energy,
        ``mpc`` or a loop period to energy or trajopt, ``objective`` to energy); an unknown keyword; an
        MJCF that is not a cart-pole; ``mpc`` without :mod:`cartpole.mpc.nmpc`.
    LoopError, PlanOptionsError, NMPCError
        Bad loop, planner or NMPC settings (a push, a model error, a duration...).
    EnergyShapingError
        ``energy`` on a model energy shaping does not drive (more than one pole, a motor on a hinge), raised
        before the basin estimate or any simulation.
    """
    from cartpole.control.energy import EnergyShapingController
    from cartpole.control.switching import SwitchingController, swingup_catch
    from cartpole.sim.rig import build_rig
    from cartpole.validation.basin import BasinCache
    from cartpole.validation.metrics import swingup_metrics

    if method not in METHODS:
        raise SwingupError(f"Unknown swing-up method '{method}'; choose one of {', '.join(METHODS)}.")
    unknown = sorted(set(legacy) - set(LEGACY_KEYWORDS))
    if unknown:
        raise SwingupError(f"run_swingup has no keyword {', '.join(map(repr, unknown))}; give the stages' settings "
                           f"as plan=, loop=, mpc= options (or the keywords {', '.join(LEGACY_KEYWORDS)}).")
    given = {stage: {k: v for k, v in legacy.items() if LEGACY_KEYWORDS[k] == stage and v is not None}
             for stage in ("plan", "loop", "mpc")}
    if isinstance(mjcf, CartPoleModel):
        model, params = mjcf, mjcf.params
    else:
        params = mjcf if isinstance(mjcf, CartPoleParams) else read_params(mjcf)
        model = None
    loop = (LoopOptions() if loop is None else loop).replace(**given["loop"])
    params, limits = planning_limits(params, u_max=u_max, cart_max=cart_max)  # stated defaults where unlimited
    model = model if model is not None and model.params is params else build_model(params)
    plan_model = None if plan_model is None else bounded_model(plan_model, limits)
    check_upright_reachable(model)
    model.contacts.check_swingup()  # geoms that touch on the way up (cartpole.models.contacts): refused, named
    check_plan_size(model, method)
    x0, moves = start_on_range(model.x_hanging, params) if x0 is None else (x0, ())
    x0 = check_start(x0, params)
    check_push(loop.push, params)  # a push needs a cart
    pm = plan_model if plan_model is not None else planning_model(model, loop.model_error)
    # designed without the friction a compensation cancels, run with it (cartpole.control.friction)
    friction = friction_design(pm, loop)
    plant, pm = pm, friction.model
    force = loop.push_force(params.timestep)
    if loop.duration is not None:
        check_push_times(loop.push, loop.duration)
    elif method != "trajopt":  # trajopt's length is known after the plan (checked there, before simulating)
        check_push_times(loop.push, MPC_DURATION if method == "mpc" else ENERGY_DURATION)
    if method != "mpc" and (mpc is not None or given["mpc"]):
        raise SwingupError("--period and --horizon set the NMPC's control period and horizon; use them with "
                           "--method mpc.")
    # energy shaping refuses a model it cannot drive with its own sentence, before any basin estimate runs
    energy = EnergyShapingController(pm, energy_options) if method == "energy" else None
    if method == "mpc" and "objective" in given["plan"]:  # the MPC's own objective (its seed plan follows it)
        from cartpole.mpc.options import MPCOptions

        mpc = (MPCOptions() if mpc is None else mpc).replace(objective=given["plan"].pop("objective"))
    if given["plan"] and method != "trajopt":
        raise SwingupError("--objective chooses what the trajectory optimisation minimises; use it with --method "
                           "trajopt or mpc.")
    if plan is not None and method == "energy":
        raise SwingupError("Plan options set the trajectory optimisation; use them with --method trajopt or mpc.")
    basin_kw = dict(progress=_stage(progress, "basin"))

    cache = BasinCache.on_disk() if basin_cache is None else basin_cache

    def basin_of(catch):
        return cache.get(params, catch, **basin_kw)

    T = loop.duration
    trajectory = None
    if method == "mpc":
        try:
            from cartpole.mpc.nmpc import nmpc_swingup
        except ModuleNotFoundError as exc:
            if exc.name not in ("cartpole.mpc.nmpc",):
                raise
            raise SwingupError("The mpc method needs cartpole.mpc.nmpc (nonlinear MPC), which this installation "
                               "does not have yet; use --method trajopt or energy.") from None
        from cartpole.mpc.options import MPCOptions, mpc_grid
        from cartpole.planning.options import PlanOptions

        mpc = _mpc_period((MPCOptions() if mpc is None else mpc).replace(**given["mpc"]), loop, params.timestep)
        mpc_grid(mpc, params.timestep)  # a horizon too long to solve, or a period it would round away: refused now
        from cartpole.mpc.ddp_mpc import seed_plan_options

        plan = PlanOptions(cart_margin=mpc.cart_margin) if plan is None else plan
        if mpc.solver == "ddp":
            plan = seed_plan_options(plan, mpc)
        options = {"plan": plan, "loop": loop, "mpc": mpc}
        if progress is not None:
            progress("mpc", 0.0)
        if mpc.solver == "ddp":
            from cartpole.mpc.ddp_mpc import ddp_mpc_swingup

            controller = ddp_mpc_swingup(params, x0=x0, model=pm, options=mpc, plan=plan)
        else:
            controller = nmpc_swingup(params, x0=x0, model=pm, options=mpc, plan=plan)
        if progress is not None:
            progress("mpc", 1.0)
        basin = None
        if T is None:
            T = max(MPC_DURATION, _episode_seconds(mpc.objective, params.timestep))
        rig = build_rig(plant, loop.replace(period=float(controller.period)), task="swingup")
        controller = friction.wrap(controller)  # the controller that runs, friction compensation outermost
        rollout = simulate(params, controller, x0, T, control_period=float(controller.period), push=force,
                           progress=_stage(progress, "simulate"), on_step=on_step, rig=rig)
        if progress is not None:
            progress("simulate", 1.0)
        caught_at = None
        extra = {"switches": [], "period": float(controller.period), "horizon": float(controller.horizon),
                 "failures": _count(getattr(controller, "failures", 0)),
                 "objective": getattr(controller, "objective", "tracking")}
        extra.update(_episode_return(rollout, model, extra["objective"]))
    elif method == "energy":
        options = {"energy": energy.options, "loop": loop}
        catch = swingup_catch(pm, *(catch_weights or ()), period=loop.period)
        basin = basin_of(catch)
        controller = SwitchingController(energy, catch, basin.rho)
        T = ENERGY_DURATION if T is None else T
        rig = build_rig(plant, loop, task="swingup")
        controller = friction.wrap(controller)  # the controller that runs, friction compensation outermost
        rollout = simulate(params, controller, x0, T, push=force, progress=_stage(progress, "simulate"),
                           on_step=on_step, control_period=loop.period, rig=rig)
        if progress is not None:
            progress("simulate", 1.0)
        caught_at = controller.caught_at
        extra = {"switches": [{"t": s.t, "mode": s.mode, "cost": s.cost} for s in controller.switches]}
    else:
        try:
            from cartpole.planning.options import PlanOptions
            from cartpole.planning.trajopt import trajopt_swingup
        except ImportError:
            raise SwingupError("The trajopt method needs cartpole.planning.trajopt, which this installation does not "
                               "have; use --method energy.") from None
        plan = (PlanOptions() if plan is None else plan).replace(**given["plan"])
        options = {"plan": plan, "loop": loop}
        if progress is not None:
            progress("trajopt", 0.0)
        sp = trajopt_swingup(params, x0=tuple(x0), model=pm, options=plan, period=loop.period)
        if progress is not None:
            progress("trajopt", 1.0)
        trajectory = sp.trajectory
        controller = sp.controller
        catch = sp.catch  # the controller that takes over: its basin is the one reported
        basin = basin_of(catch)
        T_plan = float(trajectory.t[-1] - trajectory.t[0])
        if T is None:
            T = T_plan + TRAJOPT_EXTRA
            T = max(T, _episode_seconds(sp.objective, params.timestep))
            check_push_times(loop.push, T)
        rig = build_rig(plant, loop, task="swingup")
        controller = friction.wrap(controller)  # the controller that runs, friction compensation outermost
        rollout = simulate(params, controller, x0, T, push=force, progress=_stage(progress, "simulate"),
                           on_step=on_step, control_period=loop.period, rig=rig)
        if progress is not None:
            progress("simulate", 1.0)
        handover = getattr(controller, "handover_time", T_plan)
        caught_at = float(handover) if handover is not None and rollout.t[-1] >= handover else None
        k = int(np.searchsorted(rollout.t, handover)) if caught_at is not None else None
        extra = {"switches": [] if caught_at is None else [{"t": caught_at, "mode": "catch",
                                                            "cost": catch.cost_to_go(rollout.x[k])}],
                 "handover_cost": None if k is None else catch.cost_to_go(rollout.x[k]),
                 "objective": sp.objective, "plan": plan_report(sp)}
        extra.update(_episode_return(rollout, model, sp.objective))
    metrics = {**swingup_metrics(rollout, model), **extra}
    if metrics["diverged"]:  # MuJoCo reset a blown-up run: whatever came before, it is never caught
        caught_at = None
    if rig is not None and rig.estimator != "none":
        from cartpole.apps.lab import state_names
        from cartpole.validation.estimation import estimation_summary

        metrics["estimation"] = estimation_summary(rollout, rig.estimator, params.hinges, state_names(params))
    metrics["rig"] = None if rig is None else rig.to_dict()
    metrics["friction"] = friction_summary(params, friction.compensated)
    metrics["limits"] = limits.to_dict()
    metrics["start_moved"] = [mv.to_dict() for mv in moves]
    return SwingupResult(method=method, success=bool(metrics["success"]), caught_at=caught_at, rollout=rollout,
                         plan=trajectory, basin=basin, metrics=metrics, push=loop.push, model_error=loop.model_error,
                         controller=controller, options=options)


def _episode_seconds(objective, timestep: float) -> float:
    """s of a dm_control task's episode (its control steps times its control step) on a file stepping ``timestep``
    s; 0 for any other objective."""
    from cartpole.ocp.dmc import is_task, task

    if not is_task(objective):
        return 0.0
    t = task(objective)
    return t.steps(timestep) * t.control_dt(timestep)


def _episode_return(rollout, model, objective) -> dict:
    """``return`` and ``return_steps``: dm_control's exact reward summed over its episode of the logged run, for a
    dm_control task's objective; empty for any other."""
    from cartpole.ocp.dmc import is_task
    from cartpole.validation.metrics import EPISODE, dmc_rewards

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
