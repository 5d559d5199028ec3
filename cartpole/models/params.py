"""Read a cart-pole's physical parameters from an MJCF file, via the compiled ``mujoco.MjModel``.

Inertias come from the compiled model, never from the XML text: MuJoCo derives a capsule's mass
distribution from its geometry, adds ``armature`` to the joint space inertia, and so on.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cartpole._arrays import readonly
from cartpole.errors import CartPoleError

#: Integrators whose one-step map :mod:`cartpole.models.discrete` reproduces exactly.
SUPPORTED_INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")

_INTEGRATOR_NAMES = {0: "Euler", 1: "RK4", 2: "implicit", 3: "implicitfast"}

SHIPPED_MJCF = Path(__file__).resolve().parent.parent / "assets" / "cartpole.xml"


class MJCFError(CartPoleError):
    """The MJCF file is missing, does not compile, or is not a cart-pole this toolkit supports."""


@dataclass(frozen=True)
class CartPoleParams:
    """Physical parameters of a cart with one hinged pole, as MuJoCo compiles them.

    All vectors are expressed in the world frame at ``qpos = 0`` (the upright pose). SI units.

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
        ``opt.gravity`` in m/s^2.
    cart_mass : float
        Mass in kg of everything that moves with the slide joint only.
    pole_mass : float
        Mass in kg of everything below the hinge.
    slide_axis : (3,) array
        Unit direction in which positive cart position moves the cart.
    hinge_axis : (3,) array
        Unit axis of positive pole rotation (right-hand rule).
    hinge_offset : (3,) array
        Hinge anchor minus cart position, in m (constant: the cart does not rotate).
    pole_com : (3,) array
        Pole centre of mass minus hinge anchor at ``qpos = 0``, in m; points up (against gravity).
    pole_inertia : (3, 3) array
        Pole rotational inertia about its centre of mass, kg m^2, world frame at ``qpos = 0``.
    damping : (2,) array
        Joint damping of [slide (N s/m), hinge (N m s/rad)].
    armature : (2,) array
        Joint armature of [slide (kg), hinge (kg m^2)].
    gear : float
        Actuator gear: slide force in N is ``gear * ctrl`` (motor actuators only).
    ctrl_range : (2,) array
        ``[low, high]`` of ``ctrl``; ``(-inf, inf)`` when the actuator is not ctrl-limited.
    cart_range : (2,) array
        Slide joint range in m; ``(-inf, inf)`` when unlimited.
    hinge_range : (2,) array
        Hinge joint range in rad; ``(-inf, inf)`` when unlimited.
    """

    mjcf: str
    xml: str
    timestep: float
    integrator: str
    euler_damping_implicit: bool
    gravity: np.ndarray
    cart_mass: float
    pole_mass: float
    slide_axis: np.ndarray
    hinge_axis: np.ndarray
    hinge_offset: np.ndarray
    pole_com: np.ndarray
    pole_inertia: np.ndarray
    damping: np.ndarray
    armature: np.ndarray
    gear: float
    ctrl_range: np.ndarray
    cart_range: np.ndarray
    hinge_range: np.ndarray

    # ---- derived quantities a control engineer reasons with -------------------------------
    @property
    def g(self) -> float:
        """Magnitude of gravity in m/s^2."""
        return float(np.linalg.norm(self.gravity))

    @property
    def pole_com_distance(self) -> float:
        """Distance in m from the hinge axis to the pole's centre of mass."""
        r = self.pole_com - np.dot(self.pole_com, self.hinge_axis) * self.hinge_axis
        return float(np.linalg.norm(r))

    @property
    def pole_inertia_about_hinge(self) -> float:
        """Pole moment of inertia about the hinge axis in kg m^2 (parallel axis, no armature)."""
        n = self.hinge_axis
        return float(n @ self.pole_inertia @ n + self.pole_mass * self.pole_com_distance**2)

    @property
    def u_max(self) -> float:
        """Largest |ctrl| allowed symmetrically, i.e. ``min(|low|, |high|)`` of ``ctrl_range``."""
        return float(min(abs(self.ctrl_range[0]), abs(self.ctrl_range[1])))

    def replace(self, **changes) -> "CartPoleParams":
        """Return a copy with some fields changed (e.g. a deliberately wrong model for robustness tests)."""
        return dataclasses.replace(self, **{k: (readonly(v) if isinstance(v, (list, tuple, np.ndarray)) else v)
                                            for k, v in changes.items()})

    def scaled_pole(self, mass_factor: float = 1.0, length_factor: float = 1.0) -> "CartPoleParams":
        """Return parameters whose pole mass and length are scaled (uniform rod scaling of COM and inertia).

        Used to build a *model* that is deliberately wrong relative to the MJCF MuJoCo runs.
        """
        return self.replace(
            pole_mass=self.pole_mass * mass_factor,
            pole_com=self.pole_com * length_factor,
            pole_inertia=self.pole_inertia * mass_factor * length_factor**2,
        )


def load_model(mjcf: str | Path | None = None, *, xml: str | None = None):
    """Compile an MJCF into a ``mujoco.MjModel``, turning MuJoCo's errors into :class:`MJCFError`.

    Parameters
    ----------
    mjcf : path, optional
        MJCF file; defaults to the shipped asset. Ignored when ``xml`` is given.
    xml : str, optional
        MJCF text to compile instead of a file.

    Returns
    -------
    (mujoco.MjModel, str path, str xml)
    """
    import mujoco

    if xml is not None:
        try:
            return mujoco.MjModel.from_xml_string(xml), "", xml
        except Exception as exc:  # mujoco raises ValueError with a multi-line message
            raise MJCFError(f"The MJCF text does not compile: {_first_line(exc)}. "
                            "Fix the XML and try again.") from None
    path = Path(mjcf) if mjcf is not None else SHIPPED_MJCF
    path = path.expanduser().resolve()
    if not path.is_file():
        raise MJCFError(f"MJCF file '{path}' does not exist; pass --mjcf with the path of a cart-pole MJCF.")
    try:
        text = path.read_text()
        model = mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:
        raise MJCFError(f"MJCF file '{path}' does not compile: {_first_line(exc)}. "
                        "Fix the XML and try again.") from None
    return model, str(path), text


def _first_line(exc: Exception) -> str:
    """MuJoCo's (often multi-line) message folded into one line, without a final period."""
    msg = " ".join(part.strip() for part in str(exc).strip().splitlines() if part.strip())
    msg = msg.replace(": Error=", ": ").rstrip(".")
    return (msg[:240] + "...") if len(msg) > 240 else (msg or type(exc).__name__)


def read_params(mjcf: str | Path | None = None, *, xml: str | None = None) -> CartPoleParams:
    """Read the parameters of a cart-pole MJCF from its compiled ``MjModel``.

    Accepts one slide joint (the cart) carrying, in its subtree, one hinge joint (the pole), driven by
    one ``motor`` actuator on the slide; any gear, ctrlrange, timestep, hinge offset, hinge axis sign,
    damping, armature and joint limits; integrators Euler, RK4, implicit and implicitfast.

    Parameters
    ----------
    mjcf : path, optional
        MJCF file; defaults to the shipped asset (``cartpole/assets/cartpole.xml``).
    xml : str, optional
        MJCF text instead of a file.

    Returns
    -------
    CartPoleParams

    Raises
    ------
    MJCFError
        With one sentence naming what was found and what is supported.
    """
    import mujoco

    m, path, text = load_model(mjcf, xml=xml)
    where = f"MJCF '{path}'" if path else "The MJCF"
    supported = ("the toolkit supports one slide joint (the cart) carrying one hinge joint (the pole), "
                 "driven by one motor actuator on the slide")

    jtypes = [int(t) for t in m.jnt_type]
    names = {int(mujoco.mjtJoint.mjJNT_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball",
             int(mujoco.mjtJoint.mjJNT_SLIDE): "slide", int(mujoco.mjtJoint.mjJNT_HINGE): "hinge"}
    found = ", ".join(f"{jtypes.count(t)} {names[t]}" for t in sorted(set(jtypes))) or "no"
    if any(t in (mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL) for t in jtypes) \
            or jtypes.count(mujoco.mjtJoint.mjJNT_SLIDE) != 1 or jtypes.count(mujoco.mjtJoint.mjJNT_HINGE) != 1 \
            or m.njnt != 2:
        raise MJCFError(f"{where} has {found} joint(s); {supported}.")
    if m.nu != 1:
        raise MJCFError(f"{where} has {m.nu} actuators; {supported}.")
    if m.ntendon:
        raise MJCFError(f"{where} has {m.ntendon} tendon(s); {supported}, without tendons.")
    if m.neq:
        raise MJCFError(f"{where} has {m.neq} equality constraint(s); {supported}, without equality constraints.")
    slide = jtypes.index(mujoco.mjtJoint.mjJNT_SLIDE)
    hinge = jtypes.index(mujoco.mjtJoint.mjJNT_HINGE)
    if slide != 0 or m.jnt_qposadr[slide] != 0 or m.jnt_qposadr[hinge] != 1:
        raise MJCFError(f"{where} declares the hinge before the slide; {supported}, with the slide first "
                        "so that qpos = [cart position, pole angle].")
    cart_body = int(m.jnt_bodyid[slide])
    pole_body = int(m.jnt_bodyid[hinge])
    # The pole must hang from the cart: the hinge body must be a descendant of the slide body.
    b = pole_body
    while b not in (0, cart_body):
        b = int(m.body_parentid[b])
    if b != cart_body or pole_body == cart_body:
        raise MJCFError(f"{where} has a hinge that is not carried by the slide joint's body; {supported}.")
    if m.actuator_trntype[0] != mujoco.mjtTrn.mjTRN_JOINT or m.actuator_trnid[0, 0] != slide:
        raise MJCFError(f"{where} has its actuator on something other than the slide joint; {supported}.")
    if (m.actuator_dyntype[0] != mujoco.mjtDyn.mjDYN_NONE or m.actuator_gaintype[0] != mujoco.mjtGain.mjGAIN_FIXED
            or m.actuator_biastype[0] != mujoco.mjtBias.mjBIAS_NONE or m.actuator_gainprm[0, 0] != 1.0):
        raise MJCFError(f"{where} has a non-motor actuator (position, velocity, filtered or scaled); "
                        f"{supported}, i.e. <motor> with force = gear * ctrl.")
    if np.any(m.jnt_stiffness != 0) or np.any(m.dof_frictionloss != 0):
        raise MJCFError(f"{where} has joint stiffness or frictionloss; {supported}, with damping and armature "
                        "only (remove stiffness/frictionloss).")
    integ = _INTEGRATOR_NAMES.get(int(m.opt.integrator))
    if integ is None:
        raise MJCFError(f"{where} uses integrator {int(m.opt.integrator)}; supported integrators are "
                        f"{', '.join(SUPPORTED_INTEGRATORS)}.")
    # Bodies must not move relative to their parent except through the two joints.
    for bid in range(1, m.nbody):
        if m.body_jntnum[bid] and bid not in (cart_body, pole_body):
            raise MJCFError(f"{where} has joints on body {bid}; {supported}.")
    if m.body_jntnum[cart_body] != 1 or m.body_jntnum[pole_body] != 1:
        raise MJCFError(f"{where} puts both joints on one body; {supported}.")

    d = mujoco.MjData(m)
    d.qpos[:] = 0.0
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)

    gravity = np.array(m.opt.gravity, dtype=float)
    g = np.linalg.norm(gravity)
    if g == 0:
        raise MJCFError(f"{where} has zero gravity; a cart-pole needs gravity to have an upright equilibrium.")
    down = gravity / g
    slide_axis = np.array(d.xaxis[slide], dtype=float)
    hinge_axis = np.array(d.xaxis[hinge], dtype=float)
    anchor = np.array(d.xanchor[hinge], dtype=float)
    if abs(slide_axis @ down) > 1e-9:
        raise MJCFError(f"{where} has a slide axis that is not horizontal; the toolkit needs a horizontal "
                        "rail so that upright rest needs no force.")
    if abs(hinge_axis @ down) > 1e-9:
        raise MJCFError(f"{where} has a hinge axis that is not horizontal; the pole must swing in gravity.")

    # Partition bodies: those in the pole body's subtree rotate with the hinge, other bodies in the
    # cart's subtree only translate with the slide.
    def in_subtree(bid: int, root: int) -> bool:
        while bid not in (0, root):
            bid = int(m.body_parentid[bid])
        return bid == root

    cart_mass = 0.0
    pole_mass = 0.0
    com_sum = np.zeros(3)
    pole_bodies = []
    for bid in range(1, m.nbody):
        if in_subtree(bid, pole_body):
            pole_bodies.append(bid)
            pole_mass += m.body_mass[bid]
            com_sum += m.body_mass[bid] * d.xipos[bid]
        elif in_subtree(bid, cart_body):
            cart_mass += m.body_mass[bid]
    if pole_mass <= 0:
        raise MJCFError(f"{where} has a massless pole; give the pole body a mass.")
    com = com_sum / pole_mass
    inertia = np.zeros((3, 3))
    for bid in pole_bodies:
        R = d.ximat[bid].reshape(3, 3)
        Ib = R @ np.diag(m.body_inertia[bid]) @ R.T
        r = d.xipos[bid] - com
        inertia += Ib + m.body_mass[bid] * (r @ r * np.eye(3) - np.outer(r, r))
    pole_com = com - anchor
    perp = pole_com - (pole_com @ hinge_axis) * hinge_axis
    if perp @ (-down) <= 0 or np.linalg.norm(np.cross(perp, down)) > 1e-6 * max(np.linalg.norm(perp), 1e-12):
        raise MJCFError(f"{where} does not have the pole's centre of mass straight above its hinge at qpos = 0; "
                        "the toolkit's convention is pole angle 0 = upright, so build the pole pointing up.")
    cart_pos = np.array(d.xpos[cart_body], dtype=float)

    def jrange(j):
        if m.jnt_limited[j]:
            return m.jnt_range[j].copy()
        return np.array([-np.inf, np.inf])

    ctrl_range = m.actuator_ctrlrange[0].copy() if m.actuator_ctrllimited[0] else np.array([-np.inf, np.inf])
    return CartPoleParams(
        mjcf=path,
        xml=text,
        timestep=float(m.opt.timestep),
        integrator=integ,
        euler_damping_implicit=not bool(m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP),
        gravity=readonly(gravity),
        cart_mass=float(cart_mass),
        pole_mass=float(pole_mass),
        slide_axis=readonly(slide_axis),
        hinge_axis=readonly(hinge_axis),
        hinge_offset=readonly(anchor - cart_pos),
        pole_com=readonly(pole_com),
        pole_inertia=readonly(inertia),
        damping=readonly([m.dof_damping[m.jnt_dofadr[slide]], m.dof_damping[m.jnt_dofadr[hinge]]]),
        armature=readonly([m.dof_armature[m.jnt_dofadr[slide]], m.dof_armature[m.jnt_dofadr[hinge]]]),
        gear=float(m.actuator_gear[0, 0]),
        ctrl_range=readonly(ctrl_range),
        cart_range=readonly(jrange(slide)),
        hinge_range=readonly(jrange(hinge)),
    )
