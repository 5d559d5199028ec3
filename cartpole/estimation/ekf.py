"""The extended Kalman filter on the exact nonlinear model over a control period: for a swing-up, where the pole
goes far from any one linearisation.

Each period of ``m`` physics steps (the ctrl ``U`` (nu, m) applied in each, :mod:`cartpole.estimation.base`)::

    predict:  x_pred = F(x_hat, U),                F = model.hold(m).step_inputs (exact, m steps of the integrator)
              P_pred = A P A' + W,                  A = dF/dx at (x_hat, U)  (model.hold(m).ABd_inputs)
    correct:  y_pred, H = h(x_pred, u), dh/dx       (u = U[:, -1], the ctrl being applied at the sample)
              K = P_pred H' (H P_pred H' + V)^-1
              x_hat = x_pred + K (y - y_pred)
              P = (I - K H) P_pred (I - K H)' + K V K'   (Joseph form: symmetric and positive for any K)

Angles: neither the state nor the innovation ``y - y_pred`` is wrapped. An encoder reading is a measurement of the
unwrapped hinge angle MuJoCo integrates, and the estimate is a state like MuJoCo's, so the two are compared as they
are (a reading of ``2 pi + 0.01`` rad against an estimate near ``2 pi``).

Speed: the prediction and its Jacobian are one SX Function, the measurement and its Jacobian another, both built
once in the constructor and evaluated on numpy buffers (:class:`cartpole.codegen.Buffered`); the rest is a few small
dense products.
"""
from __future__ import annotations

import math
import time

import casadi as ca
import numpy as np

from cartpole._arrays import readonly
from cartpole.codegen import Buffered
from cartpole.estimation.base import SampledEstimator
from cartpole.estimation.kalman import check_steps, process_noise
from cartpole.estimation.measurement import (check_measurement_model, measured_positions, measurement_jacobians,
                                             positions_initial_state)
from cartpole.estimation.mhe_functions import positive_definite

#: Default initial standard deviation of a position that no sensor reads one-to-one (m, rad): its first estimate
#: (from the hanging rest, or a caller's ``initial_state``) may be wrong by about a radian.
UNMEASURED_POSITION_STD = 1.0
#: Default initial standard deviation of every rate (m/s, rad/s): the first estimate has zero rates and a rig is
#: rarely started faster than this; large against what one period of encoder readings resolves, so the first
#: updates follow the measurements.
INITIAL_RATE_STD = 2.0


def default_initial_covariance(h, model, V) -> np.ndarray:
    """The EKF's default ``P0`` (nx, nx), diagonal: a position that ``h`` reads one-to-one (an encoder, row ``i``
    of ``y``) gets the measurement's variance ``V[i, i]``; any other position :data:`UNMEASURED_POSITION_STD` squared;
    every rate :data:`INITIAL_RATE_STD` squared.

    Parameters
    ----------
    h : casadi.Function
        ``h(x (nx,), u (nu,)) -> y (ny,)``.
    model : CartPoleModel
        Its ``nq`` and ``nu``.
    V : (ny, ny) array
        Measurement covariance (sensor units squared).

    Returns
    -------
    (nx, nx) array
        Units: m^2, rad^2, (m/s)^2, (rad/s)^2.
    """
    nq = int(model.nq)
    d = np.r_[np.full(nq, UNMEASURED_POSITION_STD ** 2), np.full(nq, INITIAL_RATE_STD ** 2)]
    V = np.atleast_2d(np.asarray(V, dtype=float))
    for i, j in measured_positions(h, nq, int(model.nu)):
        d[j] = V[i, i]
    return np.diag(d)


class ExtendedKalmanFilter(SampledEstimator):
    """The extended Kalman filter on the exact discrete model over the control period with a ctrl per physics step
    (see the module doc); the :class:`~cartpole.estimation.base.Estimator` contract.

    Parameters
    ----------
    model : CartPoleModel
        The plant; its ``hold(steps)`` (:class:`~cartpole.models.HoldModel`) gives the period's map and Jacobian.
    steps : int
        Physics steps ``m`` per control period (period ``m * model.dt`` s).
    h : casadi.Function
        Measurement model ``(x (nx,), u (nu,)) -> y (ny,)`` (sensor units), differentiated once here.
    V : (ny, ny) array, (ny,) array or float
        Measurement noise covariance (sensor units squared; a vector: its diagonal), positive definite.
    W : (nx, nx) array, optional
        Process noise covariance over one period (SI units squared), positive semidefinite. Give ``W`` or
        ``accel_std``, not both.
    accel_std : float or (nq,) array, optional
        Unknown acceleration's standard deviation (m/s^2 on slides, rad/s^2 on hinges),
        ``W = process_covariance(accel_std, period)``; default that of the Kalman filter
        (:data:`cartpole.estimation.kalman.DEFAULT_SLIDE_ACCEL_STD`, ``DEFAULT_HINGE_ACCEL_STD``).
    P0 : (nx, nx) array, (nx,) array or float, optional
        Covariance of the first estimate (SI units squared), positive definite; default
        :func:`default_initial_covariance` (the measurement's variance on positions read one-to-one,
        :data:`UNMEASURED_POSITION_STD` on other positions, :data:`INITIAL_RATE_STD` on the rates).
    initial_state : callable, optional
        ``y0 (ny,) -> x0 (nx,)``: the first estimate. Default
        :func:`~cartpole.estimation.measurement.positions_initial_state` with base ``model.x_hanging`` (a swing-up
        starts hanging): positions ``h`` reads one-to-one from ``y0``, the others hanging, zero rates.
    name : str
        The estimator's name (the CLI's ``--estimator``).

    ``reset(y0)`` starts from ``initial_state(y0)`` (zero rates) with covariance ``P0``; ``update(y, U)`` predicts
    with the nonlinear model over the ``m`` physics steps and corrects with ``y``.

    Attributes
    ----------
    x_hat : (nx,) array or None
        The current estimate (m, rad, m/s, rad/s; None before :meth:`reset`).
    P : (nx, nx) array or None
        Its error covariance after the last update.
    K : (nx, ny) array or None
        The last gain.
    V, W, P0 : arrays (ny, ny), (nx, nx), (nx, nx)
        The covariances in use.
    steps : int
        Physics steps per period.
    period : float
        Control period in s.
    failures : list of int
        Updates (counted from 1 after :meth:`reset`) whose prediction was not finite; they kept the previous
        estimate as the prediction, its covariance grown by ``W``.

    Raises
    ------
    EstimationError
        Covariances that are not symmetric positive (semi)definite, an ``h`` whose shapes disagree with the model.
    """

    title = "extended Kalman filter"

    def __init__(self, model, steps: int, h: ca.Function, V, *, W=None, accel_std=None, P0=None,
                 initial_state=None, name: str = "ekf"):
        self.name = str(name)
        nq, nx, nu = int(model.nq), int(model.nx), int(model.nu)
        self.nq, self.nx, self.nu = nq, nx, nu
        self.steps = check_steps(steps)
        self.period = self.steps * float(model.dt)
        self.ny = ny = check_measurement_model(h, nx, nu)
        self.V = readonly(positive_definite("V", V, ny))
        self.W = readonly(process_noise(model, self.period, W, accel_std))
        self.P0 = readonly(positive_definite("P0", default_initial_covariance(h, model, self.V) if P0 is None
                                             else P0, nx))
        hold = model.hold(self.steps)
        x, U = ca.SX.sym("x", nx), ca.SX.sym("U", nu, self.steps)
        outs = [ca.densify(hold.step_inputs(x, U)), ca.densify(hold.ABd_inputs(x, U)[0])]
        predict = ca.Function("ekf_predict", [x, U], outs, ["x", "U"], ["x_pred", "A"], {"cse": True})
        self._predict = Buffered(predict)
        self._measure = Buffered(measurement_jacobians(h, nx, nu))
        self._initial_state = (positions_initial_state(h, model, model.x_hanging) if initial_state is None
                               else initial_state)
        self._I = np.eye(nx)
        self.x_hat: np.ndarray | None = None
        self.P: np.ndarray | None = None
        self.K: np.ndarray | None = None
        self.failures: list[int] = []
        self._k = 0

    def _start(self, y0, x0) -> np.ndarray:
        self.x_hat, self.P, self.K = x0, np.array(self.P0), None
        self.failures, self._k = [], 0
        return x0

    def _correct(self, y, U) -> np.ndarray:
        self._k += 1
        nx = self.nx
        x_pred, A = self._predict(self.x_hat, U.ravel(order="F"))
        if math.isfinite(x_pred.sum()) and math.isfinite(A.sum()):
            A = A.reshape(nx, nx, order="F")
            x_pred = x_pred.copy()
            P = A @ self.P @ A.T + self.W
        else:  # a prediction that blew up: keep the last estimate, and trust it less
            self.failures.append(self._k)
            x_pred, P = self.x_hat.copy(), self.P + self.W
        y_pred, H, _ = self._measure(x_pred, U[:, -1])
        H = H.reshape(self.ny, nx, order="F")
        PHt = P @ H.T
        S = H @ PHt + self.V
        K = np.linalg.solve(S, PHt.T).T  # P H' S^-1, S symmetric
        self.x_hat = x_pred + K @ (y - y_pred)
        IKH = self._I - K @ H
        P = IKH @ P @ IKH.T + K @ self.V @ K.T
        self.P = 0.5 * (P + P.T)
        self.K = K
        return self.x_hat


def bench_ekf(model, steps: int, h: ca.Function, V, *, updates: int = 2000, seed: int = 0) -> dict:
    """Wall time of one :meth:`ExtendedKalmanFilter.update` on ``model``: the median (and 90th percentile) of
    ``updates`` calls, each timed with :func:`time.perf_counter`, along a random walk near hanging.

    Parameters
    ----------
    model : CartPoleModel
    steps : int
        Physics steps per period.
    h : casadi.Function
        Measurement model ``(x (nx,), u (nu,)) -> y (ny,)``.
    V : (ny, ny) array
        Measurement covariance.
    updates : int
        Calls timed.
    seed : int
        Of the random ctrl and measurements.

    Returns
    -------
    dict
        ``median_us``, ``p90_us`` (microseconds per update), ``updates``.
    """
    ekf = ExtendedKalmanFilter(model, steps, h, V)
    rng = np.random.default_rng(seed)
    y0 = np.asarray(h(model.x_hanging, np.zeros(model.nu)), dtype=float).ravel()
    ekf.reset(y0)
    times = np.empty(int(updates))
    for k in range(int(updates)):
        y = y0 + 1e-3 * rng.normal(size=y0.size)
        U = 0.1 * rng.normal(size=(model.nu, steps))
        t0 = time.perf_counter()
        ekf.update(y, U)
        times[k] = time.perf_counter() - t0
    return {"median_us": float(np.median(times) * 1e6), "p90_us": float(np.percentile(times, 90) * 1e6),
            "updates": int(updates)}
