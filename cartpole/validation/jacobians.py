"""Check the symbolic Jacobians against MuJoCo: central differences of ``mj_forward`` (continuous) and of
``mj_step`` (discrete), at any states, for any supported integrator (``mjd_transitionFD`` refuses RK4)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole.models.params import CartPoleParams
from cartpole.models.symbolic import CartPoleModel
from cartpole.sim import make_mujoco


def mujoco_fd_jacobians(source: CartPoleParams | str | None, x, u, *, eps: float = 1e-6,
                        discrete: bool = False, _md=None) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference Jacobians of MuJoCo's dynamics at ``(x, u)``.

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
    x : (4,) state; u : scalar or (1,) ctrl
    eps : float
        Perturbation, in the state's and ctrl's own units.
    discrete : bool
        False: Jacobians of ``[qvel, qacc]`` from ``mj_forward`` (compare with ``A, B``);
        True: Jacobians of one ``mj_step`` (compare with ``Ad, Bd``).

    Returns
    -------
    (A (4, 4), B (4, 1))
    """
    import mujoco

    m, d = _md if _md is not None else make_mujoco(source)
    x = np.asarray(x, float)
    u = np.atleast_1d(np.asarray(u, float))

    def fun(xx, uu):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:], d.ctrl[:] = xx[:2], xx[2:], uu
        if discrete:
            mujoco.mj_step(m, d)
            return np.concatenate([d.qpos, d.qvel])
        mujoco.mj_forward(m, d)
        return np.concatenate([d.qvel, d.qacc])

    A = np.empty((4, 4))
    B = np.empty((4, 1))
    for i in range(4):
        dx = np.zeros(4)
        dx[i] = eps
        A[:, i] = (fun(x + dx, u) - fun(x - dx, u)) / (2 * eps)
    B[:, 0] = (fun(x, u + eps) - fun(x, u - eps)) / (2 * eps)
    return A, B


@dataclass(frozen=True)
class JacobianCheck:
    """Relative errors of the symbolic Jacobians against MuJoCo finite differences at many states.

    Attributes
    ----------
    states : (k, 4) array; inputs : (k, 1) array
    err_A, err_B : (k,) arrays
        ``max|sym - fd| / max|fd|`` per state (dimensionless).
    eps : float; discrete : bool
    """

    states: np.ndarray
    inputs: np.ndarray
    err_A: np.ndarray
    err_B: np.ndarray
    eps: float
    discrete: bool

    @property
    def worst(self) -> float:
        """Largest relative error over all states and both matrices."""
        return float(max(self.err_A.max(), self.err_B.max()))


def random_states(params: CartPoleParams, n: int, *, seed: int = 0, speed: float = 2.0,
                  rate: float = 6.0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` random states (n, 4) and ctrls (n, 1) away from the joint limits, with nonzero velocities.

    Cart positions stay within 60 % of the track (no limit constraint active), angles cover (-pi, pi),
    cart speeds within ``speed`` m/s, pole rates within ``rate`` rad/s, ctrl within the ctrl range.
    """
    rng = np.random.default_rng(seed)
    lo, hi = params.cart_range
    s_max = min(1.0, 0.6 * (hi - lo) / 2) if np.isfinite(hi - lo) else 1.0
    x = np.column_stack([rng.uniform(-s_max, s_max, n), rng.uniform(-np.pi, np.pi, n),
                         rng.uniform(-speed, speed, n), rng.uniform(-rate, rate, n)])
    umax = params.u_max if np.isfinite(params.u_max) else 1.0
    return x, rng.uniform(-umax, umax, (n, 1))


def check_jacobians(model: CartPoleModel, states, inputs, *, eps: float = 1e-6,
                    discrete: bool = False) -> JacobianCheck:
    """Compare ``model``'s exact (A, B) (or (Ad, Bd)) with MuJoCo central differences at each state.

    Parameters
    ----------
    model : CartPoleModel (its ``params`` name the MJCF MuJoCo runs)
    states : (k, 4) array; inputs : (k, 1) array
    eps : float, finite-difference step
    discrete : bool, compare the discrete step instead of the continuous dynamics
    """
    md = make_mujoco(model.params)
    states = np.asarray(states, float)
    inputs = np.asarray(inputs, float).reshape(len(states), -1)
    eA, eB = np.empty(len(states)), np.empty(len(states))
    for k, (x, u) in enumerate(zip(states, inputs)):
        A, B = model.linearize(x, u, discrete=discrete)
        Af, Bf = mujoco_fd_jacobians(None, x, u, eps=eps, discrete=discrete, _md=md)
        eA[k] = np.abs(A - Af).max() / np.abs(Af).max()
        eB[k] = np.abs(B - Bf).max() / np.abs(Bf).max()
    return JacobianCheck(states=states, inputs=inputs, err_A=eA, err_B=eB, eps=eps, discrete=discrete)
