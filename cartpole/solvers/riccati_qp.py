"""The SQP's stage QP by Riccati recursions and a primal-dual active set, in C (``riccati_qp.c`` beside this file).

The QP of each :class:`~cartpole.solvers.sqp.CollocationSQP` iteration is an optimal control problem in stage form
(stages k = 0..N-1, state ``s_k`` (nz), input ``w_k`` (nu)):

    min  sum_k 1/2 y_k' Hy_k y_k + gy_k' y_k,   y_k = (s_k, w_k)
    s.t. s_k+1 = T_k y_k + (ct_k, 0),   s_0 = (0, du_0),   lo_k <= s_k <= hi_k (k >= 1),   lo_0 <= du_0 <= hi_0

(``T``, ``ct``, ``Hy``, ``gy`` as :mod:`cartpole.solvers.sqp_functions`' ``sqp_stages`` returns them; the input
entries of knot k >= 1 are ``w_k-1``). The condensed route (DAQP on the dense QP in the N+1 inputs) pays an
O(N^2) condensing and an O(N^3) factorisation every iteration; here each active set costs O(N):

- an **active set** holds some bounds: a held input bound removes that input from the stage's Riccati step (its
  value fixed), a held state bound (the rail, a limited joint, the pinned ``x_N``) is a row ``e' s_k = b`` whose
  multiplier enters the recursion as a linear term on ``s_k``;
- the held state rows also enter the recursion as ``rho/2 (e' s_k - b)^2`` (``rho`` relative to the stage
  Hessians, :data:`RHO`): zero with a zero gradient wherever the rows hold, so the active set's solution and
  multipliers are the same, but the stages before a pinned end become a stabilised regulator instead of an open-loop
  propagation through the unstable modes (on the triple the responses otherwise grew to 1e12 to 1e16 over 100
  stages), and a reduced Hessian is indefinite only where the constrained problem is not convex;
- the equality-constrained QP of an active set: one backward Riccati pass (status 1 when a reduced Hessian of
  the active set is not positive definite: the SQP then shifts the Hessian, or convexifies it; from the second
  active set of a solve on, only the stages below its latest change are factorised again, the others' factors
  being the same numbers), one
  forward pass, and per held state row its response (a backward pass of the linear term, a forward pass), the
  rows' multipliers from the small system of their values (``nrow x nrow``, by pivoted elimination);
- the **primal-dual active-set** update (Hintermuller, Ito and Kunisch): bounds the solution violates are added,
  held bounds whose multiplier has the wrong sign released, all at once; after 10 such updates, or when a
  simultaneous change makes the held rows dependent, one change at a time (the largest violation). It starts from
  the caller's active set (the previous SQP iteration's: near convergence it is already right, one pass).

The answer is the QP's unique optimum (the QP is strictly convex), the same as DAQP's to rounding
(``tests/solvers/test_riccati_qp.py``). It returns a status instead of a guarantee: a QP whose held rows become
dependent (an infeasible linearisation) or whose active set does not settle in ``max_iter`` sets is reported, and
the SQP then solves that QP by the condensed DAQP route, which also handles infeasible QPs (soft rows).
"""
from __future__ import annotations

import ctypes
import functools
from pathlib import Path

import numpy as np

from cartpole.codegen import build_c_library, compiled_or_none

#: Statuses of :meth:`StageQP.solve`.
STATUS = {0: "optimal", 1: "not convex", 2: "dependent rows (infeasible?)", 3: "active set did not settle"}
#: Active sets tried before a QP counts as unsettled.
MAX_ACTIVE_SETS = 60

#: The held rows' penalty (``rho`` of :meth:`StageQP.solve`) relative to the largest diagonal entry of the stage
#: Hessians.
RHO = 1e4
_SOURCE = Path(__file__).with_name("riccati_qp.c")


@functools.lru_cache(maxsize=None)
def _library(nx: int, nu: int, n_free: int = 0):
    """The solver compiled for ``nx`` states (the last ``n_free`` free at knot 0) and ``nu`` inputs (sizes fixed at
    compile time), loaded."""
    src = f"#define RQP_NX {int(nx)}\n#define RQP_NU {int(nu)}\n#define RQP_NP {int(n_free)}\n" + _SOURCE.read_text()
    lib = ctypes.CDLL(build_c_library(src, "riccati_qp"))
    vp, ci = ctypes.c_void_p, ctypes.c_int
    fn = lib.rqp_solve
    fn.argtypes = [ci, ci, ci, vp, vp, vp, vp, vp, vp, vp, vp, vp, ci, ctypes.c_double, ci, ctypes.c_double, vp, vp, vp]
    fn.restype = ci
    size = lib.rqp_work_size
    size.argtypes = [ci, ci, ci, ci, ctypes.POINTER(ctypes.c_long), ctypes.POINTER(ctypes.c_long)]
    size.restype = None
    return fn, size


def available(nx: int, nu: int, n_free: int = 0) -> bool:
    """True when the C solver for ``nx`` states and ``nu`` inputs is built (or was already) and loads; False without
    a C compiler or with ``CARTPOLE_NO_COMPILE`` set (then the SQP uses DAQP on the condensed QP)."""
    return compiled_or_none(lambda: _library(nx, nu, n_free), "Riccati QP solver",
                            "the SQP condenses its QPs for DAQP") is not None


def max_rows(N: int, nx: int) -> int:
    """State rows a QP may hold at once (the pinned ``x_N``, and room for the rail and joint limits of many knots);
    a QP that needs more is reported (status 2) and solved the condensed way."""
    return int(min(N * nx, 8 * nx + 64))


class StageQP:
    """The C solver bound to one size (``N`` stages, ``nx`` states, ``nu`` inputs), with its work and output buffers.
    ``n_free``: the last ``n_free`` state entries are free at knot 0 (bounded there like ``du_0``; parameters the
    dynamics carry from stage to stage, such as the SQP's time scale of a minimum-time problem); the others are
    ``dx_0 = 0``.

    Call :meth:`solve` once per QP; ``active`` carries the active set from one call to the next (reset it with
    :meth:`reset`).
    """

    def __init__(self, N: int, nx: int, nu: int, n_free: int = 0):
        self.N, self.nx, self.nu, self.nz = int(N), int(nx), int(nu), int(nx + nu)
        if not 0 <= int(n_free) <= self.nx:
            raise ValueError(f"StageQP: n_free = {n_free} free states at knot 0 of {nx}; give 0 to {nx}.")
        self.n_free = int(n_free)
        self._fn, size = _library(self.nx, self.nu, self.n_free)
        self.maxrow = max_rows(self.N, self.nx)
        nd, ni = ctypes.c_long(0), ctypes.c_long(0)
        size(self.N, self.nx, self.nu, self.maxrow, ctypes.byref(nd), ctypes.byref(ni))
        self._work = np.zeros(nd.value)
        self._iwork = np.zeros(ni.value, dtype=np.intc)
        self.active = np.zeros((self.N + 1) * self.nz, dtype=np.intc)
        self.dz = np.zeros((self.N + 1, self.nz))
        self.nb = np.zeros((self.N + 1, self.nz))
        self._iters = ctypes.c_int(0)
        self._fixed = [a.ctypes.data for a in (self.active, self.dz, self.nb)]
        self._iters_ref = ctypes.byref(self._iters)
        self.iterations = 0

    def reset(self) -> None:
        """Start the next QP from no held bound (but the equalities)."""
        self.active[:] = 0

    def solve(self, T, ct, Hy, gy, lo, hi, *, tol: float = 1e-9, max_iter: int = MAX_ACTIVE_SETS,
              rho: float | None = None) -> int:
        """Solve one QP (module docstring) from the current active set.

        Parameters
        ----------
        T : (N, nz, nz + nu) array
            Stage dynamics ``[A_k B_k]``.
        ct : (N, nx) array
            The dynamics' constant (state rows).
        Hy : (N, nz + nu, nz + nu) array
            Stage Hessians (a reduced Hessian that is not positive definite is status 1), ``gy`` (N, nz + nu) the
            gradients.
        lo, hi : (N + 1, nz) arrays
            Bounds on the knots' steps (``-inf``/``inf`` where none; equal where pinned); knot 0's state entries
            are ignored (``dx_0 = 0``) but for the last ``n_free``.
        tol : float
            Primal and dual tolerance of the active-set test (scaled units).
        max_iter : int
            Active sets tried before giving up.
        rho : float, optional
            Weight of ``rho/2 (e' s_k - b)^2`` added for each held state row (zero, with a zero gradient, wherever
            the rows hold: the same solution and multipliers); default :data:`RHO` times the largest diagonal entry of
            ``Hy``; 0 for none.

        Returns
        -------
        int
            0 optimal (``dz`` (N+1, nz) the step, ``nb`` (N+1, nz) the bounds' multipliers, positive at an upper
            bound, ``active`` the final set), else 1, 2, 3 (:data:`STATUS`); ``iterations`` the active sets tried.
        """
        N, nx, nz = self.N, self.nx, self.nz
        ny = nz + self.nu
        arrs = [np.ascontiguousarray(a, dtype=float) for a in (T, ct, Hy, gy, lo, hi)]
        for a, n in zip(arrs, (N * nz * ny, N * nx, N * ny * ny, N * ny, (N + 1) * nz, (N + 1) * nz)):
            if a.size != n:
                raise ValueError(f"StageQP.solve: an input has {a.size} entries where {n} are expected.")
        if rho is None:
            rho = RHO * max(float(np.abs(np.diagonal(arrs[2].reshape(N, ny, ny), axis1=1, axis2=2)).max()), 1e-300)
        st = self._fn(N, nx, self.nu, *(a.ctypes.data for a in arrs), *self._fixed, int(max_iter), float(tol),
                      self.maxrow, float(rho), self._work.ctypes.data, self._iwork.ctypes.data, self._iters_ref)
        self.iterations = int(self._iters.value)
        return int(st)
