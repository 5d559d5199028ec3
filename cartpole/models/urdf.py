"""URDF cart-poles: the motors a URDF's ``<transmission>`` (or its one prismatic joint) implies, added through MjSpec.

MuJoCo compiles a URDF (root element ``<robot>``) but drops its ``<transmission>`` elements, so a URDF cart-pole
arrives without actuators, and a URDF cannot hold a ``<motor>``. This module reads what MuJoCo drops, with
``xml.etree`` on the raw text, and adds one motor per driven joint through :class:`mujoco.MjSpec`:

* **Which joints.** ``actuated_joints=`` (the command line's ``--actuated-joint NAME``, repeatable) when given:
  it overrides everything below. Otherwise every joint named by a ``SimpleTransmission``, in both dialects:
  ROS (``<transmission><type>transmission_interface/SimpleTransmission</type><joint name><hardwareInterface>
  <actuator><mechanicalReduction>``) and Drake (``<transmission type="SimpleTransmission"><actuator name/>
  <joint name/><mechanicalReduction/>``), and ROS 2's ``<ros2_control>`` joints with an ``effort`` command
  interface. A URDF with none of these: its only prismatic joint, when it has exactly one (the cart-pole
  convention of Bullet's and Isaac Gym's ``cartpole.urdf``, which drive the cart from code); else refused in one
  sentence naming the option that chooses.
* **What a motor is.** MuJoCo's ``<general>`` with a fixed gain of 1 and ``gear = 1``: ``ctrl`` is the joint's own
  force in N (prismatic) or torque in N m (revolute, continuous), whatever the transmission's
  ``mechanicalReduction`` (recorded, not applied: the reduction scales the *motor's* torque, and a URDF gives no
  rotor inertia that would make it matter to the dynamics; a joint force in N keeps ``R`` and ``ctrlrange`` in the
  units a control engineer reads). The ctrl range is the joint's ``<limit effort>`` (``+-effort``); no effort, or
  an effort of 0 or one above :data:`EFFORT_AS_UNLIMITED` (a placeholder such as ``1e30``), leaves the motor
  unlimited. MuJoCo's URDF reader turns ``effort`` into the joint's
  ``actuatorfrcrange``; that clamp is cleared (on a driven joint the ctrl range carries the same bound, on an
  undriven one it clamps nothing).
* **What MuJoCo's reader keeps.** ``<dynamics damping friction>`` become the joint's ``damping`` and
  ``frictionloss``; ``<limit lower upper>`` its range (a ``continuous`` joint is an unlimited hinge); the root link
  is welded to the world (a fixed base, as every cart-pole has; a link called ``world`` with a fixed joint is the
  same); links without a moving joint are fused into their parent (``fusestatic``), ``<visual>`` elements are
  discarded (``discardvisual``: the video shows the collision geometry), unless the file's own
  ``<mujoco><compiler>`` says otherwise. Inertias are read from the compiled model, never from this text.
* **Quirks made to load.** ``package://`` and ``file://`` mesh names resolved to files (the package found above the
  URDF or on ``ROS_PACKAGE_PATH``); a missing *visual* mesh is dropped (visuals change no dynamics), a missing
  *collision* mesh refused naming the file; an ``<inertial>`` without ``<inertia>`` read as a point mass (as
  Bullet, Isaac Gym and Drake read it) and principal inertias below MuJoCo's minimum raised to
  :data:`MIN_INERTIA` (``boundinertia``); principal moments no body has (the largest above the sum of the other
  two, as Drake's cart-pole gives its rod a moment only about the hinge), mended by raising the moments across the
  link's hinge axis, which leaves a planar chain's motion exactly the file's (refused naming the link when no such
  change mends them); an ``<inertia>`` without its products read with them 0; a joint hung from an undeclared link
  ``world`` hung from the world (as Drake reads it); contacts between a link welded to the world and its child are
  excluded, as Bullet, Gazebo and Drake keep adjacent links of one robot apart (MuJoCo filters only a moving parent).
  Each change is said in one sentence (:attr:`URDFImport.changes`).

The result is an MJCF text (``MjSpec.to_xml``, mesh paths absolute) that recompiles to the same model anywhere:
:func:`cartpole.models.read_params` keeps it as ``CartPoleParams.xml`` and the record as ``CartPoleParams.urdf``.
"""
from __future__ import annotations

import contextlib
import os
import re
import xml.parsers.expat
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Sequence
from xml.etree import ElementTree as ET

import mujoco
import numpy as np

from cartpole._arrays import readonly
from cartpole._files import InputFileError, check_input_file, short
from cartpole.errors import CartPoleError, first_line

#: Principal moment of inertia (kg m^2) a link below MuJoCo's minimum is raised to (``<compiler boundinertia>``):
#: a point mass or an infinitely thin rod, which MuJoCo refuses. 1e-12 kg m^2 beside a 1 kg pole of 0.5 m (m l^2 =
#: 0.25 kg m^2) changes its inertia about the hinge by 4e-12 relative.
MIN_INERTIA = 1e-12

#: An effort limit (N or N m) above this is a placeholder for "no limit" (``effort="1e30"``), read as unlimited:
#: beyond it the toolkit refuses a ctrl range as no real motor (:data:`cartpole.models.params.MAX_ACTUATOR_FORCE`).
EFFORT_AS_UNLIMITED = 1e6

#: MuJoCo's mjMINVAL: the smallest mass and principal inertia it accepts on a moving body.
_MJ_MINVAL = 1e-15

_MOVABLE = {"prismatic": "slide", "revolute": "hinge", "continuous": "hinge"}


class URDFError(CartPoleError):
    """A URDF that cannot become a cart-pole: an ambiguous or unknown driven joint, a missing collision mesh, a
    transmission the toolkit cannot model, or a file MuJoCo's URDF reader refuses."""


@dataclass(frozen=True)
class AddedActuator:
    """One motor added to a URDF joint (MuJoCo's ``<general>``, gain 1, ``gear = 1``: ctrl is the joint's force).

    Attributes
    ----------
    name : str
        Actuator name in the compiled model (the transmission's ``<actuator name>``, else ``<joint>_motor``).
    joint : str
        The URDF joint it drives.
    joint_type : str
        ``"prismatic"``, ``"revolute"`` or ``"continuous"``.
    gear : float
        Generalized force per unit ctrl: 1 (N per unit ctrl on a prismatic joint, N m on a hinge).
    ctrl_range : (2,) array
        ``[-effort, effort]`` in N or N m, ``(-inf, inf)`` when the joint gives no effort limit (or 0).
    source : str
        ``"actuated_joints"`` (chosen by the caller), ``"transmission"``, ``"ros2_control"`` or
        ``"single_prismatic"`` (no transmission; the only prismatic joint).
    transmission : str or None
        Name of the ``<transmission>`` (or ``<ros2_control>``) element it came from.
    mechanical_reduction : float or None
        The transmission's ``mechanicalReduction`` (recorded, not applied: see the module docstring).
    interface : str or None
        The ROS ``hardwareInterface`` (or ROS 2 command interface) the transmission names.
    effort : float or None
        The joint's ``<limit effort>`` in N or N m (None when absent).
    """

    name: str
    joint: str
    joint_type: str
    gear: float
    ctrl_range: np.ndarray
    source: str
    transmission: str | None = None
    mechanical_reduction: float | None = None
    interface: str | None = None
    effort: float | None = None

    @property
    def unit(self) -> str:
        """``"N"`` on a prismatic joint, ``"N m"`` on a hinge."""
        return "N" if self.joint_type == "prismatic" else "N m"

    def sentence(self) -> str:
        """What was added and why, in one sentence."""
        why = {"actuated_joints": "chosen by the caller",
               "transmission": f"from <transmission> '{self.transmission}'",
               "ros2_control": f"from <ros2_control> '{self.transmission}' (effort command interface)",
               "single_prismatic": "the file has no <transmission> and this is its only prismatic joint, the cart"
               }[self.source]
        lo, hi = self.ctrl_range
        if np.isfinite(lo) or np.isfinite(hi):
            rng = f"ctrlrange [{lo:g}, {hi:g}] {self.unit} (the joint's effort limit)"
        else:
            rng = "unlimited (the joint gives no effort limit)"
        extra = ""
        if self.mechanical_reduction not in (None, 1.0):
            extra += f"; its mechanicalReduction {self.mechanical_reduction:g} is recorded, not applied"
        if self.interface and "effort" not in self.interface.lower():
            extra += f"; its {self.interface} is driven as a force, as the toolkit's controllers need"
        return (f"added motor '{self.name}' on {self.joint_type} joint '{self.joint}' ({why}): ctrl is its "
                f"{'force in N' if self.unit == 'N' else 'torque in N m'}, {rng}{extra}.")

    def to_dict(self) -> dict:
        """JSON-ready fields (an unlimited range as ``null`` bounds)."""
        lo, hi = (float(v) for v in self.ctrl_range)
        return {"actuator": self.name, "joint": self.joint, "joint_type": self.joint_type, "gear": self.gear,
                "ctrlrange": [lo if np.isfinite(lo) else None, hi if np.isfinite(hi) else None],
                "unit": self.unit, "source": self.source, "transmission": self.transmission,
                "mechanical_reduction": self.mechanical_reduction, "interface": self.interface,
                "effort": self.effort, "sentence": self.sentence()}


@dataclass(frozen=True)
class URDFImport:
    """What reading a URDF added and changed (kept as :attr:`cartpole.models.CartPoleParams.urdf`).

    Attributes
    ----------
    path : str
        Absolute path of the URDF ("" for URDF text).
    actuators : tuple of :class:`AddedActuator`
        The motors added, in actuator (ctrl) order.
    changes : tuple of str
        One sentence per other change made so that MuJoCo loads the file (meshes resolved or dropped, point
        masses, excluded adjacent contacts).
    mjcf : str
        The MJCF text MuJoCo runs: the URDF as MuJoCo reads it with the motors added (``MjSpec.to_xml``).
    """

    path: str
    actuators: tuple
    changes: tuple = ()
    mjcf: str = field(default="", repr=False, compare=False)

    def sentences(self) -> list:
        """Every added motor and change, one sentence each, starting with the file."""
        where = f"URDF '{short(self.path)}'" if self.path else "URDF text"
        return [f"{where}: {s}" for s in [a.sentence() for a in self.actuators] + [c + "." for c in self.changes]]

    def to_dict(self) -> dict:
        """JSON-ready: ``file``, ``actuators_added`` (one object per motor), ``changes`` (sentences)."""
        return {"file": self.path, "actuators_added": [a.to_dict() for a in self.actuators],
                "changes": list(self.changes)}


# ---- the command line's choice, and what was read (cartpole.cli sets both around a command) -------------------
@dataclass
class _Session:
    actuated_joints: tuple | None
    option: str
    imports: list


_SESSION: ContextVar = ContextVar("cartpole_urdf_session", default=None)


@contextlib.contextmanager
def urdf_session(actuated_joints: Sequence[str] | None = None, *,
                 option: str = "actuated_joints=[...]") -> Iterator[list]:
    """Inside the block, URDFs read without an explicit ``actuated_joints=`` drive ``actuated_joints`` (None: what
    the file says), sentences name ``option`` as the way to choose (the command line passes
    ``"--actuated-joint NAME"``), and every :class:`URDFImport` made is appended to the list the block receives.

    Parameters
    ----------
    actuated_joints : sequence of str, optional
        Joint names to drive, overriding transmissions.
    option : str
        How a sentence names the choice to the reader.

    Yields
    ------
    list of URDFImport
    """
    session = _Session(tuple(actuated_joints) if actuated_joints else None, option, [])
    token = _SESSION.set(session)
    try:
        yield session.imports
    finally:
        _SESSION.reset(token)


# ---- reading ----------------------------------------------------------------------------------------------------
def _parse_raw(text: str) -> ET.Element:
    """The XML as an ElementTree without namespace processing: ``<drake:joint>`` keeps its prefix (MuJoCo's reader
    sees the same names), a Drake default ``xmlns`` stays an attribute."""
    builder = ET.TreeBuilder()
    parser = xml.parsers.expat.ParserCreate()
    parser.buffer_text = True
    parser.StartElementHandler = builder.start
    parser.EndElementHandler = builder.end
    parser.CharacterDataHandler = builder.data
    parser.Parse(text, True)
    return builder.close()


def is_urdf(text: str) -> bool:
    """True when ``text`` is XML whose root element is ``<robot>`` (a URDF), as MuJoCo decides.

    Parameters
    ----------
    text : str

    Returns
    -------
    bool
    """
    if "robot" not in text:
        return False
    head = _PROLOG.match(text)
    rest = text[head.end():] if head else text
    root = re.match(r"<([\w:.-]+)", rest)
    return bool(root) and root.group(1) == "robot"  # as MuJoCo decides: the root element named robot


#: What may come before the root element: an XML declaration, comments, processing instructions, a DOCTYPE, blanks.
_PROLOG = re.compile(r"(?:\ufeff)?(?:\s+|<\?.*?\?>|<!--.*?-->|<!DOCTYPE[^>\[]*(?:\[.*?\])?\s*>)*", re.S)


def _local(tag: str) -> str:
    return tag.rsplit(":", 1)[-1].lower()


def _children(el, name: str) -> list:
    return [c for c in el if _local(c.tag) == name]


def _child(el, name: str):
    found = _children(el, name)
    return found[0] if found else None


def _text(el) -> str:
    return (el.text or "").strip() if el is not None else ""


def _float(text, what: str, where: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        raise URDFError(f"{where} gives {what} '{text}', which is not a number; write a number there.") from None


@dataclass(frozen=True)
class _Joint:
    name: str
    kind: str
    parent: str
    child: str
    effort: float | None
    axis: np.ndarray  # (3,) unit axis in the child link's frame (URDF's default 1 0 0)
    rotation: np.ndarray  # (3, 3) the child link's frame in the parent's (<origin rpy>)


@dataclass(frozen=True)
class _Drive:
    joint: str
    source: str
    transmission: str | None = None
    actuator: str | None = None
    reduction: float | None = None
    interface: str | None = None


def _joints(robot, where: str) -> dict:
    out = {}
    for el in _children(robot, "joint"):
        name, kind = el.get("name", ""), (el.get("type") or "").lower()
        parent, child = _child(el, "parent"), _child(el, "child")
        limit = _child(el, "limit")
        effort = None
        if limit is not None and limit.get("effort") is not None:
            effort = abs(_float(limit.get("effort"), f"joint '{name}' an effort limit", where))
        axis_el = _child(el, "axis")
        axis = _vector(axis_el.get("xyz") if axis_el is not None else None, "1 0 0", f"joint '{name}' an axis", where)
        norm = float(np.linalg.norm(axis))
        out[name] = _Joint(name, kind, parent.get("link", "") if parent is not None else "",
                           child.get("link", "") if child is not None else "", effort,
                           axis / norm if norm > 0 else axis, _rpy(el, f"joint '{name}'", where))
    return out


def _vector(text, default: str, what: str, where: str) -> np.ndarray:
    """Three numbers of a URDF attribute (``default`` when absent), or one URDFError sentence."""
    parts = (text or default).split()
    if len(parts) != 3:
        raise URDFError(f"{where} gives {what} '{text}', which is not three numbers; write three numbers there.")
    return np.array([_float(v, what, where) for v in parts])


def _rpy(el, owner: str, where: str) -> np.ndarray:
    """(3, 3) rotation of ``el``'s ``<origin rpy>`` (roll, pitch, yaw about the fixed axes, as MuJoCo's URDF reader
    turns it: Euler sequence ``XYZ``), the identity when absent."""
    origin = _child(el, "origin")
    rpy = _vector(origin.get("rpy") if origin is not None else None, "0 0 0", f"{owner} an origin rpy", where)
    quat, mat = np.zeros(4), np.zeros(9)
    mujoco.mju_euler2Quat(quat, rpy, "XYZ")
    mujoco.mju_quat2Mat(mat, quat)
    return mat.reshape(3, 3)


def _transmissions(robot, where: str) -> list:
    """Every SimpleTransmission (ROS and Drake dialects) and ROS 2 effort interface, as drives."""
    drives = []
    for tr in _children(robot, "transmission"):
        name = tr.get("name") or "unnamed"
        kind = tr.get("type") or _text(_child(tr, "type"))
        joints = _children(tr, "joint")
        if kind.rsplit("/", 1)[-1] != "SimpleTransmission" or len(joints) != 1:
            raise URDFError(f"{where} has <transmission> '{name}' of type '{kind or 'none'}' on {len(joints)} "
                            "joint(s), not a SimpleTransmission on one joint; choose the driven joints with OPTION.")
        act = _child(tr, "actuator")
        red_el = _child(act, "mechanicalreduction") if act is not None else None
        if red_el is None:
            red_el = _child(tr, "mechanicalreduction")
        reduction = _float(_text(red_el), f"<transmission> '{name}' a mechanicalReduction", where) \
            if red_el is not None and _text(red_el) else None
        iface = _child(joints[0], "hardwareinterface")
        if iface is None and act is not None:
            iface = _child(act, "hardwareinterface")
        drives.append(_Drive(joints[0].get("name", ""), "transmission", name,
                             act.get("name") if act is not None else None, reduction,
                             _text(iface).rsplit("/", 1)[-1] or None))
    for rc in _children(robot, "ros2_control"):
        for j in _children(rc, "joint"):
            if any((c.get("name") or "").lower() == "effort" for c in _children(j, "command_interface")):
                drives.append(_Drive(j.get("name", ""), "ros2_control", rc.get("name") or "ros2_control",
                                     interface="effort"))
    return drives


def _choose(joints: dict, drives: list, chosen, option: str, where: str) -> list:
    movable = [n for n, j in joints.items() if j.kind in _MOVABLE]
    listed = ", ".join(f"'{n}'" for n in movable) or "none"
    if chosen:
        out = []
        for name in dict.fromkeys(chosen):
            if name not in joints or joints[name].kind not in _MOVABLE:
                what = f"is a {joints[name].kind} joint" if name in joints else "is not a joint"
                raise URDFError(f"Joint '{name}' {what} of {where}; give {option} with one of its movable joints "
                                f"({listed}).")
            out.append(_Drive(name, "actuated_joints"))
        return out
    if drives:
        out, seen = [], set()
        for d in drives:
            if d.joint not in joints or joints[d.joint].kind not in _MOVABLE:
                what = f"{joints[d.joint].kind} joint" if d.joint in joints else "joint that it does not have"
                raise URDFError(f"{where} drives {what} '{d.joint}' in <{d.source}> '{d.transmission}'; fix the "
                                f"name, or choose with {option} ({listed}).")
            if d.joint not in seen:
                seen.add(d.joint)
                out.append(d)
        return out
    prismatic = [n for n in movable if joints[n].kind == "prismatic"]
    if len(prismatic) == 1:
        return [_Drive(prismatic[0], "single_prismatic")]
    found = (f"{len(prismatic)} prismatic joints ({', '.join(repr(n) for n in prismatic)})" if prismatic
             else "no prismatic joint (no cart)")
    raise URDFError(f"{where} has no <transmission> and {found}; name the joint to drive with {option} "
                    f"(movable joints: {listed}).")


def _package_candidates(uri: str, base: Path) -> list:
    pkg, _, rest = uri[len("package://"):].partition("/")
    out = []
    for anc in [base, *base.parents]:
        if anc.name == pkg:
            out.append(anc / rest)
        out.append(anc / pkg / rest)
    for root in filter(None, os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)):
        out += [Path(root) / pkg / rest, Path(root) / rest]
    out += [base / rest, base / Path(rest).name]
    return out


def _resolve_mesh(name: str, base: Path, meshdir: str | None, strippath: bool) -> Path | None:
    """The existing file a URDF mesh name means, or None."""
    if name.startswith("file://"):
        name = name[len("file://"):]
    if name.startswith("package://"):
        candidates = _package_candidates(name, base)
    else:
        mdir = (base / meshdir) if meshdir else base
        p = Path(Path(name).name if strippath else name)
        candidates = [p] if p.is_absolute() else [mdir / p, base / p]
    for cand in candidates:
        if os.path.lexists(cand):
            return cand
    return None


def _fix_meshes(robot, compiler, base: Path, where: str, changes: list) -> None:
    meshdir = compiler.get("meshdir") or compiler.get("assetdir")
    strippath = (compiler.get("strippath") or "false").lower() == "true"
    discard = (compiler.get("discardvisual") or "true").lower() == "true"
    for link in _children(robot, "link"):
        for kind in ("visual", "collision"):
            for el in list(_children(link, kind)):
                geom = _child(el, "geometry")
                mesh = _child(geom, "mesh") if geom is not None else None
                if mesh is None or not mesh.get("filename"):
                    continue
                name = mesh.get("filename")
                found = _resolve_mesh(name, base, meshdir, strippath)
                if found is None and kind == "visual":
                    link.remove(el)
                    if not discard:
                        changes.append(f"visual mesh '{name}' of link '{link.get('name')}' was not found and is "
                                       "left out (visuals change no dynamics)")
                    continue
                if found is None:
                    raise URDFError(f"{where} gives link '{link.get('name')}' collision mesh '{name}', which is not "
                                    f"found beside the URDF{' or under its package' if 'package://' in name else ''}"
                                    "; put the mesh there (or the package on ROS_PACKAGE_PATH) or replace it with a "
                                    "<box>, <cylinder> or <sphere>.")
                try:
                    real = check_input_file(found, what=f"Mesh file of link '{link.get('name')}'")
                except InputFileError as exc:
                    raise URDFError(str(exc)) from None
                mesh.set("filename", str(real))
                if name.startswith(("package://", "file://")):
                    changes.append(f"{kind} mesh '{name}' of link '{link.get('name')}' read from {short(real)}")
    compiler.set("strippath", "false")
    if meshdir is not None:
        compiler.attrib.pop("meshdir", None)


def _rotation_axes(joints: dict) -> dict:
    """Each link's hinge axes: link name -> unit axes (in the link's frame) of every revolute or continuous joint
    between it and the root (``joints`` as :func:`_joints` reads them), the directions its angular velocity can take."""
    by_child = {j.child: j for j in joints.values() if j.child}
    out = {}
    for link in {j.child for j in joints.values()} | {j.parent for j in joints.values()}:
        name, axes, rot, seen = link, [], np.eye(3), set()
        while name in by_child and name not in seen:  # up the tree: rot maps this link's frame into the current one
            seen.add(name)
            j = by_child[name]
            if j.kind in ("revolute", "continuous"):
                axes.append(rot.T @ j.axis)  # the joint's axis is in its child's frame
            rot = j.rotation @ rot
            name = j.parent
        out[link] = axes
    return out


def _keep_hinge_moment(tensor: np.ndarray, axes: list) -> np.ndarray | None:
    """``tensor`` (3, 3) kg m^2 made a body's inertia (every principal moment at most the sum of the other two) by
    adding ``lam (E - n n')``, a rod along ``n``: the moment about ``n`` is unchanged, so where the link only ever
    turns about ``n`` (every hinge between it and the root parallel to ``n``) the dynamics are the same. None when no
    such rod can mend it (the hinges are not parallel, or the excess is about another axis)."""
    second = 0.5 * np.trace(tensor) * np.eye(3) - tensor  # the mass's second moment: PSD for any body
    if axes:
        n = axes[0]
        if any(np.linalg.norm(np.cross(n, a)) > 1e-9 for a in axes[1:]):
            return None
    else:  # the link never turns: any axis keeps its dynamics; the one along the excess mends it least
        n = np.linalg.eigh(second)[1][:, 0]
    basis = np.linalg.svd(np.eye(3) - np.outer(n, n))[0][:, :2]  # the plane across n
    across, mixed, along = basis.T @ second @ basis, basis.T @ second @ n, n @ second @ n
    scale = max(np.abs(second).max(), _MJ_MINVAL)
    w, v = np.linalg.eigh(across)
    if w.min() < -1e-12 * scale:
        return None
    proj = v.T @ mixed
    if np.any((w <= 1e-12 * scale) & (np.abs(proj) > 1e-9 * scale)):
        return None
    need = float(np.sum(np.where(w > 1e-12 * scale, proj ** 2 / np.where(w > 0, w, 1.0), 0.0)) - along)
    lam = max(need, 0.0) * (1 + 1e-9) + 1e-9 * scale  # MuJoCo's A + B >= C has no tolerance
    return tensor + lam * (np.eye(3) - np.outer(n, n))


def _is_body_inertia(tensor: np.ndarray) -> bool:
    d = np.linalg.eigvalsh(tensor)
    return bool(d[0] + d[1] >= d[2])


def _fix_inertia(robot, joints: dict, compiler, where: str, changes: list) -> None:
    small, mended = [], []
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    axes = None
    for link in _children(robot, "link"):
        inertial = _child(link, "inertial")
        if inertial is None:
            continue
        name = link.get("name")
        inertia = _child(inertial, "inertia")
        if inertia is None:
            inertia = ET.SubElement(inertial, "inertia", {k: "0" for k in keys})
            changes.append(f"link '{name}' has an <inertial> without <inertia>, read as a point mass (as Bullet, "
                           "Isaac Gym and Drake read it)")
        missing = [k for k in keys if inertia.get(k) is None]
        if missing:
            for k in missing:
                inertia.set(k, "0")
            changes.append(f"link '{name}' gives <inertia> without {', '.join(missing)}, read as 0")
        mass_el = _child(inertial, "mass")
        mass = _float(mass_el.get("value", "0"), f"link '{name}' a mass", where) if mass_el is not None else 0.0
        v = {k: _float(inertia.get(k), f"link '{name}' an inertia {k}", where) for k in keys}
        tensor = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                           [v["ixz"], v["iyz"], v["izz"]]])
        if mass <= 0 or not np.all(np.isfinite(tensor)):
            continue
        if not _is_body_inertia(tensor):
            axes = _rotation_axes(joints) if axes is None else axes
            rot = _rpy(inertial, f"link '{name}'", where)  # the inertia's frame in the link's
            fixed = _keep_hinge_moment(tensor, [rot.T @ a for a in axes.get(name, [])])
            if fixed is None:
                d = np.linalg.eigvalsh(tensor)
                raise URDFError(f"{where} gives link '{name}' principal moments of inertia {d[0]:.4g}, {d[1]:.4g} "
                                f"and {d[2]:.4g} kg m^2, which no body has (the largest above the sum of the other "
                                "two), and no change that keeps its inertia about its hinge mends them; correct its "
                                "<inertia> (a thin rod of mass m and length l along z: ixx = iyy = m l^2 / 12, "
                                "izz = 0).")
            for k, (i, j) in zip(keys, [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]):
                inertia.set(k, repr(float(fixed[i, j])))
            mended.append(name)
            tensor = fixed
        if np.linalg.eigvalsh(tensor).min() < _MJ_MINVAL:
            small.append(name)
    if small and compiler.get("boundinertia") is None:
        compiler.set("boundinertia", repr(MIN_INERTIA))
        changes.append(f"link(s) {', '.join(repr(n) for n in small)} have a principal inertia below MuJoCo's "
                       f"minimum (a point mass or a thin rod), raised to {MIN_INERTIA:g} kg m^2 (boundinertia)")
    if mended:
        changes.append(f"link(s) {', '.join(repr(n) for n in mended)} give principal moments of inertia no body "
                       "has (the largest above the sum of the other two), which MuJoCo refuses; the moments across "
                       "the hinge axis were raised until they are a body's, and the moment about it, the only one "
                       "that moves a planar chain, kept as the file gives it")


def _declare_world(robot, joints: dict, where: str, changes: list) -> None:
    """Declare a ``world`` link that ``joints`` (:func:`_joints`) name but the file does not (Drake reads ``world``
    as the world); refuse any other undeclared link in one sentence."""
    links = {el.get("name") for el in _children(robot, "link")}
    for j in joints.values():
        for end, name in (("parent", j.parent), ("child", j.child)):
            if not name:
                raise URDFError(f"{where} gives joint '{j.name}' no <{end} link=...>; name its {end} link.")
            if name in links:
                continue
            if name == "world" and end == "parent":
                robot.insert(0, ET.Element("link", {"name": "world"}))
                links.add("world")
                changes.append(f"joint '{j.name}' hangs from link 'world', which the file does not declare; read as "
                               "the world (as Drake reads it)")
                continue
            raise URDFError(f"{where} gives joint '{j.name}' the {end} link '{name}', which the file does not "
                            f"declare; declare <link name=\"{name}\"/> or fix the name.")


def _mujoco_text(text: str, path: str, where: str, changes: list) -> tuple:
    """The URDF rewritten so that MuJoCo reads it from a string anywhere: (text, robot element, joints by name as
    :func:`_joints` reads them)."""
    try:
        robot = _parse_raw(text)
    except (xml.parsers.expat.ExpatError, ValueError) as exc:
        raise URDFError(f"{where} is not well-formed XML ({first_line(exc)}); fix the XML and try again.") from None
    if any(el.tag.startswith("xacro:") or "${" in (el.text or "") or any("${" in v for v in el.attrib.values())
           for el in robot.iter()):  # xmlns:xacro alone is no sign: xacro's own output keeps it
        raise URDFError(f"{where} is a xacro file (xacro macros or ${{...}} expressions), which MuJoCo cannot read; "
                        "expand it first (ROS's `xacro FILE > robot.urdf`) and give the URDF it writes.")
    mj = _child(robot, "mujoco")
    if mj is None:
        mj = ET.SubElement(robot, "mujoco")
    compiler = _child(mj, "compiler")
    if compiler is None:
        compiler = ET.SubElement(mj, "compiler")
    base = Path(path).parent if path else Path.cwd()
    joints = _joints(robot, where)
    _declare_world(robot, joints, where, changes)
    _fix_meshes(robot, compiler, base, where, changes)
    _fix_inertia(robot, joints, compiler, where, changes)
    return ET.tostring(robot, encoding="unicode"), robot, joints


def _name_of(m, objtype, i: int) -> str:
    return mujoco.mj_id2name(m, objtype, i) or ""


def _name_geoms(spec) -> None:
    """Name each unnamed geom after its link (``cart``, ``cart_2``, ...), so that a sentence about a contact names
    the links, not ``geom 3``."""
    taken = {g.name for g in spec.geoms if g.name}
    for body in spec.bodies:
        for k, g in enumerate(body.geoms):
            if g.name:
                continue
            name, n = body.name, 1
            while name in taken:
                n += 1
                name = f"{body.name}_{n}"
            g.name = name
            taken.add(name)


def _adjacent_excludes(m, joints: dict) -> list:
    """(parent body, child body, parent link, child link) of moving joints whose parent body is welded to the world
    and whose geoms MuJoCo's masks would let touch (a link fused into the world is body ``world``)."""
    def collides(b):
        return any(m.geom_bodyid[g] == b and (m.geom_contype[g] or m.geom_conaffinity[g]) for g in range(m.ngeom))

    out = []
    for name, j in joints.items():
        if j.kind not in _MOVABLE:
            continue
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            continue
        child = int(m.jnt_bodyid[jid])
        parent = int(m.body_parentid[child])
        if m.body_weldid[parent] == 0 and collides(child) and any(
                collides(b) for b in range(m.nbody) if m.body_weldid[b] == 0):
            pair = (_name_of(m, mujoco.mjtObj.mjOBJ_BODY, parent) or "world",
                    _name_of(m, mujoco.mjtObj.mjOBJ_BODY, child), j.parent, j.child)
            if pair[:2] not in [p[:2] for p in out]:
                out.append(pair)
    return out


def import_urdf(text: str, path: str = "", *, actuated_joints: Sequence[str] | None = None):
    """Compile a URDF with a motor on each driven joint (see the module docstring for the rules).

    Parameters
    ----------
    text : str
        The URDF text.
    path : str
        Its absolute path ("" for text: relative mesh names resolve from the current directory).
    actuated_joints : sequence of str, optional
        Joint names to drive (ctrl order), overriding transmissions; default: the :func:`urdf_session`'s choice,
        else the file's transmissions, else its only prismatic joint.

    Returns
    -------
    (mujoco.MjModel, str, URDFImport)
        The compiled model, the MJCF text it recompiles from, and what was added and changed.

    Raises
    ------
    URDFError
        One sentence: an ambiguous or unknown driven joint (naming the option that chooses), a missing collision
        mesh, an unsupported transmission, or MuJoCo's own refusal of the URDF.
    """
    session = _SESSION.get()
    option = session.option if session is not None else "actuated_joints=[...]"
    if actuated_joints is None and session is not None:
        actuated_joints = session.actuated_joints
    where = f"URDF '{short(path)}'" if path else "The URDF text"
    changes: list[str] = []
    mj_text, robot, joints = _mujoco_text(text, path, where, changes)
    try:
        found = _transmissions(robot, where)
    except URDFError as exc:
        if not actuated_joints:
            raise URDFError(str(exc).replace("OPTION", option)) from None
        found = []
    drives = _choose(joints, found, actuated_joints, option, where)
    try:
        spec = mujoco.MjSpec.from_string(mj_text)
        _name_geoms(spec)  # before compiling fuses static links into their parents
        m0 = spec.compile()
    except Exception as exc:
        msg = first_line(exc)
        if "mass and inertia of moving bodies" in msg:
            body = msg.split("Element name '", 1)[-1].split("'", 1)[0] if "Element name '" in msg else "?"
            raise URDFError(f"{where} gives moving link '{body}' no mass (no <inertial>, or a mass of 0), which "
                            "MuJoCo refuses; give it an <inertial> with a positive <mass>.") from None
        raise URDFError(f"{where} does not compile in MuJoCo: {msg}; fix the URDF and try again.") from None
    for sj in spec.joints:
        sj.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE  # the effort limit becomes the motor's ctrlrange
    for a, b, parent, child in _adjacent_excludes(m0, joints):
        spec.add_exclude(bodyname1=a, bodyname2=b)
        changes.append(f"contacts between link '{parent}' (welded to the world) and its child '{child}' are "
                       "excluded, as Bullet, Gazebo and Drake keep adjacent links of one robot apart")
    added, names = [], set()
    for d in drives:
        j = joints[d.joint]
        name = d.actuator if d.actuator and d.actuator not in names else f"{d.joint}_motor"
        names.add(name)
        limited = j.effort is not None and 0 < j.effort <= EFFORT_AS_UNLIMITED
        rng = [-j.effort, j.effort] if limited else [-np.inf, np.inf]
        if j.effort is not None and j.effort > EFFORT_AS_UNLIMITED:
            changes.append(f"the effort limit {j.effort:g} of joint '{d.joint}' is read as no limit (above "
                           f"{EFFORT_AS_UNLIMITED:g}, no real motor's)")
        act = spec.add_actuator(name=name, target=d.joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.gear[0] = 1.0
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE if limited else mujoco.mjtLimited.mjLIMITED_FALSE
        if limited:
            act.ctrlrange = rng
        added.append(AddedActuator(name=name, joint=d.joint, joint_type=j.kind, gear=1.0, ctrl_range=readonly(rng),
                                   source=d.source, transmission=d.transmission, mechanical_reduction=d.reduction,
                                   interface=d.interface, effort=j.effort))
    if actuated_joints and found:
        changes.append(f"its {len(found)} transmission(s) are overridden by the joints chosen with {option}")
    try:
        m = spec.compile()
        xml_text = spec.to_xml()
    except Exception as exc:
        raise URDFError(f"{where} does not compile in MuJoCo with its motors added: {first_line(exc)}; fix the URDF "
                        "and try again.") from None
    record = URDFImport(path=path, actuators=tuple(added), changes=tuple(changes), mjcf=xml_text)
    if session is not None and record.sentences() not in [r.sentences() for r in session.imports]:
        session.imports.append(record)
    return m, xml_text, record
