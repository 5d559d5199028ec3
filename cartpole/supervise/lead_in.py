"""The law a cart-pole's supervisor acts with while its first plan is made, from a start near its library's own:
the stored plan's inputs, so that the plan is asked for from a knot of that plan.

A supervisor with ``cart_plans`` (:func:`cartpole.supervise.supervisor_for`) plans from the state predicted when the
plan will be ready, under the law that acts meanwhile. With the energy law meanwhile the state it plans from is
wherever the law has pumped to, and the swing-up ends later than the stored plan from the same start would
(docs/dmc.md). :class:`PlanLeadIn` instead follows the stored plan (TVLQR along it, its gains computed when the
supervisor is made, from the stored plan alone) from a run's start near that plan's start (dm_control's cart-pole
episodes start within about 0.01 of hanging at rest, the library's start): the state predicted over the latency is
then near a knot of the stored plan, the warm start from that knot
(:meth:`~cartpole.planning.library.PlanLibrary.knot_guesses`) is nearly the answer, and the plan made from the state
the supervisor sees continues the stored swing-up without losing the planning time. Elsewhere (a later time, a state
off the stored plan) it is the fallback law (the energy law).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from cartpole.control import LinearFeedback
from cartpole.control.tvlqr import TVLQRController
from cartpole.models import CartPoleModel, wrap_angle
from cartpole.ocp.trajectory import Trajectory
from cartpole.riccati import default_weights, tvlqr

#: rad: a hinge further than this from the stored plan's state at the same time hands the lead-in to the fallback law.
LEAD_TUBE = 0.1
#: rad/s (and m/s for the cart): a rate further than this from the stored plan's hands it to the fallback law too.
LEAD_RATE_TUBE = 1.0


class PlanLeadIn:
    """``u = tvlqr(t, x)`` (TVLQR along the stored plan at the run's time ``t``, clipped) while ``t`` is within the
    plan and the state within ``tube`` rad (hinges, whole turns aside) and ``rate_tube`` of the plan's state at ``t``;
    else ``fallback(t, x)``. Call shape ``u = lead(t, x)``.

    Parameters
    ----------
    model : CartPoleModel
        Its hinges (wrapped when comparing) and sizes.
    trajectory : Trajectory
        The stored plan (time from 0 s, the run's start; e.g. the library's plan from hanging at rest).
    fallback : callable
        ``(t, x) -> ctrl`` (nu,), the law elsewhere (the energy law).
    catch : LinearFeedback
        The upright LQR (its ``S`` the TVLQR's terminal cost, its ctrl limits the clip).
    dt : float
        s, the TVLQR's step (the control period).
    tube : float
        rad, default :data:`LEAD_TUBE`.
    rate_tube : float
        rad/s (m/s), default :data:`LEAD_RATE_TUBE`.
    """

    def __init__(self, model: CartPoleModel, trajectory: Trajectory, fallback: Callable, catch: LinearFeedback,
                 dt: float, *, tube: float = LEAD_TUBE, rate_tube: float = LEAD_RATE_TUBE):
        self.model, self.trajectory, self.fallback = model, trajectory, fallback
        Q, R = default_weights(model)
        step = model if abs(float(model.dt) - float(dt)) < 1e-15 else model.rebuilt(dt=float(dt))
        grid = np.allclose(np.diff(trajectory.t), float(dt), rtol=0.0, atol=1e-9)
        # a plan on the step grid (an exact discrete plan) holds its knots' inputs over each step, not their mean
        gains = tvlqr(step, trajectory, Q, R, dt=float(dt),
                      reference=(trajectory.x, trajectory.u[:-1]) if grid else None)
        self.tracker = TVLQRController(trajectory, gains, catch, u_limits=catch.u_limits)
        self.span = float(trajectory.duration)
        self.tube, self.rate_tube = float(tube), float(rate_tube)
        self.hinges = [int(h) for h in model.hinges]

    def leads(self, t: float, x) -> bool:
        """Whether the stored plan's input acts at ``t`` (s) for ``x`` (nx,): within its span and tubes."""
        tau = float(t) - float(self.trajectory.t[0])
        if not 0.0 <= tau < self.span:
            return False
        x = np.asarray(x, dtype=float)
        d = x - np.asarray(self.trajectory.state(float(t)), dtype=float)
        d[self.hinges] = wrap_angle(d[self.hinges])
        nq = self.model.nq
        return bool(np.max(np.abs(d[self.hinges])) <= self.tube and np.max(np.abs(d[nq:])) <= self.rate_tube)

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at ``t`` (s) for the state ``x`` (nx,)."""
        if self.leads(t, x):
            return np.asarray(self.tracker(float(t) - float(self.trajectory.t[0]), x), dtype=float)
        return np.asarray(self.fallback(t, x), dtype=float)
