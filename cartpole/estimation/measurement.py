"""The exact noise-free measurement model ``h(x, u) -> y`` of a :class:`~cartpole.estimation.sensors.SensorSpec`,
and the estimators' first state from the first measurement.

``h`` is what MuJoCo's ``d.sensordata`` holds after ``mj_forward`` at ``x = [qpos, qvel]`` with ``ctrl = u``, written
in CasADi SX from the toolkit's kinematics (:func:`cartpole.models.forward_kinematics`): a point ``p(q)`` on a body
moves with ``dp/dt = J(q) v`` and ``d2p/dt2 = J qacc + d(J v)/dq v`` with ``qacc`` from the continuous dynamics
``model.f``; angular velocities are the body's angular Jacobian times ``v``. MuJoCo's accelerometer is the proper
acceleration ``R' (d2p/dt2 - g)`` in the site frame (``g`` zero when the MJCF disables gravity). ``u`` is clipped to
the ctrl range first, as MuJoCo does; no joint limit may be active (its constraint force is outside the model).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from cartpole.estimation.sensors import KINDS, SensorError, SensorSpec
from cartpole.models import forward_kinematics


def _rotation(quat) -> np.ndarray:
    """(3, 3) rotation of a quaternion ``(w, x, y, z)``, normalised first."""
    import mujoco

    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, float) / np.linalg.norm(quat))
    return out.reshape(3, 3)


def _pose(params, kin, frame):
    """World position (3, 1) and rotation (3, 3) of ``frame`` (SX; constants for a frame fixed in the world)."""
    R_local = ca.DM(_rotation(frame.quat))
    pos = ca.DM(np.reshape(frame.pos, (3, 1)))
    if frame.body < 0:
        return ca.SX(pos), ca.SX(R_local)
    b = frame.body
    R = kin.rotation[b]
    origin = kin.com[b] - ca.mtimes(R, ca.DM(np.reshape(params.bodies[b].ipos, (3, 1))))
    return origin + ca.mtimes(R, pos), ca.mtimes(R, R_local)


def _motion(params, kin, frame, q, v, qacc):
    """(p, R, linear velocity, angular velocity, linear acceleration, angular acceleration) of ``frame``, world."""
    p, R = _pose(params, kin, frame)
    Jv = ca.jacobian(p, q)
    Jw = kin.angular_jacobian[frame.body] if frame.body >= 0 else ca.DM.zeros(3, q.numel())
    lin, ang = ca.mtimes(Jv, v), ca.mtimes(Jw, v)
    lin_acc = ca.mtimes(Jv, qacc) + ca.mtimes(ca.jacobian(lin, q), v)
    ang_acc = ca.mtimes(Jw, qacc) + ca.mtimes(ca.jacobian(ang, q), v)
    return p, R, lin, ang, lin_acc, ang_acc


def _value(model, kin, s, q, v, uc, qacc):
    """SX column (dim, 1) of sensor ``s``, before MuJoCo's cutoff."""
    k = s.kind
    if k == "jointpos":
        return q[s.target]
    if k == "jointvel":
        return v[s.target]
    if k == "actuatorfrc":
        return s.scale * uc[s.target]
    if k == "jointactuatorfrc":
        return ca.mtimes(ca.DM(model.actuation[s.target:s.target + 1]), uc)
    p, R, lin, ang, lin_acc, ang_acc = _motion(model.params, kin, s.frame, q, v, qacc)
    if k == "velocimeter":
        return ca.mtimes(R.T, lin)
    if k == "gyro":
        return ca.mtimes(R.T, ang)
    if k == "accelerometer":
        return ca.mtimes(R.T, lin_acc - ca.DM(np.reshape(model.params.gravity, (3, 1))))
    if k == "framelinacc":
        return lin_acc - ca.DM(np.reshape(model.params.gravity, (3, 1)))
    if k == "frameangacc":
        return ang_acc
    axis = {"framexaxis": 0, "frameyaxis": 1, "framezaxis": 2}.get(k)
    if s.ref is None:
        return {"framepos": p, "framelinvel": lin, "frameangvel": ang}.get(k, R[:, axis] if axis is not None
                                                                          else None)
    pr, Rr, lin_r, ang_r, _, _ = _motion(model.params, kin, s.ref, q, v, qacc)
    if k == "framepos":
        return ca.mtimes(Rr.T, p - pr)
    if axis is not None:
        return ca.mtimes(Rr.T, R[:, axis])
    if k == "framelinvel":  # MuJoCo: relative velocity, corrected for the rotating reference frame
        return ca.mtimes(Rr.T, lin - lin_r - ca.cross(ang_r, p - pr))
    return ca.mtimes(Rr.T, ang - ang_r)


def _check(model, spec: SensorSpec) -> None:
    nb = len(model.params.bodies)
    for s in spec.sensors:
        limit = model.nu if s.kind == "actuatorfrc" else model.nq
        bodies = [f.body for f in (s.frame, s.ref) if f is not None]
        frame_ok = (s.frame is not None) == (s.kind not in ("jointpos", "jointvel", "actuatorfrc",
                                                            "jointactuatorfrc"))
        if (s.frame is None and not 0 <= s.target < limit) or any(b >= nb for b in bodies) or not frame_ok:
            raise SensorError(f"Sensor '{s.name}' ({s.kind} on {s.target}) does not fit this model (nq = "
                              f"{model.nq}, nu = {model.nu}, {nb} bodies); build the spec from the model's MJCF.")


def measurement_function(model, spec: SensorSpec) -> ca.Function:
    """The exact noise-free, unbiased, unquantised measurement ``h(x, u) -> y`` as an SX CasADi Function.

    Parameters
    ----------
    model : CartPoleModel
        Its params (kinematics), ``f`` (qacc for acceleration sensors), ``actuation`` and ctrl range.
    spec : SensorSpec
        From :func:`~cartpole.estimation.sensors.sensor_spec` on the same MJCF.

    Returns
    -------
    casadi.Function
        ``h(x (nx,) [qpos, qvel], u (nu,) ctrl) -> y (ny,)`` in sensor units (m, rad, m/s, rad/s, N, m/s^2, ...).

    Raises
    ------
    SensorError
        A sensor whose joint, actuator or body is not in the model.
    """
    _check(model, spec)
    nq = model.nq
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    q, v = x[:nq], x[nq:]
    lo, hi = model.u_low, model.u_high
    uc = ca.vertcat(*[ca.fmin(ca.fmax(u[i], lo[i]), hi[i]) if np.isfinite(lo[i]) or np.isfinite(hi[i]) else u[i]
                      for i in range(model.nu)])
    needs_acc = any(KINDS[s.kind][1] == "acceleration" for s in spec.sensors)
    qacc = model.f(x, uc)[nq:] if needs_acc else ca.SX.zeros(nq)
    kin = forward_kinematics(model.params, q)
    parts = []
    for s in spec.sensors:
        val = ca.reshape(_value(model, kin, s, q, v, uc, qacc), s.dim, 1)
        if s.cutoff > 0:
            val = ca.fmin(ca.fmax(val, -s.cutoff), s.cutoff)
        parts.append(val)
    y = ca.vertcat(*parts) if parts else ca.SX(0, 1)
    return ca.Function("h", [x, u], [y], ["x", "u"], ["y"])


def initial_state(model, spec: SensorSpec, y, *, iterations: int = 30) -> np.ndarray:
    """The estimators' first state from the first measurement: positions from ``y``, rates zero (never the truth).

    A joint measured by a ``jointpos`` sensor takes its value (the first such sensor; no bias is subtracted: the
    estimators do not know it). The other joints are solved from the remaining position sensors (``framepos``,
    frame axes: functions of qpos alone) by Gauss-Newton on ``h(q, 0) = y``, started from the hanging rest, the
    upright equilibrium and ``qpos0`` (the best fit kept); a joint none of them depends on keeps
    ``model.x_hanging``'s value.

    Parameters
    ----------
    model : CartPoleModel
    spec : SensorSpec
    y : (ny,) array
        The first measurement, sensor units.
    iterations : int, optional
        Gauss-Newton iterations per start.

    Returns
    -------
    (nx,) array
        ``[qpos, 0]`` (m, rad; rates m/s, rad/s zero).
    """
    y = np.asarray(y, float).ravel()
    if y.shape != (spec.ny,) or not np.all(np.isfinite(y)):
        raise SensorError(f"The first measurement must be {spec.ny} finite numbers ({', '.join(spec.names)}); "
                          f"got {np.asarray(y).tolist()}.")
    nq = model.nq
    hanging = np.array(model.x_hanging[:nq], dtype=float)
    known = {}
    rows, sensors, start = [], [], 0
    for s in spec.sensors:
        if s.kind == "jointpos":
            known.setdefault(s.target, y[start])
        elif KINDS[s.kind][1] == "position":
            rows.extend(range(start, start + s.dim))
            sensors.append(s)
        start += s.dim
    free = [j for j in range(nq) if j not in known]
    q0 = hanging.copy()
    for j, val in known.items():
        q0[j] = val
    if not free or not rows:
        return np.concatenate([q0, np.zeros(nq)])

    qs = ca.SX.sym("q", nq)
    h = measurement_function(model, SensorSpec(sensors=tuple(sensors)))
    hq = h(ca.vertcat(qs, ca.SX.zeros(nq)), ca.SX.zeros(model.nu))
    fun = ca.Function("h_pos", [qs], [hq, ca.jacobian(hq, qs)[:, free]])
    target = y[rows]
    rng = np.random.default_rng(0)
    probes = [np.asarray(fun(q0 + rng.normal(size=nq))[1]) for _ in range(3)]
    observable = [i for i in range(len(free)) if any(np.any(P[:, i] != 0) for P in probes)]
    if not observable:
        return np.concatenate([q0, np.zeros(nq)])
    cols = [free[i] for i in observable]

    def cost(q):
        return float(np.sum((np.asarray(fun(q)[0]).ravel() - target) ** 2))

    best, best_cost = q0, np.inf
    for guess in (hanging, np.asarray(model.x_eq[:nq]), np.array([j.qpos0 for j in model.params.joints])):
        q = q0.copy()
        q[cols] = guess[cols]
        c = cost(q)
        for _ in range(iterations):
            r, J = (np.asarray(a) for a in fun(q))
            dq = np.linalg.lstsq(J[:, observable], target - r.ravel(), rcond=None)[0]
            for _ in range(20):  # step halving keeps each iterate a descent
                trial = q.copy()
                trial[cols] += dq
                ct = cost(trial)
                if ct <= c:
                    break
                dq = dq / 2
            else:
                break
            q, done, c = trial, np.max(np.abs(dq)) < 1e-13, ct
            if done:
                break
        if c < best_cost:
            best, best_cost = q, c
    return np.concatenate([best, np.zeros(nq)])
