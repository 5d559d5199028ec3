"""Check the symbolic Jacobians against MuJoCo: central differences of ``mj_forward`` (continuous) and of
``mj_step`` (discrete), at any states, for any supported integrator (``mjd_transitionFD`` refuses RK4)."""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from cartpole.models import CartPoleModel, CartPoleParams, Plant
from cartpole.sim import make_mujoco


def mujoco_fd_jacobians(plant: Plant, x, u, *, eps: float = 1e-6,
                        discrete: bool = False, _md=None) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference Jacobians of MuJoCo's dynamics at ``(x, u)``.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    x : (nx,) array
        State ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    u : (nu,) array
        ctrl (MuJoCo's units: force = gear * ctrl).
    eps : float
        Perturbation, in the state's and ctrl's own units.
    discrete : bool
        False: Jacobians of ``[qvel, qacc]`` from ``mj_forward`` (compare with ``A, B``);
        True: Jacobians of one ``mj_step`` (compare with ``Ad, Bd``).

    Returns
    -------
    (A (nx, nx), B (nx, nu))
    """
    m, d = _md if _md is not None else make_mujoco(plant)
    x = np.asarray(x, float)
    u = np.atleast_1d(np.asarray(u, float))
    nq = m.nq

    def fun(xx, uu):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:], d.ctrl[:] = xx[:nq], xx[nq:], uu
        if discrete:
            mujoco.mj_step(m, d)
            return np.concatenate([d.qpos, d.qvel])
        mujoco.mj_forward(m, d)
        return np.concatenate([d.qvel, d.qacc])

    A = np.empty((x.size, x.size))
    B = np.empty((x.size, u.size))
    for i in range(x.size):
        dx = np.zeros(x.size)
        dx[i] = eps
        A[:, i] = (fun(x + dx, u) - fun(x - dx, u)) / (2 * eps)
    for i in range(u.size):
        du = np.zeros(u.size)
        du[i] = eps
        B[:, i] = (fun(x, u + du) - fun(x, u - du)) / (2 * eps)
    return A, B


@dataclass(frozen=True)
class JacobianCheck:
    """Relative errors of the symbolic Jacobians against MuJoCo finite differences at many states.

    Attributes
    ----------
    states : (k, nx) array; inputs : (k, nu) array
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
    """``n`` random states (n, nx) and ctrls (n, nu) away from the joint limits, with nonzero velocities.

    A limited joint stays within the middle 60 % of its range (no limit constraint active); an unlimited
    slide within +-1 m, an unlimited hinge anywhere in (-pi, pi); slide speeds within ``speed`` m/s, hinge
    rates within ``rate`` rad/s; ctrl within the ctrl range (+-1 where unlimited).
    """
    rng = np.random.default_rng(seed)
    cols = []
    for j in params.joints:
        lo, hi = j.range
        if np.isfinite(lo) and np.isfinite(hi):
            mid, half = 0.5 * (lo + hi), 0.3 * (hi - lo)
            cols.append(rng.uniform(mid - half, mid + half, n))
        else:
            cols.append(rng.uniform(-1.0, 1.0, n) if j.kind == "slide" else rng.uniform(-np.pi, np.pi, n))
    for j in params.joints:
        lim = speed if j.kind == "slide" else rate
        cols.append(rng.uniform(-lim, lim, n))
    cr = np.where(np.isfinite(params.ctrl_range), params.ctrl_range, np.sign(params.ctrl_range))
    u = rng.uniform(cr[:, 0], cr[:, 1], (n, params.nu))
    return np.column_stack(cols), u


def check_jacobians(model: CartPoleModel, states, inputs, *, eps: float = 1e-6,
                    discrete: bool = False) -> JacobianCheck:
    """Compare ``model``'s exact (A, B) (or (Ad, Bd)) with MuJoCo central differences at each state.

    Parameters
    ----------
    model : CartPoleModel (its ``params`` name the MJCF MuJoCo runs)
    states : (k, nx) array; inputs : (k, nu) array
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
