"""Track a planned trajectory with TVLQR, then hand over to the LQR catch at the end of the plan."""
from __future__ import annotations

import numpy as np

from cartpole.control.linear import LinearFeedback, ctrl_limits
from cartpole.models import state_error


class TVLQRController:
    """``u = u_ff(t) - K(t) (x - x_ff(t))`` for ``t < T``, then the LQR ``catch``; call shape ``u = c(t, x)``.

    Any number of states ``nx`` and inputs ``nu``. The hinge-angle errors are wrapped to (-pi, pi], so a plan that
    ends at ``theta = 2 pi`` and a MuJoCo hinge that never wraps agree. With discrete gains (held over each
    simulator step) the feed-forward is the zero-order-hold equivalent of the plan's first-order-hold input,
    ``u_ff(t) = input(t + dt / 2)`` (the mean over the step the gain was designed for); with continuous gains it is
    ``input(t)``. When the gains carry their own discrete reference (``gains.has_reference``: an exact solution of
    the discrete model, e.g. :func:`cartpole.planning.trajopt.exact_discrete_plan`), the law follows it instead,
    ``u = u_ref[k] - K[k] (x - x_ref[k])`` for the step ``k`` that contains ``t``, and the catch takes over at the
    end of that reference, ``gains.t_final``.

    Parameters
    ----------
    traj : Trajectory
        The plan (cubic-Hermite states, first-order-hold inputs); time 0 of the controller is ``traj.t[0]``.
    gains : TVLQRGains
        From :func:`cartpole.riccati.tvlqr.tvlqr` along ``traj``: ``K`` (n, nu, nx).
    catch : LinearFeedback
        Balancing controller that takes over at ``t >= traj.t[-1]``.
    u_limits : (2,) or (nu, 2) array, optional
        ``[low, high]`` ctrl clip per actuator (default: the catch's limits).
    hinges : sequence of int, optional
        qpos indices of the hinges whose tracking errors are wrapped (default: the catch's).

    Attributes
    ----------
    handover_time : float or None
        Time (s) of the first call that used the catch in the current run (reset when time goes back).
    u_limits : (nu, 2) array
    hinges : tuple of int
    """

    def __init__(self, traj, gains, catch: LinearFeedback, *, u_limits=None, hinges=None):
        self.traj = traj
        self.gains = gains
        self.catch = catch
        nu = gains.K.shape[1]
        self.u_limits = np.array(catch.u_limits if u_limits is None else ctrl_limits(u_limits, nu), dtype=float)
        self.hinges = tuple(catch.hinges if hinges is None else hinges)
        self._ff_shift = 0.5 * gains.dt if gains.method == "discrete" else 0.0
        self._exact = bool(getattr(gains, "has_reference", False))
        self._t_end = float(gains.t_final) if self._exact else float(traj.t[-1])
        self.handover_time: float | None = None
        self._last_t = -np.inf

    @property
    def T(self) -> float:
        """End of the plan in s (of the gains' own reference when they carry one); the catch holds from then on."""
        return self._t_end

    def reset(self) -> None:
        """Forget the hand-over (done automatically when called with an earlier time than the last call)."""
        self.handover_time = None
        self._last_t = -np.inf

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s) for state ``x`` (nx,), clipped to ``u_limits``."""
        t = float(t)
        if t < self._last_t:  # a new run started
            self.reset()
        self._last_t = t
        lo, hi = self.u_limits[:, 0], self.u_limits[:, 1]
        if t >= self.T - 1e-12:
            if self.handover_time is None:
                self.handover_time = t
            return np.clip(self.catch(t, x), lo, hi)
        if self._exact:
            k = self.gains.index(t)
            e = state_error(x, self.gains.x_ref[k], self.hinges)
            u = self.gains.u_ref[k] - self.gains.K[k] @ e
            return np.clip(u, lo, hi)
        e = state_error(x, self.traj.state(t), self.hinges)
        u_ff = np.asarray(self.traj.input(min(t + self._ff_shift, self.T)), dtype=float).ravel()
        u = u_ff - self.gains.gain(t) @ e
        return np.clip(u, lo, hi)
