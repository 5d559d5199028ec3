"""The moving-horizon estimator's part (:class:`cartpole.export.program.CPart`): the window of
:class:`cartpole.estimation.mhe.MovingHorizonEstimator` in C, one Gauss-Newton step a period.

The window's stages and measurements with their Jacobians are CasADi-generated (``cp_mhe_window``,
``cp_mhe_stage``, ``cp_mhe_meas``: the graphs the Python estimator compiles); the condensing onto
``(dx_0, de_0 .. de_n-1)``, the LU solve of the unconstrained step, the bounded fallback (the joints' ranges, by
the dual active-set solver of :mod:`cartpole.export.qp` with run-time sizes), the window's slide with its
arrival-cost update (an EKF step, Joseph form) and the arrival weight's factor (Cholesky with the same jitter) are
written in C in the order of :mod:`cartpole.estimation.mhe_functions`.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from cartpole.export.csource import call, table
from cartpole.export.estimators import LINALG, reset_code
from cartpole.export.program import CPart
from cartpole.export.qp import qp_code, qp_fields


def mhe_part(mhe, model, spec) -> CPart:
    """The MHE ``mhe`` (just built) on ``model`` with sensors ``spec`` as an estimator part.

    Parameters
    ----------
    mhe : MovingHorizonEstimator
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    CPart
    """
    from cartpole.estimation import measurement_function
    from cartpole.estimation.mhe_functions import window_functions

    nx, nu, ny, m, N = mhe.nx, mhe.nu, mhe.ny, mhe.steps, mhe.N
    des = mhe.design
    L, P0, RV = des["L"], des["P0"], des["RV"]
    r = int(L.shape[1])
    bidx, lo, hi = [int(v) for v in des["bounded"]], des["low"], des["high"]
    nb = len(bidx)
    nzmax = nx + N * r
    fns = window_functions(model, m, measurement_function(model, spec), N, compiled=False)
    X, UU, UH = ca.MX.sym("X", nx, N + 1), ca.MX.sym("UU", nu * m, N), ca.MX.sym("UH", nu, N + 1)
    window = ca.Function("cp_mhe_window", [X, UU, UH], fns.window(X, UU, UH))
    x, Uv, u = ca.MX.sym("x", nx), ca.MX.sym("U", nu * m), ca.MX.sym("u", nu)
    stage = ca.Function("cp_mhe_stage", [x, Uv], fns.stage(x, Uv))
    meas = ca.Function("cp_mhe_meas", [x, u], fns.measurement(x, u))
    rtab, rcode = reset_code(model, spec, model.x_hanging)
    tables = rtab + (table("MH_L", L if r else np.zeros((nx, 1))) + table("MH_P0", P0) + table("MH_RV", RV)
                     + table("MH_V", mhe.V) + table("MH_W", mhe.W))
    if nb:
        tables += table("MH_BIDX", bidx, "int") + table("MH_LO", lo) + table("MH_HI", hi)
    tables += f"#define MH_N {N}\n#define MH_R {r}\n#define MH_NB {nb}\n#define MH_NZMAX {nzmax}\n"
    fields = (f"cp_real mh_X[{(N + 1) * nx}];", f"cp_real mh_E[{max(1, N * r)}];", f"cp_real mh_Y[{(N + 1) * ny}];",
              f"cp_real mh_UU[{N * nu * m}];", f"cp_real mh_UH[{(N + 1) * nu}];", f"cp_real mh_xbar[{nx}];",
              f"cp_real mh_P[{nx * nx}];", f"cp_real mh_Pinv[{nx * nx}];", "int mh_n;",
              f"cp_real mh_F[{nx * N}];", f"cp_real mh_A[{nx * nx * N}];", f"cp_real mh_Yh[{ny * (N + 1)}];",
              f"cp_real mh_C[{ny * nx * (N + 1)}];", f"cp_real mh_T[{(N + 1) * nx * (nzmax + 1)}];",
              f"cp_real mh_B[{(N + 1) * ny * (nzmax + 1)}];", f"cp_real mh_H[{nzmax * nzmax}];",
              f"cp_real mh_H2[{nzmax * nzmax}];", f"cp_real mh_g[{nzmax}];", f"cp_real mh_z[{nzmax}];",
              f"cp_real mh_rows[{max(1, (N + 1) * nb) * nzmax}];", f"cp_real mh_rlo[{max(1, (N + 1) * nb)}];",
              f"cp_real mh_rhi[{max(1, (N + 1) * nb)}];", f"cp_real mh_blo[{nzmax}];",
              f"cp_real mh_bhi[{nzmax}];", f"cp_real mh_zq[{nzmax}];",
              *(qp_fields(nzmax, (N + 1) * nb, prefix="mq") if nb else ()))
    c_win = call(window, ["S.mh_X", "S.mh_UU", "S.mh_UH"], ["S.mh_F", "S.mh_A", "S.mh_Yh", "S.mh_C"])
    c_stage_n = call(stage, ["S.mh_X + n * NX", "Uv"], ["xn", "An"])
    c_stage_0 = call(stage, ["S.mh_X", "S.mh_UU"], ["F0", "A0cm"])
    c_meas_0 = call(meas, ["S.mh_X", "S.mh_UH"], ["h0", "C0cm"])
    bounds_fallback = _BOUNDED if nb else "    (void)ok;\n"
    qp = qp_code(nzmax, (N + 1) * nb, prefix="mq", sized=True) if nb else ""
    code = LINALG + rcode + qp + _MH_HELPERS + f"""
static void mh_reset(void)
{{
    S.mh_n = -1;
}}

/* the arrival cost one node later (mhe_functions.arrival_update) and the slide of the window by one node */
static void mh_slide(void)
{{
    cp_real F0[NX], A0cm[NX * NX], A0[NX * NX], h0[CP_NY], C0cm[CP_NY * NX], C0[CP_NY * NX];
    cp_real PCt[NX * CP_NY], Sm[CP_NY * CP_NY], K[NX * CP_NY], xf[NX], res[CP_NY], IKC[NX * NX], T1[NX * NX];
    cp_real Pf[NX * NX], KV[NX * CP_NY], Pn[NX * NX], xb[NX], acc, dxv[NX];
    int i, j, ok = 1, nrow;
    {c_stage_0}
    {c_meas_0}
    for (i = 0; i < NX; ++i) {{
        for (j = 0; j < NX; ++j) {{
            A0[i * NX + j] = A0cm[j * NX + i];
        }}
    }}
    for (i = 0; i < CP_NY; ++i) {{
        for (j = 0; j < NX; ++j) {{
            C0[i * NX + j] = C0cm[j * CP_NY + i];
        }}
    }}
    la_mul_t(S.mh_P, C0, PCt, NX, NX, CP_NY);
    la_mul(C0, PCt, Sm, CP_NY, NX, CP_NY);
    for (i = 0; i < CP_NY * CP_NY; ++i) {{
        Sm[i] += MH_V[i];
    }}
    ok = la_right_solve(Sm, PCt, K, CP_NY, NX) == 0;
    for (i = 0; i < NX; ++i) {{
        dxv[i] = S.mh_xbar[i] - S.mh_X[i];
    }}
    for (i = 0; i < CP_NY; ++i) {{
        acc = 0;
        for (j = 0; j < NX; ++j) {{
            acc += C0[i * NX + j] * dxv[j];
        }}
        res[i] = (S.mh_Y[i] - h0[i]) - acc;
    }}
    for (i = 0; i < NX; ++i) {{
        acc = 0;
        for (j = 0; j < CP_NY; ++j) {{
            acc += K[i * CP_NY + j] * res[j];
        }}
        xf[i] = S.mh_xbar[i] + acc;
    }}
    la_mul(K, C0, IKC, NX, CP_NY, NX);
    for (i = 0; i < NX * NX; ++i) {{
        IKC[i] = (i / NX == i % NX ? 1 : 0) - IKC[i];
    }}
    la_mul(IKC, S.mh_P, T1, NX, NX, NX);
    la_mul_t(T1, IKC, Pf, NX, NX, NX);
    la_mul(K, MH_V, KV, NX, CP_NY, CP_NY);
    la_mul_t(KV, K, T1, NX, CP_NY, NX);
    for (i = 0; i < NX * NX; ++i) {{
        Pf[i] += T1[i];
    }}
    la_mul(A0, Pf, T1, NX, NX, NX);
    la_mul_t(T1, A0, Pn, NX, NX, NX);
    for (i = 0; i < NX * NX; ++i) {{
        Pn[i] += MH_W[i];
    }}
    for (i = 0; i < NX; ++i) {{
        acc = 0;
        for (j = 0; j < NX; ++j) {{
            acc += A0[i * NX + j] * (xf[j] - S.mh_X[j]);
        }}
        xb[i] = F0[i] + acc;
        ok = ok && isfinite(xb[i]);
    }}
    for (i = 0; i < NX; ++i) {{
        for (j = 0; j < NX; ++j) {{
            T1[i * NX + j] = 0.5 * (Pn[i * NX + j] + Pn[j * NX + i]);
            ok = ok && isfinite(T1[i * NX + j]);
        }}
    }}
    if (ok) {{
        for (i = 0; i < NX; ++i) {{
            S.mh_xbar[i] = xb[i];
        }}
        for (i = 0; i < NX * NX; ++i) {{
            S.mh_P[i] = T1[i];
        }}
        mh_arrival_weight();
    }} else {{
        for (i = 0; i < NX; ++i) {{
            S.mh_xbar[i] = S.mh_X[NX + i];
        }}
    }}
    nrow = MH_N; /* buf[:-1] = buf[1:] */
    for (i = 0; i < nrow * NX; ++i) {{
        S.mh_X[i] = S.mh_X[i + NX];
    }}
    for (i = 0; i < (nrow - 1) * MH_R; ++i) {{
        S.mh_E[i] = S.mh_E[i + MH_R];
    }}
    for (i = 0; i < nrow * CP_NY; ++i) {{
        S.mh_Y[i] = S.mh_Y[i + CP_NY];
    }}
    for (i = 0; i < (nrow - 1) * CP_NU * CP_STEPS; ++i) {{
        S.mh_UU[i] = S.mh_UU[i + CP_NU * CP_STEPS];
    }}
    for (i = 0; i < nrow * CP_NU; ++i) {{
        S.mh_UH[i] = S.mh_UH[i + CP_NU];
    }}
    S.mh_n -= 1;
}}

/* one Gauss-Newton step of the window (mhe_functions.condensed_qp, solve_window_qp) */
static void mh_gn_step(void)
{{
    int n = S.mh_n, nz = NX + S.mh_n * MH_R, j, i, k, c, ok = 1;
    cp_real acc;
    {c_win}
    /* T_0 = [I 0], T_j+1 = A_j T_j, then L in the noise columns of interval j and the gap d_j in the last */
    for (i = 0; i < (n + 1) * NX * (nz + 1); ++i) {{
        S.mh_T[i] = 0;
    }}
    for (i = 0; i < NX; ++i) {{
        S.mh_T[i * (nz + 1) + i] = 1;
    }}
    for (j = 0; j < n; ++j) {{
        cp_real* Tn = S.mh_T + (j + 1) * NX * (nz + 1);
        const cp_real* Tj = S.mh_T + j * NX * (nz + 1);
        for (i = 0; i < NX; ++i) {{
            for (c = 0; c < nz + 1; ++c) {{
                acc = 0;
                for (k = 0; k < NX; ++k) {{
                    acc += S.mh_A[(j * NX + k) * NX + i] * Tj[k * (nz + 1) + c];
                }}
                Tn[i * (nz + 1) + c] = acc;
            }}
            for (c = 0; c < MH_R; ++c) {{
                Tn[i * (nz + 1) + NX + j * MH_R + c] = MH_L[i * MH_R + c];
            }}
            /* d_j = F_j + L e_j - x_j+1 */
            acc = 0;
            for (c = 0; c < MH_R; ++c) {{
                acc += S.mh_E[j * MH_R + c] * MH_L[i * MH_R + c];
            }}
            Tn[i * (nz + 1) + nz] += (S.mh_F[j * NX + i] + acc) - S.mh_X[(j + 1) * NX + i];
        }}
    }}
    /* B = (RV C_j) T_j stacked, its last column + RV r_j */
    for (j = 0; j <= n; ++j) {{
        cp_real RC[CP_NY * NX], rr[CP_NY];
        for (i = 0; i < CP_NY; ++i) {{
            for (k = 0; k < NX; ++k) {{
                acc = 0;
                for (c = 0; c < CP_NY; ++c) {{
                    acc += MH_RV[i * CP_NY + c] * S.mh_C[(j * NX + k) * CP_NY + c];
                }}
                RC[i * NX + k] = acc;
            }}
            rr[i] = S.mh_Yh[j * CP_NY + i] - S.mh_Y[j * CP_NY + i];
        }}
        for (i = 0; i < CP_NY; ++i) {{
            cp_real* Bi = S.mh_B + (j * CP_NY + i) * (nz + 1);
            for (c = 0; c < nz + 1; ++c) {{
                acc = 0;
                for (k = 0; k < NX; ++k) {{
                    acc += RC[i * NX + k] * S.mh_T[(j * NX + k) * (nz + 1) + c];
                }}
                Bi[c] = acc;
            }}
            acc = 0;
            for (c = 0; c < CP_NY; ++c) {{
                acc += rr[c] * MH_RV[i * CP_NY + c];
            }}
            Bi[nz] += acc;
        }}
    }}
    /* [H; g'] = B' B[:, :nz] */
    for (i = 0; i < nz + 1; ++i) {{
        for (c = 0; c < nz; ++c) {{
            acc = 0;
            for (k = 0; k < (n + 1) * CP_NY; ++k) {{
                acc += S.mh_B[k * (nz + 1) + i] * S.mh_B[k * (nz + 1) + c];
            }}
            if (i < nz) {{
                S.mh_H[i * nz + c] = acc;
            }} else {{
                S.mh_g[c] = acc;
            }}
        }}
    }}
    for (i = 0; i < NX; ++i) {{
        acc = 0;
        for (k = 0; k < NX; ++k) {{
            S.mh_H[i * nz + k] += S.mh_Pinv[i * NX + k];
            acc += S.mh_Pinv[i * NX + k] * (S.mh_X[k] - S.mh_xbar[k]);
        }}
        S.mh_g[i] += acc;
    }}
    for (i = NX; i < nz; ++i) {{
        S.mh_H[i * nz + i] += 1;
        S.mh_g[i] += S.mh_E[i - NX];
    }}
    /* z = -H^-1 g (LU with partial pivoting, as numpy.linalg.solve) */
    for (i = 0; i < nz * nz; ++i) {{
        S.mh_H2[i] = S.mh_H[i];
    }}
    for (i = 0; i < nz; ++i) {{
        S.mh_zq[i] = -S.mh_g[i];
    }}
    if (mh_lu_solve(S.mh_H2, S.mh_zq, S.mh_z, nz) != 0) {{
        return;
    }}
{bounds_fallback}    for (i = 0; i < nz; ++i) {{
        if (!isfinite(S.mh_z[i])) {{
            return;
        }}
    }}
    /* X += c + S z, E += z[nx:], the bounded positions clipped */
    for (j = 0; j <= n; ++j) {{
        for (i = 0; i < NX; ++i) {{
            const cp_real* Tr = S.mh_T + (j * NX + i) * (nz + 1);
            acc = 0;
            for (c = 0; c < nz; ++c) {{
                acc += Tr[c] * S.mh_z[c];
            }}
            S.mh_X[j * NX + i] += Tr[nz] + acc;
        }}
    }}
    for (i = 0; i < n * MH_R; ++i) {{
        S.mh_E[i] += S.mh_z[NX + i];
    }}
    for (j = 0; j <= n; ++j) {{
        for (i = 0; i < MH_NB; ++i) {{
            int q = MH_BIDX_AT(i);
            S.mh_X[j * NX + q] = cp_clip(S.mh_X[j * NX + q], MH_LO_AT(i), MH_HI_AT(i));
        }}
    }}
}}

static void est_reset(const cp_real* y, cp_real* x)
{{
    int i, j;
    first_state(y, x);
    for (i = 0; i < MH_NB; ++i) {{
        x[MH_BIDX_AT(i)] = cp_clip(x[MH_BIDX_AT(i)], MH_LO_AT(i), MH_HI_AT(i));
    }}
    for (j = 0; j <= MH_N; ++j) {{
        for (i = 0; i < NX; ++i) {{
            S.mh_X[j * NX + i] = x[i];
        }}
        for (i = 0; i < CP_NY; ++i) {{
            S.mh_Y[j * CP_NY + i] = y[i];
        }}
        for (i = 0; i < CP_NU; ++i) {{
            S.mh_UH[j * CP_NU + i] = 0;
        }}
    }}
    for (i = 0; i < MH_N * MH_R; ++i) {{
        S.mh_E[i] = 0;
    }}
    for (i = 0; i < MH_N * CP_NU * CP_STEPS; ++i) {{
        S.mh_UU[i] = 0;
    }}
    for (i = 0; i < NX; ++i) {{
        S.mh_xbar[i] = x[i];
    }}
    for (i = 0; i < NX * NX; ++i) {{
        S.mh_P[i] = MH_P0[i];
    }}
    mh_arrival_weight();
    S.mh_n = 0;
}}

static void est_update(const cp_real* y, const cp_real* U, cp_real* x)
{{
    cp_real xn[NX], An[NX * NX];
    const cp_real* Uv = U;
    int i, n, ok = 1;
    if (S.mh_n == MH_N) {{
        mh_slide();
    }}
    n = S.mh_n;
    {c_stage_n}
    for (i = 0; i < NX; ++i) {{
        ok = ok && isfinite(xn[i]);
    }}
    for (i = 0; i < NX; ++i) {{
        S.mh_X[(n + 1) * NX + i] = ok ? xn[i] : S.mh_X[n * NX + i];
    }}
    for (i = 0; i < MH_R; ++i) {{
        S.mh_E[n * MH_R + i] = 0;
    }}
    for (i = 0; i < CP_NU * CP_STEPS; ++i) {{
        S.mh_UU[n * CP_NU * CP_STEPS + i] = Uv[i];
    }}
    for (i = 0; i < CP_NU; ++i) {{
        S.mh_UH[(n + 1) * CP_NU + i] = Uv[(CP_STEPS - 1) * CP_NU + i];
    }}
    for (i = 0; i < CP_NY; ++i) {{
        S.mh_Y[(n + 1) * CP_NY + i] = y[i];
    }}
    S.mh_n = n + 1;
    mh_gn_step();
    for (i = 0; i < NX; ++i) {{
        x[i] = S.mh_X[S.mh_n * NX + i];
    }}
}}
"""
    bmacros = ("#define MH_BIDX_AT(i) (MH_BIDX[i])\n#define MH_LO_AT(i) (MH_LO[i])\n#define MH_HI_AT(i) (MH_HI[i])\n"
               if nb else "#define MH_BIDX_AT(i) 0\n#define MH_LO_AT(i) 0\n#define MH_HI_AT(i) 0\n")
    return CPart(tables=tables + bmacros, code=code, fields=fields, reset="    mh_reset();\n",
                 functions=(window, stage, meas))


_MH_HELPERS = """
/* x = A^-1 b by LU with partial pivoting (A overwritten); 0, or 1 for a singular A */
static int mh_lu_solve(cp_real* A, const cp_real* b, cp_real* x, int n)
{
    int i, j, k, piv;
    cp_real big, f, tmp;
    for (i = 0; i < n; ++i) {
        x[i] = b[i];
    }
    for (k = 0; k < n; ++k) {
        piv = k;
        big = fabs(A[k * n + k]);
        for (i = k + 1; i < n; ++i) {
            if (fabs(A[i * n + k]) > big) {
                big = fabs(A[i * n + k]);
                piv = i;
            }
        }
        if (big == 0) {
            return 1;
        }
        if (piv != k) {
            for (j = 0; j < n; ++j) {
                tmp = A[k * n + j];
                A[k * n + j] = A[piv * n + j];
                A[piv * n + j] = tmp;
            }
            tmp = x[k];
            x[k] = x[piv];
            x[piv] = tmp;
        }
        for (i = k + 1; i < n; ++i) {
            f = A[i * n + k] / A[k * n + k];
            for (j = k + 1; j < n; ++j) {
                A[i * n + j] -= f * A[k * n + j];
            }
            x[i] -= f * x[k];
        }
    }
    for (i = n - 1; i >= 0; --i) {
        for (j = i + 1; j < n; ++j) {
            x[i] -= A[i * n + j] * x[j];
        }
        x[i] /= A[i * n + i];
    }
    return 0;
}

/* Pinv = R' R with R = L^-1, P + jitter I = L L' (mhe_functions.inverse_factor) */
static void mh_arrival_weight(void)
{
    cp_real Lc[NX * NX], R[NX * NX], acc, jitter = 0, scale = 0;
    int i, j, k, tries, ok = 0;
    for (i = 0; i < NX; ++i) {
        scale += S.mh_P[i * NX + i];
    }
    scale = scale / NX > 1e-300 ? scale / NX : (cp_real)1e-300;
    for (tries = 0; tries < 8 && !ok; ++tries) {
        ok = 1;
        for (j = 0; j < NX && ok; ++j) {
            acc = S.mh_P[j * NX + j] + jitter;
            for (k = 0; k < j; ++k) {
                acc -= Lc[j * NX + k] * Lc[j * NX + k];
            }
            if (!(acc > 0)) {
                ok = 0;
                break;
            }
            Lc[j * NX + j] = sqrt(acc);
            for (i = j + 1; i < NX; ++i) {
                acc = S.mh_P[i * NX + j];
                for (k = 0; k < j; ++k) {
                    acc -= Lc[i * NX + k] * Lc[j * NX + k];
                }
                Lc[i * NX + j] = acc / Lc[j * NX + j];
            }
        }
        if (!ok) {
            jitter = jitter == 0 ? (cp_real)1e-14 * scale : 100 * jitter;
        }
    }
    if (!ok) {
        return; /* keep the old weight */
    }
    for (i = 0; i < NX; ++i) { /* R = L^-1, lower */
        for (j = 0; j < NX; ++j) {
            acc = i == j ? 1 : 0;
            for (k = j; k < i; ++k) {
                acc -= Lc[i * NX + k] * R[k * NX + j];
            }
            R[i * NX + j] = j > i ? 0 : acc / Lc[i * NX + i];
        }
    }
    for (i = 0; i < NX; ++i) {
        for (j = 0; j < NX; ++j) {
            acc = 0;
            for (k = 0; k < NX; ++k) {
                acc += R[k * NX + i] * R[k * NX + j];
            }
            S.mh_Pinv[i * NX + j] = acc;
        }
    }
}
"""

#: The bounded fallback of one window step (solve_window_qp): the positions of the bounded joints after the
#: unconstrained step checked against their ranges, else the QP with those rows, its solution when it succeeds.
_BOUNDED = """    {
        int viol = 0, nr = (n + 1) * MH_NB, rr;
        for (j = 0; j <= n; ++j) {
            for (i = 0; i < MH_NB; ++i) {
                int q = MH_BIDX[i];
                const cp_real* Tr = S.mh_T + (j * NX + q) * (nz + 1);
                cp_real v = S.mh_X[j * NX + q] + Tr[nz], qz;
                rr = j * MH_NB + i;
                acc = 0;
                for (c = 0; c < nz; ++c) {
                    S.mh_rows[rr * nz + c] = Tr[c];
                    acc += Tr[c] * S.mh_z[c];
                }
                qz = v + acc;
                viol = viol || qz > MH_HI[i] + 1e-12 || qz < MH_LO[i] - 1e-12;
                S.mh_rhi[rr] = MH_HI[i] - v;
                S.mh_rlo[rr] = MH_LO[i] - v;
            }
        }
        if (viol) {
            for (i = 0; i < nz; ++i) {
                S.mh_blo[i] = -INFINITY;
                S.mh_bhi[i] = INFINITY;
            }
            for (i = 0; i < nz * nz; ++i) {
                S.mh_H2[i] = S.mh_H[i];
            }
            S.mq_nz = nz;
            S.mq_nr = nr;
            ok = mq_solve(S.mh_H2, S.mh_g, S.mh_rows, S.mh_rlo, S.mh_rhi, S.mh_blo, S.mh_bhi, S.mh_zq) == 0;
            if (ok) {
                for (i = 0; i < nz; ++i) {
                    S.mh_z[i] = S.mh_zq[i];
                }
            }
        }
    }
"""
