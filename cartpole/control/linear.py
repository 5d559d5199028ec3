"""Linear state feedback about an equilibrium: ``u = u* - K (x - x*)``, with the angle error wrapped."""
from __future__ import annotations

import numpy as np

from cartpole.models import wrap_angle


def state_error(x, x_ref) -> np.ndarray:
    """``x - x_ref`` (..., 4) with the pole-angle entry wrapped to (-pi, pi] (hinge angles never wrap in MuJoCo)."""
    e = np.asarray(x, dtype=float) - np.asarray(x_ref, dtype=float)
    e = np.array(e, copy=True)
    e[..., 1] = wrap_angle(e[..., 1])
    return e


class LinearFeedback:
    """The controller ``u = u* - K (x - x*)`` clipped to ``[u_min, u_max]``, with the call shape ``u = c(t, x)``.

    Parameters
    ----------
    K : (1, 4) or (4,) array
        Gain in ctrl per state unit (ctrl/m, ctrl/rad, ctrl/(m/s), ctrl/(rad/s)).
    x_eq : (4,) array, optional
        Equilibrium state (default upright rest at the origin).
    u_eq : float, optional
        Equilibrium ctrl (default 0).
    u_limits : (2,) array, optional
        ``[low, high]`` ctrl clip (default none; MuJoCo clips to ctrlrange anyway).
    S : (4, 4) array, optional
        LQR cost-to-go, kept so :meth:`cost_to_go` can test the catch basin ``e' S e < rho``.
    """

    def __init__(self, K, x_eq=None, u_eq: float = 0.0, *, u_limits=None, S=None):
        self.K = np.asarray(K, dtype=float).reshape(1, -1)
        self.x_eq = np.zeros(self.K.shape[1]) if x_eq is None else np.asarray(x_eq, dtype=float)
        self.u_eq = float(u_eq)
        self.u_limits = (-np.inf, np.inf) if u_limits is None else tuple(float(v) for v in u_limits)
        self.S = None if S is None else np.asarray(S, dtype=float)

    def __call__(self, t: float, x) -> float:
        """ctrl at time t (s) for state x (4,)."""
        e = state_error(x, self.x_eq)
        u = self.u_eq - float(self.K[0] @ e)
        return float(np.clip(u, *self.u_limits))

    def cost_to_go(self, x) -> float:
        """``e' S e`` with ``e`` the wrapped error from the equilibrium (needs ``S``)."""
        if self.S is None:
            raise ValueError("This LinearFeedback was built without S; pass S= to use cost_to_go.")
        e = state_error(x, self.x_eq)
        return float(e @ self.S @ e)
