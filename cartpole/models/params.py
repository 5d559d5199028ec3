"""Read a cart-pole (any tree of slide and hinge joints) from an MJCF file, via the compiled ``mujoco.MjModel``.

Inertias come from the compiled model, never from the XML text: MuJoCo derives a capsule's mass
distribution from its geometry, applies defaults and ``childclass``, adds ``armature`` to the joint-space
inertia, and so on. What is read is exactly what the smooth model in :mod:`cartpole.models.symbolic`
models, with one deliberate exception: a joint's ``frictionloss`` is read as it is (MuJoCo keeps its true
friction constraint) and the symbolic model carries a smooth version of it (:mod:`cartpole.models.friction`).
Actuators are MuJoCo's affine ones on joints, ``force = gain * ctrl + b0 + b1 * length + b2 * velocity`` with
``length = gear * qpos`` and ``velocity = gear * qvel`` (``<motor>``, ``<position>``, ``<velocity>``, ``<general>``
with ``biastype="affine"``), plus MuJoCo's actuator ``damping`` and ``armature``. Anything else MuJoCo would add
(fluid forces, gravity compensation, force clamping that can bite, tendons, equality constraints, activation
states, state-dependent gains) is refused with one sentence naming it and the fix.

Contacts are judged by whether they can happen, not by the collision masks (:mod:`cartpole.models.contacts`): a
file may keep its floor, rail and MuJoCo's default ``contype``/``conaffinity``, and explicit ``<pair>`` elements.
MuJoCo's own ``mj_geomDistance`` decides, over the configurations a task visits, which pairs the collision filter
lets collide can touch: a pair in contact at the upright equilibrium is refused (by
:func:`cartpole.models.build_model`, naming the pair, its depth and the edit); a pair that touches only away from
upright allows balancing and refuses a swing-up, naming where it touches; a pair that never touches is accepted and
listed (``model.contacts`` in the JSON). Every MuJoCo run keeps the file's contacts as written.
"""
from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import os
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import mujoco
import numpy as np

from cartpole._arrays import readonly
from cartpole._files import InputFileError, check_input_file, short
from cartpole.errors import FOREIGN_WIDTH, CartPoleError, first_line
from cartpole.models.kinematics import forward_kinematics_np
from cartpole.models.urdf import URDFError, URDFImport, import_urdf, is_urdf

#: Integrators whose one-step map :mod:`cartpole.models.symbolic` reproduces exactly.
SUPPORTED_INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")

_INTEGRATOR_NAMES = {0: "Euler", 1: "RK4", 2: "implicit", 3: "implicitfast"}

SHIPPED_MJCF = Path(__file__).resolve().parent.parent / "assets" / "cartpole.xml"

_SUPPORTED = ("the toolkit supports a tree of slide and hinge joints (typically one slide, the cart, carrying a "
              "chain of hinged poles) driven by motor actuators on those joints")


class MJCFError(CartPoleError):
    """The MJCF file is missing, does not compile, or is not a cart-pole this toolkit supports."""


@dataclass(frozen=True)
class JointParams:
    """One 1-DOF joint as MuJoCo compiled it (qpos order = joint order).

    Attributes
    ----------
    name : str
    kind : str
        ``"slide"`` (qpos in m) or ``"hinge"`` (qpos in rad).
    body : int
        Index into :attr:`CartPoleParams.bodies` of the body the joint moves.
    pos, axis : (3,) arrays
        Anchor (m) and unit axis in the body frame (``jnt_pos``, ``jnt_axis``).
    qpos0 : float
        Reference position (``ref``): the joint's displacement is ``qpos - qpos0``.
    damping : float
        N s/m or N m s/rad (zero when the MJCF disables dampers).
    armature : float
        kg or kg m^2, added to the joint-space inertia.
    stiffness : float
        N/m or N m/rad (zero when the MJCF disables springs); spring force ``-stiffness (qpos - springref)``.
    springref : float
        Spring rest position (``qpos_spring``).
    range : (2,) array
        Joint limits ``[low, high]``; ``(-inf, inf)`` when unlimited. Limits are constraint forces outside the
        smooth model: plans keep inside them, rollouts are checked against them.
    frictionloss : float
        Dry (Coulomb) friction, N on a slide, N m on a hinge (``dof_frictionloss``; zero when the MJCF disables
        frictionloss or constraints). MuJoCo applies it as a constraint force of at most this size opposing the
        motion; the symbolic model has the smooth ``-frictionloss * tanh(qvel / width)``
        (:func:`cartpole.models.friction.smooth_friction`).
    """

    name: str
    kind: str
    body: int
    pos: np.ndarray
    axis: np.ndarray
    qpos0: float
    damping: float
    armature: float
    stiffness: float
    springref: float
    range: np.ndarray
    frictionloss: float = 0.0


@dataclass(frozen=True)
class BodyParams:
    """One moving rigid body (bodies welded to the world are left out: they add nothing).

    Attributes
    ----------
    name : str
    parent : int
        Index of the parent in :attr:`CartPoleParams.bodies`, or -1 for a parent fixed to the world.
    pos : (3,) array
        Body frame origin in the parent frame, m (for parent -1: in the world frame).
    quat : (4,) array
        Body frame orientation in the parent frame, MuJoCo's ``(w, x, y, z)`` (for parent -1: in the world).
    mass : float
        kg.
    ipos : (3,) array
        Centre of mass in the body frame, m.
    iquat : (4,) array
        Principal inertia frame in the body frame ``(w, x, y, z)``.
    inertia : (3,) array
        Principal moments of inertia about the centre of mass, kg m^2.
    joints : tuple of int
        Indices into :attr:`CartPoleParams.joints` of the joints of this body, in MuJoCo's order.
    """

    name: str
    parent: int
    pos: np.ndarray
    quat: np.ndarray
    mass: float
    ipos: np.ndarray
    iquat: np.ndarray
    inertia: np.ndarray
    joints: tuple


def _no_bias() -> np.ndarray:
    return readonly(np.zeros(3))


@dataclass(frozen=True)
class ActuatorParams:
    """One actuator on one joint, MuJoCo's affine model with a joint transmission.

    With ``r`` = :attr:`transmission` (MuJoCo's ``gear``), the actuator's length is ``r * qpos`` and its velocity
    ``r * qvel`` (``qpos`` itself, not ``qpos - qpos0``, as MuJoCo defines them), its force
    ``gain * ctrl + b0 + b1 * r * qpos + b2 * r * qvel``, and the generalized force on the joint ``r`` times that:
    ``gear * ctrl + r * (b0 + b1 * r * qpos + b2 * r * qvel)``. A plain ``<motor>`` has ``gain = 1`` and no bias, so
    its force is ``gear * ctrl``; a ``<position kp kv>`` has ``gain = kp``, ``bias = (0, -kp, -kv)``; a
    ``<velocity kv>`` has ``gain = kv``, ``bias = (0, 0, -kv)``; a DC motor without inductance (current settles
    at once) is ``gain = K / R`` per volt, ``b2 = -K**2 / R`` (back-EMF).

    Attributes
    ----------
    name : str
    joint : int
        Index into :attr:`CartPoleParams.joints` (= qpos index).
    gear : float
        Generalized force per unit ctrl, N or N m (``transmission * gain``; MuJoCo's ``gear`` for ``<motor>``).
    ctrl_range : (2,) array
        ``[low, high]`` of ``ctrl``, MuJoCo clamps to it; ``(-inf, inf)`` when not ctrl-limited.
    transmission : float
        MuJoCo's ``gear[0]``: actuator length = ``transmission * qpos``, joint force = ``transmission`` times the
        actuator force.
    gain : float
        Actuator force per unit ctrl (``gainprm[0]``, fixed gain).
    bias : (3,) array
        ``(b0, b1, b2)`` = ``biasprm[:3]`` of ``biastype="affine"`` (zeros for ``biastype="none"``): actuator
        force ``b0`` (N or N m), ``b1`` per unit actuator length, ``b2`` per unit actuator velocity.
    damping : float
        MuJoCo's actuator ``damping``: actuator force ``-damping * velocity`` (a joint damping of
        ``transmission**2 * damping``, treated by MuJoCo exactly as joint damping; zero when dampers are disabled).
    armature : float
        MuJoCo's actuator ``armature``: ``transmission**2 * armature`` is added to the joint's armature.
    """

    name: str
    joint: int
    gear: float
    ctrl_range: np.ndarray
    transmission: float = 1.0
    gain: float = 1.0
    bias: np.ndarray = dataclasses.field(default_factory=_no_bias)
    damping: float = 0.0
    armature: float = 0.0

    @property
    def biased(self) -> bool:
        """True when the actuator's force depends on the state (any of ``b0, b1, b2`` nonzero)."""
        return bool(np.any(np.asarray(self.bias) != 0))


@dataclass(frozen=True)
class CartPoleParams:
    """Physical parameters of a tree of slide and hinge joints, as MuJoCo compiles them. SI units.

    Attributes
    ----------
    mjcf : str
        Absolute path of the MJCF file read ("" for a model given as a string).
    xml : str
        The MJCF text, so a MuJoCo model can be rebuilt exactly (e.g. by worker processes).
    timestep : float
        Simulator step ``opt.timestep`` in s.
    integrator : str
        One of ``SUPPORTED_INTEGRATORS``.
    euler_damping_implicit : bool
        False when the MJCF disables ``eulerdamp`` (Euler then treats damping explicitly).
    gravity : (3,) array
        Gravity acting in the model, m/s^2 (``opt.gravity``, or zero when the MJCF disables gravity).
    up : (3,) array
        Unit vector against ``opt.gravity`` (``+z`` when it is zero): the direction "upright" points in.
    joints, bodies, actuators : tuples of :class:`JointParams`, :class:`BodyParams`, :class:`ActuatorParams`
    urdf : :class:`cartpole.models.urdf.URDFImport` or None
        For a URDF (``mjcf`` its path): the motors added and the changes made so MuJoCo loads it; ``xml`` is then
        the MJCF text (with those motors) that MuJoCo runs, so compile ``xml``, not the file
        (:func:`mujoco_model`). None for an MJCF.
    """

    mjcf: str
    xml: str
    timestep: float
    integrator: str
    euler_damping_implicit: bool
    gravity: np.ndarray
    up: np.ndarray
    joints: tuple
    bodies: tuple
    actuators: tuple
    urdf: URDFImport | None = None

    # ---- sizes and named indices ------------------------------------------------------------
    @property
    def nq(self) -> int:
        """Number of joint coordinates (= ``nv``: every joint is 1-DOF)."""
        return len(self.joints)

    @property
    def nu(self) -> int:
        """Number of actuators (ctrl entries)."""
        return len(self.actuators)

    @property
    def slides(self) -> tuple:
        """qpos indices of the slide joints."""
        return tuple(i for i, j in enumerate(self.joints) if j.kind == "slide")

    @property
    def hinges(self) -> tuple:
        """qpos indices of the hinge joints (the poles), in tree order."""
        return tuple(i for i, j in enumerate(self.joints) if j.kind == "hinge")

    @property
    def slide(self) -> int | None:
        """qpos index of the cart's slide (the first slide joint), or None for a model without a cart."""
        return self.slides[0] if self.slides else None

    @property
    def g(self) -> float:
        """Magnitude of gravity in m/s^2."""
        return float(np.linalg.norm(self.gravity))

    @property
    def ctrl_range(self) -> np.ndarray:
        """(nu, 2) array of ``[low, high]`` per actuator."""
        return readonly([a.ctrl_range for a in self.actuators]).reshape(self.nu, 2)

    @property
    def gears(self) -> np.ndarray:
        """(nu,) generalized force per unit ctrl of each actuator."""
        return readonly([a.gear for a in self.actuators])

    @property
    def actuated(self) -> tuple:
        """qpos index of the joint each actuator drives, (nu,)."""
        return tuple(a.joint for a in self.actuators)

    @property
    def damping(self) -> np.ndarray:
        """(nq,) damping in qpos order, N s/m or N m s/rad: each joint's own plus ``transmission**2 * damping`` of
        every actuator on it (MuJoCo adds the two, and integrates them alike)."""
        d = np.array([j.damping for j in self.joints])
        for a in self.actuators:
            if a.damping:
                d[a.joint] += a.transmission ** 2 * a.damping
        return readonly(d)

    @property
    def armature(self) -> np.ndarray:
        """(nq,) armature in qpos order, kg or kg m^2: each joint's own plus ``transmission**2 * armature`` of every
        actuator on it."""
        arm = np.array([j.armature for j in self.joints])
        for a in self.actuators:
            if a.armature:
                arm[a.joint] += a.transmission ** 2 * a.armature
        return readonly(arm)

    @property
    def frictionloss(self) -> np.ndarray:
        """(nq,) dry friction in qpos order, N on slides, N m on hinges (zero where there is none)."""
        return readonly([j.frictionloss for j in self.joints])

    @property
    def has_friction(self) -> bool:
        """True when any joint has frictionloss."""
        return bool(np.any(self.frictionloss != 0))

    @property
    def has_actuator_bias(self) -> bool:
        """True when any actuator's force depends on the state (an affine bias)."""
        return any(a.biased for a in self.actuators)

    @property
    def joint_ranges(self) -> np.ndarray:
        """(nq, 2) joint limits in qpos order (``+-inf`` when unlimited)."""
        return readonly([j.range for j in self.joints]).reshape(self.nq, 2)

    @property
    def joint_names(self) -> tuple:
        """Joint names in qpos order."""
        return tuple(j.name for j in self.joints)

    @property
    def cart_range(self) -> np.ndarray:
        """Range in m of the cart's slide; ``(-inf, inf)`` when unlimited or when there is no slide."""
        return self.joints[self.slide].range if self.slide is not None else readonly([-np.inf, np.inf])

    # ---- the single-actuator view many applications use -----------------------------------------
    def _one_actuator(self, what: str) -> ActuatorParams:
        if self.nu != 1:
            raise MJCFError(f"{what} is defined for one actuator and this model has {self.nu}; "
                            "use the per-actuator arrays (gears, ctrl_range).")
        return self.actuators[0]

    @property
    def gear(self) -> float:
        """Force (N) or torque (N m) per unit ctrl of the only actuator (models with one actuator)."""
        return float(self._one_actuator("gear").gear)

    @property
    def u_max(self) -> float:
        """Largest |ctrl| allowed in both directions, ``min(|low|, |high|)``, of the only actuator."""
        lo, hi = self._one_actuator("u_max").ctrl_range
        return float(min(abs(lo), abs(hi)))

    # ---- the first pole, what single-pole energy shaping reasons with -------------------------
    def subtree(self, body: int) -> tuple:
        """Indices of ``body`` and every body below it."""
        out = [body]
        for b in range(body + 1, len(self.bodies)):
            p = self.bodies[b].parent
            if p in out:
                out.append(b)
        return tuple(out)

    @property
    def pole_bodies(self) -> tuple:
        """Bodies that rotate with the first hinge (the first pole and everything it carries)."""
        if not self.hinges:
            return ()
        return self.subtree(self.joints[self.hinges[0]].body)

    @property
    def pole_mass(self) -> float:
        """Mass in kg of everything that rotates with the first hinge."""
        return float(sum(self.bodies[b].mass for b in self.pole_bodies))

    @property
    def cart_mass(self) -> float:
        """Mass in kg of every moving body that does not rotate with the first hinge."""
        pole = set(self.pole_bodies)
        return float(sum(b.mass for i, b in enumerate(self.bodies) if i not in pole))

    def carried_by(self, hinge: int) -> tuple[float, float, float]:
        """What hinge ``hinge`` (a qpos index) carries, as one rigid body at ``qpos = qpos0``.

        Returns ``(mass kg, distance m of its centre of mass from the hinge axis, moment of inertia kg m^2
        about the axis without armature)``; zeros when it carries no mass.
        """
        fk = forward_kinematics_np(self, np.array([j.qpos0 for j in self.joints]))
        n, anchor = fk.joint_axis[hinge], fk.joint_anchor[hinge]
        bodies = self.subtree(self.joints[hinge].body)
        m = np.array([self.bodies[b].mass for b in bodies])
        if not m.sum() > 0:
            return 0.0, 0.0, 0.0
        c = np.array([fk.com[b] for b in bodies])
        com = (m[:, None] * c).sum(0) / m.sum()
        inertia = np.zeros((3, 3))
        for b, mb, cb in zip(bodies, m, c):
            r = cb - com
            inertia += fk.inertia[b] + mb * (r @ r * np.eye(3) - np.outer(r, r))
        d = (com - anchor) - ((com - anchor) @ n) * n
        return float(m.sum()), float(np.linalg.norm(d)), float(n @ inertia @ n + m.sum() * (d @ d))

    def _first_hinge(self) -> int:
        if not self.hinges:
            raise MJCFError("This model has no hinge, so it has no pole; add a hinged body.")
        return self.hinges[0]

    @property
    def pole_com_distance(self) -> float:
        """Distance in m from the first hinge's axis to the centre of mass of what it carries."""
        return self.carried_by(self._first_hinge())[1]

    @property
    def pole_inertia_about_hinge(self) -> float:
        """Moment of inertia in kg m^2 about the first hinge's axis of what it carries (no armature)."""
        return self.carried_by(self._first_hinge())[2]

    # ---- deliberate model error ---------------------------------------------------------------
    def replace(self, **changes) -> "CartPoleParams":
        """A copy with some fields changed (e.g. a deliberately wrong model for robustness tests)."""
        return dataclasses.replace(self, **{k: (readonly(v) if isinstance(v, (list, np.ndarray)) else v)
                                            for k, v in changes.items()})

    @property
    def driven_joints(self) -> tuple:
        """qpos indices of the joints an actuator drives with a nonzero gear, each once, in actuator order."""
        return tuple(dict.fromkeys(a.joint for a in self.actuators if a.gear != 0))

    @property
    def driven_friction(self) -> bool:
        """True when a joint an actuator drives (with a nonzero gear) has frictionloss: friction the controllers can
        cancel (:class:`cartpole.control.friction.FrictionCompensation`)."""
        return any(self.joints[j].frictionloss != 0 for j in self.driven_joints)

    def without_friction(self, joints=None) -> "CartPoleParams":
        """A copy with the ``frictionloss`` of ``joints`` (qpos indices; default every joint) set to zero.

        The model controllers are designed on when a compensation cancels the friction of the driven joints
        (``without_friction(params.actuated)``), or a frictionless reference. MuJoCo still runs the MJCF (its path or
        XML text is kept), so the true friction stays in the loop.
        """
        drop = set(range(self.nq)) if joints is None else {int(j) for j in joints}
        return dataclasses.replace(self, joints=tuple(
            dataclasses.replace(j, frictionloss=0.0) if i in drop else j for i, j in enumerate(self.joints)))

    def scaled_pole(self, mass_factor: float = 1.0, length_factor: float = 1.0) -> "CartPoleParams":
        """Parameters whose poles (every body that rotates with the first hinge) are heavier and longer.

        Masses scale by ``mass_factor``; lengths (centres of mass, child-body and joint positions inside the
        poles) by ``length_factor``; inertias by ``mass_factor * length_factor**2``, as for a uniformly
        scaled body. Used to build a *planning model* that is deliberately wrong relative to the MJCF MuJoCo
        runs. The hinge anchor of the first pole stays where it is.
        """
        poles = set(self.pole_bodies)
        bodies = []
        for i, b in enumerate(self.bodies):
            if i not in poles:
                bodies.append(b)
                continue
            child = b.parent in poles  # the first pole's own frame stays on the cart
            bodies.append(dataclasses.replace(
                b, mass=b.mass * mass_factor, ipos=readonly(b.ipos * length_factor),
                inertia=readonly(b.inertia * mass_factor * length_factor**2),
                pos=readonly(b.pos * length_factor) if child else b.pos))
        joints = tuple(dataclasses.replace(j, pos=readonly(j.pos * length_factor)) if j.body in poles
                       and self.bodies[j.body].parent in poles else j for j in self.joints)
        return dataclasses.replace(self, bodies=tuple(bodies), joints=joints)


def load_model(mjcf: str | Path | None = None, *, xml: str | None = None,
               actuated_joints: Sequence[str] | None = None):
    """Compile an MJCF (or a URDF) into a ``mujoco.MjModel``, turning MuJoCo's errors into :class:`MJCFError`.

    A URDF (root element ``<robot>``) is compiled with a motor on each driven joint
    (:mod:`cartpole.models.urdf`: its transmissions, else its only prismatic joint, or ``actuated_joints``).

    Parameters
    ----------
    mjcf : path, optional
        MJCF or URDF file; defaults to the shipped asset. Ignored when ``xml`` is given.
    xml : str, optional
        MJCF (or URDF) text to compile instead of a file.
    actuated_joints : sequence of str, optional
        URDF only: the joints to drive (ctrl order), overriding the file's transmissions.

    Returns
    -------
    (mujoco.MjModel, str path, str xml)
        For a URDF, ``xml`` is the MJCF text, motors included, that recompiles to the model.
    """
    m, path, text, _ = _load(mjcf, xml=xml, actuated_joints=actuated_joints)
    return m, path, text


def mujoco_model(params: "CartPoleParams"):
    """Compile the MuJoCo model ``params`` were read from: the MJCF file where it is, else the XML text (for a URDF:
    the MJCF text with its added motors, never the URDF again, whose driven joints may have been chosen by the
    caller).

    Parameters
    ----------
    params : CartPoleParams

    Returns
    -------
    mujoco.MjModel
    """
    if params.mjcf and params.urdf is None and (Path(params.mjcf).is_file() or not params.xml):
        return load_model(params.mjcf)[0]
    return load_model(xml=params.xml)[0]  # a URDF's, or parameters whose file has moved: the text they were read from


def _urdf(text: str, path: str, actuated_joints):
    """(model, MJCF text, URDFImport) of a URDF, MuJoCo's warnings collected as for an MJCF."""
    try:
        with _compiler_warnings():
            return import_urdf(text, path, actuated_joints=actuated_joints)
    except URDFError as exc:
        raise MJCFError(str(exc)) from None


def _load(mjcf=None, *, xml=None, actuated_joints=None):
    """:func:`load_model` plus the :class:`URDFImport` of a URDF (None for an MJCF)."""
    if xml is not None:
        if is_urdf(xml):
            m, text, record = _urdf(xml, "", actuated_joints)
            return m, "", text, record
        if actuated_joints:
            raise MJCFError("actuated_joints chooses the driven joints of a URDF; this MJCF text declares its own "
                            "actuators, so drop actuated_joints.")
        try:
            with _compiler_warnings():
                return mujoco.MjModel.from_xml_string(xml), "", xml, None
        except Exception as exc:  # mujoco raises ValueError with a multi-line message
            raise MJCFError(f"The MJCF text does not compile: {first_line(exc, FOREIGN_WIDTH)}. "
                            "Fix the XML and try again.") from None

    try:  # by kind, before opening: a FIFO would block, /dev/zero never ends, a symbolic-link loop raises
        path = check_input_file(Path(mjcf) if mjcf is not None else SHIPPED_MJCF, what="MJCF file",
                                flag="`plant`")
    except InputFileError as exc:
        raise MJCFError(str(exc).replace("the path of a readable file", "the path of a cart-pole MJCF")) from None
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise MJCFError(f"MJCF file '{short(path)}' cannot be read as text ({type(exc).__name__}); pass `plant` with the "
                        "path of a cart-pole MJCF.") from None
    if is_urdf(text):
        m, mjcf_text, record = _urdf(text, str(path), actuated_joints)
        return m, str(path), mjcf_text, record
    if actuated_joints:
        raise MJCFError(f"MJCF file '{short(path)}' declares its own actuators; `actuated_joints` "
                        "chooses the driven joints of a URDF only, so drop it.")
    check_referenced_files(path, text)  # an <include> or asset naming a FIFO would block MuJoCo's reader forever
    try:
        with _compiler_warnings():
            model = mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:
        raise MJCFError(f"MJCF file '{short(path)}' does not compile: {first_line(exc, FOREIGN_WIDTH)}. "
                        "Fix the XML and try again.") from None
    return model, str(path), text, None


#: Most files an MJCF may pull in through nested <include> elements before it is refused (a loop of includes).
MAX_INCLUDES = 100


def check_referenced_files(path: Path, text: str) -> None:
    """Refuse, before MuJoCo opens them, files an MJCF names (``<include file>``, nested, and every asset's
    ``file`` attribute, resolved as MuJoCo does: includes beside the including file, assets under ``meshdir`` /
    ``texturedir`` / ``assetdir`` or beside the model) that are not regular files when they exist: a FIFO would
    block the reader forever, a device never end. Missing files and XML errors are left to MuJoCo's own sentence.

    Raises
    ------
    MJCFError
        A referenced file is a FIFO, a device, a directory, a socket or a loop of symbolic links, or the includes
        pull in more than :data:`MAX_INCLUDES` files.
    """
    root_dir = Path(path).parent
    todo, seen = [(Path(path), text)], 0
    while todo:
        where, body = todo.pop()
        if "file" not in body or len(body) > 32 * 2**20:  # nothing named, or too big to parse twice: MuJoCo's turn
            continue
        try:
            tree = ET.fromstring(body)
        except ET.ParseError:
            continue  # MuJoCo says what is wrong with the XML (expat also refuses entity amplification)
        comp = tree.find("compiler")
        dirs = {k: (comp.get(k) if comp is not None else None) for k in ("meshdir", "texturedir", "assetdir")}
        for el in tree.iter():
            name = el.get("file")
            if not name:
                continue
            if el.tag == "include":
                candidates = [where.parent / name]
            else:
                base = dirs.get("texturedir" if el.tag in ("texture", "hfield") else "meshdir") or dirs["assetdir"]
                candidates = [root_dir / base / name if base else root_dir / name, root_dir / name]
            for cand in candidates:
                if not os.path.lexists(cand):
                    continue
                try:
                    real = check_input_file(cand, what=f"The {el.tag} file")
                except InputFileError as exc:
                    raise MJCFError(f"MJCF file '{short(path)}' names {short(cand)} ({el.tag} file), which {exc.reason}; point it "
                                    "at a regular file.") from None
                if el.tag == "include":
                    seen += 1
                    if seen > MAX_INCLUDES:
                        raise MJCFError(f"MJCF file '{short(path)}' pulls in more than {MAX_INCLUDES} files through "
                                        "<include>; remove the loop of includes.")
                    try:
                        todo.append((real, real.read_text()))
                    except (OSError, UnicodeDecodeError):
                        pass  # MuJoCo says what is wrong with it
                break


@contextlib.contextmanager
def mujoco_warnings(handler: Callable[[str], None]):
    """Send MuJoCo's warnings to ``handler(message)`` (folded into one line) inside the block, instead of MuJoCo's
    default of a line on stderr and a MUJOCO_LOG.TXT file in the current directory; yields the handler that was
    installed before (None for MuJoCo's default) and puts it back afterwards."""
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: handler(" ".join(str(msg).split())))
    try:
        yield previous
    finally:
        mujoco.set_mju_user_warning(previous)


@contextlib.contextmanager
def _compiler_warnings():
    """MuJoCo's compiler warnings (e.g. "XML contains a 'NaN'") while compiling go to the handler already installed
    (the command line collects them), or else to Python's ``warnings``; never to MUJOCO_LOG.TXT."""
    caught: list[str] = []
    with mujoco_warnings(caught.append) as previous:
        yield
    for msg in dict.fromkeys(caught):
        if previous is not None:
            try:
                previous(msg)
            except ctypes.ArgumentError:  # a C callback (dm_control installs its own): it takes the text as bytes
                previous(msg.encode())
        else:
            warnings.warn(f"MuJoCo: {msg}", RuntimeWarning, stacklevel=3)


def _name(m, objtype, i: int, fallback: str) -> str:
    return mujoco.mj_id2name(m, objtype, i) or f"{fallback} {i}"


def _check_supported(m, where: str) -> None:
    """Refuse, with one sentence, everything MuJoCo would add that the smooth model does not model."""
    jt = mujoco.mjtJoint
    kinds = {int(jt.mjJNT_FREE): "free", int(jt.mjJNT_BALL): "ball", int(jt.mjJNT_SLIDE): "slide",
             int(jt.mjJNT_HINGE): "hinge"}
    types = [int(t) for t in m.jnt_type]
    if m.njnt == 0:
        raise MJCFError(f"{where} has no joints; {_SUPPORTED}.")
    bad = [t for t in types if t in (jt.mjJNT_FREE, jt.mjJNT_BALL)]
    if bad:
        found = ", ".join(f"{types.count(t)} {kinds[t]}" for t in sorted(set(types)))
        raise MJCFError(f"{where} has {found} joint(s); {_SUPPORTED}, without free or ball joints.")
    if m.nu == 0:
        raise MJCFError(f"{where} has no actuator; {_SUPPORTED}: add a <motor> on the cart's slide.")
    if m.ntendon:
        raise MJCFError(f"{where} has {m.ntendon} tendon(s); {_SUPPORTED}, without tendons.")
    if m.neq:
        raise MJCFError(f"{where} has {m.neq} equality constraint(s); {_SUPPORTED}, without equality constraints.")
    for i in range(m.nu):
        _check_actuator(m, i, where)
    for j in range(m.njnt):
        name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
        if m.jnt_actfrclimited[j]:
            raise MJCFError(f"{where} limits the actuator force on joint '{name}' (actuatorfrcrange); "
                            "the smooth model has no force clamp, so remove actuatorfrcrange.")
    if np.any(m.body_gravcomp != 0):
        b = int(np.flatnonzero(m.body_gravcomp)[0])
        raise MJCFError(f"{where} gives body '{_name(m, mujoco.mjtObj.mjOBJ_BODY, b, 'body')}' gravcomp; "
                        "the smooth model has no gravity compensation, so remove gravcomp.")
    if m.opt.density != 0 or m.opt.viscosity != 0 or np.any(np.asarray(m.opt.wind) != 0):
        raise MJCFError(f"{where} sets fluid forces (<option density, viscosity or wind>); the smooth model has "
                        "none, so remove them.")
    dis = int(m.opt.disableflags)
    flags = mujoco.mjtDisableBit
    if dis & flags.mjDSBL_ACTUATION:
        raise MJCFError(f"{where} disables actuation (<flag actuation=\"disable\"/>), so nothing can be "
                        "controlled; remove that flag.")
    if dis & flags.mjDSBL_CLAMPCTRL:
        raise MJCFError(f"{where} disables ctrl clamping (<flag clampctrl=\"disable\"/>), so ctrlrange would "
                        "not hold in MuJoCo; remove that flag.")
    # Contacts are not refused here by their masks: cartpole.models.contacts decides with MuJoCo's geometry which
    # pairs can touch, once the equilibrium is known (build_model refuses a pair in contact there).
    for field in _FINITE_FIELDS:
        if not field.startswith("opt.") and not hasattr(m, field):
            continue  # older MuJoCo has no actuator damping or armature
        values = np.asarray(getattr(m, field) if not field.startswith("opt.") else getattr(m.opt, field[4:]), float)
        if field in _INF_MEANS_NO_LIMIT:  # range="-inf inf": no limit on that side, as MuJoCo simulates it
            values = np.where(np.isinf(values), 0.0, values)
        if not np.all(np.isfinite(values)):
            raise MJCFError(f"{where} has a number that is not finite in {field} (nan or inf in the XML); "
                            "give every mass, size, position, axis, gear, range and option a finite value.")
    for i in range(m.nu):  # a ctrlrange so wide that full ctrl is no physical force (1e300) is a typo, refused
        if m.actuator_ctrllimited[i] and np.all(np.isfinite(m.actuator_ctrlrange[i])):
            reach = float(np.max(np.abs(m.actuator_ctrlrange[i]))) * abs(float(m.actuator_gainprm[i, 0])) \
                * float(np.max(np.abs(m.actuator_gear[i])))
            if reach > MAX_ACTUATOR_FORCE:
                raise MJCFError(f"{where} lets actuator '{_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i, 'actuator')}' "
                                f"ask for {reach:.3g} N (or N m: gain x gear x ctrlrange), more than the "
                                f"{MAX_ACTUATOR_FORCE:g} limit; give a ctrlrange and gear of a real motor.")
    integ = _INTEGRATOR_NAMES.get(int(m.opt.integrator))
    if integ is None:
        raise MJCFError(f"{where} uses integrator {int(m.opt.integrator)}; supported integrators are "
                        f"{', '.join(SUPPORTED_INTEGRATORS)}.")


def _check_actuator(m, i: int, where: str) -> None:
    """Refuse, with one sentence, an actuator whose force is not ``gain * ctrl + b0 + b1 length + b2 velocity``."""
    name = _name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i, "actuator")
    dyn, gain, bias = int(m.actuator_dyntype[i]), int(m.actuator_gaintype[i]), int(m.actuator_biastype[i])
    dcmotor = any(hasattr(t, n) and value == int(getattr(t, n)) for value, t, n in (
        (dyn, mujoco.mjtDyn, "mjDYN_DCMOTOR"), (gain, mujoco.mjtGain, "mjGAIN_DCMOTOR"),
        (bias, mujoco.mjtBias, "mjBIAS_DCMOTOR")))
    if m.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
        raise MJCFError(f"{where} has actuator '{name}' on something other than a joint; {_SUPPORTED}.")
    if dcmotor:
        raise MJCFError(f"{where} has actuator '{name}' of MuJoCo's dcmotor type, which the toolkit does not model; "
                        "for a DC motor whose current settles at once use <general> with gainprm=\"K/R\", "
                        "biastype=\"affine\" and biasprm=\"0 0 -K^2/R\" (back-EMF).")
    if dyn in (mujoco.mjtDyn.mjDYN_FILTER, mujoco.mjtDyn.mjDYN_FILTEREXACT, mujoco.mjtDyn.mjDYN_INTEGRATOR):
        kind = {int(mujoco.mjtDyn.mjDYN_FILTER): "filter", int(mujoco.mjtDyn.mjDYN_FILTEREXACT): "filterexact",
                int(mujoco.mjtDyn.mjDYN_INTEGRATOR): "integrator"}[dyn]
        raise MJCFError(f"{where} gives actuator '{name}' activation dynamics (dyntype {kind}, e.g. a timeconst or an "
                        "<intvelocity>), which adds an activation state the toolkit does not model yet (its state "
                        "is x = [qpos, qvel]); use a plain motor, or a <position>/<velocity> servo without timeconst.")
    if dyn != mujoco.mjtDyn.mjDYN_NONE:
        raise MJCFError(f"{where} gives actuator '{name}' activation dynamics (dyntype {dyn}), an extra state the "
                        f"toolkit does not model; {_SUPPORTED}, i.e. <motor>, <position>, <velocity> or <general> "
                        "without dyntype.")
    if gain != mujoco.mjtGain.mjGAIN_FIXED:
        raise MJCFError(f"{where} gives actuator '{name}' a gain that is not fixed (gaintype {gain}, e.g. <damper> "
                        "or a muscle); the toolkit models force = gain * ctrl + bias with a fixed gain, so use "
                        "<motor>, <position>, <velocity> or <general> with gaintype=\"fixed\".")
    if bias not in (mujoco.mjtBias.mjBIAS_NONE, mujoco.mjtBias.mjBIAS_AFFINE):
        raise MJCFError(f"{where} gives actuator '{name}' a bias that is not affine (biastype {bias}); the toolkit "
                        "models force = gain * ctrl + b0 + b1 * length + b2 * velocity, so use biastype=\"affine\".")
    delay = float(m.actuator_delay[i]) if hasattr(m, "actuator_delay") else 0.0
    if delay:
        raise MJCFError(f"{where} delays actuator '{name}' by {delay:g} s inside MuJoCo; the toolkit's model acts "
                        "at once, so remove the actuator's delay (the rig's `delay` models one).")
    if m.actuator_forcelimited[i]:
        # MuJoCo clamps the actuator force gain * ctrl + bias, before the transmission multiplies it by gear.
        lo, hi = m.actuator_forcerange[i]
        b = m.actuator_biasprm[i, :3] if bias == mujoco.mjtBias.mjBIAS_AFFINE else np.zeros(3)
        if b[1] or b[2]:
            raise MJCFError(f"{where} clamps actuator '{name}' to forcerange [{lo:g}, {hi:g}] while its force "
                            "depends on the state (biasprm), so the clamp can bite; the smooth model has no clamp, "
                            "so remove forcerange.")
        g = float(m.actuator_gainprm[i, 0])
        clo, chi = m.actuator_ctrlrange[i] if m.actuator_ctrllimited[i] else (-np.inf, np.inf)
        with np.errstate(invalid="ignore"):
            reach = sorted([g * clo + b[0], g * chi + b[0]])
        if not (reach[0] >= lo and reach[1] <= hi):
            raise MJCFError(f"{where} clamps actuator '{name}' to forcerange [{lo:g}, {hi:g}] inside what its "
                            f"ctrlrange can ask for ([{reach[0]:g}, {reach[1]:g}] before the gear); the smooth model "
                            "has no clamp, so remove forcerange or narrow ctrlrange to match it.")


#: Largest force (N, or torque N m) an actuator's full ctrl may ask for: gain x gear x max |ctrlrange|; far beyond any
#: real rig (the lab's motor: 20 N), so that a ctrlrange of 1e300 is refused rather than simulated into overflow.
MAX_ACTUATOR_FORCE = 1e6


#: Compiled fields the model reads that must hold finite numbers (joint and ctrl ranges may be infinite only when
#: unlimited, which MuJoCo stores as zeros, so they are checked too).
_FINITE_FIELDS = ("opt.gravity", "opt.timestep", "body_pos", "body_quat", "body_mass", "body_ipos", "body_iquat",
                  "body_inertia", "jnt_pos", "jnt_axis", "jnt_range", "jnt_stiffness", "qpos0", "qpos_spring",
                  "dof_damping", "dof_armature", "dof_frictionloss", "actuator_gear", "actuator_gainprm",
                  "actuator_biasprm", "actuator_ctrlrange", "actuator_forcerange", "actuator_damping",
                  "actuator_armature")


#: Range fields where an infinite bound means "no limit on that side" (``range="-inf inf"``, limited or not): only
#: nan is refused there. :func:`read_params` reads an infinite side as unlimited.
_INF_MEANS_NO_LIMIT = ("jnt_range", "actuator_ctrlrange", "actuator_forcerange")


def read_params(mjcf: str | Path | None = None, *, xml: str | None = None,
                actuated_joints: Sequence[str] | None = None) -> CartPoleParams:
    """Read the parameters of a cart-pole MJCF from its compiled ``MjModel``.

    Accepts a kinematic tree of slide and hinge joints (typically one slide, the cart, carrying a chain of
    1..n hinged poles; also a pendulum or an acrobot-like chain without a cart), any number of bodies and
    geoms, each body's compiled mass, centre of mass and full inertia, joint positions, axes, references,
    damping, armature, stiffness, limits and frictionloss, driven by one or more actuators on any of those
    joints: ``<motor>``, ``<position>`` and ``<velocity>`` servos (without ``timeconst``), ``<general>`` with a
    fixed gain and no or an affine bias (e.g. a DC motor's back-EMF), with MuJoCo's actuator damping and armature,
    with any (also asymmetric) ctrlrange; integrators Euler, RK4, implicit and implicitfast; gravity, dampers,
    springs and frictionloss may be disabled. Refused, with one sentence naming it and the fix: free and ball
    joints, tendons, equality constraints, actuators with an activation state (dyntype filter, filterexact,
    integrator, ...), state-dependent gains, non-affine biases, actuator delays, force clamps that can bite,
    gravity compensation, fluid forces. Geoms that may collide are accepted here; :func:`cartpole.models.build_model`
    refuses a pair in contact at the upright equilibrium (:mod:`cartpole.models.contacts`).

    Parameters
    ----------
    mjcf : path, optional
        MJCF file; defaults to the shipped asset (``cartpole/assets/cartpole.xml``).
    xml : str, optional
        MJCF text instead of a file.
    actuated_joints : sequence of str, optional
        URDF only: the joints its motors drive, in ctrl order, overriding its ``<transmission>`` elements (default:
        the transmissions, else the only prismatic joint; see :mod:`cartpole.models.urdf`).

    Returns
    -------
    CartPoleParams
        For a URDF, ``urdf`` records the motors added and ``xml`` is the MJCF text MuJoCo runs.

    Raises
    ------
    MJCFError
        With one sentence naming what was found and what is supported.
    """
    m, path, text, urdf = _load(mjcf, xml=xml, actuated_joints=actuated_joints)
    where = (f"{'URDF' if urdf else 'MJCF'} '{short(path)}'" if path else f"The {'URDF' if urdf else 'MJCF'}")
    _check_supported(m, where)

    # Moving bodies: those with a joint somewhere on their path to the world.
    weld = m.body_weldid
    moving = [b for b in range(1, m.nbody) if weld[b] != 0]
    index = {b: i for i, b in enumerate(moving)}
    dis = int(m.opt.disableflags)
    flags = mujoco.mjtDisableBit
    no_damper, no_spring = bool(dis & flags.mjDSBL_DAMPER), bool(dis & flags.mjDSBL_SPRING)
    no_friction = bool(dis & (flags.mjDSBL_FRICTIONLOSS | flags.mjDSBL_CONSTRAINT))

    bodies = []
    d = None
    for b in moving:
        parent = int(m.body_parentid[b])
        if parent in index:
            pos, quat, pidx = m.body_pos[b], m.body_quat[b], index[parent]
        elif parent == 0:
            pos, quat, pidx = m.body_pos[b], m.body_quat[b], -1
        else:  # parent welded to the world: express this body's frame in the world
            if d is None:
                d = mujoco.MjData(m)
                mujoco.mj_kinematics(m, d)
            pos, quat, pidx = _world_frame_of_static(m, d, parent, b)
        jids = tuple(range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])) if m.body_jntnum[b] else ()
        bodies.append(BodyParams(
            name=_name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body"), parent=pidx, pos=readonly(pos),
            quat=readonly(quat), mass=float(m.body_mass[b]), ipos=readonly(m.body_ipos[b]),
            iquat=readonly(m.body_iquat[b]), inertia=readonly(m.body_inertia[b]), joints=jids))

    joints = []
    for j in range(m.njnt):
        kind = "slide" if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE else "hinge"
        dof, qadr = int(m.jnt_dofadr[j]), int(m.jnt_qposadr[j])
        joints.append(JointParams(
            name=_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint"), kind=kind, body=index[int(m.jnt_bodyid[j])],
            pos=readonly(m.jnt_pos[j]), axis=readonly(m.jnt_axis[j]), qpos0=float(m.qpos0[qadr]),
            damping=0.0 if no_damper else float(m.dof_damping[dof]), armature=float(m.dof_armature[dof]),
            stiffness=0.0 if no_spring else float(m.jnt_stiffness[j]), springref=float(m.qpos_spring[qadr]),
            range=readonly(m.jnt_range[j] if m.jnt_limited[j] else [-np.inf, np.inf]),
            frictionloss=0.0 if no_friction else float(m.dof_frictionloss[dof])))

    actuators = _actuators(m, no_damper)
    raw_g = np.array(m.opt.gravity, dtype=float)
    up = -raw_g / np.linalg.norm(raw_g) if np.linalg.norm(raw_g) > 0 else np.array([0.0, 0.0, 1.0])
    gravity = np.zeros(3) if dis & flags.mjDSBL_GRAVITY else raw_g
    return CartPoleParams(
        mjcf=path, xml=text, timestep=float(m.opt.timestep), integrator=_INTEGRATOR_NAMES[int(m.opt.integrator)],
        euler_damping_implicit=not bool(dis & flags.mjDSBL_EULERDAMP), gravity=readonly(gravity), up=readonly(up),
        joints=tuple(joints), bodies=tuple(bodies), actuators=tuple(actuators), urdf=urdf)


def _actuators(m, no_damper: bool) -> list:
    """The :class:`ActuatorParams` of every actuator of the compiled ``m`` (actuator damping left out when the
    MJCF disables dampers)."""
    actuators = []
    for i in range(m.nu):
        lim = bool(m.actuator_ctrllimited[i])
        affine = m.actuator_biastype[i] == mujoco.mjtBias.mjBIAS_AFFINE
        act_damping = float(m.actuator_damping[i]) if hasattr(m, "actuator_damping") and not no_damper else 0.0
        act_armature = float(m.actuator_armature[i]) if hasattr(m, "actuator_armature") else 0.0
        actuators.append(ActuatorParams(
            name=_name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i, "actuator"), joint=int(m.actuator_trnid[i, 0]),
            gear=float(m.actuator_gear[i, 0] * m.actuator_gainprm[i, 0]),
            ctrl_range=readonly(m.actuator_ctrlrange[i] if lim else [-np.inf, np.inf]),
            transmission=float(m.actuator_gear[i, 0]), gain=float(m.actuator_gainprm[i, 0]),
            bias=readonly(m.actuator_biasprm[i, :3] if affine else np.zeros(3)),
            damping=act_damping, armature=act_armature))
    return actuators


def _world_frame_of_static(m, d, parent: int, b: int):
    """World position and orientation of body ``b``'s frame when its parent is fixed to the world."""
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, d.xquat[parent], m.body_quat[b])
    pos = d.xpos[parent] + d.xmat[parent].reshape(3, 3) @ m.body_pos[b]
    return pos, quat, -1
