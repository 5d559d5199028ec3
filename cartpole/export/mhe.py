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

from cartpole.codegen import render
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
    qp = qp_code(nzmax, (N + 1) * nb, prefix="mq", sized=True) if nb else ""
    code = LINALG + rcode + qp + render("mhe.c.jinja", nb=nb, c_win=c_win, c_stage_n=c_stage_n,
                                        c_stage_0=c_stage_0, c_meas_0=c_meas_0)
    bmacros = ("#define MH_BIDX_AT(i) (MH_BIDX[i])\n#define MH_LO_AT(i) (MH_LO[i])\n#define MH_HI_AT(i) (MH_HI[i])\n"
               if nb else "#define MH_BIDX_AT(i) 0\n#define MH_LO_AT(i) 0\n#define MH_HI_AT(i) 0\n")
    return CPart(tables=tables + bmacros, code=code, fields=fields, reset="    mh_reset();\n",
                 functions=(window, stage, meas))
