"""Finite-horizon time-varying LQR (TVLQR) along a planned trajectory.

Two syntheses of the same regulator, with the law ``u = u0(t) - K(t) (x - x0(t))`` (Drake's convention):

* ``method="discrete"`` (default): the backward Riccati recursion on the EXACT discrete model at the
  simulator's step ``dt`` (one step of the MJCF's integrator, ``model.ABd``), linearised along the plan
  resampled at ``dt`` (cubic-Hermite states, and for each step the mean of the first-order-hold input over
  the step, i.e. the zero-order-hold value the simulator applies). All ``n`` linearisations come from one
  call of a CasADi ``map`` of ``ABd``. Stage weights are ``Q dt`` and ``R dt`` so the sum approximates the
  continuous cost ``integral (x'Qx + u'Ru) dt``; the terminal cost is ``dlqr(Ad, Bd, Q dt, R dt).S`` at
  the final state, the cost-to-go of the discrete LQR catch, so the hand-over is seamless.
* ``method="continuous"``: the Riccati ODE ``-dS/dt = Q + A'S + SA - S B R^-1 B' S`` integrated backward
  with ``scipy.integrate.solve_ivp`` from ``S(T) = lqr(A, B, Q, R).S`` at the final state, ``K = R^-1 B'S``.

For small ``dt`` the two agree (the recursion is a consistent discretisation of the ODE).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole.lqr.riccati import LQRError, check_weights, dlqr, lqr
from cartpole.models import CartPoleModel
from cartpole._arrays import readonly

METHODS = ("discrete", "continuous")


@dataclass(frozen=True)
class TVLQRGains:
    """Time-varying gains and cost-to-go along a trajectory.

    Attributes
    ----------
    t : (n,) array, s
        Times at which ``K[k]`` starts to apply (step starts, ``t[k] = t0 + k dt``).
    K : (n, 1, 4) array
        Gains in ctrl per state unit, for ``u = u0 - K (x - x0)``.
    S : (n+1, 4, 4) array
        Cost-to-go matrices at ``t[0] .. t[-1] + dt`` (the last one is the terminal cost).
    dt : float
        Step of the grid in s (the simulator's step for the discrete method).
    method : str
        ``discrete`` (K held over each step) or ``continuous`` (K interpolated linearly in time).
    """

    t: np.ndarray
    K: np.ndarray
    S: np.ndarray
    dt: float
    method: str = "discrete"

    def __post_init__(self):
        for name in ("t", "K", "S"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        n = self.t.size
        if self.K.shape != (n, 1, 4) or self.S.shape != (n + 1, 4, 4):
            raise LQRError(f"TVLQR arrays disagree: t {self.t.shape}, K {self.K.shape}, S {self.S.shape}; "
                           "need t (n,), K (n, 1, 4), S (n+1, 4, 4).")

    @property
    def t_final(self) -> float:
        """End of the horizon in s (where the terminal cost applies)."""
        return float(self.t[-1] + self.dt)

    def _index(self, t):
        return np.clip(np.floor((np.asarray(t, float) - self.t[0]) / self.dt + 1e-9).astype(int), 0,
                       self.t.size - 1)

    def gain(self, t) -> np.ndarray:
        """``K(t)``: scalar t -> (1, 4), array (m,) -> (m, 1, 4); held (discrete) or interpolated (continuous),
        clamped outside the horizon."""
        t_arr = np.atleast_1d(np.asarray(t, float))
        if self.method == "discrete":
            K = self.K[self._index(t_arr)]
        else:
            flat = self.K.reshape(self.t.size, -1)
            K = np.column_stack([np.interp(t_arr, self.t, flat[:, j]) for j in range(flat.shape[1])])
            K = K.reshape(-1, 1, 4)
        return K[0] if np.ndim(t) == 0 else K

    def cost_to_go(self, t) -> np.ndarray:
        """``S(t)`` (4, 4) (or (m, 4, 4) for an array of times), linear between grid points, clamped outside."""
        t_arr = np.atleast_1d(np.asarray(t, float))
        grid = np.append(self.t, self.t_final)
        flat = self.S.reshape(grid.size, -1)
        S = np.column_stack([np.interp(t_arr, grid, flat[:, j]) for j in range(16)]).reshape(-1, 4, 4)
        return S[0] if np.ndim(t) == 0 else S


def reference(traj, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plan on the simulator's grid: times ``t`` (n,), states ``x`` (n+1, 4) at ``t0 + k dt``, and the
    zero-order-hold input of each step ``u`` (n, 1) = mean of the first-order-hold input over the step."""
    n = max(1, int(round(traj.duration / dt)))
    tk = traj.t[0] + dt * np.arange(n + 1)
    x = traj.state(tk)
    u = 0.5 * (traj.input(tk[:-1]) + traj.input(tk[1:]))  # exact mean of a linear input over the step
    return tk[:-1], x, u


def _riccati_backward(Ad, Bd, Qd, Rd, Sf):
    """Backward discrete Riccati recursion for one input: returns K (n, 1, 4), S (n+1, 4, 4)."""
    n = Ad.shape[0]
    K = np.empty((n, 1, 4))
    S = np.empty((n + 1, 4, 4))
    S[n] = Sf
    Sk = Sf
    r = float(Rd[0, 0])
    for k in range(n - 1, -1, -1):
        A = Ad[k]
        b = Bd[k]  # (4,)
        Sb = Sk @ b
        Kk = (Sb @ A) / (r + b @ Sb)  # (4,)
        Sk = Qd + A.T @ Sk @ (A - np.outer(b, Kk))
        Sk = 0.5 * (Sk + Sk.T)
        K[k, 0] = Kk
        S[k] = Sk
    return K, S


def tvlqr(model: CartPoleModel, traj, Q, R, *, Qf=None, dt: float | None = None,
          method: str = "discrete", rtol: float = 1e-8) -> TVLQRGains:
    """Finite-horizon TVLQR along ``traj`` (see the module docstring for both methods).

    Parameters
    ----------
    model : CartPoleModel
        Symbolic model to linearise (the plan's model; ``model.ABd`` is one step of its integrator).
    traj : Trajectory
        Reference (cubic-Hermite states, first-order-hold inputs).
    Q : (4, 4) array
        State weight (per s).
    R : (1, 1) array or float
        Input weight (per ctrl^2 per s).
    Qf : (4, 4) array, optional
        Terminal cost; default the LQR catch's cost-to-go at the final state (``dlqr(Ad, Bd, Q dt, R dt).S``
        for ``discrete``, ``lqr(A, B, Q, R).S`` for ``continuous``).
    dt : float, optional
        Grid step in s; default ``model.dt`` (the MJCF's timestep). For ``discrete`` the model is rebuilt at
        this step when it differs.
    method : {'discrete', 'continuous'}
    rtol : float
        Relative tolerance of the ODE solver (``continuous`` only).

    Returns
    -------
    TVLQRGains
    """
    if method not in METHODS:
        raise LQRError(f"TVLQR method '{method}' is not known; choose one of {', '.join(METHODS)}.")
    dt = float(model.dt if dt is None else dt)
    if not dt > 0:
        raise LQRError(f"TVLQR step dt = {dt} s is not positive; give dt > 0.")
    _, _, Q, R = check_weights(np.zeros((4, 4)), np.zeros((4, 1)), Q, np.atleast_2d(R))
    x_end = traj.x[-1]
    u_end = traj.u[-1]
    if method == "discrete":
        dmodel = model if abs(model.dt - dt) < 1e-15 else model.rebuilt(dt=dt)
        t, xr, ur = reference(traj, dt)
        n = t.size
        Ad, Bd = dmodel.ABd.map(n)(xr[:-1].T, ur.T)  # all n linearisations in one call
        Ad = np.asarray(Ad).reshape(4, n, 4).transpose(1, 0, 2)
        Bd = np.asarray(Bd).T  # (n, 4)
        if Qf is None:
            A1, B1 = dmodel.linearize(x_end, u_end, discrete=True)
            Qf = dlqr(A1, B1, Q * dt, R * dt).S
        K, S = _riccati_backward(Ad, Bd, Q * dt, R * dt, np.asarray(Qf, float))
        return TVLQRGains(t=t, K=K, S=S, dt=dt, method="discrete")
    return _tvlqr_ode(model, traj, Q, R, Qf, dt, rtol)


def _tvlqr_ode(model, traj, Q, R, Qf, dt, rtol) -> TVLQRGains:
    from scipy.integrate import solve_ivp

    t0, T = float(traj.t[0]), float(traj.t[-1])
    n = max(1, int(round((T - t0) / dt)))
    grid = t0 + dt * np.arange(n + 1)
    Rinv = np.linalg.inv(R)
    if Qf is None:
        A1, B1 = model.linearize(traj.x[-1], traj.u[-1])
        Qf = lqr(A1, B1, Q, R).S
    Qf = np.asarray(Qf, float)

    def AB(t):
        A, B = model.AB(traj.state(t), traj.input(t))
        return np.asarray(A), np.asarray(B)

    def rhs(t, s):
        S = s.reshape(4, 4)
        A, B = AB(t)
        SB = S @ B
        dS = -(Q + A.T @ S + S @ A - SB @ Rinv @ SB.T)
        return dS.ravel()

    atol = 1e-10 * max(1.0, np.abs(Qf).max())
    sol = solve_ivp(rhs, (grid[-1], t0), Qf.ravel(), t_eval=grid[::-1], rtol=rtol, atol=atol,
                    method="RK45")
    if not sol.success:
        raise LQRError(f"The Riccati ODE did not integrate ({sol.message}); use method='discrete'.")
    S = sol.y.T[::-1].reshape(n + 1, 4, 4)
    S = 0.5 * (S + S.transpose(0, 2, 1))
    K = np.empty((n, 1, 4))
    for k in range(n):
        _, B = AB(grid[k])
        K[k] = Rinv @ B.T @ S[k]
    return TVLQRGains(t=grid[:-1], K=K, S=S, dt=dt, method="continuous")
