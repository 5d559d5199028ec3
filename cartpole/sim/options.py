"""The MuJoCo closed loop's settings as one value (:class:`LoopOptions`: duration, control period, pushes, model
error), and the checks of pushes and model errors. Here, because the loop is the simulator's (its period, pushes and
scenario, and later its sensors and delay); the shape every stage's options share is :mod:`cartpole.options`.
"""
from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from cartpole.options import OptionsError, StageOptions
from cartpole.sim.disturbance import Disturbances, Knockdown, Throw


class LoopError(OptionsError):
    """Bad closed-loop settings: a push that is not a pair of finite numbers, a model error that is not a scale in
    [0.1, 10], a duration or period that is not a positive number of seconds."""


#: The estimators a loop can run (:attr:`LoopOptions.estimator`).
ESTIMATORS = ("none", "kf", "ekf", "mhe")

#: Seconds each push lasts.
PUSH_SECONDS = 0.1
#: Largest push force, N (magnitude): 50 times the lab motor's 20 N. A larger one only blows MuJoCo up.
MAX_PUSH_FORCE = 1000.0
#: Latest push start time accepted before the run's length is known, s (a push must also start before the run ends,
#: :func:`check_push_times`).
MAX_PUSH_TIME = 1e6


def check_push(push, params=None) -> tuple:
    """Validate pushes: ``push``, a sequence of ``(T, F)`` pairs, ``T >= 0`` s and ``F`` N finite; the model (``params``, a
    :class:`~cartpole.models.CartPoleParams`, optional) must have a cart.

    Returns
    -------
    tuple of (float, float), sorted by time

    Raises
    ------
    LoopError
        Not pairs of finite numbers, a time outside ``[0, MAX_PUSH_TIME]``, a force above :data:`MAX_PUSH_FORCE`,
        or a model without a slide joint to push.
    """
    if push is None:
        return ()
    try:
        pairs = [(float(T), float(F)) for T, F in push]
    except (TypeError, ValueError):
        raise LoopError(f"A push is a pair (T, F) of a start time in s and a force in N; got {push!r}.") from None
    for T, F in pairs:
        if not (np.isfinite(T) and np.isfinite(F) and 0 <= T <= MAX_PUSH_TIME and abs(F) <= MAX_PUSH_FORCE):
            raise LoopError(f"The push ({T:g} s, {F:g} N) needs a start time in [0, {MAX_PUSH_TIME:g}] s and a "
                            f"finite force of at most {MAX_PUSH_FORCE:g} N in magnitude; give e.g. `push=[(1.5, 20)]`.")
    if pairs and params is not None and params.slide is None:
        raise LoopError("This MJCF has no slide joint, so there is no cart to push; drop the push.")
    return tuple(sorted(pairs))


def check_push_times(push, duration: float) -> None:
    """Refuse a push that would never act: one starting at or after the end of the run (``duration``, s).

    Raises
    ------
    LoopError
        A push's start time is not before ``duration``.
    """
    for T, F in check_push(push):
        if T >= float(duration):
            raise LoopError(f"The push at {T:g} s ({F:g} N) starts after the run ends at {float(duration):g} s, so it "
                            "would never act; give a time before the end or a longer `duration`.")


def check_model_error(model_error) -> float:
    """The planning model's scale ``S`` (1.0 for None): a finite number, ``0.1 <= S <= 10``.

    Raises
    ------
    LoopError
    """
    if model_error is None:
        return 1.0
    try:
        S = float(model_error)
    except (TypeError, ValueError):
        raise LoopError(f"The model error {model_error!r} is not a number; give a scale such as 0.8.") from None
    if not (np.isfinite(S) and 0.1 <= S <= 10):
        raise LoopError(f"The model error {S:g} is not a scale in [0.1, 10] of the poles' masses and lengths; give "
                        "e.g. 1.2 for 20 % heavier and longer.")
    return S


def push_force(push, timestep: float):
    """``push`` pairs as the ``push(t) -> F`` callable :func:`~cartpole.sim.rollout.simulate` takes, or None.

    Each push acts on the physics steps ``k`` with ``round(T / h) <= k < round((T + PUSH_SECONDS) / h)``
    (``h = timestep``, s); overlapping pushes add."""
    pairs = check_push(push)
    if not pairs:
        return None
    h = float(timestep)
    spans = [(int(round(T / h)), int(round((T + PUSH_SECONDS) / h)), F) for T, F in pairs]

    def force(t: float) -> float:
        k = int(round(t / h))
        return float(sum(F for a, b, F in spans if a <= k < b))
    return force


@dataclasses.dataclass(frozen=True, eq=False)
class LoopOptions(StageOptions):
    """The MuJoCo closed loop's settings: how long it runs, at what control period, the scenario it runs (pushes on
    the cart, a planning model that is wrong on purpose) and the rig between MuJoCo and the controller (delay,
    sensors, estimator; :mod:`cartpole.sim.rig`).

    Attributes
    ----------
    duration : float or None
        Simulated seconds; None: the caller's default (for ``run_swingup``: 10 s energy, 8 s mpc, the plan + 3 s
        trajopt).
    period : float or None
        Control period in s: each ctrl is held this long (MuJoCo still logs every physics step); None: the
        controller's own (the NMPC's period; every physics step for the others). A controller with a period of its
        own (the NMPC) re-plans at this one when its own is not given.
    push : tuple of (float, float)
        Pushes ``(T [s], F [N])``: a world-x force of F N on the cart body for :data:`PUSH_SECONDS` from time T s
        (:func:`push_force`), sorted by time; any sequence of pairs is accepted and normalised.
    model_error : float
        Scale S in [0.1, 10] of the *planning* model's pole masses and lengths (1: the MJCF's own); MuJoCo always
        runs the MJCF. The scenario the controller is designed for, kept with the loop it is tested in.
    delay : float
        Seconds from sampling the sensors to the ctrl taking effect (computation and transport), a whole number of
        physics steps >= 0; it may exceed the period.
    estimator : str or None
        ``"none"`` (the controller reads MuJoCo's exact state), ``"kf"`` (steady-state Kalman filter on the model
        linearised at upright over the period: with LQR, LQG), ``"ekf"`` (extended Kalman filter on the exact
        nonlinear model) or ``"mhe"`` (moving-horizon estimation). None: ``"none"`` unless a sensor option is
        given, then ``"kf"`` for balancing and ``"ekf"`` for a swing-up.
    encoder_cpr : int or None
        Counts per revolution of every hinge's encoder (quantum ``2 pi / cpr`` rad); None: not quantised.
    encoder_resolution : float or None
        Metres per count of every slide's encoder; None: not quantised.
    sensor_noise : float or None
        Standard deviation of every sensor's noise in its own units (rad, m, ...); None: the MJCF's own ``noise``
        attribute (0 without one).
    process_noise : float or None
        Standard deviation of the unknown acceleration the estimators allow per joint (m/s^2, rad/s^2); None: the
        estimator's default.
    mhe_horizon : float or None
        The MHE's window in s (a whole number of periods); None: its default.
    seed : int
        Seed of the sensor noise (each run of a batch draws its own stream from it).
    delay_compensation : bool
        Predict the estimate forward through the model over the delay with the ctrl already sent (True), or act
        on the stale estimate (False: what the delay costs).
    friction_compensation : bool
        On a model whose driven joints have ``frictionloss``: design every controller on the model without that
        friction and add the ctrl cancelling it (:class:`cartpole.control.friction.FrictionCompensation`, True), or
        design on the smooth friction model and add nothing (False). Changes nothing on a model without it.
    knockdown : Knockdown or str or None
        Knock the poles down each time they have been upright for a while (:class:`cartpole.sim.disturbance.
        Knockdown`, or its ``"AFTER:LENGTH[:SEED[:ENERGY]]"`` text); None: never.
    throw : Throw or str or None
        Throw the state at random times whatever it is doing (:class:`cartpole.sim.disturbance.Throw`, or its
        ``"EVERY[:RATE[:SEED]]"`` text); None: never.

    Raises
    ------
    LoopError
        A duration or period that is not a positive number of seconds, a bad push or model error, a delay or noise
        that is negative or not finite, an unknown estimator.
    """

    duration: float | None = None
    period: float | None = None
    push: tuple = ()
    model_error: float = 1.0
    delay: float = 0.0
    estimator: str | None = None
    encoder_cpr: int | None = None
    encoder_resolution: float | None = None
    sensor_noise: float | None = None
    process_noise: float | None = None
    mhe_horizon: float | None = None
    seed: int = 0
    delay_compensation: bool = True
    friction_compensation: bool = True
    knockdown: object = None
    throw: object = None

    error: ClassVar[type] = LoopError
    SCALARS: ClassVar[tuple] = ("duration", "period", "model_error", "delay", "encoder_cpr", "encoder_resolution",
                                "sensor_noise", "process_noise", "mhe_horizon", "seed")

    def __post_init__(self):
        for name, example in (("duration", 8), ("period", 0.02)):
            self.number(name, low=0.0, low_open=True, optional=True, unit="s", hint=f"give e.g. `{name}={example}`")
        self.set_field("push", check_push(self.push))
        self.set_field("model_error", check_model_error(self.model_error))
        self.number("delay", low=0.0, unit="s")
        self.number("encoder_cpr", low=1.0, integer=True, optional=True, unit="counts per revolution")
        self.number("encoder_resolution", low=0.0, low_open=True, optional=True, unit="m per count")
        self.number("sensor_noise", low=0.0, optional=True, unit="(each sensor's units)")
        self.number("process_noise", low=0.0, optional=True, unit="m/s^2 or rad/s^2")
        self.number("mhe_horizon", low=0.0, low_open=True, optional=True, unit="s")
        self.number("seed", low=0.0, high=2.0 ** 63 - 1, integer=True)
        if self.estimator is not None and self.estimator not in ESTIMATORS:
            raise LoopError(f"The estimator {self.estimator!r} is not one of {', '.join(ESTIMATORS)}; give e.g. "
                            "`estimator='kf'`.")
        self.set_field("delay_compensation", bool(self.delay_compensation))
        self.set_field("friction_compensation", bool(self.friction_compensation))
        if self.knockdown is not None and not isinstance(self.knockdown, Knockdown):
            self.set_field("knockdown", Knockdown.parse(self.knockdown))
        if isinstance(self.throw, str):
            self.set_field("throw", Throw.parse(self.throw))
        if self.throw is not None and not isinstance(self.throw, Throw):
            raise LoopError(f"LoopOptions.throw must be a cartpole.sim.disturbance.Throw or its text "
                            f"'EVERY[:RATE[:SEED]]'; got {self.throw!r}.")

    @property
    def sensed(self) -> bool:
        """True when a sensor option is given (quantisation or noise): the controller must not see the true state."""
        return any(v is not None for v in (self.encoder_cpr, self.encoder_resolution, self.sensor_noise))

    def estimator_for(self, task: str) -> str:
        """The estimator this loop runs for ``task`` (``"balance"`` or ``"swingup"``): the one given, else
        ``"none"`` without sensor options, ``"kf"`` for balancing and ``"ekf"`` for a swing-up with them."""
        if self.estimator is not None:
            return self.estimator
        if not self.sensed:
            return "none"
        return "kf" if task == "balance" else "ekf"

    @property
    def disturbed(self) -> bool:
        """True when the loop knocks or throws the poles (:meth:`disturbance` is not None)."""
        return self.knockdown is not None or self.throw is not None

    def disturbance(self, source, *, x_eq, hinges, model=None):
        """The generalized-force disturbance ``f(t, x) -> (nv,)`` of one run on ``source`` (CartPoleParams; upright at
        ``x_eq`` (nx,), pole angles at qpos ``hinges``), or None: the knockdowns and throws added; ``model``, the
        symbolic model of ``source`` if the caller has it, sizes the knocks without building another."""
        parts = []
        if self.knockdown is not None:
            parts.append(self.knockdown.start(source, x_eq=x_eq, hinges=hinges, model=model))
        if self.throw is not None:
            parts.append(self.throw.start(source, x_eq=x_eq, hinges=hinges, timestep=source.timestep))
        return None if not parts else Disturbances(tuple(parts))

    def push_force(self, timestep: float):
        """The pushes as the ``push(t) -> F`` (N) callable :func:`~cartpole.sim.rollout.simulate` takes at the
        physics step ``timestep`` (s), or None without pushes."""
        return push_force(self.push, timestep)
