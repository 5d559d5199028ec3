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

from collections.abc import Callable

import casadi as ca
import mujoco
import numpy as np

from cartpole.estimation.base import EstimationError
from cartpole.estimation.sensors import KINDS, SensorError, SensorSpec
from cartpole.models import forward_kinematics


def _rotation(quat) -> np.ndarray:
    """(3, 3) rotation of a quaternion ``(w, x, y, z)``, normalised first."""
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


#: Row ``i`` of ``C`` is taken for the unit vector ``e_j`` (a sensor reading joint ``j`` directly) within this.
_UNIT_TOL = 1e-12


def check_measurement_model(h, nx: int, nu: int) -> int:
    """Check that ``h`` is a CasADi Function ``h(x (nx,), u (nu,)) -> y (ny,)``; returns ``ny``.

    Parameters
    ----------
    h : casadi.Function
        The measurement model (sensor units).
    nx, nu : int
        State and input sizes.

    Returns
    -------
    int
        ``ny``, the measurement's size (>= 1).

    Raises
    ------
    EstimationError
        Anything else.
    """
    if not isinstance(h, ca.Function) or h.n_in() != 2 or h.n_out() < 1:
        raise EstimationError("The measurement model h must be a CasADi Function h(x, u) -> y.")
    if h.numel_in(0) != nx or h.numel_in(1) != nu or h.size2_out(0) != 1 or h.size1_out(0) < 1:
        raise EstimationError(f"The measurement model h takes x ({h.numel_in(0)}) and u ({h.numel_in(1)}) and "
                              f"returns {h.size1_out(0)} x {h.size2_out(0)}; it must take ({nx},) and ({nu},) and "
                              "return a column y (ny,) with ny >= 1.")
    return int(h.size1_out(0))


def measurement_jacobians(h, nx: int, nu: int) -> ca.Function:
    """``(x (nx,), u (nu,)) -> (y (ny,), dh/dx (ny, nx), dh/du (ny, nu))``, built once from ``h`` (SX where ``h``
    takes SX symbols, else MX); dense outputs.

    Parameters
    ----------
    h : casadi.Function
        ``h(x, u) -> y`` (sensor units), checked by :func:`check_measurement_model`.
    nx, nu : int
        State and input sizes.

    Returns
    -------
    casadi.Function
    """
    check_measurement_model(h, nx, nu)
    for sym in (ca.SX, ca.MX):  # an MX-only h (e.g. with a lookup table) cannot take SX symbols
        x, u = sym.sym("x", nx), sym.sym("u", nu)
        try:
            y = h(x, u)
        except (RuntimeError, NotImplementedError, TypeError):
            continue
        y = y[0] if isinstance(y, (list, tuple)) else y
        outs = [ca.densify(v) for v in (y, ca.jacobian(y, x), ca.jacobian(y, u))]
        return ca.Function("h_jac", [x, u], outs, ["x", "u"], ["y", "C", "D"], {"cse": True} if sym is ca.SX else {})
    raise EstimationError("The measurement model h cannot be evaluated on symbols; give a CasADi Function "
                          "h(x, u) -> y built from SX or MX expressions.")


def measured_positions(h, nq: int, nu: int) -> tuple[tuple[int, int], ...]:
    """The positions a measurement reads one-to-one: pairs ``(i, j)`` with ``y_i = q_j`` (an encoder on joint
    ``j``), found as rows of ``h`` that equal ``q_j`` with Jacobian ``e_j`` at three random states and ctrls.

    Parameters
    ----------
    h : casadi.Function
        ``h(x (2 nq,), u (nu,)) -> y (ny,)``.
    nq, nu : int
        Joints and inputs.

    Returns
    -------
    tuple of (int, int)
        ``(row of y, qpos index)``, at most one row per joint (the first), in order of ``y``.
    """
    nx = 2 * int(nq)
    ny = check_measurement_model(h, nx, nu)
    fun = measurement_jacobians(h, nx, nu)
    rng = np.random.default_rng(0)
    evals = []
    for _ in range(3):
        x, u = rng.normal(size=nx), rng.normal(size=nu)
        y, C, _ = (np.asarray(v, dtype=float) for v in fun(x, u))
        evals.append((x, y.ravel(), C.reshape(ny, nx)))
    pairs, taken = [], set()
    for i in range(ny):
        for j in range(int(nq)):
            if j in taken:
                continue
            unit = np.eye(nx)[j]
            if all(abs(y[i] - x[j]) <= _UNIT_TOL and np.allclose(C[i], unit, rtol=0, atol=_UNIT_TOL)
                   for x, y, C in evals):
                pairs.append((i, j))
                taken.add(j)
                break
    return tuple(pairs)


def positions_initial_state(h, model, base) -> Callable[[np.ndarray], np.ndarray]:
    """The default first estimate ``y0 (ny,) -> x0 (nx,)``: each position that ``h`` reads one-to-one
    (:func:`measured_positions`) from ``y0``, the other positions from ``base``, all rates zero.

    Parameters
    ----------
    h : casadi.Function
        ``h(x (nx,), u (nu,)) -> y (ny,)``.
    model : CartPoleModel
        Its ``nq`` and ``nu``.
    base : (nx,) array
        Where the unmeasured positions come from (m, rad): the KF's operating point, the EKF's hanging rest.

    Returns
    -------
    callable
        ``y0 (ny,) -> x0 (nx,)`` (m, rad; rates m/s, rad/s zero).
    """
    nq, nu = int(model.nq), int(model.nu)
    x_base = np.array(base, dtype=float).ravel()
    if x_base.shape != (2 * nq,):
        raise EstimationError(f"The base state of the first estimate must be {2 * nq} numbers [qpos, qvel].")
    x_base[nq:] = 0.0
    pairs = measured_positions(h, nq, nu)
    rows = [i for i, _ in pairs]
    cols = [j for _, j in pairs]

    def initial_state(y0):
        x0 = x_base.copy()
        x0[cols] = np.asarray(y0, dtype=float).ravel()[rows]
        return x0

    return initial_state
