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
