"""Finite-horizon time-varying LQR (TVLQR) along a planned trajectory.

Two syntheses of the same regulator, with the law ``u = u0(t) - K(t) (x - x0(t))`` (Drake's convention):

* ``method="discrete"`` (default): the backward Riccati recursion on the EXACT discrete model at the
  simulator's step ``dt`` (one step of the MJCF's integrator, ``model.ABd``), linearised along the plan
  resampled at ``dt`` (cubic-Hermite states, and for each step the mean of the first-order-hold input over
  the step, i.e. the zero-order-hold value the simulator applies). All ``n`` linearisations come from one
  call of a CasADi ``map`` of ``ABd``. Stage weights are ``Q dt`` and ``R dt`` so the sum approximates the
  continuous cost ``integral (x'Qx + u'Ru) dt``; the terminal cost is ``dlqr(Ad, Bd, Q dt, R dt).S`` at
  the final state, the cost-to-go of the discrete LQR catch, so the hand-over is seamless.
  The recursion itself is :func:`riccati_backward`.
* ``method="continuous"``: the Riccati ODE ``-dS/dt = Q + A'S + SA - S B R^-1 B' S`` integrated backward
  with ``scipy.integrate.solve_ivp`` from ``S(T) = lqr(A, B, Q, R).S`` at the final state, ``K = R^-1 B'S``.

For small ``dt`` the two agree (the recursion is a consistent discretisation of the ODE). Any number of states
``nx`` and inputs ``nu``: gains are ``(n, nu, nx)``, cost-to-go matrices ``(n+1, nx, nx)``, time first.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from cartpole._arrays import readonly
from cartpole.models import CartPoleModel
from cartpole.riccati.algebraic import LQRError, check_weights, dlqr, lqr
from cartpole.riccati.weights import default_weights

METHODS = ("discrete", "continuous")


@dataclass(frozen=True)
class TVLQRGains:
    """Time-varying gains and cost-to-go along a trajectory, for ``nx`` states and ``nu`` inputs.

    Attributes
    ----------
    t : (n,) array, s
        Times at which ``K[k]`` starts to apply (step starts, ``t[k] = t0 + k dt``).
    K : (n, nu, nx) array
        Gains in ctrl per state unit, for ``u = u0 - K (x - x0)``.
    S : (n+1, nx, nx) array
        Cost-to-go matrices at ``t[0] .. t[-1] + dt`` (the last one is the terminal cost).
    dt : float
        Step of the grid in s (the simulator's step for the discrete method).
    method : str
        ``discrete`` (K held over each step) or ``continuous`` (K interpolated linearly in time).
    x_ref : (n+1, nx) array or None
        The discrete reference the gains were designed along, when it was given explicitly (``tvlqr(...,
        reference=(x, u))``, e.g. a plan that is an exact solution of the discrete model): the tracking controller
        then follows ``x_ref[k]`` instead of the plan's cubic-Hermite states. None otherwise.
    u_ref : (n, nu) array or None
        The ctrl of each step of that reference (held over the step), or None.
    """

    t: np.ndarray
    K: np.ndarray
    S: np.ndarray
    dt: float
    method: str = "discrete"
    x_ref: np.ndarray | None = None
    u_ref: np.ndarray | None = None

    def __post_init__(self):
        for name in ("t", "K", "S"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        n = self.t.size
        nx = self.K.shape[-1] if self.K.ndim == 3 else -1
        if self.t.ndim != 1 or self.K.ndim != 3 or self.K.shape[0] != n or self.S.shape != (n + 1, nx, nx):
            raise LQRError(f"TVLQR arrays disagree: t {self.t.shape}, K {self.K.shape}, S {self.S.shape}; "
                           "need t (n,), K (n, nu, nx), S (n+1, nx, nx).")
        if (self.x_ref is None) != (self.u_ref is None):
            raise LQRError("TVLQR reference needs both x_ref (n+1, nx) and u_ref (n, nu), or neither.")
        if self.x_ref is not None:
            x_ref = readonly(np.asarray(self.x_ref, float))
            u_ref = readonly(np.asarray(self.u_ref, float).reshape(n, -1))
            if x_ref.shape != (n + 1, nx) or u_ref.shape != (n, self.K.shape[1]):
                raise LQRError(f"TVLQR reference arrays disagree with the gains: x_ref {x_ref.shape}, u_ref "
                               f"{u_ref.shape}, K {self.K.shape}; need x_ref (n+1, nx), u_ref (n, nu).")
            object.__setattr__(self, "x_ref", x_ref)
            object.__setattr__(self, "u_ref", u_ref)

    @property
    def has_reference(self) -> bool:
        """True when the gains carry their own discrete reference (``x_ref``, ``u_ref``)."""
        return self.x_ref is not None

    def index(self, t) -> np.ndarray:
        """Step index ``k`` (int array, or int for a scalar) whose gain applies at time ``t`` s, clamped."""
        k = self._index(np.atleast_1d(np.asarray(t, float)))
        return int(k[0]) if np.ndim(t) == 0 else k

    @property
    def nx(self) -> int:
        """Number of states."""
        return int(self.K.shape[2])

    @property
    def nu(self) -> int:
        """Number of inputs."""
        return int(self.K.shape[1])

    @property
    def t_final(self) -> float:
        """End of the horizon in s (where the terminal cost applies)."""
        return float(self.t[-1] + self.dt)

    def _index(self, t):
        return np.clip(np.floor((np.asarray(t, float) - self.t[0]) / self.dt + 1e-9).astype(int), 0,
                       self.t.size - 1)

    def gain(self, t) -> np.ndarray:
        """``K(t)``: scalar t -> (nu, nx), array (m,) -> (m, nu, nx); held (discrete) or interpolated
        (continuous), clamped outside the horizon."""
        t_arr = np.atleast_1d(np.asarray(t, float))
        if self.method == "discrete":
            K = self.K[self._index(t_arr)]
        else:
            flat = self.K.reshape(self.t.size, -1)
            K = np.column_stack([np.interp(t_arr, self.t, flat[:, j]) for j in range(flat.shape[1])])
            K = K.reshape(-1, self.nu, self.nx)
        return K[0] if np.ndim(t) == 0 else K

    def cost_to_go(self, t) -> np.ndarray:
        """``S(t)`` (nx, nx) (or (m, nx, nx) for an array of times), linear between grid points, clamped outside."""
        t_arr = np.atleast_1d(np.asarray(t, float))
        grid = np.append(self.t, self.t_final)
        flat = self.S.reshape(grid.size, -1)
        S = np.column_stack([np.interp(t_arr, grid, flat[:, j]) for j in range(flat.shape[1])])
        S = S.reshape(-1, self.nx, self.nx)
        return S[0] if np.ndim(t) == 0 else S


def _reference(traj, dt):
    return reference(traj, dt)


def reference(traj, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plan on the simulator's grid: times ``t`` (n,), states ``x`` (n+1, nx) at ``t0 + k dt``, and the
    zero-order-hold input of each step ``u`` (n, nu) = mean of the first-order-hold input over the step."""
    n = max(1, int(round(traj.duration / dt)))
    tk = traj.t[0] + dt * np.arange(n + 1)
    x = traj.state(tk)
    u = 0.5 * (traj.input(tk[:-1]) + traj.input(tk[1:]))  # exact mean of a linear input over the step
    return tk[:-1], x, u


def riccati_backward(Ad, Bd, Qd, Rd, Sf) -> tuple[np.ndarray, np.ndarray]:
    """Backward discrete Riccati recursion of the finite-horizon LQR ``sum x'Qd x + u'Rd u + x_n' Sf x_n``.

    ``K[k] = (Rd + B'S[k+1]B)^-1 B'S[k+1]A``, ``S[k] = Qd + A'S[k+1](A - B K[k])`` (symmetrised) from
    ``S[n] = Sf``, for ``x[k+1] = Ad[k] x[k] + Bd[k] u[k]`` and the law ``u[k] = -K[k] x[k]``.

    Parameters
    ----------
    Ad : (n, nx, nx) array
    Bd : (n, nx, nu) array
    Qd : (nx, nx) array
        Stage state weight.
    Rd : (nu, nu) array
        Stage input weight.
    Sf : (nx, nx) array
        Terminal cost.

    Returns
    -------
    K : (n, nu, nx) array
    S : (n+1, nx, nx) array
    """
    Ad = np.asarray(Ad, dtype=float)
    Bd = np.asarray(Bd, dtype=float)
    n, nx, nu = Bd.shape
    if Ad.shape != (n, nx, nx):
        raise LQRError(f"riccati_backward needs Ad (n, nx, nx) and Bd (n, nx, nu); got {Ad.shape} and {Bd.shape}.")
    Qd, Rd, Sf = (np.asarray(M, dtype=float) for M in (Qd, Rd, Sf))
    K = np.empty((n, nu, nx))
    S = np.empty((n + 1, nx, nx))
    S[n] = Sf
    Sk = Sf
    for k in range(n - 1, -1, -1):
        A, B = Ad[k], Bd[k]
        if nu == 1:  # one input: a division instead of a solve (the arithmetic every one-input result uses)
            b = B[:, 0]
            Sb = Sk @ b
            kk = (Sb @ A) / (float(Rd[0, 0]) + b @ Sb)
            Kk, BK = kk[None, :], np.outer(b, kk)
        else:
            SB = Sk @ B
            Kk = np.linalg.solve(Rd + B.T @ SB, SB.T @ A)
            BK = B @ Kk
        Sk = Qd + A.T @ Sk @ (A - BK)
        Sk = 0.5 * (Sk + Sk.T)
        K[k] = Kk
        S[k] = Sk
    return K, S


def tvlqr(model: CartPoleModel, traj, Q=None, R=None, *, Qf=None, dt: float | None = None,
          method: str = "discrete", rtol: float = 1e-8, reference=None) -> TVLQRGains:
    """Finite-horizon TVLQR along ``traj`` (see the module docstring for both methods).

    Parameters
    ----------
    model : CartPoleModel
        Symbolic model to linearise (the plan's model; ``model.ABd`` is one step of its integrator).
    traj : Trajectory
        Reference (cubic-Hermite states, first-order-hold inputs): anything with ``t`` (knot times), ``x``
        (knots, nx), ``u`` (knots, nu), ``duration``, ``state(t)`` and ``input(t)``.
    Q : (nx, nx) array, optional
        State weight (per s); default :func:`~cartpole.riccati.weights.default_weights` of the model.
    R : (nu, nu) array or float, optional
        Input weight (per ctrl^2 per s); default 0.1 per input (:func:`~cartpole.riccati.weights.default_weights`).
    Qf : (nx, nx) array, optional
        Terminal cost; default the LQR catch's cost-to-go at the final state (``dlqr(Ad, Bd, Q dt, R dt).S``
        for ``discrete``, ``lqr(A, B, Q, R).S`` for ``continuous``).
    dt : float, optional
        Grid step in s; default ``model.dt`` (the MJCF's timestep). For ``discrete``: a control period of a whole
        number of physics steps uses the exact discrete model over that hold (:func:`held_steps`), any other step
        the model rebuilt at it.
    method : {'discrete', 'continuous'}
    rtol : float
        Relative tolerance of the ODE solver (``continuous`` only).
    reference : (x, u), optional
        ``discrete`` only: the reference on the step grid ``traj.t[0] + k dt`` itself, states ``x`` (n+1, nx) and
        the ctrl held over each step ``u`` (n, nu) (e.g. :func:`cartpole.planning.trajopt.exact_discrete_plan`, an
        exact solution of ``model.step``), instead of :func:`reference` of ``traj``. It is linearised along and
        kept in the gains (``x_ref``, ``u_ref``), so the controller tracks it; the terminal cost is taken at
        ``x[-1]``, ``u[-1]``.

    Returns
    -------
    TVLQRGains
        ``K`` (n, nu, nx), ``S`` (n+1, nx, nx).
    """
    if method not in METHODS:
        raise LQRError(f"TVLQR method '{method}' is not known; choose one of {', '.join(METHODS)}.")
    dt = float(model.dt if dt is None else dt)
    if not dt > 0:
        raise LQRError(f"TVLQR step dt = {dt} s is not positive; give dt > 0.")
    nx, nu = model.nx, model.nu
    Q0, R0 = default_weights(model)
    Q = Q0 if Q is None else Q
    R = R0 if R is None else R
    _, _, Q, R = check_weights(np.zeros((nx, nx)), np.zeros((nx, nu)), Q, R)
    x_end = np.asarray(traj.x[-1], dtype=float)
    u_end = np.asarray(traj.u[-1], dtype=float)
    if Qf is not None:
        Qf = np.asarray(Qf, dtype=float)
        if Qf.shape != (nx, nx):
            raise LQRError(f"Qf has shape {Qf.shape} but must be ({nx}, {nx}) for this model's {nx} states.")
    if method == "discrete":
        held = held_steps(dt, model.dt)
        if held:  # a control period of whole physics steps: the exact discrete model over the hold
            dmodel = model.hold(held)
        else:
            dmodel = model if abs(model.dt - dt) < 1e-15 else model.rebuilt(dt=dt)
        if reference is None:
            t, xr, ur = _reference(traj, dt)
        else:
            xr = np.asarray(reference[0], dtype=float)
            ur = np.asarray(reference[1], dtype=float).reshape(-1, nu)
            if xr.ndim != 2 or xr.shape != (ur.shape[0] + 1, nx):
                raise LQRError(f"TVLQR reference has x {xr.shape} and u {ur.shape}; need x (n+1, {nx}) and "
                               f"u (n, {nu}).")
            t = float(traj.t[0]) + dt * np.arange(ur.shape[0])
            x_end, u_end = xr[-1], ur[-1]
        n = t.size
        Ad, Bd = dmodel.ABd.map(n)(xr[:-1].T, np.asarray(ur, float).reshape(n, nu).T)  # n linearisations, one call
        Ad = np.asarray(Ad).reshape(nx, n, nx).transpose(1, 0, 2)
        Bd = np.asarray(Bd).reshape(nx, n, nu).transpose(1, 0, 2)
        if Qf is None:
            A1, B1 = dmodel.linearize(x_end, u_end) if held else dmodel.linearize(x_end, u_end, discrete=True)
            Qf = dlqr(A1, B1, Q * dt, R * dt).S
        K, S = riccati_backward(Ad, Bd, Q * dt, R * dt, Qf)
        if reference is None:
            return TVLQRGains(t=t, K=K, S=S, dt=dt, method="discrete")
        return TVLQRGains(t=t, K=K, S=S, dt=dt, method="discrete", x_ref=xr, u_ref=ur)
    if reference is not None:
        raise LQRError("An explicit TVLQR reference is a discrete one; use method='discrete' with it.")
    return _tvlqr_ode(model, traj, Q, R, Qf, dt, rtol)


def held_steps(dt: float, step: float) -> int:
    """``m`` when ``dt`` (s) is a whole number ``m > 1`` of physics steps ``step`` (s), else 0: then the discrete
    TVLQR runs on the exact model over the hold (:meth:`~cartpole.models.CartPoleModel.hold`), not on one
    integrator step of size ``dt``."""
    m = round(dt / step)
    return int(m) if m > 1 and abs(m * step - dt) <= 1e-9 * dt else 0


def _tvlqr_ode(model, traj, Q, R, Qf, dt, rtol) -> TVLQRGains:
    nx, nu = model.nx, model.nu
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
        return np.asarray(A), np.asarray(B).reshape(nx, nu)

    def rhs(t, s):
        S = s.reshape(nx, nx)
        A, B = AB(t)
        SB = S @ B
        dS = -(Q + A.T @ S + S @ A - SB @ Rinv @ SB.T)
        return dS.ravel()

    atol = 1e-10 * max(1.0, np.abs(Qf).max())
    sol = solve_ivp(rhs, (grid[-1], t0), Qf.ravel(), t_eval=grid[::-1], rtol=rtol, atol=atol,
                    method="RK45")
    if not sol.success:
        raise LQRError(f"The Riccati ODE did not integrate ({sol.message}); use method='discrete'.")
    S = sol.y.T[::-1].reshape(n + 1, nx, nx)
    S = 0.5 * (S + S.transpose(0, 2, 1))
    K = np.empty((n, nu, nx))
    for k in range(n):
        _, B = AB(grid[k])
        K[k] = Rinv @ B.T @ S[k]
    return TVLQRGains(t=grid[:-1], K=K, S=S, dt=dt, method="continuous")
