"""Angle traces that read continuously: wrapped errors from upright, with the line broken at each wrap.

A pole that swings over the top has a wrapped error that jumps from +pi to -pi; drawn as one line it shows a vertical
stroke that is not motion. :func:`wrapped_angle_trace` inserts a gap there instead, so every figure marks a wrap the
same way.
"""
from __future__ import annotations

import numpy as np

from cartpole.models import wrap_angle


def wrapped_angle_trace(t, angle, reference=0.0, *, degrees: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` ready for ``plot``: ``y`` the error ``angle - reference`` wrapped to (-pi, pi], NaN at each wrap.

    Parameters
    ----------
    t : (n,) array
        Time in s.
    angle : (n,) array
        Joint angle in rad (MuJoCo's, never wrapped).
    reference : float
        Upright angle in rad (``x_eq`` of that hinge).
    degrees : bool
        Return ``y`` in degrees (default) or radians.

    Returns
    -------
    (t (m,), y (m,)) with ``m - n`` the number of wraps; a NaN in both at each wrap breaks the line there.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(wrap_angle(np.asarray(angle, dtype=float) - reference), dtype=float).reshape(-1)
    jump = np.flatnonzero(np.abs(np.diff(y)) > np.pi) + 1  # half a turn in one sample is a wrap, not motion
    y = np.insert(y, jump, np.nan)
    t = np.insert(t, jump, np.nan)
    return t, (np.rad2deg(y) if degrees else y)
