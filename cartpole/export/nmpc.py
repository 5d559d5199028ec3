"""The NMPC's controller part (:class:`cartpole.export.program.CPart`): real-time iteration in C, as
:class:`cartpole.mpc.nmpc.NMPCController` runs it.

Each control instant: the stored iterate shifted by the periods since the last solve (its tail extended with the
offline plan's input while the plan lasts, else the upright LQR's, through the CasADi-generated stage), re-seeded
from the measured state when it is garbage, aligned to the measured hinge turns; then ``iterations`` Gauss-Newton
steps, each the CasADi-generated condensing (``cp_nmpc_qp_data``, the same graph the Python controller compiles)
and the condensed QP solved by the static-memory dual active-set solver of :mod:`cartpole.export.qp`; the first
input applied. A QP that fails, or a step that is not finite, takes the Python controller's safe action (the
previous plan's input mid swing-up, the upright LQR near upright) and returns ``CP_FALLBACK``.

Both condensings of the Python controller: plain (``z = du``, the ctrl bounds are bounds of ``z``) and
pre-stabilised (``z = dv`` with ``du = fu + Fu dv``, the ctrl bounds are general rows ``Fu``, causal like the rail's;
the double pole at the default horizon: its plain Hessian's condition number is about 1e6, the pre-stabilised one's
about 5), the same QP rows in the same order as :meth:`cartpole.mpc.nmpc.NMPCController._gn_step` builds them.
"""
from __future__ import annotations

import casadi as ca
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
    from cartpole.mpc.stage_functions import stage_functions

    pre = bool(ctl.prestabilize)
    p = ctl.problem
    N, steps, nx, nu = int(ctl.N), int(ctl.steps), p.nx, p.nu
    nzu = N * nu
    nz = nzu + 1
    nb = len(p.bounded)
    nuc = nzu if pre else 0  # pre-stabilised: the ctrl bounds are the first nuc rows
    nr = nuc + 2 * N * nb
    fns = stage_functions(ctl.model, steps, N, compiled=False, prestabilized=pre)
    args = [ca.MX.sym(f"a{i}", fns.qp_data.size_in(i)) for i in range(fns.qp_data.n_in())]
    qp_data = ca.Function("cp_nmpc_qp_data", args, fns.qp_data(*args))
    xs, us = ca.MX.sym("x", nx), ca.MX.sym("u", nu)
    stage = ca.Function("cp_nmpc_stage", [xs, us], [fns.stage(xs, us)[0]])
    Ur = ca.MX.sym("U", nu, N)
    rollout = ca.Function("cp_nmpc_rollout", [xs, Ur], [fns.rollout(xs, Ur)])
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
              f"cp_real mp_Hu[{nzu * nzu}];", f"cp_real mp_hu[{nzu}];", f"cp_real mp_g[{nx * (N + 1)}];",
              f"cp_real mp_G[{nx * N * nzu}];", f"cp_real mp_goal[{nx}];", f"cp_real mp_tmp[{nx * N}];",
              f"cp_real mp_Fu[{nzu * nzu if pre else 1}];", f"cp_real mp_fu[{nzu if pre else 1}];",
              *qp_fields(nz, nr))
    c_qp = call(qp_data, ["x", "Sx", "Ux", "S.mp_goal", "MP_UG", "MP_QS", "MP_RS", "MP_P"],
                ["S.mp_Hu", "S.mp_hu", "S.mp_g", "S.mp_G"] + (["S.mp_Fu", "S.mp_fu"] if pre else []))
    c_stage = call(stage, ["S.mp_S + MP_N * NX", "ut"], ["xt"])
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
    rows = """
    for (k = 0; k < MP_N; ++k) { /* stage-major, bound-minor: q_k - sigma <= q_high, q_k + sigma >= q_low */
        for (b = 0; b < MP_NB; ++b) {
            int rr = MP_NUC + k * MP_NB + b, q = MP_BIDX[b];
            cp_real val = Sx[(k + 1) * NX + q] + S.mp_g[(k + 1) * NX + q];
            for (j = 0; j < MP_NZU; ++j) {
                cp_real gv = S.mp_G[((long)k * MP_NZU + j) * NX + q];
                S.mp_A[rr * (MP_NZU + 1) + j] = gv;
                S.mp_A[(MP_N * MP_NB + rr) * (MP_NZU + 1) + j] = gv;
            }
            S.mp_A[rr * (MP_NZU + 1) + MP_NZU] = -1;
            S.mp_A[(MP_N * MP_NB + rr) * (MP_NZU + 1) + MP_NZU] = 1;
            S.mp_lba[rr] = -INFINITY;
            S.mp_uba[rr] = MP_QHI[b] - val;
            S.mp_lba[MP_N * MP_NB + rr] = MP_QLO[b] - val;
            S.mp_uba[MP_N * MP_NB + rr] = INFINITY;
        }
    }
""" if nb else "    (void)b;\n"
    row_len = ([(k + 1) * nu for k in range(N) for _i in range(nu)] if pre else []) + [
        (k + 1) * nu for _ in range(2) for k in range(N) for _b in range(nb)]
    ctrl_rows = """
    for (i = 0; i < MP_NUC; ++i) { /* ctrl rows: u_low - (U + fu) <= Fu dv <= u_high - (U + fu); Fu column-major */
        cp_real un = Ux[i] + S.mp_fu[i];
        for (j = 0; j < MP_NZU; ++j) {
            S.mp_A[i * (MP_NZU + 1) + j] = S.mp_Fu[j * MP_NZU + i];
        }
        S.mp_A[i * (MP_NZU + 1) + MP_NZU] = 0;
        S.mp_lba[i] = MP_ULO[i % CP_NU] - un;
        S.mp_uba[i] = MP_UHI[i % CP_NU] - un;
    }
""" if pre else ""
    bounds = ("""        S.mp_lbx[i] = -INFINITY;
        S.mp_ubx[i] = INFINITY;
""" if pre else """        S.mp_lbx[i] = MP_ULO[i % CP_NU] - Ux[i];
        S.mp_ubx[i] = MP_UHI[i % CP_NU] - Ux[i];
""")
    du = ("""        du = S.mp_fu[i];
        for (j = 0; j < (i / CP_NU + 1) * CP_NU; ++j) {
            du += S.mp_Fu[j * MP_NZU + i] * S.mp_z[j];
        }
""" if pre else "        du = S.mp_z[i];\n")
    code = lcode + qp_code(nz, nr, row_len) + plan_input + f"""
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
    int i, j, k, b, code;
    cp_real acc, du;
    for (i = 0; i < NX; ++i) {{
        S.mp_goal[i] = MP_XG[i];
    }}
    for (i = 0; i < MP_NH; ++i) {{
        int hh = MP_HINGE[i];
        S.mp_goal[hh] += 2 * CP_PI_ * rint((Sx[MP_N * NX + hh] - S.mp_goal[hh]) / (2 * CP_PI_));
    }}
    {c_qp}
    for (i = 0; i < MP_NZU; ++i) {{
        for (j = 0; j < MP_NZU; ++j) {{
            S.mp_H[i * (MP_NZU + 1) + j] = S.mp_Hu[i * MP_NZU + j];
        }}
        S.mp_H[i * (MP_NZU + 1) + MP_NZU] = 0;
        S.mp_H[MP_NZU * (MP_NZU + 1) + i] = 0;
        S.mp_h[i] = S.mp_hu[i];
{bounds}    }}
    S.mp_H[MP_NZU * (MP_NZU + 1) + MP_NZU] = MP_RHO2;
    S.mp_h[MP_NZU] = MP_RHO1;
    S.mp_lbx[MP_NZU] = 0;
    S.mp_ubx[MP_NZU] = INFINITY;
{ctrl_rows}{rows}    code = qp_solve(S.mp_H, S.mp_h, S.mp_A, S.mp_lba, S.mp_uba, S.mp_lbx, S.mp_ubx, S.mp_z);
    if (code != 0 || !mp_finite(S.mp_z, MP_NZU)) {{
        return 1;
    }}
    *step = 0;
    for (k = 0; k <= MP_N; ++k) {{
        for (i = 0; i < NX; ++i) {{
            acc = S.mp_g[k * NX + i];
            if (k > 0) {{
                cp_real a2 = 0;
                for (j = 0; j < MP_NZU; ++j) {{
                    a2 += S.mp_G[((long)(k - 1) * MP_NZU + j) * NX + i] * S.mp_z[j];
                }}
                acc += a2;
            }}
            S.mp_Sn[k * NX + i] = Sx[k * NX + i] + acc;
        }}
    }}
    for (i = 0; i < MP_NZU; ++i) {{
{du}        S.mp_Un[i] = cp_clip(Ux[i] + du, MP_ULO[i % CP_NU], MP_UHI[i % CP_NU]);
        *step = fabs(du) > *step ? fabs(du) : *step;
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
    return CPart(tables=tables, code=code, fields=fields, reset="    mp_reset();\n",
                 functions=(qp_data, stage, rollout))


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
    sp = trajopt_swingup(model.params, x0=x0, model=model, options=PlanOptions(cart_margin=options.cart_margin))
    ctl = NMPCController(model, model.params, options=options, guess=sp.trajectory, x0=x0)
    return ctl, sp.trajectory
