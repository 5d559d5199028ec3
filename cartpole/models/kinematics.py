"""Forward kinematics of a tree of slide and hinge joints, written once for CasADi symbols and numbers.

It mirrors MuJoCo's ``mj_kinematics``: a body's frame is its parent's frame moved by ``body_pos``,
``body_quat``, then by each of its joints in order (a slide translates along its axis by ``q - qpos0``;
a hinge rotates about its axis through its anchor by ``q - qpos0``). Given SX ``q`` the results are SX
expressions (what :mod:`cartpole.models.symbolic` differentiates); given numbers they are numbers.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np


def quat_to_mat(quat) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion ``(w, x, y, z)`` (MuJoCo's convention)."""
    return _quat_to_mat(tuple(float(v) for v in quat))


@functools.lru_cache(maxsize=256)
def _quat_to_mat(quat: tuple) -> np.ndarray:
    w, x, y, z = np.asarray(quat, float) / np.linalg.norm(quat)
    out = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    out.setflags(write=False)
    return out


def axis_rotation(axis: np.ndarray, angle):
    """Rotation matrix about the constant unit ``axis`` by ``angle`` (SX or number), Rodrigues' formula."""
    n = np.asarray(axis, float) / np.linalg.norm(axis)
    cross = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    if isinstance(angle, (ca.SX, ca.MX)):
        return ca.DM.eye(3) * ca.cos(angle) + ca.DM(cross) * ca.sin(angle) + ca.DM(np.outer(n, n)) * (1 - ca.cos(angle))
    return np.eye(3) * np.cos(angle) + cross * np.sin(angle) + np.outer(n, n) * (1 - np.cos(angle))


@dataclass(frozen=True)
class Kinematics:
    """World-frame quantities of every body and joint at one configuration (lists indexed like params).

    Attributes
    ----------
    rotation : list of (3, 3)
        Body frame orientations.
    com : list of (3,)
        Body centres of mass, m.
    inertia : list of (3, 3)
        Body inertia tensors about their centres of mass in world axes, kg m^2.
    joint_anchor, joint_axis : list of (3,)
        Joint anchors (m) and unit axes in the world.
    angular_jacobian : list of (3, nq)
        ``omega_b = J_b qdot``, body angular velocities (constant world axes of the hinges above).
    """

    rotation: list
    com: list
    inertia: list
    joint_anchor: list
    joint_axis: list
    angular_jacobian: list


def forward_kinematics(params, q) -> Kinematics:
    """Forward kinematics at ``q`` (nq,) for :class:`~cartpole.models.params.CartPoleParams`.

    With CasADi ``q`` (SX/MX) every entry is an expression; with numbers, use :func:`forward_kinematics_np`. A
    body's ``ipos`` (3,) and ``inertia`` (3,) may be CasADi symbols too (with symbolic ``q``), for a model whose
    inertial parameters are decision variables (system identification).
    """
    symbolic = isinstance(q, (ca.SX, ca.MX))
    mul = ca.mtimes if symbolic else np.matmul
    const = ca.DM if symbolic else (lambda a: np.asarray(a, float))
    nq = len(params.joints)
    eye = np.eye(nq)
    pos, rot, jw = [], [], []
    anchors, axes = [None] * nq, [None] * nq
    com, inertia = [], []
    for b in params.bodies:
        R_local = const(quat_to_mat(b.quat))
        if b.parent < 0:
            p, R, J = const(np.asarray(b.pos, float).reshape(3, 1)), R_local, const(np.zeros((3, nq)))
        else:
            p = pos[b.parent] + mul(rot[b.parent], const(np.reshape(b.pos, (3, 1))))
            R, J = mul(rot[b.parent], R_local), jw[b.parent]
        for j in b.joints:
            jp = params.joints[j]
            jpos = const(np.reshape(jp.pos, (3, 1)))
            anchor = p + mul(R, jpos)
            axis = mul(R, const(np.reshape(jp.axis, (3, 1))))
            anchors[j], axes[j] = anchor, axis
            if jp.kind == "slide":
                p = p + axis * (q[j] - jp.qpos0)
            else:
                R = mul(R, axis_rotation(jp.axis, q[j] - jp.qpos0))
                p = anchor - mul(R, jpos)
                J = J + mul(axis, const(eye[j:j + 1]))  # hinge j turns everything below it
        pos.append(p)
        rot.append(R)
        jw.append(J)
        ipos, diag = _inertial(b, const)
        com.append(p + mul(R, ipos))
        Ri = mul(R, const(quat_to_mat(b.iquat)))
        inertia.append(mul(mul(Ri, diag), Ri.T))
    return Kinematics(rotation=rot, com=com, inertia=inertia, joint_anchor=anchors, joint_axis=axes,
                      angular_jacobian=jw)


def _inertial(body, const):
    """The body's centre of mass (3, 1) and diagonal principal inertia (3, 3), either of which may be CasADi
    symbols (a parametric model, :func:`cartpole.models.symbolic.equations`)."""
    sym = (ca.SX, ca.MX)
    ipos = ca.reshape(body.ipos, 3, 1) if isinstance(body.ipos, sym) else const(np.reshape(body.ipos, (3, 1)))
    diag = ca.diag(body.inertia) if isinstance(body.inertia, sym) else const(np.diag(body.inertia))
    return ipos, diag


def forward_kinematics_np(params, q) -> Kinematics:
    """:func:`forward_kinematics` at numeric ``q`` (nq,): numpy arrays, vectors (3,), matrices (3, 3)."""
    k = forward_kinematics(params, np.asarray(q, float))
    flat = lambda vs: [np.asarray(v).ravel() for v in vs]  # noqa: E731
    return Kinematics(rotation=k.rotation, com=flat(k.com), inertia=k.inertia, joint_anchor=flat(k.joint_anchor),
                      joint_axis=flat(k.joint_axis), angular_jacobian=k.angular_jacobian)
