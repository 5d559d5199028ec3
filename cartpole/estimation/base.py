"""What every state estimator of the toolkit is: the contract the closed loop (:mod:`cartpole.sim`) drives.

A rig samples its sensors every control period (``m`` physics steps of ``h`` s, :class:`~cartpole.models.HoldModel`)
and the controller acts on an estimate ``x_hat`` of the state ``[qpos, qvel]`` (MuJoCo's order), never on the true
state. An estimator is an object with state (its estimate and covariance) and two calls:

* ``reset(y0) -> x_hat0`` (nx,): start from the first measurement ``y0`` (ny,), with zero rates (never from the true
  state);
* ``update(y, U) -> x_hat`` (nx,): the measurement ``y`` (ny,) taken now, and ``U`` (nu, m), the ctrl MuJoCo applied
  during each of the ``m`` physics steps since the previous sample (the controller knows it: it commanded it, and
  MuJoCo's clip to ``ctrlrange`` is part of the model). Returns the estimate of the state at this sample instant.

Measurements come from :mod:`cartpole.estimation.sensors` as a CasADi Function ``h(x, u) -> y`` (ny,) and a
measurement covariance; estimators take those, not the sensor objects, so any measurement model can be estimated.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from cartpole.errors import CartPoleError


class EstimationError(CartPoleError, ValueError):
    """An estimator that cannot be built: an unobservable pair (naming the states), covariances that are not
    symmetric positive (semi)definite, shapes that disagree, a horizon that is not a whole number of periods."""


class Estimator(Protocol):
    """The call shape of every estimator (see the module doc)."""

    name: str

    def reset(self, y0) -> np.ndarray:
        """Start from the first measurement ``y0`` (ny,) with zero rates; returns ``x_hat0`` (nx,)."""

    def update(self, y, U) -> np.ndarray:
        """Take the measurement ``y`` (ny,) and the ctrl ``U`` (nu, m) applied since the last sample; returns
        ``x_hat`` (nx,) at this sample."""


def check_measurement(y, ny: int) -> np.ndarray:
    """A measurement as ``ny`` finite floats (sensor units).

    Parameters
    ----------
    y : array_like
        The measurement.
    ny : int
        Its size.

    Returns
    -------
    (ny,) array

    Raises
    ------
    EstimationError
        Another size, or a NaN or infinite entry.
    """
    y = np.asarray(y, dtype=float).ravel()
    if y.shape != (ny,) or not np.isfinite(y.sum()):
        raise EstimationError(f"The measurement must be {ny} finite numbers; got {y.tolist()}.")
    return y


def first_estimate(initial_state, y0, nx: int) -> np.ndarray:
    """The first estimate ``initial_state(y0)`` as ``nx`` finite floats ``[qpos, qvel]`` (m, rad, m/s, rad/s).

    Parameters
    ----------
    initial_state : callable
        ``y0 (ny,) -> x0 (nx,)``.
    y0 : (ny,) array
        The first measurement (sensor units), already checked.
    nx : int
        State size.

    Returns
    -------
    (nx,) array
        A fresh copy.

    Raises
    ------
    EstimationError
        When ``initial_state`` returns another size or a non-finite entry.
    """
    x0 = np.array(initial_state(y0), dtype=float).ravel()
    if x0.shape != (nx,) or not np.all(np.isfinite(x0)):
        raise EstimationError(f"initial_state(y0) must return {nx} finite numbers [qpos, qvel]; got {x0.tolist()}.")
    return x0
