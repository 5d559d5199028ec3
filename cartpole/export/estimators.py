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


def reset_code(model, spec, base) -> tuple[str, str]:
    """Tables and ``first_state(y, x)``: the rig's first estimate (:func:`first_state_rows`: encoder positions,
    ``base``'s elsewhere, zero rates) in C.

    Parameters
    ----------
    model : CartPoleModel
    spec : SensorSpec
    base : (nx,) array
        Where the unmeasured positions come from.

    Returns
    -------
    (str, str)
    """
    rows = first_state_rows(model, spec)
    nq = int(model.nq)
    base = np.array(base, dtype=float).ravel()
    base[nq:] = 0.0
    tables = table("EST_ROW", rows, "int") + table("EST_BASE", base)
    code = """
static void first_state(const cp_real* y, cp_real* x)
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

    rtab, rcode = reset_code(model, spec, model.x_hanging)
    rcode += _EST_RESET
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


#: ``est_reset`` of the filters: the first estimate, nothing else.
_EST_RESET = """
static void est_reset(const cp_real* y, cp_real* x)
{
    first_state(y, x);
}
"""

#: Small dense linear algebra the EKF and MHE parts use (row-major, sizes as arguments).
LINALG = """
/* C = A B with A (n x m), B (m x p), row-major */
static void la_mul(const cp_real* A, const cp_real* B, cp_real* C, int n, int m, int p)
{
    int i, j, k;
    cp_real acc;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < p; ++j) {
            acc = 0;
            for (k = 0; k < m; ++k) {
                acc += A[i * m + k] * B[k * p + j];
            }
            C[i * p + j] = acc;
        }
    }
}

/* C = A B' with A (n x m), B (p x m) */
static void la_mul_t(const cp_real* A, const cp_real* B, cp_real* C, int n, int m, int p)
{
    int i, j, k;
    cp_real acc;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < p; ++j) {
            acc = 0;
            for (k = 0; k < m; ++k) {
                acc += A[i * m + k] * B[j * m + k];
            }
            C[i * p + j] = acc;
        }
    }
}

/* X (r x n) = B (r x n) S^-1 for S (n x n) symmetric positive definite: solve S X' = B' by LU with partial
   pivoting (as LAPACK gesv); S is overwritten. Returns 0, or 1 for a singular S. */
static int la_right_solve(cp_real* Sm, const cp_real* B, cp_real* X, int n, int r)
{
    int i, j, k, piv;
    cp_real big, f, tmp;
    int perm[CP_NY];
    cp_real col[CP_NY];
    for (i = 0; i < n; ++i) {
        perm[i] = i;
    }
    for (k = 0; k < n; ++k) {
        piv = k;
        big = fabs(Sm[k * n + k]);
        for (i = k + 1; i < n; ++i) {
            if (fabs(Sm[i * n + k]) > big) {
                big = fabs(Sm[i * n + k]);
                piv = i;
            }
        }
        if (big == 0) {
            return 1;
        }
        if (piv != k) {
            for (j = 0; j < n; ++j) {
                tmp = Sm[k * n + j];
                Sm[k * n + j] = Sm[piv * n + j];
                Sm[piv * n + j] = tmp;
            }
            i = perm[k];
            perm[k] = perm[piv];
            perm[piv] = i;
        }
        for (i = k + 1; i < n; ++i) {
            f = Sm[i * n + k] / Sm[k * n + k];
            Sm[i * n + k] = f;
            for (j = k + 1; j < n; ++j) {
                Sm[i * n + j] -= f * Sm[k * n + j];
            }
        }
    }
    for (j = 0; j < r; ++j) { /* column j of X' solves S c = B[j, :]' */
        for (i = 0; i < n; ++i) {
            col[i] = B[j * n + perm[i]];
        }
        for (i = 0; i < n; ++i) {
            for (k = 0; k < i; ++k) {
                col[i] -= Sm[i * n + k] * col[k];
            }
        }
        for (i = n - 1; i >= 0; --i) {
            for (k = i + 1; k < n; ++k) {
                col[i] -= Sm[i * n + k] * col[k];
            }
            col[i] /= Sm[i * n + i];
        }
        for (i = 0; i < n; ++i) {
            X[j * n + i] = col[i];
        }
    }
    return 0;
}
"""


def ekf_part(ekf, model, spec) -> CPart:
    """The extended Kalman filter ``ekf`` (:class:`cartpole.estimation.ekf.ExtendedKalmanFilter`) in C: the
    prediction over the period and its Jacobian (``model.hold(m)``) and the measurement and its Jacobian
    CasADi-generated (``cp_ekf_predict``, ``cp_ekf_measure``), the covariance update in the Joseph form with
    ``P`` symmetrised, a prediction that is not finite kept at the last estimate with ``P + W``, as the Python
    filter does.

    Parameters
    ----------
    ekf : ExtendedKalmanFilter
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    CPart
    """
    import casadi as ca

    from cartpole.estimation import measurement_function
    from cartpole.export.csource import call

    nx, nu, m = ekf.nx, ekf.nu, ekf.steps
    hold = model.hold(m)
    x, U = ca.SX.sym("x", nx), ca.SX.sym("U", nu, m)
    predict = ca.Function("cp_ekf_predict", [x, U], [ca.densify(hold.step_inputs(x, U)),
                                                      ca.densify(hold.ABd_inputs(x, U)[0])], {"cse": True})
    u = ca.SX.sym("u", nu)
    y = measurement_function(model, spec)(x, u)
    measure = ca.Function("cp_ekf_measure", [x, u], [ca.densify(y), ca.densify(ca.jacobian(y, x))], {"cse": True})
    rtab, rcode = reset_code(model, spec, model.x_hanging)
    rcode += _EST_RESET
    tables = rtab + table("EKF_W", ekf.W) + table("EKF_V", ekf.V) + table("EKF_P0", ekf.P0)
    c_pred = call(predict, ["x", "U"], ["xp", "Acm"])
    c_meas = call(measure, ["xp", "U + (CP_STEPS - 1) * CP_NU"], ["yp", "Hcm"])
    code = LINALG + rcode + f"""
static void ekf_reset(void)
{{
    int i;
    for (i = 0; i < NX * NX; ++i) {{
        S.P[i] = EKF_P0[i];
    }}
}}

static void est_update(const cp_real* y, const cp_real* U, cp_real* x)
{{
    cp_real xp[NX], Acm[NX * NX], A[NX * NX], T1[NX * NX], P[NX * NX], yp[CP_NY], Hcm[CP_NY * NX], H[CP_NY * NX];
    cp_real PHt[NX * CP_NY], Sm[CP_NY * CP_NY], K[NX * CP_NY], IKH[NX * NX];
    cp_real KV[NX * CP_NY], T2[NX * NX];
    int i, j, ok = 1;
    {c_pred}
    for (i = 0; i < NX; ++i) {{
        ok = ok && isfinite(xp[i]);
    }}
    for (i = 0; i < NX * NX; ++i) {{
        ok = ok && isfinite(Acm[i]);
    }}
    if (ok) {{
        for (i = 0; i < NX; ++i) {{
            for (j = 0; j < NX; ++j) {{
                A[i * NX + j] = Acm[j * NX + i];
            }}
        }}
        la_mul(A, S.P, T1, NX, NX, NX);
        la_mul_t(T1, A, P, NX, NX, NX);
        for (i = 0; i < NX * NX; ++i) {{
            P[i] += EKF_W[i];
        }}
    }} else {{
        for (i = 0; i < NX; ++i) {{
            xp[i] = x[i];
        }}
        for (i = 0; i < NX * NX; ++i) {{
            P[i] = S.P[i] + EKF_W[i];
        }}
    }}
    {c_meas}
    for (i = 0; i < CP_NY; ++i) {{
        for (j = 0; j < NX; ++j) {{
            H[i * NX + j] = Hcm[j * CP_NY + i];
        }}
    }}
    la_mul_t(P, H, PHt, NX, NX, CP_NY);
    la_mul(H, PHt, Sm, CP_NY, NX, CP_NY);
    for (i = 0; i < CP_NY * CP_NY; ++i) {{
        Sm[i] += EKF_V[i];
    }}
    /* K' = S^-1 PHt' (numpy: solve(S, PHt.T).T), i.e. rows of PHt right-divided by S (S symmetric) */
    la_right_solve(Sm, PHt, K, CP_NY, NX);
    for (i = 0; i < NX; ++i) {{
        cp_real acc = 0;
        for (j = 0; j < CP_NY; ++j) {{
            acc += K[i * CP_NY + j] * (y[j] - yp[j]);
        }}
        x[i] = xp[i] + acc;
    }}
    la_mul(K, H, IKH, NX, CP_NY, NX);
    for (i = 0; i < NX * NX; ++i) {{
        IKH[i] = (i / NX == i % NX ? 1 : 0) - IKH[i];
    }}
    la_mul(IKH, P, T1, NX, NX, NX);
    la_mul_t(T1, IKH, T2, NX, NX, NX);
    la_mul(K, EKF_V, KV, NX, CP_NY, CP_NY);
    la_mul_t(KV, K, T1, NX, CP_NY, NX);
    for (i = 0; i < NX; ++i) {{
        for (j = 0; j < NX; ++j) {{
            P[i * NX + j] = T2[i * NX + j] + T1[i * NX + j];
        }}
    }}
    for (i = 0; i < NX; ++i) {{
        for (j = 0; j < NX; ++j) {{
            S.P[i * NX + j] = 0.5 * (P[i * NX + j] + P[j * NX + i]);
        }}
    }}
}}
"""
    return CPart(tables=tables, code=code, fields=("cp_real P[NX * NX];",), reset="    ekf_reset();\n",
                 functions=(predict, measure))
