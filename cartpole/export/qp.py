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

from importlib import resources

#: Active-set changes a QP may take before it counts as a failure (the Python NMPC's ``QP_ITER_LIMIT``).
QP_ITER_LIMIT = 1000


def qp_source() -> str:
    """The text of ``cartpole/csrc/qp_dual.c``, the solver's one source."""
    return resources.files("cartpole").joinpath("csrc", "qp_dual.c").read_text()


def qp_fields(nz: int, nr: int, prefix: str = "qp") -> tuple:
    """State-struct members of the solver's work arrays for at most ``nz`` variables and ``nr`` general rows
    (``prefix`` as given to :func:`qp_code`)."""
    return tuple(f.replace("qp_", prefix + "_") for f in (
        f"cp_real qp_J[{nz * nz}];", f"cp_real qp_R[{nz * nz}];", f"cp_real qp_d[{nz}];", f"cp_real qp_zd[{nz}];",
        f"cp_real qp_r[{nz}];", f"cp_real qp_u[{nz + 1}];", f"int qp_act[{nz + 1}];",
        f"unsigned char qp_isact[{2 * nz + 2 * max(nr, 1)}];", "int qp_nz;", "int qp_nr;"))


def qp_code(nz: int, nr: int, row_len=None, *, prefix: str = "qp", sized: bool = False) -> str:
    """C text of ``qp_solve`` for ``nz`` variables and ``nr`` general rows (see the module doc).

    ``row_len`` (nr,) ints: row ``r`` of ``A`` is zero from column ``row_len[r]`` on except its last column (the
    condensed rows of a causal horizon: stage ``k`` depends on the first ``(k + 1) nu`` inputs and the slack);
    default dense rows. ``J`` is stored transposed (``L^-1``, row by row) so that the rotations of its columns run
    over contiguous memory. ``prefix`` names its function and fields (two solvers in one export); with ``sized``
    the sizes are the run-time ``S.<prefix>_nz``, ``S.<prefix>_nr`` (at most ``nz``, ``nr``; dense rows), set by
    the caller before ``<prefix>_solve``.
    """
    from cartpole.export.csource import table

    if sized:
        head = ("#define QP_NZ (S.qp_nz)\n#define QP_NR (S.qp_nr)\n#define QP_ROWLEN(r) (QP_NZ - 1)\n")
    else:
        lens = [nz - 1] * max(1, nr) if row_len is None else [int(v) for v in row_len]
        head = (table("QP_RLEN", lens, "int") if nr else "") + (f"#define QP_NZ {nz}\n#define QP_NR {nr}\n"
                                                                  "#define QP_ROWLEN(r) (QP_RLEN[r])\n")
    text = head + f"#define QP_ITER_LIMIT {QP_ITER_LIMIT}\n" + qp_source()
    return text.replace("qp_", prefix + "_").replace("QP_", prefix.upper() + "_")
