"""The rig between MuJoCo and a controller: control period, delay, sensors and the state estimator.

A real cart-pole's controller runs every ``T`` s (a whole number ``m`` of physics steps), samples encoders (no
velocities, quantised, noisy), estimates the state, and its ctrl takes effect ``delay`` s after the sample. A
:class:`Rig` is that chain, built once for a model and a :class:`~cartpole.sim.options.LoopOptions` by
:func:`build_rig`; :func:`cartpole.sim.rollout.simulate` drives it (``rig=``): every period it calls
:meth:`RigRun.sample` with MuJoCo's live data, which measures, updates the estimate with the ctrl applied since the
last sample and, when the rig compensates the delay, predicts the estimate forward through the model over the delay
with the ctrl already sent (:meth:`~cartpole.models.CartPoleModel.hold`). The controller never sees the true state
unless the estimator is ``"none"``.

The estimator is built on the model the controller is designed on (with ``--model-error``, the wrong one), so it
knows what a rig's engineer would know; MuJoCo runs the MJCF.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable

import mujoco
import numpy as np

from cartpole.errors import CartPoleError
from cartpole.estimation import (ExtendedKalmanFilter, KalmanFilter, MHEOptions, MovingHorizonEstimator, SensorSampler,
                                 horizon_periods, initial_state, measurement_function, sensor_spec)
from cartpole.models import steps_per_period
from cartpole.sim.options import LoopError, LoopOptions


class RigError(LoopError):
    """A rig that cannot be built: a delay that is not a whole number of physics steps, sensor options without an
    estimator, an estimator that cannot see the state from the sensors."""


#: Longest sensing-to-actuation delay accepted, s.
MAX_DELAY = 1.0


def delay_steps(delay: float, timestep: float) -> int:
    """Physics steps in ``delay`` s (0 for 0), or one sentence when it is not a whole number of them.

    Parameters
    ----------
    delay : float
        Seconds from sampling to the ctrl taking effect, >= 0.
    timestep : float
        The MJCF's physics step in s.

    Returns
    -------
    int

    Raises
    ------
    RigError
    """
    d = float(delay)
    if d == 0:
        return 0
    if np.isfinite(d) and d > MAX_DELAY:
        raise RigError(f"The delay {d:g} s is longer than the {MAX_DELAY:g} s limit (the loop holds every sample of "
                       "it in memory); give a shorter `delay`.")
    k = round(d / timestep)
    if not np.isfinite(d) or d < 0 or abs(k * timestep - d) > 1e-6 * d:
        near = sorted({max(0, int(np.floor(d / timestep))) * timestep, int(np.ceil(d / timestep)) * timestep})
        raise RigError(f"The delay {d:g} s is not a whole number of the MJCF's {timestep:g} s physics steps; give "
                       f"{' or '.join(f'{v:g}' for v in near)} s.")
    return int(k)


@dataclass(frozen=True)
class Rig:
    """Period, delay, sensors and estimator for the runs of one model (see the module doc); built by
    :func:`build_rig`.

    Attributes
    ----------
    model : CartPoleModel
        The model the estimator and the delay prediction use: the controller's planning model with all its
        friction (they see the ctrl MuJoCo applied, a friction compensation included).
    steps : int
        Physics steps per control period.
    delay_steps : int
        Physics steps from a sample to its ctrl taking effect.
    estimator : str
        ``"none"``, ``"kf"``, ``"ekf"`` or ``"mhe"``.
    spec : SensorSpec or None
        The sensors (None with estimator ``"none"``: the controller reads ``[qpos, qvel]``).
    compensate : bool
        Predict the estimate over the delay.
    seed : int
        Seed of this run's sensor noise.
    make_estimator : callable or None
        ``() -> Estimator``, a fresh estimator for a run.
    """

    model: object
    steps: int
    delay_steps: int
    estimator: str
    spec: object
    compensate: bool
    seed: int
    make_estimator: Callable | None = None

    @property
    def period(self) -> float:
        """Control period in s."""
        return self.steps * float(self.model.dt)

    @property
    def delay(self) -> float:
        """Delay from sample to ctrl in s."""
        return self.delay_steps * float(self.model.dt)

    def for_run(self, index: int) -> "Rig":
        """The same rig with the sensor noise stream of run ``index`` of a batch (independent, reproducible)."""
        seed = int(np.random.SeedSequence([self.seed, int(index)]).generate_state(1)[0])
        return replace(self, seed=seed)

    def start(self, m) -> "RigRun":
        """A fresh run on the MuJoCo model ``m``: a new sampler (from :attr:`seed`) and a new estimator."""
        return RigRun(self, m)

    def to_dict(self) -> dict:
        """JSON-ready description: ``period``, ``delay`` (s), ``estimator``, ``delay_compensation``, ``seed`` and
        ``sensors`` (the spec, or None)."""
        return {"period": self.period, "delay": self.delay, "estimator": self.estimator,
                "delay_compensation": self.compensate, "seed": self.seed,
                "sensors": None if self.spec is None else self.spec.to_dict()}


class RigRun:
    """One run's sensors, estimator and delay prediction (state: the noise generator and the estimate).

    Parameters
    ----------
    rig : Rig
    m : mujoco.MjModel
        The model MuJoCo runs (its sensors are sampled).
    """

    def __init__(self, rig: Rig, m):
        self.rig = rig
        self.sampler = None
        self.estimator = None
        self.forward = False
        if rig.spec is not None:
            self.sampler = SensorSampler(rig.spec, m, seed=rig.seed)
            self.forward = any(s.adr >= 0 for s in rig.spec.sensors)  # MJCF sensors: sensordata at this state
            self.estimator = rig.make_estimator()
        lag = rig.delay_steps
        self.predict = rig.model.hold(lag).step_inputs if lag and rig.compensate else None
        self.started = False

    def sample(self, m, d, k: int, since, ahead, log) -> np.ndarray:
        """The state the controller acts on at physics step ``k``.

        Parameters
        ----------
        m, d : mujoco.MjModel, mujoco.MjData
            MuJoCo's model and live data at step ``k``.
        k : int
            Physics step of this sample.
        since : (m_k, nu) array
            The ctrl MuJoCo applied during each physics step since the previous sample (empty at the first).
        ahead : (delay_steps, nu) array
            The ctrl already sent for the steps between this sample and this ctrl taking effect.
        log : object with ``add(t, y, x_hat, ms)``
            Where the sample is logged.

        Returns
        -------
        (nx,) array
            The estimate, predicted over the delay when the rig compensates it.
        """
        t = k * float(m.opt.timestep)
        if self.sampler is None:
            y = x_hat = np.concatenate([d.qpos, d.qvel])
            ms = 0.0
        else:
            if self.forward:
                mujoco.mj_forward(m, d)
            y = self.sampler(d)
            t0 = time.perf_counter()
            if not self.started:
                x_hat = self.estimator.reset(y)
                self.started = True
            else:
                x_hat = self.estimator.update(y, np.asarray(since, dtype=float).T)
            ms = 1e3 * (time.perf_counter() - t0)
            x_hat = np.asarray(x_hat, dtype=float).ravel()
        log.add(t, y, x_hat, ms)
        if self.predict is None or len(ahead) == 0:
            return x_hat
        return np.asarray(self.predict(x_hat, np.asarray(ahead, dtype=float).T)).ravel()


def build_rig(model, loop: LoopOptions | None, *, task: str = "balance") -> Rig | None:
    """The :class:`Rig` for ``loop`` on ``model``, or None when ``loop`` asks for nothing a perfect loop lacks
    (period one physics step or unset, no delay, estimator ``"none"``).

    Parameters
    ----------
    model : CartPoleModel
        The controller's design model (its ``dt`` must be the MJCF's physics step).
    loop : LoopOptions or None
    task : str
        ``"balance"`` or ``"swingup"``: picks the default estimator when sensor options are given
        (:meth:`~cartpole.sim.options.LoopOptions.estimator_for`).

    Returns
    -------
    Rig or None

    Raises
    ------
    RigError, PeriodError, EstimationError
        A period or delay that is not a whole number of physics steps, sensor options with estimator ``"none"``,
        sensors the reader cannot model, an estimator that cannot see every state from the sensors.
    """
    if loop is None:
        return None
    h = float(model.dt)
    steps = steps_per_period(loop.period, h)
    lag = delay_steps(loop.delay, h)
    name = loop.estimator_for(task)
    if name == "none" and loop.sensed:
        raise RigError("`estimator='none'` gives the controller MuJoCo's exact state, so sensor options (encoders, "
                       "noise) would not be used; pick an `estimator` (kf, ekf or mhe), or drop the sensor options.")
    if steps == 1 and lag == 0 and name == "none":
        return None
    spec = make = None
    if name != "none":
        spec, make = estimator_factory(model, loop, name, steps)
    return Rig(model=model, steps=steps, delay_steps=lag, estimator=name, spec=spec,
               compensate=bool(loop.delay_compensation), seed=int(loop.seed), make_estimator=make)


def estimator_factory(model, loop: LoopOptions, name: str, steps: int):
    """``(SensorSpec, make)``: the sensors ``loop`` describes on ``model`` and a factory of fresh estimators
    ``name`` over ``steps`` physics steps, with the measurement model, covariances and first state built once.

    Raises
    ------
    EstimationError
        Unknown sensors, an unobservable pair, a bad horizon.
    """
    spec = sensor_spec(model, encoder_cpr=loop.encoder_cpr, encoder_resolution=loop.encoder_resolution,
                       noise_std=loop.sensor_noise)
    h = measurement_function(model, spec)
    V = spec.measurement_covariance()
    if not np.all(np.linalg.eigvalsh(V) > 0):
        V = V + np.eye(spec.ny) * 1e-12  # an ideal sensor: the filters need V > 0; a tiny floor keeps them exact
    first = (lambda y: initial_state(model, spec, y))  # noqa: E731
    noise = {} if loop.process_noise is None else {"accel_std": float(loop.process_noise)}
    if name == "kf":
        cls, extra = KalmanFilter, {}
    elif name == "ekf":
        cls, extra = ExtendedKalmanFilter, {}
    elif name == "mhe":
        cls = MovingHorizonEstimator
        extra = {} if loop.mhe_horizon is None else {
            "options": MHEOptions(horizon=horizon_periods(loop.mhe_horizon, steps * float(model.dt)))}
    else:
        raise CartPoleError(f"No estimator named {name!r}.")

    # the KF is linear at upright, where dry friction has no slope (CartPoleModel.without_friction); the EKF and
    # the MHE predict through the smooth friction, as MuJoCo's friction acts on the ctrl they are given
    est_model = model.without_friction() if name == "kf" else model

    def make():
        return cls(est_model, steps, h, V, initial_state=first, **noise, **extra)
    make()  # built once here so that a bad pair or horizon is refused before anything runs
    return spec, make
