"""Energy pumping for a pendulum driven at its hinge: the supervisor's swing-up law where there is no cart.

A single pole on a driven hinge (dm_control's pendulum, a tutorial's pendulum built hanging, a torque-limited
servo) swings up from any state by pumping its energy ``E`` (zero at upright rest) towards zero: the hinge's power is
``gear * u * q_dot``, so ``u`` proportional to ``-E q_dot`` (clipped to the ctrl range) raises ``E`` when it is short
of upright's and takes it out when a knock left too much, whatever the state. Near ``E = 0`` the law is sharp
(:data:`PUMP_SHARPNESS`): a gentle one stalls a little short of the top, where the hinge's damping takes out what its
small pushes put in (dm_control's pendulum, measured). The catch takes the pole at the top.

The supervisor's swing-up law on such a pendulum is :func:`hinge_swingup`: the optimal policy for time within the
upright band, by value iteration over the pendulum's whole (angle, rate) plane
(:mod:`cartpole.planning.value_iteration`), with the pump for states faster than its grid.
"""
from __future__ import annotations

import math

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, motor_drive
from cartpole.planning.value_iteration import (BandReward, ValueIterationOptions, ValuePolicy, cached_hinge_values,
                                               pendulum_driven_at_hinge)

#: The fraction of the energy a swing-up must gain (``|E|`` at hanging rest) below which the pump pushes less than its
#: whole range (at the hanging mode's frequency): 0.005 reaches the top on the corpus's pendulums and dm_control's,
#: 0.05 stalled 1 % short of it (pendulum_built_hanging.xml: -0.024 J of -2.75 J).
PUMP_SHARPNESS = 0.005
#: s: the control period of the value iteration's table behind :func:`hinge_swingup` (a whole number of physics steps,
#: at least one): dm_control's pendulum step. A table at a far shorter step moves less than a cell a step, and the
#: interpolation smears its value; the policy still decides every period it is called, looking one table period ahead.
SWINGUP_STEP = 0.02
#: s: the horizon of that table: long enough for a swing-up from hanging under a weak motor (dm_control's pendulum:
#: 6.5 s) and its hold; every node gaining alike ends the backups sooner (the rest extrapolated).
SWINGUP_HORIZON = 30.0
#: The grid of that table (angle and rate nodes): made in seconds and kept in the user cache under the model's hash.
SWINGUP_GRID = ValueIterationOptions(angles=160, rates=161)


class HingePumpError(CartPoleError):
    """A model the hinge pump does not apply to (not one driven hinge) or a motor without a ctrl range."""


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


def hinge_swingup(model: CartPoleModel, u_limits, period: float | None = None) -> ValuePolicy:
    """The supervisor's swing-up law on a pendulum driven at its hinge: the optimal policy for the time spent within
    :data:`cartpole.sim.UPRIGHT_BAND` of upright (:class:`~cartpole.planning.value_iteration.BandReward`), by value
    iteration on :data:`SWINGUP_GRID` over :data:`SWINGUP_HORIZON` s at a table period of at least
    :data:`SWINGUP_STEP` s (cached by the model's hash), with :class:`HingePump` for a state faster than the grid.

    Parameters
    ----------
    model : CartPoleModel
        One pole on one driven hinge.
    u_limits : (1, 2) array
        The ctrl range (finite).
    period : float, optional
        s: the supervisor's control period (default one physics step); the table's period is the smallest whole
        number of these at least :data:`SWINGUP_STEP` s.

    Returns
    -------
    ValuePolicy

    Raises
    ------
    HingePumpError
        Not one driven hinge, or an infinite ctrl range.
    """
    pump = HingePump(model, u_limits)
    step = float(model.dt) if period is None else float(period)
    table = step * max(1, math.ceil(SWINGUP_STEP / step - 1e-9))
    reward = BandReward(model)
    options = SWINGUP_GRID.replace(horizon=max(1, math.ceil(SWINGUP_HORIZON / table)))
    values = cached_hinge_values(model, reward, period=table, u_limits=u_limits, options=options)
    return ValuePolicy(values, model, reward, outside=pump)
