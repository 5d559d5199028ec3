"""Swing the pole up and hold it, proven in MuJoCo: ``run_swingup(mjcf, method="energy" | "trajopt")``.

* ``energy``: energy shaping (:class:`~cartpole.control.energy.EnergyShapingController`) until the state enters
  the LQR catch's basin ``e' S e < rho`` (``rho`` estimated in MuJoCo by :func:`~cartpole.validation.basin.
  estimate_basin`), then an LQR catch (the lab's Q with R = 1,
  :func:`~cartpole.control.switching.swingup_catch`, whose verified basin is about five times the lab LQR's), with
  hysteresis (:class:`~cartpole.control.switching.SwitchingController`);
* ``trajopt``: direct collocation + TVLQR (:func:`cartpole.ocp.pipeline.trajopt_swingup`), handing over to the
  LQR hold after the plan.

Either way MuJoCo runs the controller on the MJCF and every physics step is logged, so the result replays
exactly (:func:`~cartpole.sim.rollout.replays_exactly`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleParams, read_params
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


def check_start(x0, params: CartPoleParams) -> np.ndarray:
    """Validate a start state against the MJCF: 4 finite numbers, cart strictly inside its joint range.

    Parameters
    ----------
    x0 : array-like
        ``[s (m), theta (rad), s_dot (m/s), theta_dot (rad/s)]``.
    params : CartPoleParams

    Returns
    -------
    (4,) float array

    Raises
    ------
    SwingupError
    """
    try:
        x = np.asarray(x0, dtype=float).ravel()
    except (TypeError, ValueError):
        raise SwingupError(f"The start state {x0!r} is not numeric; give four numbers X TH XD THD.") from None
    if x.size != 4:
        raise SwingupError(f"The start state has {x.size} number(s); give exactly four: cart position (m), "
                           "pole angle (rad), cart velocity (m/s), pole rate (rad/s).")
    if not np.all(np.isfinite(x)):
        raise SwingupError(f"The start state {x.tolist()} is not finite; give four finite numbers.")
    lo, hi = params.cart_range
    if not lo < x[0] < hi:
        raise SwingupError(f"The start cart position {x[0]} m is outside the cart's joint range "
                           f"[{lo}, {hi}] m; start the cart strictly inside it.")
    hlo, hhi = params.hinge_range
    if not hlo <= x[1] <= hhi:
        raise SwingupError(f"The start pole angle {x[1]} rad is outside the hinge's joint range "
                           f"[{hlo}, {hhi}] rad; start the pole inside it.")
    return x


def _stage(progress, name):
    return None if progress is None else (lambda f: progress(name, f))


def run_swingup(mjcf=None, *, method: str = "energy", x0=(0.0, np.pi, 0.0, 0.0), duration: float | None = None,
                progress: Callable[[str, float], None] | None = None, basin_cache=None,
                energy_options: dict | None = None, catch_weights: tuple | None = None) -> SwingupResult:
    """Swing up from ``x0`` and hold upright, in MuJoCo on the MJCF.

    Parameters
    ----------
    mjcf : path or CartPoleParams or None
        The cart-pole (None = shipped asset).
    method : {"energy", "trajopt"}
    x0 : (4,) array
        Start state; default hanging at rest.
    duration : float, optional
        Simulated seconds; default 10 s (energy) or the plan's horizon + 3 s (trajopt).
    progress : callable, optional
        ``progress(stage, fraction)`` with stage "basin", "trajopt" or "simulate".
    basin_cache : BasinCache, optional
        Reuse basin estimates across calls (in memory).
    energy_options : dict, optional
        Keyword arguments for :class:`~cartpole.control.energy.EnergyShapingController`.
    catch_weights : (Q, R), optional
        LQR weights of the catch; default the lab's ``Q`` with ``R = 1``
        (:func:`~cartpole.control.switching.swingup_catch`; the lab's ``R = 0.1`` gives a much smaller basin).
        Pass ``(cartpole.Q_LAB, cartpole.R_LAB)`` for the lab's LQR.

    Returns
    -------
    SwingupResult

    Raises
    ------
    SwingupError, MJCFError
        Bad method, start state or duration; an MJCF that is not a cart-pole.
    """
    from cartpole.control.energy import EnergyShapingController
    from cartpole.control.switching import SwitchingController, swingup_catch
    from cartpole.models import build_model
    from cartpole.validation.basin import estimate_basin
    from cartpole.validation.metrics import swingup_metrics

    if method not in METHODS:
        raise SwingupError(f"Unknown swing-up method '{method}'; choose one of {', '.join(METHODS)}.")
    params = mjcf if isinstance(mjcf, CartPoleParams) else read_params(mjcf)
    x0 = check_start(x0, params)
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise SwingupError(f"Duration {duration} s is not a positive number of seconds; give e.g. --duration 8.")
    model = build_model(params)
    catch = swingup_catch(model) if catch_weights is None else swingup_catch(model, *catch_weights)
    basin_kw = dict(progress=_stage(progress, "basin"))
    basin = basin_cache.get(params, catch, **basin_kw) if basin_cache is not None else \
        estimate_basin(params, catch, **basin_kw)

    plan = None
    if method == "energy":
        controller = SwitchingController(EnergyShapingController(model, **(energy_options or {})), catch, basin.rho)
        T = ENERGY_DURATION if duration is None else float(duration)
        rollout = simulate(params, controller, x0, T, progress=_stage(progress, "simulate"))
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
        sp = trajopt_swingup(params, x0=tuple(x0), model=model)
        if progress is not None:
            progress("trajopt", 1.0)
        plan = sp.trajectory
        controller = sp.controller
        T_plan = float(plan.t[-1] - plan.t[0])
        T = T_plan + TRAJOPT_EXTRA if duration is None else float(duration)
        rollout = simulate(params, controller, x0, T, progress=_stage(progress, "simulate"))
        if progress is not None:
            progress("simulate", 1.0)
        handover = getattr(controller, "handover_time", T_plan)
        caught_at = float(handover) if handover is not None and rollout.t[-1] >= handover else None
        k = int(np.searchsorted(rollout.t, handover)) if caught_at is not None else None
        extra = {"switches": [] if caught_at is None else [{"t": caught_at, "mode": "catch",
                                                            "cost": catch.cost_to_go(rollout.x[k])}],
                 "handover_cost": None if k is None else catch.cost_to_go(rollout.x[k])}
    metrics = {**swingup_metrics(rollout, params), **extra}
    return SwingupResult(method=method, success=bool(metrics["success"]), caught_at=caught_at, rollout=rollout,
                         plan=plan, basin=basin, metrics=metrics)
