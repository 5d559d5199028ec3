"""The NMPC's controller part (:class:`cartpole.export.program.CPart`): real-time iteration in C, as
:class:`cartpole.mpc.nmpc.NMPCController` runs it.

Each control instant: the stored iterate shifted by the periods since the last solve (its tail extended with the
offline plan's input while the plan lasts, else the upright LQR's, through the CasADi-generated stage), re-seeded
from the measured state when it is garbage, aligned to the measured hinge turns; then ``iterations`` Gauss-Newton
steps, each the stages' exact linearisations (``cp_nmpc_lin``: the Python controller's stage, chain rule over the
period's physics steps, as one CasADi-generated straight-line SX expression), the QP condensed in C by the Python
controller's recursions (:func:`condense_code`: O(N^2) arithmetic on O(N) memory, no dense ``G``) and solved by the
static-memory dual active-set solver of :mod:`cartpole.export.qp`; the first input applied. A QP that fails, or a
step that is not finite, takes the Python controller's safe action (the previous plan's input mid swing-up, the
upright LQR near upright) and returns ``CP_FALLBACK``.

Both condensings of the Python controller: plain (``z = du``, the ctrl bounds are bounds of ``z``) and
pre-stabilised (``z = dv`` with ``du = fu + Fu dv``, the ctrl bounds are general rows ``Fu``, causal like the rail's;
the double pole at the default horizon: its plain Hessian's condition number is about 1e6, the pre-stabilised one's
about 5), the same QP rows in the same order as :meth:`cartpole.mpc.nmpc.NMPCController._gn_step` builds them.
"""
from __future__ import annotations

import numpy as np

from cartpole.export.controllers import linear_code
from cartpole.export.csource import call, literal, table
from cartpole.export.program import CPart
from cartpole.export.qp import qp_code, qp_fields


def nmpc_part(ctl, plan) -> CPart:
    """``ctrl_eval`` of an :class:`~cartpole.mpc.nmpc.NMPCController` (just reset) whose offline plan is ``plan``.

    Parameters
    ----------
    ctl : NMPCController
        Plain or pre-stabilised condensing (``ctl.prestabilize``).
    plan : Trajectory or None
        The offline plan whose inputs extend the shifted tail (the controller's guess).

    Returns
    -------
    CPart
    """
    from cartpole.mpc.stage_functions import stage_expression, stage_rollout

    pre = bool(ctl.prestabilize)
    p = ctl.problem
    N, steps, nx, nu = int(ctl.N), int(ctl.steps), p.nx, p.nu
    nzu = N * nu
    nz = nzu + 1
    nb = len(p.bounded)
    nuc = nzu if pre else 0  # pre-stabilised: the ctrl bounds are the first nuc rows
    nr = nuc + 2 * N * nb
    lin = stage_expression(ctl.model, steps, "cp_nmpc_lin")  # (x_next, A, B); A, B dense, column-major
    rollout = stage_rollout(ctl.model, steps, N, "cp_nmpc_rollout")
    S0, U0 = ctl.plan
    ltabs, lcode = linear_code(ctl.lqr, "mlqr")
    hinges = list(p.hinges)
    tables = ltabs + (table("MP_S0", S0) + table("MP_U0", U0) + table("MP_QS", p.Qs) + table("MP_RS", p.Rs)
                      + table("MP_P", p.P) + table("MP_XG", p.x_goal) + table("MP_UG", p.u_goal)
                      + table("MP_ULO", p.u_low) + table("MP_UHI", p.u_high)
                      + table("MP_HINGE", hinges or [-1], "int"))
    if nb:
        tables += (table("MP_BIDX", list(p.bounded), "int") + table("MP_QLO", p.q_low) + table("MP_QHI", p.q_high))
    has_plan = plan is not None
    if has_plan:
        tables += table("NP_T", plan.t, "double") + table("NP_U", plan.u)
    tables += (f"#define MP_N {N}\n#define MP_STEPS {steps}\n#define MP_NZU {nzu}\n#define MP_NB {nb}\n"
               f"#define MP_NH {len(hinges)}\n#define MP_ITERS {int(ctl.iterations)}\n#define MP_NUC {nuc}\n"
               f"#define NP_N {int(plan.N) if has_plan else 0}\n"
               f"static const double MP_DT = {literal(p.dt)};\nstatic const cp_real MP_TOL = {literal(ctl.tol)};\n"
               f"static const cp_real MP_RHO1 = {literal(p.rho1)};\nstatic const cp_real MP_RHO2 = "
               f"{literal(p.rho2)};\n")
    fields = (f"cp_real mp_S[{(N + 1) * nx}];", f"cp_real mp_U[{nzu}];", f"cp_real mp_Sa[{(N + 1) * nx}];",
              f"cp_real mp_Sn[{(N + 1) * nx}];", f"cp_real mp_Un[{nzu}];", f"cp_real mp_St[{(N + 1) * nx}];",
              f"cp_real mp_Ut[{nzu}];", "long mp_k_plan;", "long mp_k_last;", "int mp_has_last;", "int mp_age;",
              f"cp_real mp_hold[{nu}];", f"cp_real mp_H[{nz * nz}];", f"cp_real mp_h[{nz}];",
              f"cp_real mp_A[{max(1, nr) * nz}];", f"cp_real mp_lba[{max(1, nr)}];", f"cp_real mp_uba[{max(1, nr)}];",
              f"cp_real mp_lbx[{nz}];", f"cp_real mp_ubx[{nz}];", f"cp_real mp_z[{nz}];",
              f"cp_real mp_g[{nx * (N + 1)}];", f"cp_real mp_e[{nx * (N + 1)}];", f"cp_real mp_c[{nx * N}];",
              f"cp_real mp_Ak[{N * nx * nx}];", f"cp_real mp_Bk[{N * nx * nu}];", f"cp_real mp_Lam[{N * nx * nx}];",
              f"cp_real mp_lam[{N * nx}];", f"cp_real mp_BtL[{N * nu * nx}];", f"cp_real mp_X[{nx * nu}];",
              f"cp_real mp_T[{nx * nx}];", f"cp_real mp_T2[{nx * nx}];", f"cp_real mp_ds[{nx}];",
              f"cp_real mp_ds2[{nx}];", f"cp_real mp_r[{nzu}];", f"cp_real mp_RK[{nu * nx}];",
              f"cp_real mp_goal[{nx}];", f"cp_real mp_tmp[{nx * N}];",
              *((f"cp_real mp_K[{N * nu * nx}];", f"cp_real mp_fu[{nzu}];", f"cp_real mp_Pn[{nx * nx}];",
                 f"cp_real mp_BtP[{nu * nx}];", f"cp_real mp_M[{nu * nu}];", f"cp_real mp_KG[{nu * nu}];")
                if pre else ()),
              *qp_fields(nz, nr))
    c_lin = call(lin, ["Sx + k * NX", "Ux + k * CP_NU"], ["ck", "S.mp_Ak + k * NX * NX", "S.mp_Bk + k * NX * CP_NU"])
    c_stage = call(lin, ["S.mp_S + MP_N * NX", "ut"], ["xt", "0", "0"])
    c_roll = call(rollout, ["x", "U"], ["S.mp_tmp"])
    plan_input = """
static void mp_plan_input(double t, cp_real* u)
{
    int lo = 0, hi = NP_N + 1, mid, k, i;
    double s, h;
    t = t < NP_T[0] ? NP_T[0] : (t > NP_T[NP_N] ? NP_T[NP_N] : t);
    while (lo < hi) {
        mid = (lo + hi) / 2;
        if (NP_T[mid] <= t) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    k = lo - 1;
    k = k < 0 ? 0 : (k > NP_N - 1 ? NP_N - 1 : k);
    h = NP_T[k + 1] - NP_T[k];
    s = (t - NP_T[k]) / h;
    for (i = 0; i < CP_NU; ++i) {
        u[i] = (cp_real)((1 - s) * NP_U[k * CP_NU + i] + s * NP_U[(k + 1) * CP_NU + i]);
    }
}
""" if has_plan else ""
    tail = ("""    double t = (double)k_phys * MP_DT;
    int i;
    if (NP_T[0] + t < NP_T[NP_N]) {
        mp_plan_input(NP_T[0] + t + 0.5 * MP_STEPS * MP_DT, u);
        for (i = 0; i < CP_NU; ++i) {
            u[i] = cp_clip(u[i], MP_ULO[i], MP_UHI[i]);
        }
        return;
    }
    mlqr_eval(s_last, u);
""" if has_plan else "    (void)k_phys;\n    mlqr_eval(s_last, u);\n")
    row_len = ([(k + 1) * nu for k in range(N) for _i in range(nu)] if pre else []) + [
        (k + 1) * nu for _ in range(2) for k in range(N) for _b in range(nb)]
    du = ("""            du = zk[a];
            for (j = 0; j < NX; ++j) {
                du -= S.mp_K[(k * CP_NU + a) * NX + j] * S.mp_ds[j];
            }
""" if pre else "            du = zk[a];\n")
    code = lcode + qp_code(nz, nr, row_len) + plan_input + condense_code(nu, pre, nb).replace("@LIN@", c_lin) + f"""
static void mp_reset(void)
{{
    int i;
    for (i = 0; i < (MP_N + 1) * NX; ++i) {{
        S.mp_S[i] = MP_S0[i];
    }}
    for (i = 0; i < MP_NZU; ++i) {{
        S.mp_U[i] = MP_U0[i];
    }}
    S.mp_k_plan = 0;
    S.mp_has_last = 0;
    S.mp_age = 0;
}}

static int mp_finite(const cp_real* v, int n)
{{
    int i;
    for (i = 0; i < n; ++i) {{
        if (!isfinite(v[i])) {{
            return 0;
        }}
    }}
    return 1;
}}

static void mp_tail_input(long k_phys, const cp_real* s_last, cp_real* u)
{{
{tail}}}

static void mp_shift(long n)
{{
    long m, i;
    cp_real ut[CP_NU], xt[NX];
    for (m = 0; m < (n < MP_N + 1 ? n : MP_N + 1); ++m) {{
        long k_end = S.mp_k_plan + (MP_N + 1) * MP_STEPS;
        mp_tail_input(k_end - MP_STEPS, S.mp_S + MP_N * NX, ut);
        {c_stage}
        for (i = 0; i < MP_N * NX; ++i) {{
            S.mp_S[i] = S.mp_S[i + NX];
        }}
        if (mp_finite(xt, NX)) {{
            for (i = 0; i < NX; ++i) {{
                S.mp_S[MP_N * NX + i] = xt[i];
            }}
        }}
        for (i = 0; i < (MP_N - 1) * CP_NU; ++i) {{
            S.mp_U[i] = S.mp_U[i + CP_NU];
        }}
        for (i = 0; i < CP_NU; ++i) {{
            S.mp_U[(MP_N - 1) * CP_NU + i] = ut[i];
        }}
        S.mp_k_plan += MP_STEPS;
        S.mp_age += 1;
    }}
    if (n > MP_N + 1) {{
        S.mp_k_plan += (n - MP_N - 1) * MP_STEPS;
    }}
}}

/* nodes from x under U (rest at x where not finite or huge) into Sout */
static void mp_reseed(const cp_real* x, const cp_real* U, cp_real* Sout)
{{
    int i, ok = 1;
    {c_roll}
    for (i = 0; i < NX; ++i) {{
        Sout[i] = x[i];
    }}
    for (i = 0; i < MP_N * NX; ++i) {{
        Sout[NX + i] = S.mp_tmp[i];
        ok = ok && isfinite(S.mp_tmp[i]) && fabs(S.mp_tmp[i]) < 1e3;
    }}
    for (i = 0; i < NX && ok; ++i) {{
        ok = fabs(x[i]) < 1e3;
    }}
    if (!ok) {{
        for (i = 0; i < (MP_N + 1) * NX; ++i) {{
            Sout[i] = x[i % NX];
        }}
    }}
}}

/* one Gauss-Newton step from (Sx, Ux) with s_0 = x into (S.mp_Sn, S.mp_Un); 0, or nonzero for a failure */
static int mp_gn_step(const cp_real* x, const cp_real* Sx, const cp_real* Ux, cp_real* step)
{{
    int i, j, k, a, code;
    cp_real acc, du;
    for (i = 0; i < NX; ++i) {{
        S.mp_goal[i] = MP_XG[i];
    }}
    for (i = 0; i < MP_NH; ++i) {{
        int hh = MP_HINGE[i];
        S.mp_goal[hh] += 2 * CP_PI_ * rint((Sx[MP_N * NX + hh] - S.mp_goal[hh]) / (2 * CP_PI_));
    }}
    mp_condense(x, Sx, Ux);
    code = qp_solve(S.mp_H, S.mp_h, S.mp_A, S.mp_lba, S.mp_uba, S.mp_lbx, S.mp_ubx, S.mp_z);
    if (code != 0 || !mp_finite(S.mp_z, MP_NZU)) {{
        return 1;
    }}
    /* the linearised prediction ds_k+1 = A_k ds_k + B_k z_k + c_k from ds_0 = g_0 (A_k the closed loop's and
       du_k = z_k - K_k ds_k when pre-stabilised; du_k = z_k when plain): the QP's g + G z */
    *step = 0;
    for (i = 0; i < NX; ++i) {{
        S.mp_ds[i] = S.mp_g[i];
        S.mp_Sn[i] = Sx[i] + S.mp_ds[i];
    }}
    for (k = 0; k < MP_N; ++k) {{
        const cp_real* Ak = S.mp_Ak + k * NX * NX;
        const cp_real* Bk = S.mp_Bk + k * NX * CP_NU;
        const cp_real* zk = S.mp_z + k * CP_NU;
        for (a = 0; a < CP_NU; ++a) {{
{du}            S.mp_Un[k * CP_NU + a] = cp_clip(Ux[k * CP_NU + a] + du, MP_ULO[a], MP_UHI[a]);
            *step = fabs(du) > *step ? fabs(du) : *step;
        }}
        for (i = 0; i < NX; ++i) {{
            acc = 0;
            for (j = 0; j < NX; ++j) {{
                acc += Ak[i + j * NX] * S.mp_ds[j];
            }}
            for (a = 0; a < CP_NU; ++a) {{
                acc += Bk[i + a * NX] * zk[a];
            }}
            S.mp_ds2[i] = acc + S.mp_c[k * NX + i];
        }}
        for (i = 0; i < NX; ++i) {{
            S.mp_ds[i] = S.mp_ds2[i];
            S.mp_Sn[(k + 1) * NX + i] = Sx[(k + 1) * NX + i] + S.mp_ds[i];
        }}
    }}
    return mp_finite(S.mp_Sn, (MP_N + 1) * NX) ? 0 : 2;
}}

static int ctrl_eval(double t, const cp_real* x, cp_real* u)
{{
    long k = (long)floor(t / MP_DT + 0.5);
    int i, it, ok, fin;
    cp_real step, e[NX];
    if (S.mp_has_last && k < S.mp_k_last) {{
        mp_reset();
    }}
    if (S.mp_has_last && k - S.mp_k_last < MP_STEPS) {{
        for (i = 0; i < CP_NU; ++i) {{
            u[i] = S.mp_hold[i];
        }}
        return CP_OK;
    }}
    if (k > S.mp_k_plan) {{
        mp_shift((k - S.mp_k_plan) / MP_STEPS);
    }}
    fin = mp_finite(x, NX);
    ok = fin;
    if (ok) {{
        int good = mp_finite(S.mp_S, (MP_N + 1) * NX);
        for (i = 0; i < (MP_N + 1) * NX && good; ++i) {{
            good = fabs(S.mp_S[i]) < 1e3;
        }}
        if (!good) {{
            mp_reseed(x, S.mp_U, S.mp_S);
        }}
        for (i = 0; i < (MP_N + 1) * NX; ++i) {{ /* align the hinge turns to x */
            S.mp_St[i] = S.mp_S[i];
        }}
        for (i = 0; i < MP_NH; ++i) {{
            int hh = MP_HINGE[i], kk;
            cp_real turns = rint((x[hh] - S.mp_S[hh]) / (2 * CP_PI_));
            if (turns != 0) {{
                for (kk = 0; kk <= MP_N; ++kk) {{
                    S.mp_St[kk * NX + hh] += 2 * CP_PI_ * turns;
                }}
            }}
        }}
        for (i = 0; i < MP_NZU; ++i) {{
            S.mp_Ut[i] = S.mp_U[i];
        }}
        for (it = 0; it < MP_ITERS && ok; ++it) {{
            if (mp_gn_step(x, S.mp_St, S.mp_Ut, &step) != 0) {{
                ok = 0;
                break;
            }}
            for (i = 0; i < (MP_N + 1) * NX; ++i) {{
                S.mp_St[i] = S.mp_Sn[i];
            }}
            for (i = 0; i < MP_NZU; ++i) {{
                S.mp_Ut[i] = S.mp_Un[i];
            }}
            if (step <= MP_TOL) {{
                break;
            }}
        }}
    }}
    if (ok) {{
        for (i = 0; i < (MP_N + 1) * NX; ++i) {{
            S.mp_S[i] = S.mp_St[i];
        }}
        for (i = 0; i < MP_NZU; ++i) {{
            S.mp_U[i] = S.mp_Ut[i];
        }}
        S.mp_age = 0;
        for (i = 0; i < CP_NU; ++i) {{
            u[i] = cp_clip(S.mp_U[i], MP_ULO[i], MP_UHI[i]);
        }}
    }} else {{
        int near = fin;
        if (fin) {{
            cp_error(x, MLQR_XEQ, e);
            for (i = 0; i < MP_NH; ++i) {{
                near = near && fabs(e[MP_HINGE[i]]) <= 0.5;
            }}
        }}
        if (!near && S.mp_age < MP_N) {{
            for (i = 0; i < CP_NU; ++i) {{
                u[i] = cp_clip(S.mp_U[i], MP_ULO[i], MP_UHI[i]);
            }}
        }} else if (fin) {{
            mlqr_eval(x, u);
        }} else {{
            for (i = 0; i < CP_NU; ++i) {{
                u[i] = MP_UG[i];
            }}
        }}
        for (i = 0; i < CP_NU; ++i) {{
            u[i] = isfinite(u[i]) ? u[i] : MP_UG[i];
        }}
        if (fin) {{
            mp_reseed(x, S.mp_U, S.mp_S);
        }}
    }}
    S.mp_k_last = k;
    S.mp_has_last = 1;
    for (i = 0; i < CP_NU; ++i) {{
        S.mp_hold[i] = u[i];
    }}
    return ok ? CP_OK : CP_FALLBACK;
}}
"""
    return CPart(tables=tables, code=code, fields=fields, reset=condense_constants_code(pre, nb) + "    mp_reset();\n",
                 functions=(lin, rollout))


def condense_code(nu: int, pre: bool, nb: int) -> str:
    """C text of ``mp_condense(x, Sx, Ux)``: the stage linearisations along the iterate (the CasADi-generated
    ``cp_nmpc_lin``, one call per stage) and the Gauss-Newton QP condensed onto ``z`` as
    :func:`cartpole.mpc.stage_functions.stage_functions`' ``qp_data`` condenses it (plain: ``z = du``;
    pre-stabilised: ``z = dv``, ``du = fu + Fu dv`` with the Riccati gains ``K_k`` along the iterate), without the
    dense ``G``: the backward recursion stores ``Lambda_k+1``, ``lambda_k+1`` per stage and each column block ``j``
    of the Hessian and of the causal rows is produced by one forward sweep of ``G_k+1,j = A_k G_k,j`` (``A_k`` the
    closed loop's when pre-stabilised), O(N^2 nx^2 nu) arithmetic on O(N nx^2) memory. It writes the lower triangle
    of ``S.mp_H`` (all the QP solver reads), ``S.mp_h``, the varying entries of ``S.mp_A`` and the row and bound
    limits; the constant ones (slack column, the identity blocks of the ctrl rows, zeros) are set once by
    :func:`condense_constants_code`.

    Parameters
    ----------
    nu : int
        Inputs per stage (``CP_NU``).
    pre : bool
        Pre-stabilised condensing.
    nb : int
        Bounded joints (rail rows per stage and side).

    Returns
    -------
    str
    """
    solve = ("""        for (a = 0; a < NX; ++a) { /* nu = 1: K = (B'PA) / (R + B'PB) */
            S.mp_K[k * NX + a] = S.mp_T2[a] / S.mp_M[0];
        }
""" if nu == 1 else """        for (a = 0; a < CP_NU; ++a) { /* M = L L' (lower, in place), then K = M^-1 (B'PA) column by column */
            for (b = 0; b <= a; ++b) {
                acc = S.mp_M[a * CP_NU + b];
                for (s = 0; s < b; ++s) {
                    acc -= S.mp_M[a * CP_NU + s] * S.mp_M[b * CP_NU + s];
                }
                S.mp_M[a * CP_NU + b] = a == b ? sqrt(acc) : acc / S.mp_M[b * CP_NU + b];
            }
        }
        for (c = 0; c < NX; ++c) {
            cp_real* Kw = S.mp_K + k * CP_NU * NX;
            for (a = 0; a < CP_NU; ++a) {
                acc = S.mp_T2[a * NX + c];
                for (s = 0; s < a; ++s) {
                    acc -= S.mp_M[a * CP_NU + s] * Kw[s * NX + c];
                }
                Kw[a * NX + c] = acc / S.mp_M[a * CP_NU + a];
            }
            for (a = CP_NU - 1; a >= 0; --a) {
                acc = Kw[a * NX + c];
                for (s = a + 1; s < CP_NU; ++s) {
                    acc -= S.mp_M[s * CP_NU + a] * Kw[s * NX + c];
                }
                Kw[a * NX + c] = acc / S.mp_M[a * CP_NU + a];
            }
        }
""")
    riccati = f"""
    for (i = 0; i < NX * NX; ++i) {{
        S.mp_Pn[i] = MP_P[i];
    }}
    for (k = MP_N - 1; k >= 0; --k) {{ /* K_k = (R + B'PB)^-1 B'PA, P <- Q + K'RK + Acl' P Acl; A_k <- Acl */
        cp_real* Ak = S.mp_Ak + k * NX * NX;
        const cp_real* Bk = S.mp_Bk + k * NX * CP_NU;
        const cp_real* Kk = S.mp_K + k * CP_NU * NX;
        for (a = 0; a < CP_NU; ++a) {{
            for (c = 0; c < NX; ++c) {{
                acc = 0;
                for (s = 0; s < NX; ++s) {{
                    acc += Bk[s + a * NX] * S.mp_Pn[s * NX + c];
                }}
                S.mp_BtP[a * NX + c] = acc;
            }}
            for (b = 0; b < CP_NU; ++b) {{
                acc = 0;
                for (s = 0; s < NX; ++s) {{
                    acc += S.mp_BtP[a * NX + s] * Bk[s + b * NX];
                }}
                S.mp_M[a * CP_NU + b] = MP_RS[a * CP_NU + b] + acc;
            }}
            for (c = 0; c < NX; ++c) {{
                acc = 0;
                for (s = 0; s < NX; ++s) {{
                    acc += S.mp_BtP[a * NX + s] * Ak[s + c * NX];
                }}
                S.mp_T2[a * NX + c] = acc;
            }}
        }}
{solve}        for (r = 0; r < NX; ++r) {{
            for (c = 0; c < NX; ++c) {{
                acc = 0;
                for (a = 0; a < CP_NU; ++a) {{
                    acc += Bk[r + a * NX] * Kk[a * NX + c];
                }}
                Ak[r + c * NX] -= acc;
            }}
        }}
        mp_lambda_update(S.mp_Pn, Ak, Kk, S.mp_Pn);
    }}
""" if pre else ""
    kterm = """
            acc = 0;
            for (a = 0; a < CP_NU; ++a) {
                acc += Kk[a * NX + r] * S.mp_RK[a * NX + c];
            }
            v += acc;""" if pre else ""
    rk = """    for (a = 0; a < CP_NU; ++a) {
        for (c = 0; c < NX; ++c) {
            acc = 0;
            for (b = 0; b < CP_NU; ++b) {
                acc += MP_RS[a * CP_NU + b] * Kk[b * NX + c];
            }
            S.mp_RK[a * NX + c] = acc;
        }
    }
""" if pre else "    (void)Kk;\n"
    fu = """        for (a = 0; a < CP_NU; ++a) { /* f_k = -K_k g_k */
            acc = 0;
            for (s = 0; s < NX; ++s) {
                acc += S.mp_K[(k * CP_NU + a) * NX + s] * gk[s];
            }
            S.mp_fu[k * CP_NU + a] = -acc;
            S.mp_r[k * CP_NU + a] = Ux[k * CP_NU + a] + S.mp_fu[k * CP_NU + a] - MP_UG[a];
        }
""" if pre else """        for (a = 0; a < CP_NU; ++a) {
            S.mp_r[k * CP_NU + a] = Ux[k * CP_NU + a] - MP_UG[a];
        }
"""
    lterm = """
            acc = 0;
            for (a = 0; a < CP_NU; ++a) { /* - K' R r_k */
                cp_real rr = 0;
                for (b = 0; b < CP_NU; ++b) {
                    rr += MP_RS[a * CP_NU + b] * S.mp_r[k * CP_NU + b];
                }
                acc += Kk[a * NX + r] * rr;
            }
            S.mp_lam[(k - 1) * NX + r] -= acc;""" if pre else ""
    kg = """                for (a = 0; a < CP_NU; ++a) { /* K_i G_i,j; the ctrl rows' block F_i,j = -K_i G_i,j */
                    for (b = 0; b < CP_NU; ++b) {
                        acc = 0;
                        for (s = 0; s < NX; ++s) {
                            acc += S.mp_K[(i * CP_NU + a) * NX + s] * X[s + b * NX];
                        }
                        S.mp_KG[a * CP_NU + b] = acc;
                        S.mp_A[(i * CP_NU + a) * (MP_NZU + 1) + j * CP_NU + b] = -acc;
                    }
                }
""" if pre else ""
    hterm = """
                        for (c = 0; c < CP_NU; ++c) {
                            acc -= MP_RS[a * CP_NU + c] * S.mp_KG[c * CP_NU + b];
                        }""" if pre else ""
    rails = """            for (bb = 0; bb < MP_NB; ++bb) { /* the rail rows of stage i: q_i+1 */
                int rr = MP_NUC + i * MP_NB + bb, q = MP_BIDX[bb];
                for (b = 0; b < CP_NU; ++b) {
                    S.mp_A[rr * (MP_NZU + 1) + j * CP_NU + b] = X[q + b * NX];
                    S.mp_A[(MP_N * MP_NB + rr) * (MP_NZU + 1) + j * CP_NU + b] = X[q + b * NX];
                }
            }
""" if nb else "            (void)bb;\n"
    limits = """    for (k = 0; k < MP_N; ++k) {
        for (bb = 0; bb < MP_NB; ++bb) {
            int rr = MP_NUC + k * MP_NB + bb, q = MP_BIDX[bb];
            cp_real val = Sx[(k + 1) * NX + q] + S.mp_g[(k + 1) * NX + q];
            S.mp_uba[rr] = MP_QHI[bb] - val;
            S.mp_lba[MP_N * MP_NB + rr] = MP_QLO[bb] - val;
        }
    }
""" if nb else ""
    ulim = """    for (i = 0; i < MP_NZU; ++i) { /* ctrl rows: u_low - (U + fu) <= Fu dv <= u_high - (U + fu) */
        cp_real un = Ux[i] + S.mp_fu[i];
        S.mp_lba[i] = MP_ULO[i % CP_NU] - un;
        S.mp_uba[i] = MP_UHI[i % CP_NU] - un;
    }
""" if pre else """    for (i = 0; i < MP_NZU; ++i) { /* z = du: the ctrl bounds are bounds */
        S.mp_lbx[i] = MP_ULO[i % CP_NU] - Ux[i];
        S.mp_ubx[i] = MP_UHI[i % CP_NU] - Ux[i];
    }
"""
    return f"""
/* L_out = Q + Acl' L Acl (+ K'RK when pre-stabilised) for one stage; L_out may be L (symmetric, row-major) */
static void mp_lambda_update(const cp_real* L, const cp_real* Ak, const cp_real* Kk, cp_real* L_out)
{{
    int r, c, s, a, b;
    cp_real acc, v;
{rk}    for (r = 0; r < NX; ++r) {{
        for (c = 0; c < NX; ++c) {{
            acc = 0;
            for (s = 0; s < NX; ++s) {{
                acc += L[r * NX + s] * Ak[s + c * NX];
            }}
            S.mp_T[r * NX + c] = acc;
        }}
    }}
    for (r = 0; r < NX; ++r) {{
        for (c = 0; c < NX; ++c) {{
            acc = 0;
            for (s = 0; s < NX; ++s) {{
                acc += Ak[s + r * NX] * S.mp_T[s * NX + c];
            }}
            v = MP_QS[r * NX + c] + acc;{kterm}
            S.mp_T2[r * NX + c] = v;
        }}
    }}
    for (r = 0; r < NX * NX; ++r) {{
        L_out[r] = S.mp_T2[r];
    }}
    (void)a;
    (void)b;
}}

/* the condensed Gauss-Newton QP of one step from (Sx, Ux) with s_0 = x (see the module doc) */
static void mp_condense(const cp_real* x, const cp_real* Sx, const cp_real* Ux)
{{
    int i, j, k, a, b, c, r, s, bb;
    cp_real acc;
    for (k = 0; k < MP_N; ++k) {{ /* F_k, A_k, B_k; the gaps c_k = F_k - s_k+1 */
        cp_real* ck = S.mp_c + k * NX;
        @LIN@
        for (r = 0; r < NX; ++r) {{
            ck[r] -= Sx[(k + 1) * NX + r];
        }}
    }}
{riccati}    for (r = 0; r < NX; ++r) {{
        S.mp_g[r] = x[r] - Sx[r];
    }}
    for (k = 0; k < MP_N; ++k) {{ /* g_k+1 = A_k g_k + c_k */
        const cp_real* Ak = S.mp_Ak + k * NX * NX;
        const cp_real* gk = S.mp_g + k * NX;
{fu}        for (r = 0; r < NX; ++r) {{
            acc = 0;
            for (s = 0; s < NX; ++s) {{
                acc += Ak[r + s * NX] * gk[s];
            }}
            S.mp_g[(k + 1) * NX + r] = acc + S.mp_c[k * NX + r];
        }}
    }}
    for (k = 0; k <= MP_N; ++k) {{ /* e_k = s_k + g_k - x* */
        for (r = 0; r < NX; ++r) {{
            S.mp_e[k * NX + r] = Sx[k * NX + r] + S.mp_g[k * NX + r] - S.mp_goal[r];
        }}
    }}
    for (i = 0; i < NX * NX; ++i) {{ /* slot k holds Lambda_k+1, lambda_k+1: Lambda_N = P, lambda_N = P e_N */
        S.mp_Lam[(MP_N - 1) * NX * NX + i] = MP_P[i];
    }}
    for (r = 0; r < NX; ++r) {{
        acc = 0;
        for (s = 0; s < NX; ++s) {{
            acc += MP_P[r * NX + s] * S.mp_e[MP_N * NX + s];
        }}
        S.mp_lam[(MP_N - 1) * NX + r] = acc;
    }}
    for (k = MP_N - 1; k >= 1; --k) {{ /* Lambda_k = Q + A_k' Lambda_k+1 A_k, lambda_k = Q e_k + A_k' lambda_k+1 */
        const cp_real* Ak = S.mp_Ak + k * NX * NX;
        const cp_real* Kk = {"S.mp_K + k * CP_NU * NX" if pre else "0"};
        mp_lambda_update(S.mp_Lam + k * NX * NX, Ak, Kk, S.mp_Lam + (k - 1) * NX * NX);
        for (r = 0; r < NX; ++r) {{
            cp_real v = 0;
            acc = 0;
            for (s = 0; s < NX; ++s) {{
                v += MP_QS[r * NX + s] * S.mp_e[k * NX + s];
                acc += Ak[s + r * NX] * S.mp_lam[k * NX + s];
            }}
            S.mp_lam[(k - 1) * NX + r] = v + acc;{lterm}
        }}
        (void)Kk;
    }}
    for (i = 0; i < MP_N; ++i) {{ /* B_i' Lambda_i+1; the diagonal blocks B_i' Lambda_i+1 B_i + R and h_i */
        const cp_real* Bi = S.mp_Bk + i * NX * CP_NU;
        cp_real* BtL = S.mp_BtL + i * CP_NU * NX;
        for (a = 0; a < CP_NU; ++a) {{
            for (c = 0; c < NX; ++c) {{
                acc = 0;
                for (s = 0; s < NX; ++s) {{
                    acc += Bi[s + a * NX] * S.mp_Lam[i * NX * NX + s * NX + c];
                }}
                BtL[a * NX + c] = acc;
            }}
            for (b = 0; b <= a; ++b) {{
                acc = 0;
                for (s = 0; s < NX; ++s) {{
                    acc += BtL[a * NX + s] * Bi[s + b * NX];
                }}
                S.mp_H[(i * CP_NU + a) * (MP_NZU + 1) + i * CP_NU + b] = acc + MP_RS[a * CP_NU + b];
            }}
            acc = 0;
            for (s = 0; s < NX; ++s) {{
                acc += Bi[s + a * NX] * S.mp_lam[i * NX + s];
            }}
            for (b = 0; b < CP_NU; ++b) {{
                acc += MP_RS[a * CP_NU + b] * S.mp_r[i * CP_NU + b];
            }}
            S.mp_h[i * CP_NU + a] = acc;
        }}
    }}
    for (j = 0; j < MP_N; ++j) {{ /* column block j: G_j+1,j = B_j, G_i+1,j = A_i G_i,j */
        cp_real* X = S.mp_X;
        for (i = 0; i < NX * CP_NU; ++i) {{
            X[i] = S.mp_Bk[j * NX * CP_NU + i];
        }}
        for (i = j; i < MP_N; ++i) {{
            if (i > j) {{
                const cp_real* Ai = S.mp_Ak + i * NX * NX;
                const cp_real* BtL = S.mp_BtL + i * CP_NU * NX;
{kg}                for (b = 0; b < CP_NU; ++b) {{
                    for (r = 0; r < NX; ++r) {{
                        acc = 0;
                        for (s = 0; s < NX; ++s) {{
                            acc += Ai[r + s * NX] * X[s + b * NX];
                        }}
                        S.mp_ds[r] = acc;
                    }}
                    for (r = 0; r < NX; ++r) {{
                        X[r + b * NX] = S.mp_ds[r];
                    }}
                }}
                for (a = 0; a < CP_NU; ++a) {{ /* H_i,j = B_i' Lambda_i+1 G_i+1,j (- R K_i G_i,j) */
                    for (b = 0; b < CP_NU; ++b) {{
                        acc = 0;
                        for (s = 0; s < NX; ++s) {{
                            acc += BtL[a * NX + s] * X[s + b * NX];
                        }}{hterm}
                        S.mp_H[(i * CP_NU + a) * (MP_NZU + 1) + j * CP_NU + b] = acc;
                    }}
                }}
            }}
{rails}        }}
    }}
    for (i = 0; i < MP_NZU; ++i) {{ /* the slack's row (its Cholesky factor overwrote it) */
        S.mp_H[MP_NZU * (MP_NZU + 1) + i] = 0;
    }}
    S.mp_H[MP_NZU * (MP_NZU + 1) + MP_NZU] = MP_RHO2;
    S.mp_h[MP_NZU] = MP_RHO1;
{ulim}{limits}}}
"""


def condense_constants_code(pre: bool, nb: int) -> str:
    """C statements (run by ``cp_reset`` on the zeroed state) setting the QP entries :func:`condense_code` never
    changes: the slack's bounds and column, the identity blocks of the pre-stabilised ctrl rows, the one-sided
    rail rows' infinite limits and the pre-stabilised ``z``'s infinite bounds."""
    ident = """    for (i = 0; i < MP_NZU; ++i) { /* F_k,k = I */
        S.mp_A[i * (MP_NZU + 1) + i] = 1;
        S.mp_lbx[i] = -INFINITY;
        S.mp_ubx[i] = INFINITY;
    }
""" if pre else ""
    rails = """    for (i = 0; i < MP_N * MP_NB; ++i) { /* q - sigma <= q_high, q + sigma >= q_low */
        S.mp_A[(MP_NUC + i) * (MP_NZU + 1) + MP_NZU] = -1;
        S.mp_A[(MP_NUC + MP_N * MP_NB + i) * (MP_NZU + 1) + MP_NZU] = 1;
        S.mp_lba[MP_NUC + i] = -INFINITY;
        S.mp_uba[MP_NUC + MP_N * MP_NB + i] = INFINITY;
    }
""" if nb else ""
    return f"""    {{
        int i;
{ident}{rails}        S.mp_lbx[MP_NZU] = 0;
        S.mp_ubx[MP_NZU] = INFINITY;
        (void)i;
    }}
"""


def nmpc_design(model, x0, period: float):
    """The Python NMPC the export reproduces and its offline plan: ``(controller, plan)``, as
    :func:`cartpole.mpc.nmpc.nmpc_swingup` builds it (the plan by trajectory optimisation from ``x0``, the first
    iterate converged for ``x0``).

    Parameters
    ----------
    model : CartPoleModel
    x0 : (nx,) array
    period : float
        Control period, s.

    Returns
    -------
    (NMPCController, Trajectory)
    """
    from cartpole.mpc.nmpc import NMPCController
    from cartpole.mpc.options import MPCOptions
    from cartpole.planning.options import PlanOptions
    from cartpole.planning.trajopt import trajopt_swingup

    options = MPCOptions(period=float(period))
    x0 = np.asarray(x0, dtype=float).ravel()
    sp = trajopt_swingup(model.params, x0=x0, plan_model=model, options=PlanOptions(cart_margin=options.cart_margin))
    ctl = NMPCController(model, model.params, options=options, guess=sp.trajectory, x0=x0)
    return ctl, sp.trajectory
