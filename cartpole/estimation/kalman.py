"""The steady-state Kalman filter of LQG: the gain from the discrete Riccati equation, and a filter on the cart-pole
linearised about an operating point over the control period.

The plant a sampled estimator sees over one period of ``m`` physics steps is ``x+ = step^m(x, U)``
(:class:`~cartpole.models.HoldModel`) with ``U`` (nu, m) the ctrl of each physics step; the measurement is
``y = h(x, u) + v``. Linearised about an operating point ``(x*, u*)`` (default upright, ``model.x_eq``,
``model.u_eq``) with ``A1, B1`` the exact Jacobians of ONE physics step there::

    x+ - x* = A (x - x*) + sum_j A1^(m-1-j) B1 (U[:, j] - u*),     A = A1^m
    y - y*  = C (x - x*) + D (u - u*),                              C = dh/dx, D = dh/du at (x*, u*)

which, when ``U`` is constant over the period, is the held model's own linearisation ``model.hold(m).linearize``
(the chain rule over the ``m`` steps; a test checks it). The filter is the time-invariant one of LQG: the gain ``L``
that the discrete Riccati equation reaches in steady state (:func:`kalman_gain`), applied every period as

    predict:  x_pred = A x_hat + B U            (in deviations from the operating point)
    correct:  x_hat  = x_pred + L (y - y_pred), y_pred the linearised measurement at x_pred.

Angles: MuJoCo's hinge angles never wrap, nor does ``x_hat``; the deviation ``x - x*`` is taken with hinge angles
wrapped to (-pi, pi] (:func:`cartpole.models.state_error`), i.e. about the copy of the operating point nearest the
estimate, where the dynamics and (for a measurement periodic in the angles) ``h`` are the same. The predicted
measurement there is ``h`` at that copy plus ``C`` times the wrapped deviation, so an encoder reading of
``2 pi + 0.01`` rad is compared with an estimate near ``2 pi``, not near 0.

The gain is the dual of the discrete LQR (estimation of ``(A, C)`` with weights ``(W, V)`` is control of
``(A', C')``): :func:`kalman_gain` solves it with :func:`cartpole.riccati.dlqr` on ``(A', C', W, V)``, after checks that
speak of estimation (which states the sensors cannot see, which covariance is wrong).

Shared with :mod:`cartpole.estimation.ekf`: the measurement model's checks
(:func:`~cartpole.estimation.measurement.check_measurement_model`), the
states' names in sentences (:func:`state_names`), the positions a measurement gives one-to-one
(:func:`~cartpole.estimation.measurement.measured_positions`) and the first estimate from the first measurement
(:func:`~cartpole.estimation.measurement.positions_initial_state`).
"""
from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from cartpole._arrays import readonly
from cartpole.estimation.base import EstimationError, SampledEstimator
from cartpole.estimation.measurement import (check_measurement_model, measurement_jacobians,
                                          positions_initial_state)
from cartpole.estimation.mhe_functions import positive_definite, symmetric_matrix
from cartpole.estimation.noise import process_covariance
from cartpole.riccati import LQRError, dlqr, uncontrollable_modes
from cartpole.models import state_error

#: Default standard deviation of the unknown acceleration, per joint kind: m/s^2 on the cart's slide, rad/s^2 on
#: each hinge. What the model does not know on a rig is of the order of 10 % of what the actuator does: the shipped
#: cart accelerates at about 20 m/s^2 and its pole at about 50 rad/s^2 per unit ctrl, so a 10 % error in a mass,
#: the gear or the friction at a typical ctrl of 0.1 to 1 is 0.2 to 2 m/s^2 and 0.5 to 5 rad/s^2. With these the
#: lab's LQG (2048-count encoders, 1 mm on the cart, 10 ms period) settles from the lab's starts as the LQR on the
#: true state does on the exact discrete model (a test checks it); the rate estimates' steady standard deviations
#: are then about 0.015 m/s and 0.05 rad/s.
DEFAULT_SLIDE_ACCEL_STD = 1.0
DEFAULT_HINGE_ACCEL_STD = 3.0

#: A null vector's component below this fraction of its largest is not counted as a state the mode involves.
_INVOLVED = 1e-6


class KalmanGain(NamedTuple):
    """Steady-state Kalman filter of ``x+ = Ad x + w``, ``y = C x + v`` (``w ~ (0, W)``, ``v ~ (0, V)``); unpacks
    like python-control's ``L, P, E = dlqe(...)``.

    Attributes
    ----------
    L : (nx, ny) array
        The filter (measurement-update) gain: ``x_hat = x_pred + L (y - C x_pred)``.
    P : (nx, nx) array
        The a-priori (predicted) steady-state error covariance, the stabilising solution of
        ``P = Ad P Ad' - Ad P C' (C P C' + V)^-1 C P Ad' + W`` (units of the states squared).
    E : (nx,) complex array
        Eigenvalues of the estimation error's dynamics ``(I - L C) Ad`` (inside the unit circle).
    """

    L: np.ndarray
    P: np.ndarray
    E: np.ndarray


# ---- shared helpers (KF and EKF) -------------------------------------------------------------------------------
def state_names(model) -> tuple[str, ...]:
    """Names of the states ``[qpos, qvel]`` for sentences: "the cart position", "the pole angle", "the cart
    velocity", "the pole angular velocity" (with several slides or poles: "the position of slide 'name'", "the
    angle of pole 2", ...).

    Parameters
    ----------
    model : CartPoleModel
        Its ``nq``, ``slides``, ``hinges`` and ``params.joint_names``; without them the names are ``x0 ..``.

    Returns
    -------
    tuple of str
        One per state (nx = 2 nq).
    """
    nq = int(model.nq)
    slides, hinges = tuple(getattr(model, "slides", ())), tuple(getattr(model, "hinges", ()))
    joints = tuple(getattr(getattr(model, "params", None), "joint_names", ()) or ())
    if len(slides) + len(hinges) != nq or len(joints) != nq:
        return tuple(f"x{i}" for i in range(2 * nq))
    # (one of its kind, several of its kind by name or number): position and rate words per joint type
    words = {True: (("the cart position", "the cart velocity"), "the position of slide '{}'",
                    "the velocity of slide '{}'"),
             False: (("the pole angle", "the pole angular velocity"), "the angle of pole {}",
                     "the angular velocity of pole {}")}
    pos, vel = [], []
    for i in range(nq):
        slide = i in slides
        group = slides if slide else hinges
        alone, pos_fmt, vel_fmt = words[slide]
        if len(group) == 1:
            pos.append(alone[0])
            vel.append(alone[1])
        else:
            label = joints[i] if slide else group.index(i) + 1
            pos.append(pos_fmt.format(label))
            vel.append(vel_fmt.format(label))
    return tuple(pos + vel)


def _join(names) -> str:
    names = list(names)
    text = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return text[0].upper() + text[1:] if text.startswith("the ") else text


def _unobservable_states(A, C, names) -> tuple[list[str], complex] | None:
    """The states involved in the modes of ``A`` with ``|lambda| >= 1`` that ``C`` cannot see (PBH: rank
    ``[A - lambda I; C] < n``), and the first such eigenvalue; None when ``(A, C)`` is detectable."""
    n = A.shape[0]
    bad = uncontrollable_modes(A.T, C.T, discrete=True)  # PBH on the dual pair: the unobservable unstable modes
    if bad.size == 0:
        return None
    involved = np.zeros(n, dtype=bool)
    for lam in bad:
        M = np.vstack([A - lam * np.eye(n), C.astype(complex)])
        _, s, Vh = np.linalg.svd(M)
        tol = 1e-9 * max(1.0, s[0])
        rank = int(np.sum(s > tol))
        null = Vh[rank:].conj().T  # (n, k) basis of the mode's unobservable eigenvectors
        size = np.abs(null).max(axis=1)
        involved |= size > _INVOLVED * max(size.max(), 1e-300)
    lam = bad[0]
    return [names[i] for i in np.flatnonzero(involved)], (lam.real if abs(lam.imag) < 1e-12 else lam)


def kalman_gain(Ad, C, W, V, *, state_names=None) -> KalmanGain:
    """The steady-state Kalman filter gain of ``x+ = Ad x + w``, ``y = C x + v`` (the estimator of LQG).

    Solved as the dual discrete LQR, ``cartpole.riccati.dlqr(Ad', C', W, V)``: its cost-to-go is the a-priori
    covariance ``P`` (equally ``scipy.linalg.solve_discrete_are(Ad', C', W, V)``), from which
    ``L = P C' (C P C' + V)^-1``.

    Parameters
    ----------
    Ad : (nx, nx) array
        State transition over one sample.
    C : (ny, nx) array
        Measurement matrix (a 1-D array of length nx is one row).
    W : (nx, nx) array
        Process noise covariance over one sample, symmetric positive semidefinite (e.g.
        :func:`~cartpole.estimation.noise.process_covariance`; SI units squared).
    V : (ny, ny) array
        Measurement noise covariance, symmetric positive definite (sensor units squared; a number or a vector:
        that times I or its diagonal).
    state_names : sequence of str, optional
        One per state, for the sentence that names unobservable states (default ``x0 .. x{nx-1}``;
        :func:`state_names` of a model gives "the cart position", ...).

    Returns
    -------
    KalmanGain
        ``L`` (nx, ny), ``P`` (nx, nx), ``E`` (nx,).

    Raises
    ------
    EstimationError
        Shapes that disagree, a ``W`` that is not symmetric positive semidefinite, a ``V`` that is not symmetric
        positive definite, a pair ``(Ad, C)`` that is not detectable (naming the states the sensors cannot see), or
        a Riccati equation without a stabilising solution.
    """
    A = np.atleast_2d(np.asarray(Ad, dtype=float))
    n = A.shape[0]
    if A.shape != (n, n) or not np.all(np.isfinite(A)):
        raise EstimationError(f"Ad must be a finite square (nx, nx) matrix; got shape {A.shape}.")
    C = np.asarray(C, dtype=float)
    C = C.reshape(1, n) if C.ndim == 1 and C.size == n else np.atleast_2d(C)
    if C.shape[1] != n or not np.all(np.isfinite(C)):
        raise EstimationError(f"C has shape {C.shape} but Ad is {A.shape}; C must be a finite (ny, {n}) matrix.")
    ny = C.shape[0]
    W = positive_semidefinite("W", W, n)
    V = positive_definite("V", V, ny)
    names = [f"x{i}" for i in range(n)] if state_names is None else [str(s) for s in state_names]
    if len(names) != n:
        raise EstimationError(f"state_names has {len(names)} names for {n} states; give one per state.")
    blind = _unobservable_states(A, C, names)
    if blind is not None:
        who, lam = blind
        raise EstimationError(f"{_join(who)} cannot be seen from these sensors: the mode of Ad with eigenvalue "
                              f"{lam:.4g} (not inside the unit circle) is unobservable from C, so no Kalman filter "
                              "converges; add a sensor that measures it.")
    try:
        dual = dlqr(A.T, C.T, W, V)
    except LQRError:
        raise EstimationError("The Kalman filter's Riccati equation has no stabilising solution: a mode of Ad on "
                              "the unit circle gets no process noise from W; give every joint a process noise > 0 "
                              "(accel_std).") from None
    P = 0.5 * (dual.S + dual.S.T)
    S = C @ P @ C.T + V
    L = np.linalg.solve(S, C @ P).T  # P C' S^-1, S symmetric
    # dlqr's E are eig(Ad - Ad L C), the same spectrum as the filtered error's (I - L C) Ad
    return KalmanGain(L, P, dual.E)


def check_steps(steps) -> int:
    """The physics steps per period ``m`` as an int >= 1, or one :class:`EstimationError` sentence.

    Parameters
    ----------
    steps : int
        Physics steps per control period.

    Returns
    -------
    int
    """
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise EstimationError(f"The physics steps per period {steps!r} must be a whole number >= 1.")
    return int(steps)


def process_noise(model, period: float, W=None, accel_std=None) -> np.ndarray:
    """The process covariance over one period: ``W`` as given, else
    :func:`~cartpole.estimation.noise.process_covariance` of ``accel_std``, else of the defaults
    (:data:`DEFAULT_SLIDE_ACCEL_STD` on slides, :data:`DEFAULT_HINGE_ACCEL_STD` on hinges).

    Parameters
    ----------
    model : CartPoleModel
        Its ``nq`` and ``hinges``.
    period : float
        The control period in s.
    W : (nx, nx) array, optional
        The covariance itself (SI units squared).
    accel_std : float or (nq,) array, optional
        Standard deviation of the unknown acceleration (m/s^2 on slides, rad/s^2 on hinges).

    Returns
    -------
    (nx, nx) array
        Symmetric.

    Raises
    ------
    EstimationError
        Both ``W`` and ``accel_std`` given, or either not a valid covariance or standard deviation.
    """
    nq = int(model.nq)
    if W is not None and accel_std is not None:
        raise EstimationError("Give the process noise as W or as accel_std, not both.")
    if W is None:
        if accel_std is None:
            hinges = set(getattr(model, "hinges", ()))
            accel_std = [DEFAULT_HINGE_ACCEL_STD if j in hinges else DEFAULT_SLIDE_ACCEL_STD for j in range(nq)]
        return process_covariance(accel_std, period, nq)
    return positive_semidefinite("W", W, 2 * nq)


def positive_semidefinite(name: str, M, n: int) -> np.ndarray:
    """The covariance ``name`` as a symmetric positive semidefinite (n, n) array (a number: that times I; a vector:
    its diagonal), or one :class:`EstimationError` sentence naming it.

    Parameters
    ----------
    name : str
        How the sentence calls it (``"W"``).
    M : (n, n) array, (n,) array or float
        The covariance.
    n : int
        Its size.

    Returns
    -------
    (n, n) array
    """
    M = symmetric_matrix(name, M, n)
    low = np.linalg.eigvalsh(M).min()
    if low < -1e-10 * max(1.0, np.abs(M).max()):
        raise EstimationError(f"The covariance {name} is not positive semidefinite (smallest eigenvalue {low:.3g}); "
                              "give variances >= 0.")
    return M


def _matrix_power_inputs(A1: np.ndarray, B1: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """``A1^m`` and ``[A1^(m-1) B1, .., A1 B1, B1]`` (nx, nu m), the linear map of m steps with a ctrl per step."""
    blocks = [B1]
    for _ in range(m - 1):
        blocks.insert(0, A1 @ blocks[0])
    return np.linalg.matrix_power(A1, m), np.hstack(blocks)


class KalmanFilter(SampledEstimator):
    """The steady-state (time-invariant) Kalman filter of LQG on the cart-pole linearised about an operating point
    over the control period (see the module doc); the :class:`~cartpole.estimation.base.Estimator` contract.

    Parameters
    ----------
    model : CartPoleModel
        The plant (one physics step of ``model.dt`` s, its exact Jacobians ``model.linearize(..., discrete=True)``).
    steps : int
        Physics steps ``m`` per control period (period ``m * model.dt`` s).
    h : casadi.Function
        Measurement model ``(x (nx,), u (nu,)) -> y (ny,)`` (sensor units); linearised at the operating point.
    V : (ny, ny) array, (ny,) array or float
        Measurement noise covariance (sensor units squared; a vector: its diagonal), positive definite.
    W : (nx, nx) array, optional
        Process noise covariance over one period (SI units squared), positive semidefinite. Give ``W`` or
        ``accel_std``, not both.
    accel_std : float or (nq,) array, optional
        Unknown acceleration's standard deviation (m/s^2 on slides, rad/s^2 on hinges),
        ``W = process_covariance(accel_std, period)``; default :data:`DEFAULT_SLIDE_ACCEL_STD` and
        :data:`DEFAULT_HINGE_ACCEL_STD`.
    x_op : (nx,) array, optional
        Operating point's state (m, rad, m/s, rad/s), default the upright equilibrium ``model.x_eq``.
    u_op : (nu,) array, optional
        Operating point's ctrl (ctrl units), default ``model.u_eq``.
    initial_state : callable, optional
        ``y0 (ny,) -> x0 (nx,)``: the first estimate. Default :func:`~cartpole.estimation.measurement.positions_initial_state` with base ``x_op``:
        positions ``h`` reads one-to-one from ``y0``, the others from the operating point, zero rates.
    name : str
        The estimator's name (the CLI's ``--estimator``).

    ``reset(y0)`` starts from ``initial_state(y0)`` (zero rates); ``update(y, U)`` predicts with the linear model
    over the ``m`` physics steps and corrects with the steady gain.

    Attributes
    ----------
    L : (nx, ny) array
        Steady-state filter gain.
    P : (nx, nx) array
        A-priori (predicted) steady-state error covariance.
    P_post : (nx, nx) array
        A-posteriori steady-state error covariance ``(I - L C) P (I - L C)' + L V L'``: the covariance of
        ``x_hat - x`` after each update, once the filter has converged.
    E : (nx,) complex array
        Eigenvalues of the error dynamics.
    A, B : arrays (nx, nx), (nx, nu m)
        The linear model over one period in deviations from the operating point (``B`` acts on ``vec(U - u_op)``,
        column-major, one block per physics step).
    C, D : arrays (ny, nx), (ny, nu)
        ``dh/dx``, ``dh/du`` at the operating point.
    V, W : arrays (ny, ny), (nx, nx)
        The covariances the gain was designed with.
    x_op, u_op, y_op : arrays (nx,), (nu,), (ny,)
        The operating point and ``h`` there.
    x_hat : (nx,) array or None
        The current estimate (None before :meth:`reset`).
    steps : int
        Physics steps per period.
    period : float
        Control period in s.

    Raises
    ------
    EstimationError
        Covariances that are not symmetric positive (semi)definite, an ``h`` whose shapes disagree with the model,
        sensors that cannot see every unstable state (the sentence names them).
    """

    title = "Kalman filter"

    def __init__(self, model, steps: int, h: ca.Function, V, *, W=None, accel_std=None, x_op=None, u_op=None,
                 initial_state=None, name: str = "kf"):
        self.name = str(name)
        nq, nx, nu = int(model.nq), int(model.nx), int(model.nu)
        self.nq, self.nx, self.nu = nq, nx, nu
        self.steps = check_steps(steps)
        self.period = self.steps * float(model.dt)
        self.hinges = tuple(getattr(model, "hinges", ()))
        self.ny = check_measurement_model(h, nx, nu)
        x_op = np.array(model.x_eq if x_op is None else x_op, dtype=float).ravel()
        u_op = np.atleast_1d(np.array(model.u_eq if u_op is None else u_op, dtype=float)).ravel()
        if x_op.shape != (nx,) or u_op.shape != (nu,) or not (np.all(np.isfinite(x_op)) and np.all(np.isfinite(u_op))):
            raise EstimationError(f"The operating point must be a finite state ({nx},) and ctrl ({nu},).")
        self.x_op, self.u_op = readonly(x_op), readonly(u_op)
        A1, B1 = model.linearize(x_op, u_op, discrete=True)
        A, B = _matrix_power_inputs(np.asarray(A1, float), np.asarray(B1, float).reshape(nx, nu), self.steps)
        self.A, self.B = readonly(A), readonly(B)
        self._h = measurement_jacobians(h, nx, nu)
        y_op, C, D = (np.asarray(v, dtype=float) for v in self._h(x_op, u_op))
        self.y_op = readonly(y_op.ravel())
        self.C, self.D = readonly(C.reshape(self.ny, nx)), readonly(D.reshape(self.ny, nu))
        self.V = readonly(positive_definite("V", V, self.ny))
        self.W = readonly(process_noise(model, self.period, W, accel_std))
        gain = kalman_gain(A, self.C, self.W, self.V, state_names=state_names(model))
        self.L, self.P, self.E = readonly(gain.L), readonly(gain.P), gain.E
        IKC = np.eye(nx) - gain.L @ self.C
        self.P_post = readonly(IKC @ gain.P @ IKC.T + gain.L @ self.V @ gain.L.T)
        self._initial_state = (positions_initial_state(h, model, x_op) if initial_state is None
                               else initial_state)
        self._y_ref: dict[tuple, np.ndarray] = {(): self.y_op}
        self.x_hat: np.ndarray | None = None

    def _start(self, y0, x0) -> np.ndarray:
        self.x_hat = x0
        return x0

    def _correct(self, y, U) -> np.ndarray:
        dU = (U - self.u_op[:, None]).ravel(order="F")
        dx = state_error(self.x_hat, self.x_op, self.hinges)
        x_pred = (self.x_hat - dx) + self.A @ dx + self.B @ dU
        dxp = state_error(x_pred, self.x_op, self.hinges)
        y_pred = self._y_at(x_pred - dxp) + self.C @ dxp + self.D @ (U[:, -1] - self.u_op)
        self.x_hat = x_pred + self.L @ (y - y_pred)
        return self.x_hat

    def _y_at(self, x_ref: np.ndarray) -> np.ndarray:
        """``h`` at the copy ``x_ref`` of the operating point (hinges shifted by whole turns), cached per copy."""
        turns = np.rint((x_ref - self.x_op)[list(self.hinges)] / (2 * np.pi)).astype(int)
        key = tuple(int(k) for k in turns) if np.any(turns) else ()
        if key not in self._y_ref:
            self._y_ref[key] = np.asarray(self._h(x_ref, self.u_op)[0], dtype=float).ravel()
        return self._y_ref[key]

