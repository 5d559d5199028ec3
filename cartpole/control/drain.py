"""Take energy out of a fast chain through its motor, down to a target energy.

The power a motor takes out of a chain is ``ctrl * gear * q_dot_j`` (``j`` the joint it drives), so it takes energy
out only while that joint moves. A damper on it (:class:`~cartpole.supervise.PassiveBrake`) takes out only what the
joint's own motion lets it, and on a chain driven at a hinge (dm_control's acrobot) that swings as one body the
driven joint hardly moves: the damper stills it further and takes almost nothing. :class:`EnergyDrain` keeps the
driven joint moving and brakes it when it moves fast:

    ``u = -u_max sat((|q_dot_j| - rate) / width) sign(q_dot_j)``

full ctrl *with* the joint's motion while it is slower than ``rate`` (bending the chain, so that its own swing
throws the joint about), full ctrl *against* it once it is faster (where the power taken out, ``u_max gear
|q_dot_j|``, is largest). It is what an open-loop optimum of the acrobot's ctrl over 3 s does from 30 J (spend a few
J bending the elbow, then brake the elbow's swings of 10-14 rad/s). The motor puts energy in for part of each swing
and takes more out over the swing; once the total energy is at or below ``target`` the law stops and hands over to
``below`` (a passive law), so it never adds energy above the target.

Measured on dm_control's acrobot (``cartpole/assets/dmc_acrobot.xml``, 2 N m at the elbow; ``tests/control/
test_drain.py``): from 50 J (above the upright's 0 J) it reaches the upright's energy in about 0.6 of the time the
joints' damping alone takes, where the reverse of Spong's swing-up pumping (partial feedback linearisation of the
elbow onto ``-alpha atan(q_dot_shoulder)``) took 0.75 of it and a passive damper on the elbow about as long (soft) or
longer (stiff). Above about 100 J no law does much better than the damping: centrifugal torques of tens of N m hold
the elbow straight against its 2 N m (a local open-loop optimum of the ctrl over 3 s, L-BFGS from two guesses, took
out 10-20 % more than the damping alone from 100-300 J, about three times as much from 30 J).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, motor_drive

#: rad/s (m/s on a slide): the driven joint's rate below which the drain drives it with its motion, above which
#: against it. On dm_control's acrobot 6 rad/s drained from 50 J fastest of 1, 2, 4, 6 and 8 rad/s (to the upright's
#: energy in 15 s at the median of the states ``Knockdown(3, 0.3)`` leaves, seeds 0-11, once the damping has taken
#: them down to 50 J; 16-17 s with 4 or 8 rad/s, 28 s with the damping alone; in MuJoCo).
DRAIN_RATE = 6.0
#: The switch's width as a fraction of ``rate`` (the law is saturated linear across ``rate +- width``).
DRAIN_WIDTH = 0.2 / 6.0


class EnergyDrainError(CartPoleError):
    """A model the energy drain does not apply to (not one motor, no joint the motor leaves free) or a rate that is
    not a positive number."""


class EnergyDrain:
    """``u = law(t, x)``: drain a chain's energy through its one motor down to ``target`` J, then ``below``.

    Parameters
    ----------
    model : CartPoleModel
        One actuator (``params.actuated``: the joint ``j`` it drives, ``gears``) and at least one joint it does not
        drive.
    target : float
        J of total mechanical energy (:attr:`CartPoleModel.energy`, zero at upright rest): at or below it the law
        hands over to ``below``. Default 0, the upright's.
    below : callable, optional
        ``(t, x) -> ctrl`` at or below ``target`` (e.g. :class:`~cartpole.supervise.PassiveBrake`); default the
        equilibrium's ctrl ``u*``.
    rate : float
        rad/s (m/s on a slide): below it the motor drives the joint with its motion, above it against it
        (:data:`DRAIN_RATE`).
    u_limits : (nu, 2) array, optional
        ctrl clip (default the model's ctrl range); ``u_max`` is the side the sign asks for.

    Raises
    ------
    EnergyDrainError
        When the model has not one actuator, or no joint it does not drive, or ``rate`` is not a positive number.
    """

    def __init__(self, model: CartPoleModel, *, target: float = 0.0, below: Callable | None = None,
                 rate: float = DRAIN_RATE, u_limits=None):
        if model.nu != 1:
            raise EnergyDrainError(f"The energy drain needs a model with one actuator; this one has {model.nu}.")
        if model.nq < 2:
            raise EnergyDrainError("The energy drain needs a joint the motor does not drive; the model has none.")
        if not (isinstance(rate, (int, float)) and np.isfinite(rate) and rate > 0):
            raise EnergyDrainError(f"The energy drain's rate must be a positive number (rad/s, m/s on a slide); "
                                   f"got {rate!r}.")
        self.model, self.target, self.below = model, float(target), below
        self.rate, self.width = float(rate), DRAIN_WIDTH * float(rate)
        drive = motor_drive(model.params, u_limits)  # the joint, the ctrl sign that pushes it forward, the range
        self.joint, self.sign = drive.joint, drive.sign
        self.u_limits = np.array([[drive.low, drive.high]])

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (1,) at time ``t`` (s) for state ``x`` (nx,), clipped to ``u_limits``."""
        x = np.asarray(x, dtype=float)
        if float(self.model.energy(x)) <= self.target:
            if self.below is not None:
                return np.asarray(self.below(t, x), dtype=float).reshape(1)
            return np.asarray(self.model.u_eq, dtype=float).reshape(1).copy()
        v = float(x[self.model.nq + self.joint])
        push = -np.clip((abs(v) - self.rate) / self.width, -1.0, 1.0) * np.sign(v) * self.sign  # + with the motion
        low, high = self.u_limits[0]
        return np.array([high * push if push > 0 else -low * push])
