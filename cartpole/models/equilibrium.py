"""The upright (and hanging) equilibrium, computed rather than assumed.

Upright means every pole's centre of mass straight above its hinge, "above" being against gravity. A pole
built slightly off vertical (Gymnasium's ``inverted_pendulum.xml`` is 1 mm off) has its upright at a small
nonzero angle; gravity with a small horizontal part tilts every pole by as much and needs a constant ctrl
on the cart to hold it, ``u*``. The solve:

1. a geometric start: each hinge in tree order turns what it carries so that its centre of mass points
   up (or down, for hanging), the cart at 0 (or the middle of its range);
2. Newton on the generalized potential forces of the joints no actuator drives (hinge torques vanish,
   i.e. the centre of mass of what each hinge carries is straight above it; an actuated hinge's own
   gravity torque vanishes too, so its pole is above it and ``u*`` is zero there);
3. ``u*`` from the remaining balance ``B u* = dV/dq`` by least squares, and a check that it balances:
   an unactuated joint that gravity pushes (a tilted rail with no motor) has no equilibrium and is refused
   with one sentence.
"""
from __future__ import annotations

import numpy as np

from cartpole.models.kinematics import forward_kinematics_np
from cartpole.models.params import CartPoleParams, MJCFError


def _start(p: CartPoleParams, target: np.ndarray) -> np.ndarray:
    q = np.array([j.qpos0 for j in p.joints], dtype=float)
    for i in p.slides:
        lo, hi = p.joints[i].range
        q[i] = 0.0 if lo <= 0.0 <= hi else (0.5 * (lo + hi) if np.isfinite(lo + hi) else (lo if np.isfinite(lo) else hi))
    for _ in range(4):  # later hinges move what earlier ones carry: a few passes settle the chain
        moved = 0.0
        for h in p.hinges:
            fk = forward_kinematics_np(p, q)
            bodies = p.subtree(p.joints[h].body)
            m = np.array([p.bodies[b].mass for b in bodies])
            if m.sum() <= 0:
                continue
            c = (m[:, None] * np.array([fk.com[b] for b in bodies])).sum(0) / m.sum()
            n = fk.joint_axis[h]
            r = c - fk.joint_anchor[h]
            r_perp, t_perp = r - (r @ n) * n, target - (target @ n) * n
            if np.linalg.norm(r_perp) < 1e-12 or np.linalg.norm(t_perp) < 1e-12:
                continue  # centre of mass on the axis, or the axis along gravity: any angle will do
            delta = np.arctan2(n @ np.cross(r_perp, t_perp), r_perp @ t_perp)
            q[h] += delta
            moved = max(moved, abs(delta))
        if moved < 1e-12:
            break
    return q


def find_equilibrium(p: CartPoleParams, potential, bmat: np.ndarray, *, upright: bool = True):
    """Rest state ``x`` (nx,) and ctrl ``u`` (nu,) with ``f(x, u) = 0``, every pole up (or down).

    Parameters
    ----------
    p : CartPoleParams
    potential : casadi.Function
        ``q -> (dV/dq (nq,), d2V/dq2 (nq, nq), dVg/dq, d2Vg/dq2)`` of the whole potential and of its gravity
        part alone.
    bmat : (nq, nu) array
        Generalized force per unit ctrl.
    upright : bool
        True for every centre of mass above its hinge, False for hanging.

    Raises
    ------
    MJCFError
        When no ctrl inside ``ctrlrange`` holds the model at rest there.
    """
    up = np.asarray(p.up, float)
    q = _start(p, up if upright else -up)
    nq = p.nq
    actuated = set(p.actuated)
    unknowns = [h for h in p.hinges] + [s for s in p.slides if s not in actuated and p.joints[s].stiffness]

    def rows(q):
        dV, d2V, dVg, d2Vg = (np.asarray(a, float) for a in potential(q))
        dV, dVg = dV.ravel(), dVg.ravel()
        r = np.array([dVg[i] if i in actuated else dV[i] for i in unknowns])
        J = np.array([d2Vg[i, unknowns] if i in actuated else d2V[i, unknowns] for i in unknowns])
        return r, J.reshape(len(unknowns), len(unknowns))

    if unknowns:
        for _ in range(50):
            r, J = rows(q)
            if np.max(np.abs(r)) < 1e-14:
                break
            dq = np.linalg.lstsq(J, -r, rcond=1e-12)[0]
            q[unknowns] += dq
            if np.max(np.abs(dq)) < 1e-15:
                break
    dV = np.asarray(potential(q)[0], float).ravel()
    u = np.linalg.lstsq(bmat, dV, rcond=None)[0] if p.nu else np.zeros(0)
    residual = bmat @ u - dV
    scale = 1.0 + np.max(np.abs(dV)) + np.max(np.abs(bmat)) * (np.max(np.abs(u)) if u.size else 0.0)
    if np.max(np.abs(residual), initial=0.0) > 1e-9 * scale:
        k = int(np.argmax(np.abs(residual)))
        raise MJCFError(f"The MJCF has no {'upright' if upright else 'hanging'} rest: gravity or a spring pushes "
                        f"joint '{p.joints[k].name}' ({abs(residual[k]):.3g} N or N m) and no actuator drives it; "
                        "make gravity perpendicular to that joint or put a motor on it.")
    lo, hi = p.ctrl_range[:, 0], p.ctrl_range[:, 1]
    if np.any(u < lo - 1e-12) or np.any(u > hi + 1e-12):
        raise MJCFError(f"Holding the MJCF {'upright' if upright else 'hanging'} needs ctrl {np.round(u, 6).tolist()}, "
                        "outside its ctrlrange; widen ctrlrange or raise the gear.")
    u = np.clip(u, lo, hi)
    return np.concatenate([q, np.zeros(nq)]), u
