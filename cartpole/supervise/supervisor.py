"""A controller that swings up again whenever it is knocked down: catch, plan, track, brake, chosen at run time.

:class:`Supervisor` has the call shape of every controller, ``u = supervisor(t, x)``. Each call it decides:

* **catch**: inside the LQR catch's verified basin (``e' S e < rho``) the catch holds; it lets go only above
  ``release_factor * rho`` (hysteresis, as :class:`~cartpole.control.switching.SwitchingController`).
* **swing-up law**: on one pole driven by the cart, the energy-shaping law swings up from any state on its own, so
  the supervisor never needs to plan (it is :class:`~cartpole.control.switching.SwitchingController` with its
  decisions logged).
* **brake**: with any hinge faster than ``calm_rate``, a passive PD on the actuated joints
  (``u = u* - kp (q - q*) - kd q_dot`` on each driven joint) removes energy until the state is one the planner
  handles; passive, so it cannot add energy whatever the state.
* **plan**: otherwise it plans a swing-up (``planner(x0) -> SwingupPlan``) from the state predicted ``latency``
  seconds ahead through the model under the brake (the latency is the median planning time measured so far). The
  planner runs in the caller's thread and its wall time ``W`` is honest latency: the plan is used only from
  ``t + W`` of simulated time, the brake acting meanwhile; a plan later than predicted is tracked from where its
  clock has got to. The planner's own searches are bounded by ``plan_budget``. A plan that fails, or takes more than ``plan_budget`` s, is logged and retried after
  ``retry_after`` s of braking.
* **track**: TVLQR along the plan, handing over to the plan's catch at its end; a hinge that strays more than
  ``funnel`` rad from the plan means the plan is lost: plan again.

Every decision is kept (:attr:`Supervisor.decisions`: time, kind, details) for the run's JSON.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np

from cartpole.control import LinearFeedback
from cartpole.control.energy import EnergyShapingController, EnergyShapingModelError, check_single_pole
from cartpole.control.model_rollout import model_rollout
from cartpole.control.switching import SWINGUP_CATCH_R
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, Plant, plant_model, plant_params, wrap_angle
from cartpole.options import OptionsError, StageOptions
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim.disturbance import joint_inertia_and_authority
from cartpole.validation import BasinCache


class SupervisorError(OptionsError):
    """Bad supervisor settings (a budget, rate, funnel or factor that is not a positive number)."""


@dataclass(frozen=True, eq=False)
class SupervisorOptions(StageOptions):
    """The supervisor's settings.

    Attributes
    ----------
    plan_budget : float
        s of wall time one plan may take; a plan over it counts as failed (it is still measured and logged).
    latency : float
        s, the planning latency assumed before any plan has been timed (then the median of the measured ones).
    calm_rate : float
        rad/s: with any hinge faster than this the brake acts before planning.
    funnel : float
        rad: a hinge angle further than this from the plan being tracked means the plan is lost.
    release_factor : float
        The catch lets go above ``release_factor * rho`` (> 1).
    retry_after : float
        s of braking after a failed plan before the next try.
    brake_time : float
        s, the brake's time constant: ``kd = M_jj / brake_time``, ``kp = M_jj / brake_time^2`` per driven joint
        (``M_jj`` its joint-space inertia at upright), in ctrl units through the actuator's moment arm.
    """

    plan_budget: float = 30.0
    latency: float = 0.5
    calm_rate: float = 6.0
    funnel: float = 0.6
    release_factor: float = 20.0
    retry_after: float = 0.5
    brake_time: float = 0.5

    error: ClassVar[type] = SupervisorError
    SCALARS: ClassVar[tuple] = ("plan_budget", "latency", "calm_rate", "funnel", "release_factor", "retry_after",
                                "brake_time")

    def __post_init__(self):
        for name, unit in (("plan_budget", "s"), ("latency", "s"), ("calm_rate", "rad/s"), ("funnel", "rad"),
                           ("retry_after", "s"), ("brake_time", "s")):
            self.number(name, low=0.0, low_open=True, unit=unit)
        self.number("release_factor", low=1.0, low_open=True, unit="(ratio)")


@dataclass(frozen=True)
class Decision:
    """One decision of the supervisor.

    Attributes
    ----------
    t : float
        s, simulated time of the decision.
    kind : str
        ``"catch"``, ``"swingup"`` (the swing-up law took over), ``"brake"``, ``"plan"`` (a plan requested),
        ``"track"`` (a plan ready and tracked), ``"plan_failed"``, ``"lost"`` (left the tracking funnel).
    detail : dict
        What the decision rests on (cost, rates, planning wall time, the failure's sentence...).
    """

    t: float
    kind: str
    detail: dict = dataclasses.field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready ``{"t", "kind", **detail}``."""
        return {"t": self.t, "kind": self.kind, **self.detail}


class PassiveBrake:
    """``u = u* - kp (q_j - q*_j) - kd q_dot_j`` through each actuator's driven joint ``j``: a passive spring and
    damper on the actuated joints, so the total energy (with the spring's) never grows, whatever the state.

    Parameters
    ----------
    model : CartPoleModel
        Its ``params.actuated`` (the joint each actuator drives), ``gears``, ``x_eq``, ``u_eq``.
    inertia : (nv,) array
        Joint-space inertia diagonal at upright (kg or kg m^2).
    time_constant : float
        s; ``kd = inertia / time_constant``, ``kp = inertia / time_constant^2`` in N/m, N m/rad (divided by the gear
        for ctrl units).
    u_limits : (nu, 2) array
        ctrl clip.
    """

    def __init__(self, model: CartPoleModel, inertia, time_constant: float, u_limits):
        self.model = model
        self.joints = tuple(int(j) for j in model.params.actuated)
        gears = np.asarray(model.params.gears, dtype=float).ravel()
        inertia = np.asarray(inertia, dtype=float)
        self.kd = np.array([inertia[j] / time_constant / g for j, g in zip(self.joints, gears)])
        self.kp = np.array([inertia[j] / time_constant ** 2 / g for j, g in zip(self.joints, gears)])
        self.u_limits = np.asarray(u_limits, dtype=float).reshape(-1, 2)
        self.nq = model.nq

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at state ``x`` (nx,)."""
        x = np.asarray(x, dtype=float)
        x_eq = np.asarray(self.model.x_eq, dtype=float)
        j = list(self.joints)
        dq = x[j] - x_eq[j]
        hinge = np.isin(j, self.model.hinges)
        dq = np.where(hinge, wrap_angle(dq), dq)
        u = np.asarray(self.model.u_eq, dtype=float).ravel() - self.kp * dq - self.kd * x[[self.nq + i for i in j]]
        return np.clip(u, self.u_limits[:, 0], self.u_limits[:, 1])


class Supervisor:
    """Recover from any state for as long as it runs: catch, swing-up law, brake, plan and track (module docstring).

    Parameters
    ----------
    model : CartPoleModel
        The planning model (its ``x_eq``, hinges, exact discrete step for the prediction).
    catch : LinearFeedback
        The balancing LQR, with ``S``.
    rho : float
        The catch's verified basin level (``e' S e < rho``; e.g. ``BasinEstimate.rho``).
    brake : callable
        ``(t, x) -> ctrl``: the energy-removing law (:class:`PassiveBrake`).
    planner : callable, optional
        ``planner(x0 (nx,)) -> SwingupPlan`` (e.g. :func:`cartpole.planning.trajopt.trajopt_swingup` bound to the
        model); raises :class:`~cartpole.errors.CartPoleError` when it finds none. None: never plans.
    swingup : callable, optional
        ``(t, x) -> ctrl``, a law that swings up from any state on its own (the energy law on one pole); when given
        it runs outside the basin instead of braking and planning.
    options : SupervisorOptions, optional

    Attributes
    ----------
    decisions : list of Decision
    mode : str
        ``"catch"``, ``"swingup"``, ``"brake"``, ``"wait"`` (a plan on its way) or ``"track"``.
    plan_seconds : list of float
        Wall time of every plan, s.
    """

    def __init__(self, model: CartPoleModel, catch: LinearFeedback, rho: float, brake: Callable, *,
                 planner: Callable | None = None, swingup: Callable | None = None,
                 options: SupervisorOptions | None = None):
        if catch.S is None:
            raise SupervisorError("The supervisor's catch needs its cost-to-go S to test the basin; build it with "
                                  "LinearFeedback.for_model.")
        self.model, self.catch, self.rho, self.brake = model, catch, float(rho), brake
        self.planner, self.swingup = planner, swingup
        self.options = SupervisorOptions() if options is None else options
        self.hinges = tuple(model.hinges)
        self.reset()

    def reset(self) -> None:
        """Forget the run: no plan, no decisions."""
        self.mode = "start"
        self.decisions: list[Decision] = []
        self.plan_seconds: list[float] = []
        self.plan = None
        self.plan_t0 = 0.0
        self.ready_at = np.inf
        self.retry_at = -np.inf
        self.plans = 0
        self.failures = 0

    @property
    def latency(self) -> float:
        """s, the planning latency the next plan is predicted with: 1.25 times the median measured so far (a plan
        that comes late is tracked from where its clock has got to, so erring long is cheaper), else the option."""
        return 1.25 * float(np.median(self.plan_seconds)) if self.plan_seconds else self.options.latency

    def _decide(self, t: float, kind: str, **detail) -> None:
        self.decisions.append(Decision(float(t), kind, detail))

    def _set(self, t: float, mode: str, **detail) -> None:
        if mode != self.mode:
            self.mode = mode
            self._decide(t, mode, **detail)

    def _fast(self, x) -> bool:
        rates = np.abs(np.asarray(x, dtype=float)[[self.model.nq + h for h in self.hinges]])
        return bool(np.any(rates > self.options.calm_rate))

    def _lost(self, t: float, x) -> bool:
        tau = min(t - self.plan_t0, self.plan.trajectory.duration)
        ref = self.plan.trajectory.state(tau)
        err = wrap_angle(np.asarray(x, dtype=float)[list(self.hinges)] - np.asarray(ref)[list(self.hinges)])
        return bool(np.max(np.abs(err)) > self.options.funnel)

    def _request_plan(self, t: float, x) -> None:
        """Plan from the state predicted ``latency`` s ahead under the brake; the plan is used from ``t + W``."""
        lat = self.latency
        steps = max(1, int(round(lat / self.model.dt)))
        xs, _ = model_rollout(self.model, self.brake, x, steps, t0=t)
        x_pred = xs[-1]
        self.plans += 1
        start = time.perf_counter()
        try:
            if not np.all(np.isfinite(x_pred)):
                raise CartPoleError("the prediction over the planning latency is not finite")
            plan = self.planner(x_pred)
        except CartPoleError as exc:
            plan, why = None, str(exc)
        wall = time.perf_counter() - start
        self.plan_seconds.append(wall)
        if plan is not None and wall > self.options.plan_budget:
            plan, why = None, f"the plan took {wall:.1f} s, over the budget of {self.options.plan_budget:g} s"
        if plan is None:
            self.failures += 1
            self.retry_at = t + wall + self.options.retry_after
            self._decide(t, "plan_failed", wall_s=wall, reason=why)
            self.mode = "brake"
            return
        self.plan, self.plan_t0, self.ready_at = plan, t + steps * self.model.dt, t + wall
        self._decide(t, "plan", wall_s=wall, predicted_latency_s=lat, T=float(plan.trajectory.duration))
        self.mode = "wait"

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s) for state ``x`` (nx,)."""
        t = float(t)
        x = np.asarray(x, dtype=float)
        cost = float(self.catch.cost_to_go(x))
        if cost < self.rho or (self.mode == "catch" and cost < self.options.release_factor * self.rho):
            self._set(t, "catch", cost=cost)
            return self.catch(t, x)
        if self.swingup is not None:
            self._set(t, "swingup", cost=cost)
            return self.swingup(t, x)
        if self.mode == "wait" and t >= self.ready_at - 1e-12:
            self._set(t, "track", late_s=max(0.0, t - self.plan_t0))
        if self.mode == "track":
            over = t - self.plan_t0 >= self.plan.trajectory.duration
            if over and cost < self.options.release_factor * self.rho:  # the plan's end: the catch takes it
                self._set(t, "catch", cost=cost)
                return self.catch(t, x)
            if not over and not self._lost(t, x):
                return self.plan.controller(t - self.plan_t0, x)
            self._decide(t, "lost", cost=cost)
            self.mode = "brake"
        if self.mode == "wait":
            return self.brake(t, x)
        if self.planner is None or self._fast(x) or t < self.retry_at:
            self._set(t, "brake", cost=cost)
            return self.brake(t, x)
        self._request_plan(t, x)
        return self.brake(t, x)

    def summary(self) -> dict:
        """JSON-ready: ``decisions``, ``plans``, ``plan_failures``, ``plan_s`` (each plan's wall time), ``rho``."""
        return {"decisions": [d.to_dict() for d in self.decisions], "plans": self.plans,
                "plan_failures": self.failures, "plan_s": list(self.plan_seconds), "rho": self.rho}


def supervisor_for(plant: Plant = None, plan_model: CartPoleModel | None = None, *, period: float | None = None,
                   plan: PlanOptions | None = None, options: SupervisorOptions | None = None,
                   basin_cache: BasinCache | None = None, basin_of: Callable | None = None) -> Supervisor:
    """The supervisor for a cart-pole: its swing-up catch and verified basin, the brake, the energy law where it
    applies (one pole driven by the cart), else the planner.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The MJCF MuJoCo runs (its ctrl ranges clip every law).
    plan_model : CartPoleModel, optional
        The planning model (default the MJCF's own).
    period : float, optional
        Control period in s (default every physics step); the catch and the plans' TVLQR are designed over it.
    plan : PlanOptions, optional
        The planner's settings (default :class:`~cartpole.planning.options.PlanOptions`).
    options : SupervisorOptions, optional
    basin_cache : BasinCache, optional
        Where the catch's basin estimate is kept (default the on-disk cache).
    basin_of : callable, optional
        ``basin_of(catch) -> BasinEstimate`` instead of ``basin_cache`` (a caller's own cache and progress).

    Returns
    -------
    Supervisor
    """
    params = plant_params(plant)
    model = plant_model(plant) if plan_model is None else plan_model
    catch = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R, period=period)
    if basin_of is None:
        cache = BasinCache.on_disk() if basin_cache is None else basin_cache
        rho = cache.get(params, catch).rho
    else:
        rho = basin_of(catch).rho
    opts = SupervisorOptions() if options is None else options
    inertia, _ = joint_inertia_and_authority(params, np.asarray(model.x_eq, dtype=float))
    brake = PassiveBrake(model, inertia, opts.brake_time, catch.u_limits)
    try:
        check_single_pole(model)
    except EnergyShapingModelError:
        plan_opts = PlanOptions() if plan is None else plan
        plan_opts = plan_opts.replace(search_s=min(plan_opts.search_s, opts.plan_budget))  # bounded planning

        def planner(x0):
            return trajopt_swingup(params, x0=tuple(x0), plan_model=model, options=plan_opts, period=period)
        return Supervisor(model, catch, rho, brake, planner=planner, options=opts)
    return Supervisor(model, catch, rho, brake, swingup=EnergyShapingController(model), options=opts)
