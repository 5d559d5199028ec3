"""Process noise over a control period: the discrete white-noise-acceleration model shared by every estimator.

Model error on a rig (unmodelled friction, a wrong mass, a push) shows up as an unknown generalized acceleration.
Held constant over a period of ``T`` s with standard deviation ``sigma_i`` on joint ``i``, it moves that joint's
position by ``a T^2 / 2`` and its rate by ``a T``: the covariance over one period is
``W = G diag(sigma^2) G'`` with ``G = [T^2/2 I; T I]`` (nx, nq), states ``[qpos, qvel]`` in MuJoCo's order. The KF,
the EKF and the MHE's stage weights all use this ``W`` so their tuning means the same thing.
"""
from __future__ import annotations

import numpy as np

from cartpole.estimation.base import EstimationError


def process_covariance(accel_std, period: float, nq: int | None = None) -> np.ndarray:
    """``W`` (2 nq, 2 nq) over one period of ``period`` s for an acceleration noise ``accel_std``.

    Parameters
    ----------
    accel_std : float or (nq,) array
        Standard deviation of the unknown acceleration per joint: m/s^2 on slides, rad/s^2 on hinges (one number:
        the same on every joint, then ``nq`` is required).
    period : float
        Control period ``T`` in s.
    nq : int, optional
        Number of joints, when ``accel_std`` is one number.

    Returns
    -------
    (2 nq, 2 nq) array
        Symmetric positive semidefinite.

    Raises
    ------
    EstimationError
        A standard deviation that is negative or not finite, a period that is not positive.
    """
    s = np.asarray(accel_std, dtype=float)
    if s.ndim == 0:
        if nq is None:
            raise EstimationError("One process-noise number needs the number of joints nq; pass nq= or one value "
                                  "per joint.")
        s = np.full(int(nq), float(s))
    s = s.ravel()
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise EstimationError(f"The process noise {s.tolist()} must be finite standard deviations >= 0 of the "
                              "joints' accelerations (m/s^2, rad/s^2); give e.g. `accel_std` 1.")
    T = float(period)
    if not (np.isfinite(T) and T > 0):
        raise EstimationError(f"The period {T:g} s is not positive.")
    n = s.size
    G = np.vstack([0.5 * T * T * np.eye(n), T * np.eye(n)])
    return G @ np.diag(s * s) @ G.T
