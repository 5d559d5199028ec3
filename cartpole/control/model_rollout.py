"""A controller run on the symbolic model's exact discrete step instead of MuJoCo: guesses and predictions."""
from __future__ import annotations

import numpy as np

from cartpole.models import CartPoleModel


def model_rollout(model: CartPoleModel, controller, x0, steps: int, *, u_limits=None, t0: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Run ``model.step_np`` (the MJCF's integrator at ``model.dt``: the step ``mj_step`` takes) ``steps`` times
    under ``controller``.

    Parameters
    ----------
    model : CartPoleModel
    controller : callable
        ``(t (s), x (nx,)) -> ctrl`` (nu,) (a scalar for one input).
    x0 : (nx,) array
        Start state.
    steps : int
        Number of steps of ``model.dt`` s.
    u_limits : (nu, 2) array, optional
        ``[low, high]`` per input: the ctrl is clipped to it (default not clipped).
    t0 : float
        s, time of the start state; step ``k`` starts at ``t0 + k dt``.

    Returns
    -------
    x : (steps+1, nx) array
        States, row 0 the start (NaN/inf are not caught: check them where it matters).
    u : (steps, nu) array
        ctrl applied during each step.
    """
    h, nu = model.dt, model.nu
    lims = None if u_limits is None else np.asarray(u_limits, dtype=float).reshape(nu, 2)
    x = np.empty((steps + 1, model.nx))
    u = np.empty((steps, nu))
    x[0] = np.asarray(x0, dtype=float)
    for k in range(steps):
        uk = np.asarray(controller(t0 + k * h, x[k]), dtype=float).reshape(nu)
        u[k] = uk if lims is None else np.clip(uk, lims[:, 0], lims[:, 1])
        x[k + 1] = model.step_np(x[k], u[k])
    return x, u
