"""Linear state feedback about an equilibrium: ``u = u* - K (x - x*)``, hinge-angle errors wrapped, per-actuator clip.

For any model with ``nq`` joints (``nx = 2 nq`` states) and ``nu`` actuators. :meth:`LinearFeedback.for_model`
is the one constructor of the upright LQR: LQR on the exact linearisation at the model's computed upright
equilibrium ``(x_eq, u_eq)``, the default weight pattern (:func:`~cartpole.riccati.weights.default_weights`), the
model's hinges wrapped and its ctrl ranges as limits.
"""
from __future__ import annotations

import numpy as np

from cartpole._arrays import readonly
from cartpole.errors import CartPoleError
from cartpole.models import plant_model, state_error, steps_per_period
from cartpole.riccati import dlqr, lqr


class FeedbackError(CartPoleError, ValueError):
    """Shapes of a linear feedback law that do not agree (K, x_eq, u_eq, limits, S, hinges)."""


def ctrl_limits(u_limits, nu: int) -> np.ndarray:
    """``[low, high]`` ctrl clip per actuator, (nu, 2) (ctrl units), from None (no clip), one ``[low, high]`` for
    all, or (nu, 2); a malformed one raises :class:`FeedbackError`."""
    if u_limits is None:
        return np.tile([-np.inf, np.inf], (nu, 1))
    lim = np.asarray(u_limits, dtype=float)
    if lim.shape == (2,):
        lim = np.tile(lim, (nu, 1))
    if lim.shape != (nu, 2) or np.any(np.isnan(lim)) or np.any(lim[:, 0] > lim[:, 1]):
        raise FeedbackError(f"u_limits {lim.tolist()} must be [low, high] (low <= high) for all {nu} inputs or "
                            f"one such row per input, shape ({nu}, 2).")
    return lim


class LinearFeedback:
    """The controller ``u = u* - K e`` clipped per actuator to ``[low, high]``, with the call shape ``u = c(t, x)``.

    ``e = state_error(x, x*, hinges)``: ``x - x*`` with the hinge-angle entries wrapped to (-pi, pi] (MuJoCo hinge
    angles never wrap; the error fed to K, and the cost ``e' S e``, must).

    Parameters
    ----------
    K : (nu, nx) array, or (nx,) for one input
        Gain in ctrl per state unit (ctrl/m or ctrl/rad on positions, ctrl/(m/s) or ctrl/(rad/s) on rates).
    x_eq : (nx,) array, optional
        Equilibrium state ``x*`` (default the origin).
    u_eq : (nu,) array or float, optional
        Equilibrium ctrl ``u*`` (default 0; a scalar is used for every input).
    u_limits : (2,) or (nu, 2) array, optional
        ``[low, high]`` ctrl clip, one row per actuator (a single row applies to all); default none (MuJoCo clips to
        ctrlrange anyway).
    S : (nx, nx) array, optional
        LQR cost-to-go, kept so :meth:`cost_to_go` can test the catch basin ``e' S e < rho``.
    E : (nx,) complex array, optional
        Closed-loop eigenvalues of the design (1/s, or per sample for a discrete one), kept for reports.
    hinges : sequence of int, optional
        qpos indices of the hinge joints whose errors are wrapped; default every joint but the first (a cart at
        qpos 0 carrying a chain of poles, e.g. ``(1,)`` for one pole). :meth:`for_model` passes the model's own.

    Attributes
    ----------
    K : (nu, nx) array
    x_eq : (nx,) array
    u_eq : (nu,) array
    u_limits : (nu, 2) array
        ``[low, high]`` per actuator.
    u_low, u_high : (nu,) arrays
    S : (nx, nx) array or None
    E : (nx,) complex array or None
    hinges : tuple of int
    nx, nu : int
    """

    def __init__(self, K, x_eq=None, u_eq=None, *, u_limits=None, S=None, E=None, hinges=None):
        K = np.asarray(K, dtype=float)
        K = K.reshape(1, -1) if K.ndim == 1 else K
        if K.ndim != 2 or K.shape[1] % 2:
            raise FeedbackError(f"K has shape {K.shape}; it must be (nu, nx) with nx = 2 nq even.")
        nu, nx = K.shape
        self.K = readonly(K)
        self.x_eq = readonly(np.zeros(nx) if x_eq is None else x_eq)
        if self.x_eq.shape != (nx,):
            raise FeedbackError(f"x_eq has shape {self.x_eq.shape} but K {K.shape} needs ({nx},).")
        u_eq = np.zeros(nu) if u_eq is None else np.asarray(u_eq, dtype=float)
        self.u_eq = readonly(np.full(nu, float(u_eq)) if u_eq.ndim == 0 else u_eq.ravel())
        if self.u_eq.shape != (nu,):
            raise FeedbackError(f"u_eq has {self.u_eq.size} entries but K {K.shape} has {nu} input(s).")
        self.u_limits = readonly(ctrl_limits(u_limits, nu))
        self.S = None if S is None else readonly(S)
        if self.S is not None and self.S.shape != (nx, nx):
            raise FeedbackError(f"S has shape {self.S.shape} but K {K.shape} needs ({nx}, {nx}).")
        self.E = None if E is None else readonly(np.ravel(E), dtype=complex)
        self.hinges = tuple(range(1, nx // 2)) if hinges is None else tuple(int(h) for h in hinges)
        if any(not 0 <= h < nx // 2 for h in self.hinges):
            raise FeedbackError(f"hinges {list(self.hinges)} must be qpos indices in 0..{nx // 2 - 1}.")

    @classmethod
    def for_model(cls, plant, Q=None, R=None, *, discrete: bool = False, period: float | None = None,
                  x_eq=None, u_limits="ctrlrange") -> "LinearFeedback":
        """The upright LQR of ``plant``: the package's one constructor of it (the lab, the swing-up's catch, the
        exports and the sweeps all call it).

        Designs :func:`~cartpole.riccati.lqr` (continuous) or :func:`~cartpole.riccati.dlqr` (the exact discrete
        model, weights per second: the package's one cost scaling, so ``S`` and every basin level ``e' S e`` mean
        the same whichever design built the gain) on the plant's exact linearisation without dry friction.

        Parameters
        ----------
        plant : path, CartPoleParams or CartPoleModel
            Any number of joints and actuators (:func:`~cartpole.models.plant_model`).
        Q : (nx, nx) array, optional
            State weight; default :func:`~cartpole.riccati.weights.default_weights` (1 per slide, 10 per hinge, 0.1 per
            rate).
        R : (nu, nu) array or float, optional
            Input weight on MuJoCo ctrl; default 0.1 per input (the swing-up's catch passes
            :data:`~cartpole.control.switching.SWINGUP_CATCH_R`).
        discrete : bool
            False: ``lqr(plant, Q, R)`` on the continuous Jacobians (its loop sampled at the physics step checked).
            True: ``dlqr(plant, Q, R)``: ``dlqr(Ad, Bd, Q dt, R dt)`` on one step of the MJCF's integrator.
        period : float, optional
            Control period in s, a whole number ``m`` of physics steps (the ctrl held in between). For ``m > 1`` the
            gain is ``dlqr(plant, Q, R, period=period)`` (``Q T, R T`` on the exact discrete model over the hold),
            whatever ``discrete`` says; ``m = 1`` is the default.
        x_eq : (nx,) array, optional
            The equilibrium to hold and linearise at (m, rad, m/s, rad/s); default the plant's computed upright
            ``x_eq`` (the lab moves the cart to the middle of its rail).
        u_limits : "ctrlrange", None or array
            Clip of the law; default the model's ctrl ranges, None for no clip.

        Returns
        -------
        LinearFeedback
            With ``S`` and ``E`` (the closed-loop eigenvalues of the design) attached and ``hinges = model.hinges``.

        Raises
        ------
        LQRError
            Bad weights, an unstabilisable linearisation, a Riccati solution that does not check out, or (continuous
            design) a gain whose loop sampled at the physics step ``model.dt`` is unstable.
        """
        model = plant_model(plant)
        x_eq = model.x_eq if x_eq is None else np.asarray(x_eq, dtype=float)
        if discrete or steps_per_period(period, model.dt) > 1:
            res = dlqr(model, Q=Q, R=R, period=period, x=x_eq)
        else:
            res = lqr(model, Q=Q, R=R, x=x_eq)
        lim = model.params.ctrl_range if isinstance(u_limits, str) and u_limits == "ctrlrange" else u_limits
        return cls(res.K, x_eq, model.u_eq, u_limits=lim, S=res.S, E=res.E, hinges=model.hinges)

    @property
    def nx(self) -> int:
        """Number of states."""
        return int(self.K.shape[1])

    @property
    def nu(self) -> int:
        """Number of inputs."""
        return int(self.K.shape[0])

    @property
    def u_low(self) -> np.ndarray:
        """(nu,) lower ctrl clip."""
        return self.u_limits[:, 0]

    @property
    def u_high(self) -> np.ndarray:
        """(nu,) upper ctrl clip."""
        return self.u_limits[:, 1]

    def error(self, x) -> np.ndarray:
        """The wrapped error ``e`` (..., nx) of state(s) ``x`` from ``x_eq``."""
        return state_error(x, self.x_eq, self.hinges)

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time t (s) for state x (nx,)."""
        u = self.u_eq - self.K @ self.error(x)
        return np.clip(u, self.u_limits[:, 0], self.u_limits[:, 1])

    def cost_to_go(self, x):
        """``e' S e`` with ``e`` the wrapped error from the equilibrium (needs ``S``): float for x (nx,), (m,) array
        for x (m, nx)."""
        if self.S is None:
            raise FeedbackError("This LinearFeedback was built without S; pass S= to use cost_to_go.")
        e = self.error(x)
        with np.errstate(over="ignore", invalid="ignore"):  # a blown-up state costs inf; MuJoCo flags the run
            if e.ndim == 1:
                return float(e @ self.S @ e)
            return np.einsum("...i,ij,...j->...", e, self.S, e)
