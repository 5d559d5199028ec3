"""Energy pumping for a pendulum driven at its hinge: the supervisor's swing-up law where there is no cart.

A single pole on a driven hinge (dm_control's pendulum, a tutorial's pendulum built hanging, a torque-limited
servo) swings up from any state by pumping its energy ``E`` (zero at upright rest) towards zero: the hinge's power is
``gear * u * q_dot``, so ``u`` proportional to ``-E q_dot`` (clipped to the ctrl range) raises ``E`` when it is short
of upright's and takes it out when a knock left too much, whatever the state. Near ``E = 0`` the law is sharp
(:data:`PUMP_SHARPNESS`): a gentle one stalls a little short of the top, where the hinge's damping takes out what its
small pushes put in (dm_control's pendulum, measured). The catch takes the pole at the top.
"""
from __future__ import annotations

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, motor_drive

#: The fraction of the energy a swing-up must gain (``|E|`` at hanging rest) below which the pump pushes less than its
#: whole range (at the hanging mode's frequency): 0.005 reaches the top on the corpus's pendulums and dm_control's,
#: 0.05 stalled 1 % short of it (pendulum_built_hanging.xml: -0.024 J of -2.75 J).
PUMP_SHARPNESS = 0.005


class HingePumpError(CartPoleError):
    """A model the hinge pump does not apply to (not one driven hinge) or a motor without a ctrl range."""


def pendulum_driven_at_hinge(model: CartPoleModel) -> bool:
    """Whether ``model`` is one pole on one driven hinge, no cart (the case :class:`HingePump` handles)."""
    actuated = [int(j) for j in model.params.actuated]
    return model.nq == 1 and len(model.hinges) == 1 and actuated == [int(model.hinges[0])]


class HingePump:
    """``u = mid + half * clip(-E q_dot / (PUMP_SHARPNESS |E_hanging| omega), -1, 1) * sign(gear)``: the pendulum's
    energy ``E`` (J, zero at upright rest) driven to zero from any state (pumped in or taken out).

    Parameters
    ----------
    model : CartPoleModel
        One pole on one driven hinge (:func:`pendulum_driven_at_hinge`).
    u_limits : (1, 2) array
        The ctrl range (finite).

    Raises
    ------
    HingePumpError
        Not one driven hinge, or an infinite ctrl range.
    """

    def __init__(self, model: CartPoleModel, u_limits):
        if not pendulum_driven_at_hinge(model):
            raise HingePumpError("The hinge pump swings up one pole driven at its hinge; this model has "
                                 f"{model.nq} joints and drives {list(model.params.actuated)}.")
        drive = motor_drive(model.params, u_limits)
        if not drive.limited:
            raise HingePumpError("The pendulum's motor has no ctrlrange, so the pump has no range to push with; design "
                                 "on cartpole.models.planning_limits(params) or set ctrlrange on the motor.")
        self.model = model
        self.rate = model.nq + int(model.hinges[0])
        self.mid, self.half, self.sign = drive.mid, drive.half, drive.sign
        self.deficit = abs(float(model.energy(np.asarray(model.x_hanging, dtype=float))))
        A, _ = model.linearize(model.x_hanging, model.u_hanging)
        self.omega = max(float(np.max(np.abs(np.linalg.eigvals(np.asarray(A, dtype=float)).imag))), 1e-6)

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (1,) at state ``x`` (2,): ``[angle (rad), rate (rad/s)]``."""
        x = np.asarray(x, dtype=float)
        rate = x[self.rate]
        if abs(rate) < 1e-3 * self.omega:  # at rest (hanging): a push to start from
            rate = 1e-3 * self.omega
        push = -float(self.model.energy(x)) * rate / (PUMP_SHARPNESS * self.deficit * self.omega)
        return np.array([self.mid + self.half * self.sign * float(np.clip(push, -1.0, 1.0))])
