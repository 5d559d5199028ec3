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

import math
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


def check_ctrl(U, nu: int, steps: int) -> np.ndarray:
    """The ctrl since the last sample as a finite (nu, m) array, or one :class:`EstimationError` sentence.

    Parameters
    ----------
    U : (nu, m) array
        Ctrl (MuJoCo ctrl units) of each of the ``m`` physics steps; a length-m vector when nu = 1.
    nu, steps : int
        Inputs and physics steps per period ``m``.

    Returns
    -------
    (nu, m) array
    """
    U = np.asarray(U, dtype=float)
    if U.ndim == 1 and nu == 1:
        U = U.reshape(1, -1)
    if U.shape != (nu, steps) or not math.isfinite(U.sum()):
        raise EstimationError(f"The ctrl since the last sample must be a finite ({nu}, {steps}) array (one column "
                              f"per physics step); got shape {U.shape}.")
    return U


class SampledEstimator:
    """The two calls of the :class:`Estimator` contract written once: the checks of the measurement and the ctrl,
    the first estimate from ``y0``, the sentence when ``update`` comes before ``reset``, and the copies returned.
    A subclass sets ``nx``, ``ny``, ``nu``, ``steps`` (physics steps per period) and ``_initial_state`` (``y0 ->
    x0``), names itself in :attr:`title`, and says what it does in ``_start(y0, x0)`` (the first estimate, which it
    may adjust) and ``_correct(y, U)`` (one period), each returning the estimate (nx,)."""

    #: What the sentence for an ``update`` before ``reset`` calls the estimator.
    title = "estimator"
    _started = False  # set by reset

    def reset(self, y0) -> np.ndarray:
        """Start from the first measurement.

        Parameters
        ----------
        y0 : (ny,) array
            The measurement at the first sample (sensor units).

        Returns
        -------
        (nx,) array
            The first estimate ``initial_state(y0)`` (zero rates; m, rad, m/s, rad/s), as the estimator's class
            says it starts.

        Raises
        ------
        EstimationError
            A measurement of another size or with a NaN or infinite entry.
        """
        y0 = check_measurement(y0, self.ny)
        x0 = first_estimate(self._initial_state, y0, self.nx)
        self._started = True
        return np.array(self._start(y0, x0), dtype=float)

    def update(self, y, U) -> np.ndarray:
        """One period: predict over the ``m`` physics steps since the last sample, correct with ``y``.

        Parameters
        ----------
        y : (ny,) array
            The measurement at this sample (sensor units).
        U : (nu, m) array
            The ctrl applied during each of the ``m`` physics steps since the last sample (ctrl units; a length-m
            vector when nu = 1). Its last column is the ``u`` of ``h(x, u)``.

        Returns
        -------
        (nx,) array
            The estimate ``x_hat`` of the state at this sample (m, rad, m/s, rad/s; angles not wrapped).

        Raises
        ------
        EstimationError
            Before :meth:`reset`, or a measurement or ctrl of the wrong shape or not finite.
        """
        if not self._started:
            raise EstimationError(f"The {self.title} has no first measurement; call reset(y0) before update(y, U).")
        y = check_measurement(y, self.ny)
        U = check_ctrl(U, self.nu, self.steps)
        return np.array(self._correct(y, U), dtype=float)
