"""The controller parts of an export (:class:`cartpole.export.program.CPart`): ``ctrl_eval(t, x, u)`` returning
``CP_OK``, written from the Python controller's own gains so the C computes what :mod:`cartpole.control` computes.
"""
from __future__ import annotations

import numpy as np

from cartpole.export.csource import literal, table
from cartpole.export.program import CPart


def linear_code(fb, name: str) -> tuple[str, str]:
    """Tables and a static function ``<name>_eval(x, u)`` of the :class:`~cartpole.control.linear.LinearFeedback`
    ``fb``: ``u = clip(u* - K e, low, high)``, ``e`` the wrapped error from ``x*``.

    Parameters
    ----------
    fb : LinearFeedback
    name : str
        C prefix of its tables and function.

    Returns
    -------
    (str, str)
        Tables and code.
    """
    p = name.upper()
    tables = (table(f"{p}_K", fb.K) + table(f"{p}_XEQ", fb.x_eq) + table(f"{p}_UEQ", fb.u_eq)
              + table(f"{p}_LO", fb.u_low) + table(f"{p}_HI", fb.u_high))
    code = f"""
static void {name}_eval(const cp_real* x, cp_real* u)
{{
    cp_real e[NX], acc;
    int i, j;
    cp_error(x, {p}_XEQ, e);
    for (i = 0; i < CP_NU; ++i) {{
        acc = 0;
        for (j = 0; j < NX; ++j) {{
            acc += {p}_K[i * NX + j] * e[j];
        }}
        u[i] = cp_clip({p}_UEQ[i] - acc, {p}_LO[i], {p}_HI[i]);
    }}
}}
"""
    return tables, code


def linear_part(fb) -> CPart:
    """``ctrl_eval`` of a :class:`~cartpole.control.linear.LinearFeedback` (the LQR balance)."""
    tables, code = linear_code(fb, "lqr")
    code += """
static int ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    (void)t;
    lqr_eval(x, u);
    return CP_OK;
}
"""
    return CPart(tables=tables, code=code)


def pid_part(pid) -> CPart:
    """``ctrl_eval`` of a :class:`~cartpole.control.pid.CascadedPID` (one pole on a cart): the cart PD, the angle
    PID on the filtered rate, conditional integration and the integrator clamp, each as the Python class does.

    Parameters
    ----------
    pid : CascadedPID

    Returns
    -------
    CPart
    """
    g = pid.gains
    nq = pid.model.nq
    consts = {"PID_KP": g.kp, "PID_KI": g.ki, "PID_KD": g.kd, "PID_KPC": g.kp_cart, "PID_KDC": g.kd_cart,
              "PID_TAU": g.filter_tau, "PID_TILT": g.tilt_limit, "PID_UEQ": float(pid.model.u_eq[0]),
              "PID_LO": float(pid.model.u_low[0]), "PID_HI": float(pid.model.u_high[0]),
              "PID_ZMAX": float(0.5 * (pid.model.u_high[0] - pid.model.u_low[0]) / abs(g.ki))
              if g.ki and np.isfinite(pid.model.u_high[0] - pid.model.u_low[0]) else np.inf}
    tables = "".join(f"static const cp_real {k} = {literal(v)};\n" for k, v in consts.items())
    tables += table("PID_XEQ", pid.model.x_eq)
    slide, hinge = pid.slide, pid.hinge
    aw = 1 if pid.anti_windup else 0
    code = f"""
static cp_real pid_law(const cp_real* e, cp_real z, cp_real yf, cp_real* e_i)
{{
    cp_real ref = cp_clip(-(PID_KPC * e[{slide}] + PID_KDC * e[{nq + slide}]), -PID_TILT, PID_TILT);
    *e_i = e[{hinge}] - ref;
    return PID_UEQ - (PID_KP * *e_i + PID_KI * z + PID_KD * yf);
}}

static int ctrl_eval(double t, const cp_real* x, cp_real* u)
{{
    cp_real e[NX], rate, e_i, u_raw, push;
    double dt;
    cp_error(x, PID_XEQ, e);
    rate = e[{nq + hinge}];
    if (!S.pid_started) {{
        S.pid_started = 1;
        S.pid_t = t;
        S.pid_y = rate;
    }} else if (t > S.pid_t) {{
        dt = t - S.pid_t;
        S.pid_t = t;
        if (PID_TAU > 0) {{
            S.pid_y += (cp_real)(1.0 - exp(-dt / PID_TAU)) * (rate - S.pid_y);
        }} else {{
            S.pid_y = rate;
        }}
        if (PID_KI != 0) {{
            u_raw = pid_law(e, S.pid_z, S.pid_y, &e_i);
            push = -PID_KI * e_i;
            if (!({aw} && ((u_raw > PID_HI && push > 0) || (u_raw < PID_LO && push < 0)))) {{
                S.pid_z += (cp_real)dt * e_i;
            }}
            if ({aw}) {{
                S.pid_z = cp_clip(S.pid_z, -PID_ZMAX, PID_ZMAX);
            }}
        }}
    }}
    u_raw = pid_law(e, S.pid_z, S.pid_y, &e_i);
    u[0] = cp_clip(u_raw, PID_LO, PID_HI);
    return CP_OK;
}}
"""
    return CPart(tables=tables, code=code, fields=("int pid_started;", "double pid_t;", "cp_real pid_z;",
                                                   "cp_real pid_y;"))


def _double_table(name: str, values) -> str:
    """A ``static const double`` table (times stay double in a float build)."""
    return table(name, values, "double")


def tvlqr_part(ctl) -> CPart:
    """``ctrl_eval`` of a :class:`~cartpole.control.tvlqr.TVLQRController`: the plan's cubic-Hermite state and
    first-order-hold input (or the gains' own discrete reference), the gain held per step (discrete) or linearly
    interpolated (continuous), the clip, and the LQR catch from the end of the plan on.

    Parameters
    ----------
    ctl : TVLQRController

    Returns
    -------
    CPart
        The plan and the gains as ``const`` tables (times in double).
    """
    traj, g = ctl.traj, ctl.gains
    exact = bool(getattr(g, "has_reference", False))
    ctabs, ccode = linear_code(ctl.catch, "catch")
    lim = np.asarray(ctl.u_limits, dtype=float)
    n = int(g.K.shape[0])
    tables = ctabs + table("TV_LO", lim[:, 0]) + table("TV_HI", lim[:, 1]) + table("TV_K", g.K)
    discrete = g.method == "discrete"
    tables += (f"static const double TV_T_END = {literal(ctl.T)};\nstatic const double G_T0 = {literal(g.t[0])};\n"
               f"static const double G_DT = {literal(g.dt)};\n#define G_N {n}\n#define TV_N {int(traj.N)}\n")
    if not exact:
        tables += f"static const double TV_SHIFT = {literal(0.5 * g.dt if discrete else 0.0)};\n"
    if not exact and not discrete:
        tables += _double_table("G_T", g.t)
    if exact:
        tables += table("TV_XREF", g.x_ref[:n]) + table("TV_UREF", g.u_ref[:n])
    else:
        tables += (_double_table("TV_T", traj.t) + table("TV_X", traj.x) + table("TV_XD", traj.xdot)
                   + table("TV_U", traj.u))
    code = ccode + """
static int gain_index(double t)
{
    double f = floor((t - G_T0) / G_DT + 1e-9);
    return f < 0 ? 0 : (f > G_N - 1 ? G_N - 1 : (int)f);
}
"""
    if exact:
        code += """
static int ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    cp_real e[NX], acc;
    int i, j, k;
    if (t >= TV_T_END - 1e-12) {
        catch_eval(x, u);
        for (i = 0; i < CP_NU; ++i) {
            u[i] = cp_clip(u[i], TV_LO[i], TV_HI[i]);
        }
        return CP_OK;
    }
    k = gain_index(t);
    cp_error(x, TV_XREF + k * NX, e);
    for (i = 0; i < CP_NU; ++i) {
        acc = 0;
        for (j = 0; j < NX; ++j) {
            acc += TV_K[(k * CP_NU + i) * NX + j] * e[j];
        }
        u[i] = cp_clip(TV_UREF[k * CP_NU + i] - acc, TV_LO[i], TV_HI[i]);
    }
    return CP_OK;
}
"""
    else:
        kij = ("            kij = TV_K[(gk * CP_NU + i) * NX + j];" if discrete else _INTERP_GAIN)
        code += """
/* the interval k of the plan holding t (clamped) and s in [0, 1], as Trajectory._locate */
static int plan_locate(double t, double* h, double* s)
{
    int lo = 0, hi = TV_N + 1, mid, k;
    t = t < TV_T[0] ? TV_T[0] : (t > TV_T[TV_N] ? TV_T[TV_N] : t);
    while (lo < hi) { /* first index with TV_T[index] > t */
        mid = (lo + hi) / 2;
        if (TV_T[mid] <= t) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    k = lo - 1;
    k = k < 0 ? 0 : (k > TV_N - 1 ? TV_N - 1 : k);
    *h = TV_T[k + 1] - TV_T[k];
    *s = (t - TV_T[k]) / *h;
    return k;
}

static int ctrl_eval(double t, const cp_real* x, cp_real* u)
{
    cp_real xr[NX], e[NX], acc, kij;
    double h, s, h00, h10, h01, h11, tu;
    int i, j, k;
@DECL@
    if (t >= TV_T_END - 1e-12) {
        catch_eval(x, u);
        for (i = 0; i < CP_NU; ++i) {
            u[i] = cp_clip(u[i], TV_LO[i], TV_HI[i]);
        }
        return CP_OK;
    }
    k = plan_locate(t, &h, &s);
    h00 = 2 * pow(s, 3) - 3 * pow(s, 2) + 1;
    h10 = pow(s, 3) - 2 * pow(s, 2) + s;
    h01 = -2 * pow(s, 3) + 3 * pow(s, 2);
    h11 = pow(s, 3) - pow(s, 2);
    for (i = 0; i < NX; ++i) {
        xr[i] = (cp_real)(h00 * TV_X[k * NX + i] + h10 * h * TV_XD[k * NX + i] + h01 * TV_X[(k + 1) * NX + i]
                          + h11 * h * TV_XD[(k + 1) * NX + i]);
    }
    cp_error(x, xr, e);
    tu = t + TV_SHIFT < TV_T_END ? t + TV_SHIFT : TV_T_END;
    k = plan_locate(tu, &h, &s);
@GK@
    for (i = 0; i < CP_NU; ++i) {
        acc = 0;
        for (j = 0; j < NX; ++j) {
@KIJ@
            acc += kij * e[j];
        }
        u[i] = cp_clip((cp_real)((1 - s) * TV_U[k * CP_NU + i] + s * TV_U[(k + 1) * CP_NU + i]) - acc,
                       TV_LO[i], TV_HI[i]);
    }
    return CP_OK;
}
"""
        code = code.replace("@KIJ@", kij).replace("@DECL@", "    int gk;" if discrete else "    double w;")
        code = code.replace("@GK@", "    gk = gain_index(t);" if discrete else "")
    return CPart(tables=tables, code=code)


#: C statements giving ``kij``, the (i, j) entry of a continuous TVLQR gain at ``t``, as ``numpy.interp`` gives it.
_INTERP_GAIN = """            if (t <= G_T[0]) {
                kij = TV_K[i * NX + j];
            } else if (t >= G_T[G_N - 1]) {
                kij = TV_K[((G_N - 1) * CP_NU + i) * NX + j];
            } else {
                int a = gain_index(t);
                while (a + 1 < G_N && G_T[a + 1] <= t) {
                    ++a;
                }
                while (a > 0 && G_T[a] > t) {
                    --a;
                }
                w = (TV_K[((a + 1) * CP_NU + i) * NX + j] - TV_K[(a * CP_NU + i) * NX + j]) / (G_T[a + 1] - G_T[a]);
                kij = (cp_real)(w * (t - G_T[a]) + TV_K[(a * CP_NU + i) * NX + j]);
            }"""


def switching_code(sw, swingup_call: str) -> tuple[str, str, tuple]:
    """Tables, code and state fields of a :class:`~cartpole.control.switching.SwitchingController`'s mode logic
    around a swing-up law called by the C statement ``swingup_call`` (writing ``u`` from ``x``): ``e' S e`` of the
    catch, the catch below ``rho``, the swing-up again above ``release_factor * rho``.

    Parameters
    ----------
    sw : SwitchingController
    swingup_call : str

    Returns
    -------
    (str, str, tuple)
    """
    ctabs, ccode = linear_code(sw.catch, "catch")
    tables = ctabs + table("SW_S", sw.catch.S) + (f"static const cp_real SW_RHO = {literal(sw.rho)};\n"
                                                  f"static const cp_real SW_RELEASE = "
                                                  f"{literal(sw.release_factor * sw.rho)};\n")
    code = ccode + f"""
static cp_real sw_cost(const cp_real* x)
{{
    cp_real e[NX], es[NX], c = 0;
    int i, j;
    cp_error(x, CATCH_XEQ, e);
    for (j = 0; j < NX; ++j) {{
        es[j] = 0;
        for (i = 0; i < NX; ++i) {{
            es[j] += e[i] * SW_S[i * NX + j];
        }}
    }}
    for (j = 0; j < NX; ++j) {{
        c += es[j] * e[j];
    }}
    return c;
}}

static int ctrl_eval(double t, const cp_real* x, cp_real* u)
{{
    cp_real cost = sw_cost(x);
    (void)t;
    if (!S.sw_catch && cost < SW_RHO) {{
        S.sw_catch = 1;
    }} else if (S.sw_catch && cost > SW_RELEASE) {{
        S.sw_catch = 0;
    }}
    if (S.sw_catch) {{
        catch_eval(x, u);
    }} else {{
        {swingup_call}
    }}
    return CP_OK;
}}
"""
    return tables, code, ("int sw_catch;",)


def energy_part(sw) -> CPart:
    """``ctrl_eval`` of a :class:`~cartpole.control.switching.SwitchingController` of an
    :class:`~cartpole.control.energy.EnergyShapingController` and its LQR catch: the energy law CasADi-generated
    (``cp_energy``, the same expression graph, its parameters as a table), the mode logic in C.

    Parameters
    ----------
    sw : SwitchingController

    Returns
    -------
    CPart
    """
    import casadi as ca

    from cartpole.export.csource import call

    fun, prm = sw.swingup.law
    x, p = ca.SX.sym("x", fun.size1_in(0)), ca.SX.sym("prm", fun.size1_in(1))
    law = ca.Function("cp_energy", [x, p], [fun(x, p)[0]], ["x", "prm"], ["u"])
    tables, code, fields = switching_code(sw, call(law, ["x", "ENERGY_PRM"], ["u"]))
    return CPart(tables=table("ENERGY_PRM", prm) + tables, code=code, fields=fields, functions=(law,))
