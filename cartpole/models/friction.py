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

import itertools
import math
from dataclasses import dataclass

import casadi as ca
import mujoco
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


def friction_treatment(params, *, width: float, omitted=(), cancelled=()) -> list:
    """What a design on the symbolic model did with MuJoCo's dry friction: one entry per joint with ``frictionloss``.

    MuJoCo sticks a joint whose generalized force stays below its ``frictionloss``; a design on the symbolic model
    either holds that friction as the smooth ``-frictionloss tanh(qvel / width)`` (whose slope at rest,
    ``frictionloss / width``, a linearisation sees as a viscous damping) or leaves it out. This is the list a
    command reports (JSON ``smoothed_friction``) so that neither happens silently.

    Parameters
    ----------
    params : CartPoleParams
        The model MuJoCo runs (its joints' ``frictionloss``, N on slides, N m on hinges).
    width : float
        The smooth friction's width, m/s or rad/s (``CartPoleModel.friction_width``).
    omitted : sequence of int
        qpos indices of the joints whose friction the design left out (e.g. a linearisation at rest without it).
    cancelled : sequence of int
        qpos indices of the joints whose friction a feedforward cancels (also left out of the design).

    Returns
    -------
    list of dict
        Per joint with friction, in qpos order: ``joint`` (name), ``kind`` (``slide`` or ``hinge``),
        ``frictionloss``, ``width`` (the smooth model's,
        m/s or rad/s), ``design``: ``"smooth"`` (held as the tanh; then ``damping_at_rest`` =
        ``frictionloss / width``, N s/m or N m s/rad), ``"omitted"`` or ``"cancelled"``. Empty without friction.
    """
    omitted, cancelled = {int(i) for i in omitted}, {int(i) for i in cancelled}
    out = []
    for i, j in enumerate(params.joints):
        loss = float(j.frictionloss)
        if loss == 0:
            continue
        entry = {"joint": j.name, "kind": j.kind, "frictionloss": loss, "width": float(width)}
        if i in cancelled:
            entry["design"] = "cancelled"
        elif i in omitted:
            entry["design"] = "omitted"
        else:
            entry["design"] = "smooth"
            entry["damping_at_rest"] = loss / float(width)
        out.append(entry)
    return out


# ---- MuJoCo's friction-loss constraint, exactly -------------------------------------------------------------------
#: MuJoCo's bounds on a constraint's impedance and its smallest regulariser (``mjMINIMP``, ``mjMAXIMP``, ``mjMINVAL``).
_MIN_IMP, _MAX_IMP, _MIN_VAL = 0.0001, 0.9999, 1e-15
#: Most friction joints the exact constraint model solves (its box QP enumerates ``3**n`` active sets).
MAX_CONSTRAINT_FRICTION_DOFS = 3


@dataclass(frozen=True)
class FrictionConstraint:
    """MuJoCo's soft-constraint coefficients of each joint's friction-loss row, read from the compiled model.

    For a joint with frictionloss ``F`` MuJoCo adds one constraint row ``J = e_i`` whose force ``f`` solves the box
    QP ``min 0.5 f' (A + R) f + f' (a0 - aref)``, ``|f| <= F`` (``A`` the friction block of ``M^-1``, ``a0`` the
    unconstrained acceleration, ``aref = -b qvel``, ``R = r invweight0``, ``invweight0`` the diagonal of ``M^-1``
    at ``qpos0``): what :func:`constraint_friction_force` solves exactly.

    Attributes
    ----------
    damping : (nq,) array
        ``b = 2 / (dmax timeconst)`` of each joint's ``solreffriction`` (1/s; ``timeconst`` at least two steps
        unless the MJCF disables ``refsafe``; ``-solref[1] / dmax`` for MuJoCo's direct form).
    regularizer : (nq,) array
        ``r = (1 - d) / d``, ``d`` the impedance at zero violation (``solimpfriction``'s ``dmin``), no unit.
    qpos0 : (nq,) array
        The model's reference configuration, m or rad, where ``invweight0`` is taken.
    """

    damping: np.ndarray
    regularizer: np.ndarray
    qpos0: np.ndarray


def friction_constraint(m) -> FrictionConstraint:
    """The :class:`FrictionConstraint` of a compiled ``mujoco.MjModel`` (every dof a slide or hinge).

    Parameters
    ----------
    m : mujoco.MjModel

    Returns
    -------
    FrictionConstraint
    """
    refsafe = not (m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_REFSAFE)
    b = np.zeros(m.nv)
    r = np.zeros(m.nv)
    for i in range(m.nv):
        ref, imp = m.dof_solref[i], m.dof_solimp[i]
        dmin, dmax = (float(np.clip(v, _MIN_IMP, _MAX_IMP)) for v in imp[:2])
        if ref[0] > 0:
            tc = max(float(ref[0]), 2 * float(m.opt.timestep)) if refsafe else float(ref[0])
            b[i] = 2 / (dmax * tc)
        else:
            b[i] = -float(ref[1]) / dmax
        r[i] = (1 - dmin) / dmin
    return FrictionConstraint(damping=b, regularizer=r, qpos0=np.asarray(m.qpos0, float).copy())


def _box_qp(H, g, F):
    """The exact solution (n,) SX of ``min 0.5 f' H f + g' f``, ``-F <= f <= F`` (``H`` (n, n) positive definite)
    by enumerating the ``3**n`` active sets (each checked by its KKT conditions; the first that holds is taken)."""
    n = g.shape[0]
    if n == 1:
        return ca.fmin(ca.fmax(-g / H, -F), F)
    out = None
    for states in reversed(list(itertools.product((0, 1, -1), repeat=n))):
        free = [i for i in range(n) if states[i] == 0]
        f = [states[i] * F[i] for i in range(n)]
        if free:
            clamp = [i for i in range(n) if states[i] != 0]
            rhs = -g[free]
            if clamp:
                rhs = rhs - ca.mtimes(H[free, clamp], ca.vertcat(*[f[i] for i in clamp]))
            sol = ca.solve(H[free, free], rhs)
            for k, i in enumerate(free):
                f[i] = sol[k]
        fv = ca.vertcat(*f)
        grad = ca.mtimes(H, fv) + g
        ok = 1
        for i in range(n):
            if states[i] == 0:
                ok = ca.logic_and(ok, ca.logic_and(fv[i] <= F[i], fv[i] >= -F[i]))
            elif states[i] == 1:
                ok = ca.logic_and(ok, grad[i] <= 0)
            else:
                ok = ca.logic_and(ok, grad[i] >= 0)
        out = fv if out is None else ca.if_else(ok, fv, out)
    return out


def constraint_friction_force(M, M0, a0, v, frictionloss, dofs, fc: FrictionConstraint):
    """MuJoCo's friction-loss constraint force (nq,) SX, solved exactly for the friction joints ``dofs``.

    Parameters
    ----------
    M : SX (nq, nq)
        Mass matrix with armature at the state, kg, kg m, kg m^2.
    M0 : SX (nq, nq)
        The same at ``qpos0`` (for ``invweight0``).
    a0 : SX (nq,)
        Unconstrained acceleration ``M^-1 F`` (everything but the constraint), m/s^2 or rad/s^2.
    v : SX (nq,)
        ``qvel``, m/s or rad/s.
    frictionloss : SX (nq,)
        N or N m (numbers or symbols).
    dofs : sequence of int
        The joints with a friction row (nonzero or symbolic frictionloss), at most
        :data:`MAX_CONSTRAINT_FRICTION_DOFS`.
    fc : FrictionConstraint

    Returns
    -------
    SX (nq,)
        Generalized friction force, N or N m (zero off ``dofs``).
    """
    nq = M.shape[0]
    dofs = list(dofs)
    out = ca.SX.zeros(nq)
    if not dofs:
        return out
    E = ca.DM.zeros(nq, len(dofs))
    for k, i in enumerate(dofs):
        E[i, k] = 1
    A = ca.mtimes(E.T, ca.solve(M, E))
    w0 = ca.diag(ca.mtimes(E.T, ca.solve(M0, E)))
    R = ca.fmax(_MIN_VAL, ca.DM(fc.regularizer[dofs]) * w0)
    g = ca.mtimes(E.T, a0) + ca.DM(fc.damping[dofs]) * ca.mtimes(E.T, v)  # a0 - aref on the rows
    f = _box_qp(A + ca.diag(R), g, ca.mtimes(E.T, frictionloss))
    return ca.mtimes(E, f)
