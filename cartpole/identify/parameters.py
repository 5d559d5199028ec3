"""Physical parameters chosen by their MJCF names, and the model's one-sample step with them as CasADi symbols.

Names (one scalar each; a name without a component expands to several):

* ``mass:BODY`` — the body's mass, kg (MuJoCo's ``body_mass``).
* ``com:BODY`` — its centre of mass in the body frame, m (``body_ipos``); expands to the components orthogonal to
  every hinge axis of the body (``com:pole:x``, ``com:pole:z`` for a pole hinged about y: a planar chain's motion
  does not depend on the component along its hinge); ``com:BODY:x|y|z`` names one component.
* ``inertia:BODY`` — the body's moment of inertia about its centre of mass around its (first) hinge axis, kg m^2;
  all three principal moments (``body_inertia``) scale by the same factor, so a physical body (positive moments,
  triangle inequalities) stays physical and only the moment the planar motion sees is a free parameter.
* ``damping:JOINT`` (N s/m or N m s/rad), ``frictionloss:JOINT`` (N or N m), ``armature:JOINT`` (kg or kg m^2).
* ``gear:ACTUATOR`` — MuJoCo's ``gear`` (the transmission; the generalized force per ctrl of a ``<motor>``).
* ``all`` — what a student with a scale cannot weigh: ``gear`` of every actuator, ``com`` and ``inertia`` of every
  hinged body, ``damping`` and ``frictionloss`` of every joint; the masses are taken as weighed (fitting masses
  with the gear makes them identifiable only as ratios, and the fit says so). The frictionloss is MuJoCo's
  friction constraint solved exactly in the model (:func:`sample_step`), which solves at most
  :data:`~cartpole.models.friction.MAX_CONSTRAINT_FRICTION_DOFS` friction joints: on a chain with more joints
  ``all`` fits the frictionloss of those the nominal MJCF gives friction.

Bounds keep the model physical: masses and inertias positive, damping, frictionloss and armature non-negative, a
gear keeping its sign.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import casadi as ca
import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import (DEFAULT_FRICTION_WIDTH, MAX_CONSTRAINT_FRICTION_DOFS, CartPoleParams, FrictionConstraint,
                             equations, friction_constraint, mujoco_model, quat_to_mat)

KINDS = ("mass", "com", "inertia", "damping", "frictionloss", "armature", "gear")
_AXES = "xyz"
#: Scale of a parameter whose nominal value is zero (regularisation and step scaling), by kind and joint kind.
_ZERO_SCALE = {("damping", "slide"): 0.1, ("damping", "hinge"): 0.01, ("frictionloss", "slide"): 0.1,
               ("frictionloss", "hinge"): 0.001, ("armature", "slide"): 0.01, ("armature", "hinge"): 1e-4,
               ("com", None): 0.01}
_UNITS = {"mass": "kg", "com": "m", "inertia": "kg m^2", "gear": "N or N m per ctrl"}


class ParameterError(CartPoleError, ValueError):
    """A parameter name the MJCF lacks or that the toolkit cannot fit."""


@dataclass(frozen=True)
class Parameter:
    """One scalar parameter to fit.

    Attributes
    ----------
    name : str
        ``kind:OBJECT`` or ``com:BODY:axis``.
    kind : str
        One of :data:`KINDS`.
    index : int
        Body, joint or actuator index in the params (``CartPoleParams.bodies`` / ``joints`` / ``actuators``).
    component : int
        Axis 0..2 for ``com``; -1 otherwise.
    nominal : float
        Value in the nominal MJCF (SI units).
    scale : float
        Typical size (``|nominal|``, or a default for a zero nominal): steps and regularisation are in its units.
    lower, upper : float
        Bounds keeping the model physical.
    """

    name: str
    kind: str
    index: int
    component: int
    nominal: float
    scale: float
    lower: float
    upper: float


def _lookup(names, what: str, obj: str, kind: str) -> int:
    if obj not in names:
        raise ParameterError(f"The MJCF has no {what} '{obj}' for parameter '{kind}:{obj}'; its {what}s are "
                             f"{', '.join(names)}.")
    return names.index(obj)


def _hinge_axes(p: CartPoleParams, b: int) -> list:
    return [np.asarray(p.joints[j].axis, float) for j in p.bodies[b].joints if p.joints[j].kind == "hinge"]


def hinge_moment(p: CartPoleParams, b: int) -> float:
    """The principal-inertia moment of body ``b`` about its first hinge axis (or its largest moment without a
    hinge), kg m^2: what ``inertia:BODY`` fits."""
    body = p.bodies[b]
    axes = _hinge_axes(p, b)
    if not axes:
        return float(np.max(body.inertia))
    R = quat_to_mat(body.iquat)
    n = axes[0] / np.linalg.norm(axes[0])
    return float(n @ R @ np.diag(body.inertia) @ R.T @ n)


def _make(p: CartPoleParams, kind: str, index: int, component: int, name: str) -> Parameter:
    jkind = None
    if kind == "mass":
        nominal, lower = p.bodies[index].mass, 0.0
    elif kind == "com":
        nominal, lower = float(p.bodies[index].ipos[component]), -np.inf
    elif kind == "inertia":
        nominal, lower = hinge_moment(p, index), 0.0
        if not nominal > 0:
            raise ParameterError(f"Body '{p.bodies[index].name}' has no inertia about its hinge, so "
                                 f"'{name}' cannot be scaled; give it a mass or an <inertial>.")
    elif kind == "gear":
        nominal = p.actuators[index].transmission
        lower = 0.0 if nominal > 0 else -np.inf
    else:
        jkind = p.joints[index].kind
        nominal, lower = float(getattr(p.joints[index], kind)), 0.0
    upper = 0.0 if (kind == "gear" and nominal < 0) else np.inf
    scale = abs(nominal) if nominal else _ZERO_SCALE.get((kind, jkind), _ZERO_SCALE[("com", None)])
    if kind == "com":
        scale = max(abs(nominal), _ZERO_SCALE[("com", None)])
    return Parameter(name=name, kind=kind, index=index, component=component, nominal=float(nominal),
                     scale=float(scale), lower=float(lower), upper=float(upper))


def default_names(p: CartPoleParams) -> list:
    """The names ``all`` stands for (module docstring), before expansion."""
    names = [f"gear:{a.name}" for a in p.actuators]
    for b, body in enumerate(p.bodies):
        if _hinge_axes(p, b):
            names += [f"com:{body.name}", f"inertia:{body.name}"]
    names += [f"damping:{j.name}" for j in p.joints]
    few = p.nq <= MAX_CONSTRAINT_FRICTION_DOFS
    names += [f"frictionloss:{j.name}" for j in p.joints if few or j.frictionloss]
    return names


def parse_parameters(p: CartPoleParams, names) -> tuple:
    """The :class:`Parameter` objects for the names given (module docstring), expanded and de-duplicated in order.

    Parameters
    ----------
    p : CartPoleParams
        The nominal model.
    names : sequence of str
        E.g. ``["mass:pole", "damping:hinge", "gear:motor"]`` or ``["all"]``.

    Returns
    -------
    tuple of Parameter

    Raises
    ------
    ParameterError
        An unknown kind, an object the MJCF lacks, a bad component, or no names at all.
    """
    names = [n.strip() for n in names if n.strip()]
    if not names:
        raise ParameterError("No parameter to fit; give `names` like mass:pole, damping:hinge or all.")
    bodies = [b.name for b in p.bodies]
    joints = list(p.joint_names)
    acts = [a.name for a in p.actuators]
    out: dict[str, Parameter] = {}
    queue = list(names)
    while queue:
        full = queue.pop(0)
        if full == "all":
            queue = default_names(p) + queue
            continue
        parts = full.split(":")
        kind = parts[0]
        if kind not in KINDS or len(parts) < 2 or not parts[1]:
            raise ParameterError(f"Parameter '{full}' is not of the form KIND:NAME with KIND one of "
                                 f"{', '.join(KINDS)} (or 'all').")
        if len(parts) > (3 if kind == "com" else 2):
            raise ParameterError(f"Parameter '{full}' has too many ':' parts; give KIND:NAME (com:BODY:x|y|z).")
        obj = parts[1]
        if kind in ("mass", "com", "inertia"):
            b = _lookup(bodies, "moving body", obj, kind)
            if kind == "com":
                if len(parts) == 3:
                    if parts[2] not in _AXES or not parts[2]:
                        raise ParameterError(f"Parameter '{full}' names axis '{parts[2]}'; give x, y or z.")
                    comps = [_AXES.index(parts[2])]
                else:
                    axes = _hinge_axes(p, b)
                    comps = [c for c in range(3) if all(abs(a[c]) < 1e-12 for a in axes)] or [0, 1, 2]
                for c in comps:
                    nm = f"com:{obj}:{_AXES[c]}"
                    out.setdefault(nm, _make(p, "com", b, c, nm))
            else:
                out.setdefault(f"{kind}:{obj}", _make(p, kind, b, -1, f"{kind}:{obj}"))
        elif kind == "gear":
            a = _lookup(acts, "actuator", obj, kind)
            out.setdefault(full, _make(p, kind, a, -1, full))
        else:
            j = _lookup(joints, "joint", obj, kind)
            out.setdefault(full, _make(p, kind, j, -1, full))
    return tuple(out.values())


def with_values(p: CartPoleParams, params, values) -> CartPoleParams:
    """A copy of ``p`` with each parameter set to its value: numbers (a fitted model) or CasADi SX scalars (a
    parametric model for :func:`cartpole.models.equations`).

    Parameters
    ----------
    p : CartPoleParams
    params : sequence of Parameter
    values : sequence of float or SX, one per parameter (or an SX column)

    Returns
    -------
    CartPoleParams
    """
    vals = [values[i] for i in range(len(params))]
    sym = any(isinstance(v, (ca.SX, ca.MX)) for v in vals)
    bodies, joints, acts = list(p.bodies), list(p.joints), list(p.actuators)
    ipos = {}
    for par, v in zip(params, vals):
        if par.kind == "mass":
            bodies[par.index] = dataclasses.replace(bodies[par.index], mass=v)
        elif par.kind == "com":
            cur = ipos.setdefault(par.index, list(np.asarray(p.bodies[par.index].ipos, float)))
            cur[par.component] = v
        elif par.kind == "inertia":
            factor = v / par.nominal
            nom = np.asarray(p.bodies[par.index].inertia, float)
            bodies[par.index] = dataclasses.replace(
                bodies[par.index], inertia=ca.DM(nom) * factor if sym else np.asarray(nom * factor))
        elif par.kind == "gear":
            a = acts[par.index]
            acts[par.index] = dataclasses.replace(a, transmission=v, gear=v * a.gain)
        else:
            joints[par.index] = dataclasses.replace(joints[par.index], **{par.kind: v})
    for b, comps in ipos.items():
        bodies[b] = dataclasses.replace(bodies[b], ipos=ca.vertcat(*comps) if sym else np.asarray(comps, float))
    return dataclasses.replace(p, bodies=tuple(bodies), joints=tuple(joints), actuators=tuple(acts))


def steps_per_sample(sample_time: float, timestep: float) -> tuple[int, float]:
    """Physics steps per log sample and their length: the MJCF's step when the sample time is a whole number of
    them (a MuJoCo log replays exactly), else the nearest shorter step that divides it.

    Parameters
    ----------
    sample_time : float
        s.
    timestep : float
        The MJCF's ``opt.timestep``, s.

    Returns
    -------
    (int, float)
        Steps per sample and the step in s.
    """
    m = max(1, round(sample_time / timestep))
    if abs(m * timestep - sample_time) <= 1e-9 * sample_time:
        return m, float(timestep)
    m = int(np.ceil(sample_time / timestep - 1e-9))
    return m, float(sample_time / m)


def mujoco_friction(p: CartPoleParams) -> FrictionConstraint:
    """MuJoCo's friction-loss constraint coefficients of the model's MJCF (its ``solreffriction``,
    ``solimpfriction``, ``qpos0``): what :func:`sample_step` needs for the exact friction.

    Parameters
    ----------
    p : CartPoleParams

    Returns
    -------
    FrictionConstraint
    """
    m = mujoco_model(p)
    return friction_constraint(m)


def sample_step(p: CartPoleParams, params, sample_time: float, *,
                friction_width: float = DEFAULT_FRICTION_WIDTH, exact_friction: bool = True) -> ca.Function:
    """The model's map over one log sample, ctrl held, with the parameters as inputs:
    ``(x (nx,), u (nu,), theta (np,)) -> x_next (nx,)``, ``theta`` in the order of ``params`` (SI units).

    Built from the same derivation as :func:`cartpole.models.build_model` (:func:`cartpole.models.equations` on
    params holding SX symbols), stepped with the MJCF's integrator (:func:`steps_per_sample`).

    Parameters
    ----------
    p : CartPoleParams
    params : sequence of Parameter
    sample_time : float
        s.
    friction_width : float
        The smooth friction's velocity scale, m/s or rad/s (used only with ``exact_friction=False``).
    exact_friction : bool
        ``frictionloss`` as MuJoCo's friction constraint solved exactly (:func:`mujoco_friction`; the step equals
        ``mj_step`` while a joint sticks too), else the smooth ``tanh`` force. At most
        :data:`~cartpole.models.friction.MAX_CONSTRAINT_FRICTION_DOFS` joints with friction for the exact one.

    Returns
    -------
    casadi.Function

    Raises
    ------
    ParameterError
        Exact friction on more joints than the exact model solves.
    """
    theta = ca.SX.sym("theta", len(params))
    ps = with_values(p, params, [theta[i] for i in range(len(params))])
    x = ca.SX.sym("x", 2 * p.nq)
    u = ca.SX.sym("u", p.nu)
    m, h = steps_per_sample(sample_time, p.timestep)
    fc = None
    if exact_friction:
        dofs = [j.name for j in ps.joints if isinstance(j.frictionloss, ca.SX) or j.frictionloss]
        if len(dofs) > MAX_CONSTRAINT_FRICTION_DOFS:
            raise ParameterError(f"Frictionloss on {len(dofs)} joints ({', '.join(dofs)}) is more than the exact "
                                 f"friction model solves ({MAX_CONSTRAINT_FRICTION_DOFS}); fit fewer joints' "
                                 "frictionloss.")
        fc = mujoco_friction(p) if dofs else None
    eq = equations(ps, x, u, dt=h, integrator=p.integrator, friction_width=friction_width, friction_constraint=fc)
    one = ca.Function("one_step", [x, u, theta], [eq.x_next])
    xk = x
    for _ in range(m):
        xk = one(xk, u, theta)
    return ca.Function("sample_step", [x, u, theta], [xk], ["x", "u", "theta"], ["x_next"])
