"""Moving-horizon estimation (MHE): the state over the last ``N`` control periods fitted to the measurements, one
Gauss-Newton step per period (real-time iteration), with the joints' ranges as hard bounds.

At sample ``k`` the window holds the nodes ``x_0 .. x_n`` (``n = min(k, N)`` intervals of one period; node ``n`` is
the current sample) and the estimator solves, in the states (multiple shooting) and the process noise::

    min  ||x_0 - x_bar||^2_{P^-1} + sum_{j=0..n} ||y_j - h(x_j, u_j)||^2_{V^-1} + sum_{j<n} ||w_j||^2_{W^-1}
    s.t. x_j+1 = F(x_j, U_j) + w_j,    q_low <= q_j <= q_high  (the joints' ranges, every node)

``F`` is the exact discrete model over one period with the ctrl ``U_j`` (nu, m) applied in each physics step
(:attr:`cartpole.models.HoldModel.step_inputs`), ``u_j`` the last ctrl applied before sample ``j`` (zero at the first
sample: nothing has been applied yet). ``W`` may be singular (the white-acceleration model of
:func:`cartpole.estimation.noise.process_covariance` has rank ``nq``): the noise is written ``w_j = L e_j`` with
``W = L L'`` (``L`` (nx, r), ``r`` the rank of ``W``) and ``||w||^2_{W^-1} = ||e||^2``, which is ``W^-1`` where ``W``
is invertible and confines ``w`` to the range of ``W`` where it is not (the limit of an infinite weight there).

Real-time iteration (like :mod:`cartpole.mpc.nmpc`): each period the window is shifted by one (the new node
predicted by ``F`` from the previous estimate, its noise zero) and ONE Gauss-Newton step is taken: the residuals are
linearised at the iterate (one call of compiled C, :mod:`cartpole.estimation.mhe_functions`) and the step's linear
least squares in ``(dx_0, de_0 .. de_n-1)`` under the shooting constraints ``dx_j+1 = A_j dx_j + L de_j + (F_j +
L e_j - x_j+1)`` is solved by a backward Riccati recursion over the nodes
(:func:`~cartpole.estimation.mhe_functions.riccati_window_step`: O(n), a few microseconds in C for a 50-period
window). When that step would put a bounded joint outside its range, the step is the QP condensed onto those
unknowns (a dense Hessian) with the ranges as rows, solved by DAQP (dual active set, exact, polished). The cost is a
sum of squares, so Gauss-Newton drops only the model's second derivatives; on a linear model one step is the exact
solution. Before the window is full (``k < N``) the window is the samples so far.

One implementation: by default each period runs the compiled C of ``cartpole/csrc/mhe.c.jinja``
(:mod:`cartpole.estimation.mhe_c`), the C ``cartpole export --estimator mhe`` ships; the numpy step described here
(``c_step=False``, or without a C compiler) is the reference the tests compare it with on the same inputs.

Arrival cost (the filtering update of Rao, Rawlings and Lee 2003, as an EKF step): when the window slides, the
measurement ``y_0`` and the interval from ``x_0`` leave it; ``(x_bar, P)`` take them in by one extended-Kalman-filter
measurement update and prediction, linearised at the current estimate ``x_hat_0`` of the node that leaves::

    K = P C' (C P C' + V)^-1,      x_f = x_bar + K (y_0 - h(x_hat_0) - C (x_bar - x_hat_0)),
    P_f = (I - K C) P (I - K C)' + K V K',
    x_bar <- F(x_hat_0, U_0) + A (x_f - x_hat_0),      P <- A P_f A' + W

(``C = dh/dx``, ``A = dF/dx`` at ``x_hat_0``). For a linear model this is the Kalman filter's own recursion, so the
unconstrained MHE then equals the Kalman filter at every sample and, while the window has not slid, the batch
least-squares (Kalman smoother) solution over all samples.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np

from cartpole._arrays import readonly
from cartpole.codegen import Buffered
from cartpole.estimation.base import EstimationError, SampledEstimator
from cartpole.estimation.mhe_c import compiled_mhe
from cartpole.estimation.mhe_functions import (
    WindowFunctions,
    arrival_update,
    condensed_qp,
    inverse_factor,
    positive_definite,
    riccati_window_step,
    solve_window_qp,
    symmetric_matrix,
    window_functions,
)
from cartpole.estimation.measurement import positions_initial_state
from cartpole.estimation.mhe_baseline import time_ipopt_window
from cartpole.estimation.noise import process_covariance
from cartpole.models import SHIPPED_MJCF, build_model, steps_per_period
from cartpole.options import StageOptions

#: Periods in the window when none is given.
DEFAULT_HORIZON = 10
#: m/s^2 on slides, rad/s^2 on hinges: the unknown acceleration when neither ``W`` nor ``accel_std`` is given.
DEFAULT_ACCEL_STD = 1.0
#: The arrival cost's initial standard deviations when ``P0`` is not given: positions (m, rad) and rates (m/s,
#: rad/s) of the first estimate (which has zero rates).
ARRIVAL_POSITION_STD = 0.1
ARRIVAL_RATE_STD = 1.0
#: Relative tolerance with which a horizon must be a whole number of periods.
_WHOLE = 1e-6
#: Eigenvalues of ``W`` below this fraction of its largest are its null space.
_RANK_TOL = 1e-12


#: Most control periods an MHE window may span.
MAX_WINDOW = 100


def horizon_periods(horizon_s: float, period_s: float) -> int:
    """The MHE window ``N`` in control periods from a horizon in seconds.

    Parameters
    ----------
    horizon_s : float
        The window's length in s (``N`` periods).
    period_s : float
        The control period in s.

    Returns
    -------
    int
        ``N = horizon_s / period_s`` (>= 1).

    Raises
    ------
    EstimationError
        A horizon or period that is not a positive number of seconds, or a horizon that is not a whole number of
        periods (within 1e-6 relative).
    """
    try:
        H, T = float(horizon_s), float(period_s)
    except (TypeError, ValueError):
        raise EstimationError(f"The MHE horizon {horizon_s!r} and period {period_s!r} must be numbers of seconds; "
                              "give e.g. 0.1 s.") from None
    if not (math.isfinite(T) and T > 0):
        raise EstimationError(f"The control period {T:g} s is not a positive number of seconds.")
    if not (math.isfinite(H) and H > 0):
        raise EstimationError(f"The MHE horizon {H:g} s is not positive; give a whole number of {T:g} s periods, "
                              f"e.g. {10 * T:g} s.")
    N = round(H / T)
    if N > MAX_WINDOW:
        raise EstimationError(f"The MHE horizon {H:g} s is {H / T:.3g} control periods, more than the {MAX_WINDOW} "
                              f"limit (each control step solves a problem over all of them); give at most "
                              f"{MAX_WINDOW * T:g} s.")
    if N < 1 or abs(N * T - H) > _WHOLE * H:
        near = sorted({max(1, math.floor(H / T)) * T, max(1, math.ceil(H / T)) * T})
        raise EstimationError(f"The MHE horizon {H:g} s is not a whole number of {T:g} s control periods; give "
                              f"{' or '.join(f'{v:g}' for v in near)} s.")
    return int(N)


@dataclass(frozen=True, eq=False)
class MHEOptions(StageOptions):
    """The moving-horizon estimator's own settings (:class:`MovingHorizonEstimator`): its window, its arrival cost's
    first covariance, the joints' bounds and how each period is computed. Keyword-only; every field has a default.

    Attributes
    ----------
    horizon : int
        Intervals ``N`` (control periods) in the window, >= 1 (default :data:`DEFAULT_HORIZON`; from seconds:
        :func:`horizon_periods`).
    P0 : (nx, nx) array, (nx,) array, float or None
        The arrival cost's covariance at the first sample (SI units squared), positive definite; None (default):
        diagonal with :data:`ARRIVAL_POSITION_STD` and :data:`ARRIVAL_RATE_STD`.
    joint_ranges : (nq, 2) array or None
        Hard bounds on the estimated positions (m, rad; ``+-inf`` where unlimited); None (default):
        ``model.params.joint_ranges``.
    compiled : bool
        False evaluates the window in CasADi's virtual machine (same numbers, slower) and runs the Python step
        (default True).
    c_step : bool
        True (default, with ``compiled``): each period runs the compiled C of ``cartpole/csrc/mhe.c.jinja``
        (:mod:`cartpole.estimation.mhe_c`), the C ``cartpole export`` ships; False, or without a C compiler: the
        Python step (the same Riccati recursion in numpy; the tests' reference).

    Raises
    ------
    EstimationError
        A horizon that is not a whole number >= 1 of periods, or a ``P0`` or ``joint_ranges`` that is not numbers
        (their shapes and definiteness are checked against the model by :class:`MovingHorizonEstimator`).
    """

    horizon: int = DEFAULT_HORIZON
    P0: object = None
    joint_ranges: object = None
    compiled: bool = True
    c_step: bool = True

    error: ClassVar[type] = EstimationError
    SCALARS: ClassVar[tuple] = ("horizon",)

    def __post_init__(self):
        horizon = self.horizon
        try:
            whole = not isinstance(horizon, bool) and float(horizon).is_integer() and horizon >= 1
        except (TypeError, ValueError):
            whole = False
        if not whole:
            raise EstimationError(f"The MHE horizon {horizon!r} is not a whole number >= 1 of control periods; give "
                                  "e.g. horizon=10 (horizon_periods converts seconds).")
        self.set_field("horizon", int(horizon))
        for name in ("P0", "joint_ranges"):
            value = getattr(self, name)
            if value is not None:
                try:
                    self.set_field(name, readonly(value))
                except (TypeError, ValueError):
                    raise EstimationError(f"MHEOptions.{name} must be numbers (SI units); got {value!r}.") from None
        self.set_field("compiled", bool(self.compiled))
        self.set_field("c_step", bool(self.c_step))


class MovingHorizonEstimator(SampledEstimator):
    """Moving-horizon estimation of ``x = [qpos, qvel]`` from ``y = h(x, u) + v`` (see the module doc), one
    Gauss-Newton step per control period; the :class:`~cartpole.estimation.base.Estimator` contract:
    ``reset(y0)`` starts from ``initial_state(y0)`` with its positions clipped to the joints' ranges (also the
    arrival cost's centre; the window holds this one node), ``update(y, U)`` shifts the window, appends the sample
    and takes one Gauss-Newton step.

    Parameters
    ----------
    model : CartPoleModel
        The plant (one physics step ``model.step`` of ``model.dt`` s); anything with ``nq``, ``nx``, ``nu``,
        ``step`` and, unless ``joint_ranges`` and ``initial_state`` are given, ``params.joint_ranges`` and
        ``x_hanging``.
    steps : int
        Physics steps ``m`` per control period (period ``m * model.dt`` s).
    h : casadi.Function
        Measurement model ``(x (nx,), u (nu,)) -> y (ny,)`` (sensor units).
    V : (ny, ny) array, (ny,) array or float
        Measurement noise covariance (sensor units squared; a vector: its diagonal), positive definite.
    W : (nx, nx) array, optional
        Process noise covariance over one period (positive semidefinite; SI units squared). Give ``W`` or
        ``accel_std``, not both.
    accel_std : float or (nq,) array, optional
        Standard deviation of the unknown acceleration (m/s^2 on slides, rad/s^2 on hinges):
        ``W = process_covariance(accel_std, period)``. Default :data:`DEFAULT_ACCEL_STD` when ``W`` is not given.
    initial_state : callable, optional
        ``y0 (ny,) -> x0 (nx,)``: the first estimate and the arrival cost's first centre. Default: each position
        that ``h`` measures one-to-one (``y_i = q_j``) from ``y0``, the others from ``model.x_hanging``, zero rates.
    options : MHEOptions, optional
        The window (``horizon``), the arrival cost's first covariance (``P0``), the bounds (``joint_ranges``) and
        the evaluation (``compiled``, ``c_step``); default :class:`MHEOptions` ``()``.
    name : str
        The estimator's name (the CLI's ``--estimator``).

    Attributes
    ----------
    N, steps, nx, ny, nu : int
        Window, physics steps per period and sizes.
    period : float
        Control period in s.
    V, W : arrays (ny, ny), (nx, nx)
        The covariances the stage weights invert.
    functions : WindowFunctions
        The compiled evaluations (of the Python step).
    c : CompiledMHE or None
        The compiled C step in use, None on the Python step.
    failures : list of int
        Samples (update counts) whose Gauss-Newton step failed and kept the prediction.

    Raises
    ------
    EstimationError
        A horizon that is not a whole number >= 1 of periods, covariances that are not symmetric positive
        (semi)definite, an ``h`` whose shapes disagree with the model, bounds that are not (nq, 2) with low <= high.
    """

    title = "MHE"

    def __init__(self, model, steps: int, h: ca.Function, V, *, W=None, accel_std=None, initial_state=None,
                 options: MHEOptions = MHEOptions(), name: str = "mhe"):
        self.name = str(name)
        nq, nx, nu = int(model.nq), int(model.nx), int(model.nu)
        self.nq, self.nx, self.nu = nq, nx, nu
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise EstimationError(f"The physics steps per period {steps!r} must be a whole number >= 1.")
        if not isinstance(options, MHEOptions):
            raise EstimationError(f"The MHE's options must be an MHEOptions; got {options!r}.")
        P0, joint_ranges, compiled = options.P0, options.joint_ranges, options.compiled
        self.steps, self.N = int(steps), options.horizon
        self.period = self.steps * float(model.dt)
        if not isinstance(h, ca.Function) or h.n_in() != 2 or h.n_out() < 1:
            raise EstimationError("The measurement model h must be a CasADi Function h(x, u) -> y.")
        if h.numel_in(0) != nx or h.numel_in(1) != nu or h.size2_out(0) != 1:
            raise EstimationError(f"The measurement model h takes x ({h.numel_in(0)}) and u ({h.numel_in(1)}) and "
                                  f"must take ({nx},) and ({nu},) and return a column y (ny,).")
        ny = int(h.size1_out(0))
        self.ny = ny
        self.V = readonly(positive_definite("V", V, ny))
        if W is not None and accel_std is not None:
            raise EstimationError("Give the process noise as W or as accel_std, not both.")
        if W is None:
            W = process_covariance(DEFAULT_ACCEL_STD if accel_std is None else accel_std, self.period, nq)
        W = symmetric_matrix("W", W, nx)
        lam, Q = np.linalg.eigh(W)
        if lam.min() < -1e-9 * max(lam.max(), 1e-300):
            raise EstimationError(f"The process covariance W is not positive semidefinite (smallest eigenvalue "
                                  f"{lam.min():.3g}); give variances >= 0.")
        self.W = readonly(W)
        keep = lam > _RANK_TOL * lam.max() if lam.max() > 0 else np.zeros(nx, bool)
        self._L = np.ascontiguousarray(Q[:, keep] * np.sqrt(lam[keep]))  # W = L L'
        self._r = int(keep.sum())
        if P0 is None:
            P0 = np.r_[np.full(nq, ARRIVAL_POSITION_STD ** 2), np.full(nq, ARRIVAL_RATE_STD ** 2)]
        self._P0 = positive_definite("P0", P0, nx)
        self._RV = np.linalg.inv(np.linalg.cholesky(self.V))  # RV' RV = V^-1
        rng_ = model.params.joint_ranges if joint_ranges is None else joint_ranges
        rng_ = np.array(rng_, dtype=float)
        if rng_.shape != (nq, 2) or np.isnan(rng_).any() or np.any(rng_[:, 0] > rng_[:, 1]):
            raise EstimationError(f"The joint ranges must be ({nq}, 2) with low <= high (+-inf where unlimited); "
                                  f"got {rng_.tolist()}.")
        self._bidx = np.flatnonzero(np.isfinite(rng_).any(axis=1))
        self._lo, self._hi = rng_[self._bidx, 0], rng_[self._bidx, 1]
        self.functions: WindowFunctions = window_functions(model, self.steps, h, self.N, compiled=compiled)
        self._window = Buffered(self.functions.window)
        self._stage = Buffered(self.functions.stage)
        self._meas = Buffered(self.functions.measurement)
        if initial_state is None:
            initial_state = positions_initial_state(h, model, getattr(model, "x_hanging", np.zeros(nx)))
        self._initial_state = initial_state
        N, r = self.N, self._r
        self._X = np.zeros((N + 1, nx))  # row-major (N+1, nx) is CasADi's column-major (nx, N+1)
        self._E = np.zeros((N, r))
        self._Y = np.zeros((N + 1, ny))
        self._UU = np.zeros((N, nu * self.steps))  # row j: vec of the interval's (nu, m) ctrl, column-major
        self._UH = np.zeros((N + 1, nu))
        self._n = -1  # intervals in the window; -1 before reset
        self._k = 0
        self.failures: list[int] = []
        self.c = compiled_mhe(self, model, h) if (options.c_step and compiled) else None

    # ---- the contract -----------------------------------------------------------------------------------------
    def _start(self, y0, x0) -> np.ndarray:
        """The first estimate with its positions clipped to the joints' ranges, also the arrival cost's centre; the
        window holds this one node."""
        x0[self._bidx] = np.clip(x0[self._bidx], self._lo, self._hi)
        self._X[:] = x0
        self._E[:] = 0.0
        self._Y[:] = y0
        self._UU[:] = 0.0
        self._UH[:] = 0.0
        self._xbar = x0.copy()
        self._P = self._P0.copy()
        R = inverse_factor(self._P)
        self._P_inv = R.T @ R
        self._n, self._k = 0, 0
        self.failures = []
        if self.c is not None:
            return self.c.start(x0, y0)
        return x0.copy()

    def _correct(self, y, U) -> np.ndarray:
        """Shift the window, append the sample, take one Gauss-Newton step."""
        if self.c is not None:
            self._k += 1
            x, failed = self.c.update(y, U)
            if failed:
                self.failures.append(self._k)
            return x
        Uv = U.ravel(order="F")
        if self._n == self.N:
            self._slide()
        n = self._n
        xn = self._stage(self._X[n], Uv)[0]
        if math.isfinite(xn.sum()):
            self._X[n + 1] = xn
        else:  # a prediction that blew up: the step starts from the last estimate
            self._X[n + 1] = self._X[n]
        self._E[n] = 0.0
        self._UU[n] = Uv
        self._UH[n + 1] = Uv[-self.nu:]
        self._Y[n + 1] = y
        self._n = n + 1
        self._k += 1
        self._gn_step()
        return self._X[self._n]

    # ---- what a caller may read -------------------------------------------------------------------------------
    @property
    def window(self) -> np.ndarray:
        """The window's state estimates (n+1, nx), oldest first; the last row is the current estimate."""
        if self.c is not None:
            return self.c.window()
        return self._X[:self._n + 1].copy()

    @property
    def arrival(self) -> tuple[np.ndarray, np.ndarray]:
        """The arrival cost's centre ``x_bar`` (nx,) and covariance ``P`` (nx, nx) at the window's first node."""
        if self.c is not None:
            return self.c.arrival()
        return self._xbar.copy(), self._P.copy()

    @property
    def design(self) -> dict:
        """What the estimator is built from, for code generation (:mod:`cartpole.export`): ``L`` (nx, r) with
        ``W = L L'``, ``P0`` (nx, nx) the first arrival covariance, ``RV`` (ny, ny) with ``RV' RV = V^-1``,
        ``bounded`` (the qpos indices with a range), ``low``, ``high`` (their ranges, m or rad); copies."""
        return {"L": self._L.copy(), "P0": np.array(self._P0), "RV": self._RV.copy(), "bounded": self._bidx.copy(),
                "low": np.array(self._lo), "high": np.array(self._hi)}

    @property
    def library(self) -> str | None:
        """Path of the compiled C in use (None on CasADi's virtual machine)."""
        return self.functions.library

    # ---- internals --------------------------------------------------------------------------------------------

    def _slide(self) -> None:
        """Drop the window's first node into the arrival cost (module doc) and shift the buffers by one."""
        nx, ny = self.nx, self.ny
        x0 = self._X[0].copy()
        F0, A0 = (v.copy() for v in self._stage(x0, self._UU[0]))
        h0, C0 = (v.copy() for v in self._meas(x0, self._UH[0]))
        xb, P = arrival_update(self._xbar, self._P, x0, self._Y[0], h0, C0.reshape(nx, ny).T, F0,
                               A0.reshape(nx, nx).T, self.V, self.W)
        if math.isfinite(xb.sum() + P.sum()):
            self._xbar, self._P = xb, P
            R = inverse_factor(P)
            self._P_inv = R.T @ R
        else:  # a linearisation that blew up: the arrival at the next node's estimate, with the old weight
            self._xbar = self._X[1].copy()
        for buf in (self._X, self._E, self._Y, self._UU, self._UH):
            buf[:-1] = buf[1:]
        self._n -= 1

    def _gn_step(self) -> None:
        """One Gauss-Newton step of the window's least squares from the current iterate (module doc)."""
        n, N, nx, ny = self._n, self.N, self.nx, self.ny
        Fv, Av, hv, Cv = self._window(self._X, self._UU, self._UH)
        # CasADi's column-major blocks side by side read as (stage, column, row): transposed views
        A = Av.reshape(N, nx, nx)[:n].transpose(0, 2, 1)
        C = Cv.reshape(N + 1, nx, ny)[:n + 1].transpose(0, 2, 1)
        X, E = self._X[:n + 1], self._E[:n]
        d = Fv.reshape(N, nx)[:n] + E @ self._L.T - X[1:]
        r_meas = hv.reshape(N + 1, ny)[:n + 1] - self._Y[:n + 1]
        b = self._bidx
        try:
            dX, dE = riccati_window_step(A, d, C, r_meas, self._RV, self._L, self._P_inv, X[0] - self._xbar, E)
        except np.linalg.LinAlgError:
            dX = None
        if dX is not None and b.size:
            qz = X[:, b] + dX[:, b]
            if (qz > self._hi + 1e-12).any() or (qz < self._lo - 1e-12).any():
                dX = None  # a range binds: the bounded QP below
        if dX is None:
            H, g, S, c = condensed_qp(A, d, C, r_meas, self._RV, self._L, self._P_inv, X[0] - self._xbar, E)
            z = solve_window_qp(H, g, S, c, X[:, b], b, self._lo, self._hi)
            if z is None:
                dX = None
            else:
                dX, dE = c + S @ z, z[nx:].reshape(E.shape)
        if dX is None or not math.isfinite(dX.sum() + dE.sum()):
            self.failures.append(self._k)
            return
        X += dX
        E += dE
        if b.size:
            X[:, b] = np.clip(X[:, b], self._lo, self._hi)  # DAQP's tolerance, not more

def bench_mhe(model=None, *, horizon: float = 0.1, period: float = 0.01, n: int = 500, accel_std: float = 1.0,
              seed: int = 0, compiled: bool = True, repeats: int = 1, python: int = 0, baseline: int = 0) -> dict:
    """Time the MHE's ``update`` on a swinging cart measured by its encoders (the benchmark's entry).

    The truth is the exact discrete model (:attr:`cartpole.models.HoldModel.step_inputs`) from hanging rest under a
    sinusoidal ctrl at the hanging pole's frequency with a weak centring of the cart (large swings, the cart inside
    its rail); the measurement the joint positions with Gaussian noise (1 mm, 1 mrad) rounded to 0.5 mm and 2 pi /
    4096 rad (an encoder's quantum), ``V`` their variances. Construction (and any compile) is not timed.

    Parameters
    ----------
    model : CartPoleModel, optional
        Default the shipped one-pole cart (another physics step: ``model.rebuilt(dt=...)``).
    horizon : float
        Window in s (a whole number of periods).
    period : float
        Control period in s (a whole number of physics steps).
    n : int
        ``update`` calls timed in each run.
    accel_std : float
        The estimator's process noise, m/s^2 and rad/s^2.
    seed : int
        Seed of the measurement noise.
    compiled : bool
        False: CasADi's virtual machine and the Python step.
    repeats : int
        Runs of the ``n`` updates (the estimator reset before each); the figures are the median of the runs'.
    python : int
        Also time this many updates of the Python step (``c_step=False``, the reference path), 0: not.
    baseline : int
        Also re-solve this many full windows (after the window filled) with IPOPT to convergence, warm-started from
        the previous solution shifted (:mod:`cartpole.estimation.mhe_baseline`), 0: not.

    Returns
    -------
    dict
        ``step_ms_median``, ``step_ms_max``, ``step_ms_p90`` (ms per ``update``, the estimator as the loop runs it:
        the compiled C step unless ``compiled`` is False or there is no compiler), ``step_ms_medians`` (one per
        run), ``n``, ``repeats``, ``N`` (periods in the window), ``steps`` (physics steps per period), ``dt``,
        ``period``, ``horizon`` (s), ``compiled`` (bool: the window's functions compiled), ``c_step`` (bool: the C
        step ran), ``rms_error`` (nx,) list: the estimate's RMS error per state after the first window (SI
        units); with ``python``: ``python`` {``step_ms_median``, ``n``, ``max_diff``: the largest difference from
        the timed estimator's estimates}; with ``baseline``: ``ipopt`` (:func:`~cartpole.estimation.mhe_baseline.
        time_ipopt_window`) and ``speedup`` (its median over ``step_ms_median``).
    """
    model = build_model(SHIPPED_MJCF) if model is None else model
    m = steps_per_period(period, model.dt)
    N = horizon_periods(horizon, period)
    nu = model.nu
    X, Us, Y, h, V = _bench_truth(model, m, int(n), seed)
    est = MovingHorizonEstimator(model, m, h, V, accel_std=accel_std, options=MHEOptions(horizon=N, compiled=compiled))
    medians, samples = [], []
    for run in range(max(1, int(repeats))):
        est.reset(Y[0])
        times, Xh = [], []
        for k in range(int(n)):
            t0 = time.perf_counter()
            Xh.append(est.update(Y[k + 1], Us[k]))
            times.append(time.perf_counter() - t0)
            if run == 0 and baseline and k + 1 >= N and len(samples) < int(baseline):
                j0 = k + 1 - N
                UH = np.array([Us[j - 1][:, -1] if j else np.zeros(nu) for j in range(j0, k + 2)])
                UU = np.array([Us[j].ravel(order="F") for j in range(j0, k + 1)])
                samples.append((Y[j0:k + 2], UU, UH, *est.arrival, Xh[-1]))
        ms = 1e3 * np.array(times)
        medians.append(float(np.median(ms)))
    err = (np.array(Xh) - X[1:])[N:]
    out = {"step_ms_median": float(np.median(medians)), "step_ms_max": float(ms.max()),
           "step_ms_p90": float(np.percentile(ms, 90)), "step_ms_medians": medians, "n": int(n),
           "repeats": len(medians), "N": N, "steps": m, "dt": float(model.dt), "period": float(period),
           "horizon": float(horizon), "compiled": est.library is not None, "c_step": est.c is not None,
           "rms_error": np.sqrt(np.mean(err ** 2, axis=0)).tolist()}
    if python:
        python_step = MHEOptions(horizon=N, compiled=compiled, c_step=False)
        out["python"] = _time_python_step(MovingHorizonEstimator(model, m, h, V, accel_std=accel_std,
                                                                 options=python_step),
                                          Y, Us, Xh, min(int(python), int(n)))
    if samples:
        out["ipopt"] = time_ipopt_window(est, model, h, samples)
        out["speedup"] = out["ipopt"]["step_ms_median"] / out["step_ms_median"]
    return out


def _bench_truth(model, m: int, n: int, seed: int) -> tuple:
    """``(X, Us, Y, h, V)`` of :func:`bench_mhe`: ``n + 1`` true states (the exact discrete model over periods of
    ``m`` steps, from hanging rest under a sinusoid at the hanging pole's frequency, the cart weakly centred), the
    ``n`` periods' inputs ``(nu, m)``, the encoders' readings, the measurement function and its covariance."""
    nq, nx, nu = model.nq, model.nx, model.nu
    xs = ca.SX.sym("x", nx)
    h = ca.Function("encoders", [xs, ca.SX.sym("u", nu)], [xs[:nq]])
    quantum = np.array([5e-4 if j in model.slides else 2 * np.pi / 4096 for j in range(nq)])
    noise = np.array([1e-3] * nq)
    V = np.diag(noise ** 2 + quantum ** 2 / 12)
    rng = np.random.default_rng(seed)
    hold = model.hold(m)
    A, _ = model.AB(model.x_hanging, model.u_hanging)
    w = float(np.abs(np.linalg.eigvals(np.asarray(A)).imag).max()) or 5.0
    amp = 0.5 * np.asarray(model.params.ctrl_range)[:, 1].clip(max=1.0)
    cart = model.slide
    x = np.array(model.x_hanging, dtype=float)
    X, Us = [x], []
    for k in range(n):
        U = np.zeros((nu, m))
        for i in range(m):
            t = (k * m + i) * model.dt
            U[:, i] = amp * np.sin(w * t)
            if cart is not None:
                U[:, i] -= 0.5 * x[cart] + 0.5 * x[nq + cart]
        x = np.asarray(hold.step_inputs(x, U)).ravel()
        X.append(x)
        Us.append(U)
    X = np.array(X)
    Y = np.round((X[:, :nq] + noise * rng.standard_normal((len(X), nq))) / quantum) * quantum
    return X, Us, Y, h, V


def _time_python_step(ref, Y, Us, Xh, count: int) -> dict:
    """``{step_ms_median, n, max_diff}``: ``count`` updates of the reference estimator ``ref`` (the Python step)
    timed, and its largest difference from the timed estimator's estimates ``Xh``."""
    ref.reset(Y[0])
    times = []
    for k in range(count):
        t0 = time.perf_counter()
        xp = ref.update(Y[k + 1], Us[k])
        times.append(time.perf_counter() - t0)
    return {"step_ms_median": float(np.median(1e3 * np.array(times))), "n": count,
            "max_diff": float(np.abs(xp - Xh[count - 1]).max())}
