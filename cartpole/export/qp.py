"""A dense QP solver in C with static memory: Goldfarb and Idnani's dual active-set method (the one of quadprog;
DAQP, the NMPC's Python solver, is a dual active-set method too), for

    min 1/2 z' H z + h' z    s.t.  lbx <= z <= ubx,   lba <= A z <= uba

with ``H`` positive definite (the condensed Gauss-Newton Hessian). From the unconstrained minimum it adds the most
violated constraint, takes full or partial steps, and drops constraints whose multiplier would change sign, keeping
``J = L^-T Q`` and the triangular ``R`` of the active normals up to date by Givens rotations (O(n^2) per change).
A bound or a row whose limit is beyond +-1e20 is never active. The optimum is unique, so it is DAQP's solution to
rounding (the NMPC export is checked against the Python controller step for step).

:func:`qp_code` returns the C text (``cartpole/csrc/qp_dual.c`` after the sizes' ``#define`` lines) for sizes
``nz`` (variables) and ``nr`` (general rows): ``qp_solve(H, h, A, lba, uba, lbx, ubx, z)`` returning 0 (optimal), 1
(``H`` not positive definite), 2 (infeasible) or 3 (iteration limit), its work arrays in the static state struct
``S``.
"""
from __future__ import annotations

from cartpole.mpc.nmpc_c import QP_ITER_LIMIT, qp_fields, qp_source  # noqa: F401 - the export's names

#: The solver's one source.
qp_code = qp_source
