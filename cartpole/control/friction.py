"""Friction compensation: a wrapper that adds the ctrl cancelling the model's smooth joint friction.

A joint with ``frictionloss`` loses up to that much force (N) or torque (N m) to dry friction, opposing its motion.
:class:`FrictionCompensation` adds, on each actuator that drives such a joint, the ctrl whose force cancels the smooth
model of it (:func:`cartpole.models.friction.smooth_friction`):

    ``u = clip(controller(t, x) + u_f, ctrl_range)``,  ``u_f = frictionloss_j tanh(v_j / width) / gear``

so the compensated plant is nearly frictionless and a controller designed on the frictionless model fits it. The
width sets how fast the compensation switches sign through rest: narrow gives a near-Coulomb feedforward that
chatters on a noisy velocity; wide leaves friction uncompensated at low speed. By default it is the model's
``friction_width``.

Only joints an actuator drives are compensated (an unactuated hinge's friction cannot be cancelled by the cart's
motor); a joint driven by several actuators gets its compensation from the first.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole._arrays import readonly
from cartpole.models import check_width


class FrictionCompensation:
    """``u = clip(controller(t, x) + u_f(x), ctrl_range)``: a controller plus the ctrl cancelling smooth friction.

    The call shape ``u = c(t, x)`` is kept. Every attribute the wrapped controller has (``K``, ``x_eq``, ``u_eq``,
    ``S``, ``cost_to_go``, ``hinges``, ``reset``, ``period`` ...) is read through from it, so callers that inspect a
    controller keep working; the ctrl limits callers read (``u_low``, ``u_high``, ``u_limits``) stay the wrapped
    controller's, while the sum is clipped to the model's ``ctrl_range``. A function that takes a
    :class:`~cartpole.control.linear.LinearFeedback` apart into its gain (e.g. the batch rollouts) does not see the
    compensation: give it the wrapper's call instead.

    Parameters
    ----------
    controller : callable
        ``controller(t [s], x (nx,)) -> ctrl (nu,)`` (or a scalar for one actuator).
    model : CartPoleModel
        Whose ``params`` give each joint's ``frictionloss`` (N or N m), each actuator's ``gear`` (force per unit
        ctrl), joint and ``ctrl_range``, and whose ``friction_width`` is the default width.
    width : float, optional
        Velocity scale of ``tanh(v / width)``, m/s on slides, rad/s on hinges; default ``model.friction_width``.

    Attributes
    ----------
    controller : callable
        The wrapped controller.
    width : float
        m/s or rad/s.
    frictionloss : (nu,) array
        Friction each actuator compensates (N or N m of its joint; zero when its joint has none or another
        actuator compensates it).
    joints : tuple of int
        qpos index of each actuator's joint, (nu,).
    gears : (nu,) array
        Generalized force per unit ctrl of each actuator.
    ctrl_range : (nu, 2) array
        ``[low, high]`` the sum is clipped to.
    """

    def __init__(self, controller, model, *, width: float | None = None):
        p = model.params
        self.controller = controller
        self.width = check_width(model.friction_width if width is None else width)
        self._nq = p.nq
        self.joints = tuple(p.actuated)
        self.gears = readonly(p.gears)
        self.ctrl_range = readonly(p.ctrl_range)
        loss = np.zeros(p.nu)
        taken = set()
        for i, j in enumerate(self.joints):
            if j not in taken and self.gears[i] != 0:
                loss[i] = p.frictionloss[j]
                taken.add(j)
        self.frictionloss = readonly(loss)
        self._idx = np.array(self.joints, dtype=int)

    def feedforward(self, x) -> np.ndarray:
        """The compensating ctrl ``u_f`` (nu,) at state ``x`` (nx,): ``frictionloss tanh(v_j / width) / gear``,
        unclipped (ctrl units)."""
        v = np.asarray(x, dtype=float)[self._nq:][self._idx]
        return self.frictionloss * np.tanh(v / self.width) / np.where(self.gears != 0, self.gears, 1.0)

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s) for state ``x`` (nx,): the wrapped controller's plus the compensation,
        clipped to the ctrl range."""
        u = np.atleast_1d(np.asarray(self.controller(t, x), dtype=float)).ravel() + self.feedforward(x)
        return np.clip(u, self.ctrl_range[:, 0], self.ctrl_range[:, 1])

    def __getattr__(self, name: str):
        # Only reached for names this wrapper does not define: read them through from the wrapped controller.
        controller = self.__dict__.get("controller")
        if controller is None or name.startswith("__"):
            raise AttributeError(name)
        return getattr(controller, name)


@dataclass(frozen=True)
class FrictionDesign:
    """How a closed loop treats a model's dry friction (:func:`friction_design`).

    Attributes
    ----------
    model : CartPoleModel
        The model to design controllers on.
    plant : CartPoleModel
        The model whose driven joints' friction is cancelled (the one :func:`friction_design` was given).
    compensated : bool
        Whether the controllers run wrapped in :class:`FrictionCompensation`.
    """

    model: object
    plant: object
    compensated: bool

    def wrap(self, controller):
        """The controller that runs: ``FrictionCompensation(controller, plant)`` when compensated, else
        ``controller`` itself."""
        return FrictionCompensation(controller, self.plant) if self.compensated else controller


def friction_design(model, loop=None) -> FrictionDesign:
    """The model to design controllers on, and the compensation to wrap them in, for a closed loop on ``model``.

    On a model whose driven joints have ``frictionloss``, with ``loop.friction_compensation`` (the default), every
    controller is designed on ``model.without_friction(driven joints)`` (the friction the compensation cancels is
    gone; an undriven joint's stays, as the smooth model) and runs wrapped in :class:`FrictionCompensation` on
    ``model``. Otherwise the controllers are designed on ``model`` itself (with its smooth friction, if any) and run
    unwrapped.

    Parameters
    ----------
    model : CartPoleModel
        The plant's model (the MJCF MuJoCo runs, or a planning model built from it).
    loop : LoopOptions, optional
        Its ``friction_compensation`` flag is read (default True).

    Returns
    -------
    FrictionDesign
    """
    wanted = True if loop is None else bool(getattr(loop, "friction_compensation", True))
    if not (wanted and model.params.driven_friction):
        return FrictionDesign(model=model, plant=model, compensated=False)
    return FrictionDesign(model=model.without_friction(model.params.driven_joints), plant=model, compensated=True)


def friction_summary(params, compensated: bool) -> dict | None:
    """JSON ``friction`` of a run: ``frictionloss`` per joint name (N or N m, the joints that have some) and
    ``compensation`` (whether the controllers cancelled the driven joints'); None on a model without friction.

    Parameters
    ----------
    params : CartPoleParams
    compensated : bool
    """
    loss = {j.name: float(j.frictionloss) for j in params.joints if j.frictionloss != 0}
    if not loss:
        return None
    return {"frictionloss": loss, "compensation": bool(compensated)}
