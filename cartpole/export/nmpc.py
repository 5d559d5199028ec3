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

from cartpole.codegen import render
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
    code = lcode + qp_code(nz, nr, row_len(N, nu, nb, pre)) + render(
        "nmpc.c.jinja", pre=pre, nb=nb, nu=nu, has_plan=has_plan, c_lin=c_lin, c_stage=c_stage, c_roll=c_roll)
    return CPart(tables=tables, code=code, fields=fields, reset="    mp_constants();\n    mp_reset();\n",
                 functions=(lin, rollout))


def row_len(N: int, nu: int, nb: int, pre: bool) -> list:
    """Causal length of each general row of the condensed QP (see :func:`cartpole.export.qp.qp_code`): the
    pre-stabilised ctrl rows of stage ``k`` then the rail rows (upper, then lower) of stage ``k`` reach the first
    ``(k + 1) nu`` unknowns.

    Parameters
    ----------
    N, nu, nb : int
        Stages, inputs per stage, bounded joints.
    pre : bool
        Pre-stabilised condensing (the ctrl bounds are rows).

    Returns
    -------
    list of int
    """
    return ([(k + 1) * nu for k in range(N) for _i in range(nu)] if pre else []) + [
        (k + 1) * nu for _ in range(2) for k in range(N) for _b in range(nb)]


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
