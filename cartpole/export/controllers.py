"""The controller parts of an export (:class:`cartpole.export.program.CPart`): the C file of ``cartpole/csrc`` that
implements ``cp_ctrl_eval(t, x, u)`` and the tables and constants it needs, taken from the Python controller's own
gains so the C computes what :mod:`cartpole.control` computes.

=========  ===================  ========================================================================
method     C file               Python class it reproduces
=========  ===================  ========================================================================
lqr        ``cp_lqr.c``         :class:`~cartpole.control.linear.LinearFeedback`
pid        ``cp_pid.c``         :class:`~cartpole.control.pid.CascadedPID`
tvlqr      ``cp_tvlqr.c``       :class:`~cartpole.control.tvlqr.TVLQRController` and its LQR catch
energy     ``cp_energy.c``      :class:`~cartpole.control.switching.SwitchingController` of the energy law
=========  ===================  ========================================================================
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from cartpole.export.csource import table
from cartpole.export.program import CPart


def linear_data(fb, name: str) -> tuple:
    """The tables ``<NAME>_K``, ``_XEQ``, ``_UEQ``, ``_LO``, ``_HI`` of the
    :class:`~cartpole.control.linear.LinearFeedback` ``fb`` (``u = clip(u* - K e, lo, hi)``, ``cp_linear_eval``).

    Parameters
    ----------
    fb : LinearFeedback
    name : str
        C prefix of its tables.

    Returns
    -------
    tuple of (name, ctype, values)
    """
    p = name.upper()
    return ((f"{p}_K", "cp_real", fb.K), (f"{p}_XEQ", "cp_real", fb.x_eq), (f"{p}_UEQ", "cp_real", fb.u_eq),
            (f"{p}_LO", "cp_real", fb.u_low), (f"{p}_HI", "cp_real", fb.u_high))


def linear_code(fb, name: str) -> tuple[str, str]:
    """For a part written as C text: ``static const`` tables of ``fb`` (:func:`linear_data`) and the macro
    ``<name>_eval(x, u)`` calling ``cp_linear_eval`` (``cartpole/csrc/cp_common.c``) on them.

    Parameters
    ----------
    fb : LinearFeedback
    name : str
        C prefix of its tables and macro.

    Returns
    -------
    (str, str)
        Tables and the macro.
    """
    p = name.upper()
    tables = "".join(table(n, v, c) for n, c, v in linear_data(fb, name))
    code = (f"\n#define {name}_eval(x, u) cp_linear_eval({p}_K, {p}_XEQ, {p}_UEQ, {p}_LO, {p}_HI, (x), (u))\n")
    return tables, code


def linear_part(fb) -> CPart:
    """``cp_lqr.c`` of a :class:`~cartpole.control.linear.LinearFeedback` (the LQR balance)."""
    return CPart(sources=("cp_lqr.c",), data=linear_data(fb, "lqr"))


def pid_part(pid) -> CPart:
    """``cp_pid.c`` of a :class:`~cartpole.control.pid.CascadedPID` (one pole on a cart): the cart PD, the angle
    PID on the filtered rate, conditional integration and the integrator clamp, each as the Python class does.

    Parameters
    ----------
    pid : CascadedPID

    Returns
    -------
    CPart
    """
    g = pid.gains
    span = pid.model.u_high[0] - pid.model.u_low[0]
    zmax = float(0.5 * span / abs(g.ki)) if g.ki and np.isfinite(span) else np.inf
    constants = (("PID_KP", "cp_real", g.kp), ("PID_KI", "cp_real", g.ki), ("PID_KD", "cp_real", g.kd),
                 ("PID_KPC", "cp_real", g.kp_cart), ("PID_KDC", "cp_real", g.kd_cart),
                 ("PID_TAU", "cp_real", g.filter_tau), ("PID_TILT", "cp_real", g.tilt_limit),
                 ("PID_UEQ", "cp_real", pid.model.u_eq[0]), ("PID_LO", "cp_real", pid.model.u_low[0]),
                 ("PID_HI", "cp_real", pid.model.u_high[0]), ("PID_ZMAX", "cp_real", zmax))
    defines = (("PID_SLIDE", pid.slide), ("PID_HINGE", pid.hinge), ("PID_ANTI_WINDUP", 1 if pid.anti_windup else 0))
    return CPart(sources=("cp_pid.c",), data=(("PID_XEQ", "cp_real", pid.model.x_eq),), constants=constants,
                 defines=defines)


def tvlqr_part(ctl) -> CPart:
    """``cp_tvlqr.c`` of a :class:`~cartpole.control.tvlqr.TVLQRController`: the plan's cubic-Hermite state and
    first-order-hold input (or the gains' own discrete reference), the gain held per step (discrete) or linearly
    interpolated (continuous), the clip, and the LQR catch from the end of the plan on.

    Parameters
    ----------
    ctl : TVLQRController

    Returns
    -------
    CPart
        The plan and the gains as tables (times in double).
    """
    traj, g = ctl.traj, ctl.gains
    exact = bool(getattr(g, "has_reference", False))
    discrete = g.method == "discrete"
    lim = np.asarray(ctl.u_limits, dtype=float)
    n = int(g.K.shape[0])
    data = linear_data(ctl.catch, "catch") + (("TV_LO", "cp_real", lim[:, 0]), ("TV_HI", "cp_real", lim[:, 1]),
                                              ("TV_K", "cp_real", g.K))
    constants = [("TV_T_END", "double", ctl.T), ("G_T0", "double", g.t[0]), ("G_DT", "double", g.dt)]
    if exact:
        data += (("TV_XREF", "cp_real", g.x_ref[:n]), ("TV_UREF", "cp_real", g.u_ref[:n]))
    else:
        constants.append(("TV_SHIFT", "double", 0.5 * g.dt if discrete else 0.0))
        data += (("TV_T", "double", traj.t), ("TV_X", "cp_real", traj.x), ("TV_XD", "cp_real", traj.xdot),
                 ("TV_U", "cp_real", traj.u))
        if not discrete:
            data += (("G_T", "double", g.t),)
    defines = (("TV_EXACT", int(exact)), ("TV_DISCRETE", int(discrete)), ("G_N", n), ("TV_N", int(traj.N)))
    return CPart(sources=("cp_tvlqr.c",), data=data, constants=tuple(constants), defines=defines, plan=True)


def energy_part(sw) -> CPart:
    """``cp_energy.c`` of a :class:`~cartpole.control.switching.SwitchingController` of an
    :class:`~cartpole.control.energy.EnergyShapingController` and its LQR catch: the energy law CasADi-generated
    (``cp_energy``, the same expression graph, its parameters as the table ``ENERGY_PRM``), the mode logic in C.

    Parameters
    ----------
    sw : SwitchingController

    Returns
    -------
    CPart
    """
    fun, prm = sw.swingup.law
    x, p = ca.SX.sym("x", fun.size1_in(0)), ca.SX.sym("prm", fun.size1_in(1))
    law = ca.Function("cp_energy", [x, p], [fun(x, p)[0]], ["x", "prm"], ["u"])
    data = (("ENERGY_PRM", "cp_real", prm),) + linear_data(sw.catch, "catch") + (("SW_S", "cp_real", sw.catch.S),)
    constants = (("SW_RHO", "cp_real", sw.rho), ("SW_RELEASE", "cp_real", sw.release_factor * sw.rho))
    return CPart(sources=("cp_energy.c",), data=data, constants=constants, functions=(law,), plan=True)
