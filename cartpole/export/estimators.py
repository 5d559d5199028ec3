"""The estimator parts of an export (:class:`cartpole.export.program.CPart`): ``est_reset(y, x)`` (the first
estimate from the first measurement) and ``est_update(y, U, x)`` (one period, ``U`` the ctrl of each physics step
since the last sample, column-major ``(nu, m)``), written from the Python estimator's own matrices so the C
computes what :mod:`cartpole.estimation` computes.
"""
from __future__ import annotations

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.export.csource import table
from cartpole.export.program import CPart


class ExportError(CartPoleError):
    """An export that cannot be made: a method or estimator the C cannot reproduce at these settings, a plan that
    does not exist, an output folder that is not an earlier export, no C compiler."""


def state_part() -> CPart:
    """Estimator ``none``: the measurement is the state ``[qpos, qvel]``."""
    code = """
static void est_reset(const cp_real* y, cp_real* x)
{
    int i;
    for (i = 0; i < NX; ++i) {
        x[i] = y[i];
    }
}

static void est_update(const cp_real* y, const cp_real* U, cp_real* x)
{
    (void)U;
    est_reset(y, x);
}
"""
    return CPart(code=code)


def first_state_rows(model, spec) -> np.ndarray:
    """For each joint, the row of ``y`` whose ``jointpos`` sensor gives the first estimate (-1: from
    ``model.x_hanging``), as :func:`cartpole.estimation.initial_state` does.

    Parameters
    ----------
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    (nq,) int array

    Raises
    ------
    ExportError
        A joint without an encoder that other position sensors (frame positions, axes) would solve for: that
        Gauss-Newton fit is not exported.
    """
    from cartpole.estimation.sensors import KINDS

    nq = int(model.nq)
    rows = np.full(nq, -1, dtype=int)
    other = False
    start = 0
    for s in spec.sensors:
        if s.kind == "jointpos":
            if rows[s.target] < 0:
                rows[s.target] = start
        elif KINDS[s.kind][1] == "position":
            other = True
        start += s.dim
    if other and np.any(rows < 0):
        raise ExportError("The first estimate of a joint without an encoder comes from a Gauss-Newton fit of the "
                          "frame sensors, which the export does not generate; put a jointpos sensor on every joint.")
    return rows


def _reset_code(model, spec, base) -> tuple[str, str]:
    rows = first_state_rows(model, spec)
    nq = int(model.nq)
    base = np.array(base, dtype=float).ravel()
    base[nq:] = 0.0
    tables = table("EST_ROW", rows, "int") + table("EST_BASE", base)
    code = """
static void est_reset(const cp_real* y, cp_real* x)
{
    int j;
    for (j = 0; j < NX; ++j) {
        x[j] = EST_BASE[j];
    }
    for (j = 0; j < NQ; ++j) {
        if (EST_ROW[j] >= 0) {
            x[j] = y[EST_ROW[j]];
        }
    }
}
"""
    return tables, code


def kalman_part(kf, model, spec) -> CPart:
    """The steady-state Kalman filter ``kf`` (:class:`cartpole.estimation.kalman.KalmanFilter`) in C: its ``A``,
    ``B``, ``C``, ``D``, ``L`` and operating point as tables; ``h`` at a copy of the operating point a whole turn
    away is generated (``cp_h``).

    Parameters
    ----------
    kf : KalmanFilter
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    CPart
    """
    import casadi as ca

    nx, nu = kf.nx, kf.nu
    from cartpole.estimation import measurement_function

    rtab, rcode = _reset_code(model, spec, model.x_hanging)
    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    h = ca.Function("cp_h", [x, u], [ca.densify(measurement_function(model, spec)(x, u))])
    tables = (rtab + table("KF_A", kf.A) + table("KF_B", kf.B) + table("KF_C", kf.C) + table("KF_D", kf.D)
              + table("KF_L", kf.L) + table("KF_XOP", kf.x_op) + table("KF_UOP", kf.u_op)
              + table("KF_YOP", kf.y_op))
    from cartpole.export.csource import call

    call_h = call(h, ["xr", "KF_UOP"], ["yr"])
    code = rcode + f"""
static void est_update(const cp_real* y, const cp_real* U, cp_real* x)
{{
    cp_real dx[NX], xp[NX], dxp[NX], xr[NX], yr[CP_NY], yp[CP_NY], acc;
    int i, j, turned = 0;
    cp_error(x, KF_XOP, dx);
    for (i = 0; i < NX; ++i) {{
        acc = 0;
        for (j = 0; j < NX; ++j) {{
            acc += KF_A[i * NX + j] * dx[j];
        }}
        xp[i] = (x[i] - dx[i]) + acc;
        acc = 0;
        for (j = 0; j < CP_STEPS * CP_NU; ++j) {{
            acc += KF_B[i * CP_STEPS * CP_NU + j] * (U[j] - KF_UOP[j % CP_NU]);
        }}
        xp[i] += acc;
    }}
    cp_error(xp, KF_XOP, dxp);
    for (i = 0; i < NX; ++i) {{
        xr[i] = xp[i] - dxp[i];
        if (WRAP[i] && rint((xr[i] - KF_XOP[i]) / (2 * CP_PI_)) != 0) {{
            turned = 1;
        }}
    }}
    if (turned) {{
        {call_h}
    }} else {{
        for (i = 0; i < CP_NY; ++i) {{
            yr[i] = KF_YOP[i];
        }}
    }}
    for (i = 0; i < CP_NY; ++i) {{
        acc = 0;
        for (j = 0; j < NX; ++j) {{
            acc += KF_C[i * NX + j] * dxp[j];
        }}
        yp[i] = yr[i] + acc;
        acc = 0;
        for (j = 0; j < CP_NU; ++j) {{
            acc += KF_D[i * CP_NU + j] * (U[(CP_STEPS - 1) * CP_NU + j] - KF_UOP[j]);
        }}
        yp[i] += acc;
    }}
    for (i = 0; i < NX; ++i) {{
        acc = 0;
        for (j = 0; j < CP_NY; ++j) {{
            acc += KF_L[i * CP_NY + j] * (y[j] - yp[j]);
        }}
        x[i] = xp[i] + acc;
    }}
}}
"""
    return CPart(tables=tables, code=code, functions=(h,))
