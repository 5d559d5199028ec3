"""A smooth model of MuJoCo's joint ``frictionloss`` (dry, Coulomb friction) for planning, linearisation and estimation.

MuJoCo applies a joint's ``frictionloss`` as a constraint: a generalized force of at most ``frictionloss`` (N on a
slide, N m on a hinge) that opposes the motion, solved together with the accelerations. While the joint slides
(``|qvel|`` well above MuJoCo's own soft-constraint band) that force is exactly ``-frictionloss * sign(qvel)``; near
rest it holds the joint, with whatever force up to ``frictionloss`` that takes. A smooth model cannot stick, and a
Jacobian of ``sign`` does not exist, so the symbolic model uses

    ``F_friction = -frictionloss * tanh(qvel / width)``

per joint: odd, bounded by ``frictionloss``, within 0.5 % of it from ``|qvel| = 3 width`` on (``tanh(3) = 0.995``)
and equal to it in double precision beyond ``|qvel| = 19 width``, with derivative ``frictionloss / width`` at rest
(the viscous damping a linearisation there sees). ``tanh`` rather than ``v / sqrt(v**2 + width**2)`` because it
reaches the Coulomb level exponentially rather than algebraically (the latter is still 0.5 % short at ten widths),
so the sliding regime matches MuJoCo's force and the step matches ``mj_step`` there.

The width (:data:`DEFAULT_FRICTION_WIDTH`, m/s on slides and rad/s on hinges) trades the sliding-regime match
against stiffness: the slope at rest ``frictionloss / width`` is a damping. The Euler (with ``eulerdamp``),
implicitfast and implicit steps of :mod:`cartpole.models.symbolic` treat it implicitly, as MuJoCo's constraint acts
in the same step as the velocity it opposes; then the step stops a joint without oscillating for widths down to
about a quarter of ``dv = h * frictionloss / M`` (the rate change one step of full friction makes, ``M`` the joint's
effective inertia), where an explicit step already chatters. Narrower widths chatter at about ``dv`` in any step
(the force is bounded, so never worse). RK4 treats the slope explicitly (stable while ``dv / width`` < 2.8).
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from cartpole.errors import CartPoleError

#: Default velocity scale of the smooth friction, m/s on slides and rad/s on hinges. 0.01 puts the full Coulomb force
#: (within 0.5 %) at every speed above 0.03 m/s or rad/s, so plans and estimators see MuJoCo's force wherever
#: MuJoCo's friction slides, and stays above ``dv`` of the shipped cart with 0.5 N and 0.002 N m of friction (0.0024
#: m/s, 0.0009 rad/s), so its steps stop the joints smoothly. Two-second coasts of that cart from swinging starts
#: follow MuJoCo to about 2 mm with 0.01 (and with 0.005; 10 mm with 0.05, 21 mm with 0.1): narrower widths buy nothing
#: measurable and make the model stiffer for RK4 and Newton-type solvers.
DEFAULT_FRICTION_WIDTH = 0.01


class FrictionWidthError(CartPoleError, ValueError):
    """A friction width that is not a finite positive velocity."""


def check_width(width) -> float:
    """The smooth-friction width as a float, m/s or rad/s.

    Parameters
    ----------
    width : float
        Velocity scale of ``tanh(qvel / width)``.

    Returns
    -------
    float

    Raises
    ------
    FrictionWidthError
        A width that is not a finite positive number.
    """
    try:
        w = float(width)
    except (TypeError, ValueError):
        raise FrictionWidthError(f"The friction width {width!r} is not a number; give a velocity in m/s or rad/s, "
                                 f"e.g. {DEFAULT_FRICTION_WIDTH}.") from None
    if not (math.isfinite(w) and w > 0):
        raise FrictionWidthError(f"The friction width {w:g} is not a positive velocity; give one in m/s or rad/s, "
                                 f"e.g. {DEFAULT_FRICTION_WIDTH}.")
    return w


def smooth_friction(frictionloss, v, width: float = DEFAULT_FRICTION_WIDTH):
    """Generalized friction force ``-frictionloss * tanh(v / width)`` per joint.

    Parameters
    ----------
    frictionloss : (nq,) array or casadi SX/MX
        Dry friction per joint, N on slides, N m on hinges (:attr:`CartPoleParams.frictionloss`; symbols for a
        parametric model).
    v : (nq,) array or casadi SX/MX
        Joint velocities ``qvel``, m/s or rad/s (numbers, or CasADi symbols for the symbolic model).
    width : float
        Velocity scale, m/s or rad/s (:data:`DEFAULT_FRICTION_WIDTH`).

    Returns
    -------
    (nq,) array, or a CasADi expression (nq, 1) for symbolic ``v``
        N on slides, N m on hinges; zero on joints without friction.
    """
    w = check_width(width)
    if isinstance(frictionloss, (ca.SX, ca.MX)):
        return -frictionloss * ca.tanh(v / w)
    if isinstance(v, (ca.SX, ca.MX)):
        return -ca.DM(np.asarray(frictionloss, float)) * ca.tanh(v / w)
    return -np.asarray(frictionloss, float) * np.tanh(np.asarray(v, float) / w)
