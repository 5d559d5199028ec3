"""Compressed Hermite-Simpson on one interval: the defect and the effort, defined once.

On an interval of length ``h`` with knots ``(x_k, u_k)``, ``(x_k+1, u_k+1)`` and ``f_k = f(x_k, u_k)``:

    x_c = (x_k + x_k+1) / 2 + h (f_k - f_k+1) / 8,   u_c = (u_k + u_k+1) / 2,
    defect = x_k+1 - x_k - h (f_k + 4 f(x_c, u_c) + f_k+1) / 6,

and the effort ``integral u^2 dt`` over the interval of the piecewise-linear input is Simpson's rule,
``h (u_k^2 + 4 u_c^2 + u_k+1^2) / 6`` (exact). Both the SX transcription (:mod:`cartpole.ocp.collocation`) and
the compiled interval functions (:mod:`cartpole.ocp.compiled_nlp`) are built from these.
"""
from __future__ import annotations

import casadi as ca


def hs_interval_function(f: ca.Function) -> ca.Function:
    """``(x_k, u_k, x_k1, u_k1, f_k, f_k1, h) -> (defect (nx,), x_c (nx,))`` of compressed Hermite-Simpson.

    ``f(x (nx,), u (nu,)) -> x_dot (nx,)``; the sizes are read from ``f``, ``h`` is in s.
    """
    nx, nu = f.size1_in(0), f.size1_in(1)
    xk, xk1, fk, fk1 = (ca.SX.sym(n, nx) for n in ("xk", "xk1", "fk", "fk1"))
    uk, uk1 = ca.SX.sym("uk", nu), ca.SX.sym("uk1", nu)
    h = ca.SX.sym("h")
    xc = 0.5 * (xk + xk1) + h / 8 * (fk - fk1)
    fc = f(xc, 0.5 * (uk + uk1))
    defect = xk1 - xk - h / 6 * (fk + 4 * fc + fk1)
    return ca.Function("hs_interval", [xk, uk, xk1, uk1, fk, fk1, h], [defect, xc],
                       ["xk", "uk", "xk1", "uk1", "fk", "fk1", "h"], ["defect", "xc"])


def simpson_effort_terms(uk, uk1):
    """``u_k^2 + 4 u_c^2 + u_k+1^2`` with ``u_c = (u_k + u_k+1) / 2``, elementwise (CasADi or numpy).

    Times ``h / 6`` it is the interval's effort ``integral u^2 dt`` (ctrl^2 s) of each input's first-order
    hold; summed over the inputs it is ``integral u'u dt``.
    """
    uc = 0.5 * (uk + uk1)
    return uk**2 + 4 * uc**2 + uk1**2
