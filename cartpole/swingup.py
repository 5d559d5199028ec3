"""Swing the poles up and hold them, proven in MuJoCo: ``run_swingup(mjcf, method="energy" | "trajopt")``.

* ``energy``: energy shaping (:class:`~cartpole.control.energy.EnergyShapingController`) until the state enters
  the LQR catch's basin ``e' S e < rho`` (``rho`` estimated in MuJoCo by :func:`~cartpole.validation.basin.
  estimate_basin`), then an LQR catch (the lab's Q with R = 1,
  :func:`~cartpole.control.switching.swingup_catch`, whose verified basin is about five times the lab LQR's), with
  hysteresis (:class:`~cartpole.control.switching.SwitchingController`). One pole on a cart driven by the cart
  only: any other model is refused with the controller's one sentence, before anything runs;
* ``trajopt``: direct collocation + TVLQR (:func:`cartpole.ocp.pipeline.trajopt_swingup`) for the chosen
  ``objective`` (:mod:`cartpole.ocp.objectives`), handing over to the LQR hold after the plan; any model the
  planner takes. The basin reported is the hand-over LQR's (:func:`cartpole.ocp.pipeline.handover_catch`), the
  controller that actually takes over; with ``objective="dmc_swingup"`` the metrics add dm_control's ``return``
  of the logged run (:func:`~cartpole.validation.metrics.dmc_swingup_return`) and its ``return_steps``.

The start state is ``[qpos, qvel]`` in MuJoCo's order (``2 nq`` numbers; default the model's hanging rest
``x_hanging``). Either way MuJoCo runs the controller on the MJCF and every physics step is logged (``qpos``
(n+1, nq), ``qvel`` (n+1, nq), ``ctrl`` (n, nu)), so the result replays exactly
(:func:`~cartpole.sim.rollout.replays_exactly`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, CartPoleParams, build_model, read_params
from cartpole.sim import Rollout, simulate

METHODS = ("energy", "trajopt")

#: Default simulated time in s after the start (energy) or after the plan's end (trajopt).
ENERGY_DURATION = 10.0
TRAJOPT_EXTRA = 3.0


class SwingupError(CartPoleError):
    """Bad swing-up request: unknown method, start state not finite or outside the joint range, bad duration."""


@dataclass(frozen=True)
class SwingupResult:
    """What a swing-up did in MuJoCo.

    Attributes
    ----------
    method : str
        "energy" or "trajopt".
    success : bool
        :func:`~cartpole.validation.metrics.swingup_success` of the rollout.
    caught_at : float or None
        s: when the LQR catch took over for good (energy: last switch into the basin; trajopt: the plan's
        handover time), None if it never did.
    rollout : Rollout
        Every physics step MuJoCo took.
    plan : Trajectory or None
        The optimised trajectory (trajopt), else None.
    basin : BasinEstimate or None
        The catch basin estimate used (energy) or checked against at the handover (trajopt).
    metrics : dict
        :func:`~cartpole.validation.metrics.swingup_metrics` plus ``switches`` (list of
        ``{"t", "mode", "cost"}``) and, for trajopt, ``handover_cost`` (``e' S e`` at the handover).
    """

    method: str
    success: bool
    caught_at: float | None
    rollout: Rollout
    plan: object = None
    basin: object = None
    metrics: dict = field(default_factory=dict)


def _state_order(params: CartPoleParams) -> str:
    """The state's order in words, from the MJCF's joint names: ``"slider (m), hinge (rad), then their rates"``."""
    pos = ", ".join(f"{j.name} ({'m' if j.kind == 'slide' else 'rad'})" for j in params.joints)
    return f"{pos}, then their rates in the same order"


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
        finite, a slide not strictly inside its range or a hinge outside its range.
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
        lo, hi = (float(v) for v in j.range)
        if j.kind == "slide" and not lo < x[i] < hi:
            raise SwingupError(f"The start position {x[i]} m of slide '{j.name}' is outside its joint range "
                               f"[{lo}, {hi}] m; start the cart strictly inside it.")
        if j.kind == "hinge" and not lo <= x[i] <= hi:
            raise SwingupError(f"The start angle {x[i]} rad of hinge '{j.name}' is outside its joint range "
                               f"[{lo}, {hi}] rad; start the pole inside it.")
    return x


def _stage(progress, name):
    return None if progress is None else (lambda f: progress(name, f))


def run_swingup(mjcf=None, *, method: str = "energy", x0=None, duration: float | None = None,
                progress: Callable[[str, float], None] | None = None, basin_cache=None,
                energy_options: dict | None = None, catch_weights: tuple | None = None,
                objective=None, on_step=None) -> SwingupResult:
    """Swing up from ``x0`` and hold upright, in MuJoCo on the MJCF.

    Parameters
    ----------
    mjcf : path, CartPoleParams, CartPoleModel or None
        The model (None = shipped asset): one pole on a cart for ``energy``, any chain for ``trajopt``.
    method : {"energy", "trajopt"}
    x0 : (2 nq,) array, optional
        Start state ``[qpos, qvel]``; default the model's hanging rest ``x_hanging`` (``[0, pi, 0, 0]`` for the
        shipped cart).
    duration : float, optional
        Simulated seconds; default 10 s (energy) or the plan's horizon + 3 s (trajopt; with ``dmc_swingup`` at
        least dm_control's episode, 1000 MJCF steps, so the return counts all of them).
    progress : callable, optional
        ``progress(stage, fraction)`` with stage "basin", "trajopt" or "simulate".
    basin_cache : BasinCache, optional
        Reuse basin estimates across calls (in memory).
    energy_options : dict, optional
        Keyword arguments for :class:`~cartpole.control.energy.EnergyShapingController`.
    catch_weights : (Q, R), optional
        LQR weights of the catch; default the lab's ``Q`` with ``R = 1``
        (:func:`~cartpole.control.switching.swingup_catch`; the lab's ``R = 0.1`` gives a much smaller basin).
        Pass ``(cartpole.Q_LAB, cartpole.R_LAB)`` for the lab's LQR. Energy method only: the trajopt hand-over is
        :func:`cartpole.ocp.pipeline.handover_catch`.
    objective : str or callable, optional
        ``trajopt`` only: the plan's objective (``effort`` default, ``time``, ``tracking``, ``dmc_swingup``,
        ``"MODULE:FUNCTION"`` or a function; see :func:`cartpole.ocp.pipeline.trajopt_swingup`).
    on_step : callable, optional
        ``on_step(m, d)`` during the MuJoCo run (e.g. :class:`cartpole.viz.viewer.LiveViewer`, to watch it live);
        returning False ends the run (see :func:`cartpole.sim.rollout.simulate`).

    Returns
    -------
    SwingupResult

    Raises
    ------
    SwingupError, MJCFError
        Bad method, start state or duration; an MJCF that is not a cart-pole.
    EnergyShapingError
        ``energy`` on a model energy shaping does not drive (more than one pole, a motor on a hinge), raised
        before the basin estimate or any simulation.
    """
    from cartpole.control.energy import EnergyShapingController
    from cartpole.control.switching import SwitchingController, swingup_catch
    from cartpole.validation.basin import estimate_basin
    from cartpole.validation.metrics import DMC_STEPS, dmc_swingup_rewards, swingup_metrics

    if method not in METHODS:
        raise SwingupError(f"Unknown swing-up method '{method}'; choose one of {', '.join(METHODS)}.")
    if isinstance(mjcf, CartPoleModel):
        model, params = mjcf, mjcf.params
    else:
        params = mjcf if isinstance(mjcf, CartPoleParams) else read_params(mjcf)
        model = None
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise SwingupError(f"Duration {duration} s is not a positive number of seconds; give e.g. --duration 8.")
    model = model if model is not None else build_model(params)
    x0 = check_start(model.x_hanging if x0 is None else x0, params)
    # energy shaping refuses a model it cannot drive with its own sentence, before any basin estimate runs
    energy = EnergyShapingController(model, **(energy_options or {})) if method == "energy" else None
    if objective is not None and method != "trajopt":
        raise SwingupError("--objective chooses what the trajectory optimisation minimises; use it with --method "
                           "trajopt.")
    basin_kw = dict(progress=_stage(progress, "basin"))

    def basin_of(catch):
        return basin_cache.get(params, catch, **basin_kw) if basin_cache is not None else \
            estimate_basin(params, catch, **basin_kw)

    plan = None
    if method == "energy":
        catch = swingup_catch(model) if catch_weights is None else swingup_catch(model, *catch_weights)
        basin = basin_of(catch)
        controller = SwitchingController(energy, catch, basin.rho)
        T = ENERGY_DURATION if duration is None else float(duration)
        rollout = simulate(params, controller, x0, T, progress=_stage(progress, "simulate"), on_step=on_step)
        if progress is not None:
            progress("simulate", 1.0)
        caught_at = controller.caught_at
        extra = {"switches": [{"t": s.t, "mode": s.mode, "cost": s.cost} for s in controller.switches]}
    else:
        try:
            from cartpole.ocp.pipeline import trajopt_swingup
        except ImportError:
            raise SwingupError("The trajopt method needs cartpole.ocp.pipeline, which this installation does not "
                               "have; use --method energy.") from None
        if progress is not None:
            progress("trajopt", 0.0)
        sp = trajopt_swingup(params, x0=tuple(x0), model=model, objective=objective)
        if progress is not None:
            progress("trajopt", 1.0)
        plan = sp.trajectory
        controller = sp.controller
        catch = sp.catch  # the controller that takes over: its basin is the one reported
        basin = basin_of(catch)
        T_plan = float(plan.t[-1] - plan.t[0])
        T = T_plan + TRAJOPT_EXTRA if duration is None else float(duration)
        if duration is None and sp.objective == "dmc_swingup":
            T = max(T, DMC_STEPS * params.timestep)
        rollout = simulate(params, controller, x0, T, progress=_stage(progress, "simulate"), on_step=on_step)
        if progress is not None:
            progress("simulate", 1.0)
        handover = getattr(controller, "handover_time", T_plan)
        caught_at = float(handover) if handover is not None and rollout.t[-1] >= handover else None
        k = int(np.searchsorted(rollout.t, handover)) if caught_at is not None else None
        extra = {"switches": [] if caught_at is None else [{"t": caught_at, "mode": "catch",
                                                            "cost": catch.cost_to_go(rollout.x[k])}],
                 "handover_cost": None if k is None else catch.cost_to_go(rollout.x[k]),
                 "objective": sp.objective}
        if sp.objective == "dmc_swingup":
            rewards = dmc_swingup_rewards(rollout, model)
            extra.update({"return": float(np.sum(rewards)), "return_steps": int(rewards.size)})
    metrics = {**swingup_metrics(rollout, model), **extra}
    return SwingupResult(method=method, success=bool(metrics["success"]), caught_at=caught_at, rollout=rollout,
                         plan=plan, basin=basin, metrics=metrics)
