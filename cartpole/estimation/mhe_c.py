"""The moving-horizon estimator's period as C: one source (``cartpole/csrc/mhe.c.jinja``, with the dual active-set
QP of ``cartpole/csrc/qp_dual.c`` for a binding joint range) rendered for one estimator, which :class:`CompiledMHE`
builds into a shared library for the MuJoCo loop (``cartpole/csrc/mhe_loop.c.jinja``, called through ctypes by
:class:`cartpole.estimation.mhe.MovingHorizonEstimator`) and :mod:`cartpole.export.mhe` copies into the exported
folder. The two are the same C compiled with the same floating-point semantics (``-std=c99``: no contraction), so
the loop's estimate and the export's are equal; the Python step of :mod:`cartpole.estimation.mhe` (the same Riccati
recursion in numpy) is the path without a compiler and the tests' reference.

The model's maths are CasADi-generated: the window's stages and measurements with their Jacobians
(``cp_mhe_window``), one interval (``cp_mhe_stage``) and one node's measurement (``cp_mhe_meas``), from
:func:`cartpole.estimation.mhe_functions.window_functions`.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass

import casadi as ca
import numpy as np

from cartpole.codegen import (build_loop_library, compiled_or_none, generated_code, load_private_copy, qp_fields,
                              qp_source, render)
from cartpole.estimation.mhe_functions import window_functions


@dataclass(frozen=True)
class MHESource:
    """One estimator's MHE as C (see the module doc).

    Attributes
    ----------
    code : str
        Its tables, the bounded QP's solver (with bounded joints) and the static functions ``mh_reset``,
        ``est_reset(y, x)``, ``est_update(y, U, x)``.
    fields : tuple of str
        Members of the state struct ``S``.
    functions : tuple of casadi.Function
        The CasADi Functions it calls (``cp_mhe_window``, ``cp_mhe_stage``, ``cp_mhe_meas``).
    """

    code: str
    fields: tuple
    functions: tuple


def _fn(fn: ca.Function) -> dict:
    """A generated function's name and argument/result pointer counts, for the template's ``call`` macro."""
    return {"name": fn.name(), "n_arg": max(1, fn.sz_arg()), "n_res": max(1, fn.sz_res())}


def mhe_functions(model, steps: int, h: ca.Function, N: int) -> tuple:
    """The CasADi Functions the C calls, named for the export: ``(cp_mhe_window, cp_mhe_stage, cp_mhe_meas)``
    (:func:`~cartpole.estimation.mhe_functions.window_functions`' graphs, uncompiled).

    Parameters
    ----------
    model : CartPoleModel
    steps : int
        Physics steps per period.
    h : casadi.Function
        Measurement model.
    N : int
        Intervals in the window.

    Returns
    -------
    tuple of casadi.Function
    """
    nx, nu = model.nx, model.nu
    fns = window_functions(model, steps, h, N, compiled=False)
    X, UU, UH = ca.MX.sym("X", nx, N + 1), ca.MX.sym("UU", nu * steps, N), ca.MX.sym("UH", nu, N + 1)
    window = ca.Function("cp_mhe_window", [X, UU, UH], fns.window(X, UU, UH))
    x, Uv, u = ca.MX.sym("x", nx), ca.MX.sym("U", nu * steps), ca.MX.sym("u", nu)
    stage = ca.Function("cp_mhe_stage", [x, Uv], fns.stage(x, Uv))
    meas = ca.Function("cp_mhe_meas", [x, u], fns.measurement(x, u))
    return window, stage, meas


def mhe_source(mhe, model, h: ca.Function) -> MHESource:
    """The C of the estimator ``mhe`` (:class:`~cartpole.estimation.mhe.MovingHorizonEstimator`) on ``model``
    with the measurement model ``h``.

    Parameters
    ----------
    mhe : MovingHorizonEstimator
    model : CartPoleModel
    h : casadi.Function

    Returns
    -------
    MHESource
    """
    nx, nu, ny, m, N = mhe.nx, mhe.nu, mhe.ny, mhe.steps, mhe.N
    des = mhe.design
    L = des["L"]
    r = int(L.shape[1])
    rs = max(1, r)
    bidx = [int(v) for v in des["bounded"]]
    nb = len(bidx)
    nzmax = nx + N * r
    window, stage, meas = mhe_functions(model, m, h, N)
    qp = qp_source(nzmax, (N + 1) * nb, prefix="mq", sized=True) if nb else ""
    flat = lambda a: np.asarray(a, dtype=float).ravel(order="C").tolist()  # noqa: E731
    code = qp + render(
        "mhe.c.jinja", N=N, R=r, NB=nb, NZMAX=nzmax, L=flat(L if r else np.zeros((nx, 1))), P0=flat(des["P0"]),
        RV=flat(des["RV"]), V=flat(mhe.V), W=flat(mhe.W), bidx=bidx, lo=flat(des["low"]), hi=flat(des["high"]),
        win=_fn(window), stage=_fn(stage), meas=_fn(meas))
    nbr = max(1, (N + 1) * nb)
    fields = (f"cp_real mh_X[{(N + 1) * nx}];", f"cp_real mh_E[{max(1, N * r)}];", f"cp_real mh_Y[{(N + 1) * ny}];",
              f"cp_real mh_UU[{N * nu * m}];", f"cp_real mh_UH[{(N + 1) * nu}];", f"cp_real mh_xbar[{nx}];",
              f"cp_real mh_P[{nx * nx}];", f"cp_real mh_Pinv[{nx * nx}];", "int mh_n;", "int mh_failed;",
              f"cp_real mh_F[{nx * N}];", f"cp_real mh_A[{nx * nx * N}];", f"cp_real mh_Yh[{ny * (N + 1)}];",
              f"cp_real mh_C[{ny * nx * (N + 1)}];", f"cp_real mh_K[{N * rs * nx}];", f"cp_real mh_k[{N * rs}];",
              f"cp_real mh_d[{N * nx}];", f"cp_real mh_dX[{(N + 1) * nx}];", f"cp_real mh_dE[{N * rs}];",
              f"cp_real mh_T[{(N + 1) * nx * (nzmax + 1)}];", f"cp_real mh_B[{(N + 1) * ny * (nzmax + 1)}];",
              f"cp_real mh_H[{nzmax * nzmax}];", f"cp_real mh_H2[{nzmax * nzmax}];", f"cp_real mh_g[{nzmax}];",
              f"cp_real mh_z[{nzmax}];", f"cp_real mh_rows[{nbr * nzmax}];", f"cp_real mh_rlo[{nbr}];",
              f"cp_real mh_rhi[{nbr}];", f"cp_real mh_blo[{nzmax}];", f"cp_real mh_bhi[{nzmax}];",
              f"cp_real mh_zq[{nzmax}];", *(qp_fields(nzmax, (N + 1) * nb, prefix="mq") if nb else ()))
    return MHESource(code=code, fields=fields, functions=(window, stage, meas))


def loop_source(mhe, model, h: ca.Function) -> str:
    """The translation unit of the loop's library (``cartpole/csrc/mhe_loop.c.jinja``) for ``mhe``.

    Parameters
    ----------
    mhe : MovingHorizonEstimator
    model : CartPoleModel
    h : casadi.Function

    Returns
    -------
    str
    """
    src = mhe_source(mhe, model, h)
    return render("mhe_loop.c.jinja", fields=src.fields, sz_w=max([1] + [int(f.sz_w()) for f in src.functions]),
                  sz_iw=max([1] + [int(f.sz_iw()) for f in src.functions]),
                  generated=generated_code(src.functions), estimator=src.code)


_DP = ctypes.POINTER(ctypes.c_double)


class CompiledMHE:
    """The loop's MHE step: the library of :func:`loop_source`, loaded privately (its own copy of the static state,
    so two estimators never share one).

    Parameters
    ----------
    mhe : MovingHorizonEstimator
    model : CartPoleModel
    h : casadi.Function
    """

    def __init__(self, mhe, model, h: ca.Function):
        self.library = build_loop_library(loop_source(mhe, model, h), "mhe_step", nx=mhe.nx, nq=model.nq,
                                          nu=mhe.nu, ny=mhe.ny, steps=mhe.steps, shared=("cp_common", "cp_linalg"))
        lib = load_private_copy(self.library, "mhe_step_")
        lib.mhe_loop_start.argtypes = [_DP, _DP, _DP]
        lib.mhe_loop_start.restype = None
        lib.mhe_loop_update.argtypes = [_DP, _DP, _DP]
        lib.mhe_loop_update.restype = ctypes.c_int
        lib.mhe_loop_window.argtypes = [_DP]
        lib.mhe_loop_window.restype = ctypes.c_int
        lib.mhe_loop_arrival.argtypes = [_DP, _DP]
        lib.mhe_loop_arrival.restype = None
        self._lib = lib
        self.nx, self.N = mhe.nx, mhe.N
        self._x, self._y = np.zeros(mhe.nx), np.zeros(mhe.ny)
        self._U = np.zeros(mhe.nu * mhe.steps)
        self._X = np.zeros((mhe.N + 1, mhe.nx))
        self._xp, self._yp, self._Up = (a.ctypes.data_as(_DP) for a in (self._x, self._y, self._U))

    def start(self, x0, y0) -> np.ndarray:
        """A new run from the first estimate ``x0`` (nx,) and measurement ``y0`` (ny,): the estimate (``x0`` with
        its bounded positions clipped), a new array."""
        x0 = np.ascontiguousarray(x0, dtype=float)
        self._y[:] = y0
        self._lib.mhe_loop_start(x0.ctypes.data_as(_DP), self._yp, self._xp)
        return self._x.copy()

    def update(self, y, U) -> tuple[np.ndarray, bool]:
        """One period: ``(x_hat, failed)`` from the measurement ``y`` (ny,) and the period's ctrl ``U`` (nu,
        steps); ``x_hat`` is a new array, ``failed`` True when the Gauss-Newton step failed (the prediction kept)."""
        self._y[:] = y
        self._U[:] = np.asarray(U, dtype=float).ravel(order="F")
        failed = self._lib.mhe_loop_update(self._yp, self._Up, self._xp)
        return self._x.copy(), bool(failed)

    def window(self) -> np.ndarray:
        """The window's estimates (n+1, nx), oldest first, a new array."""
        n = self._lib.mhe_loop_window(self._X.ctypes.data_as(_DP))
        return self._X[:n + 1].copy()

    def arrival(self) -> tuple[np.ndarray, np.ndarray]:
        """The arrival cost's centre (nx,) and covariance (nx, nx), new arrays."""
        xb, P = np.zeros(self.nx), np.zeros((self.nx, self.nx))
        self._lib.mhe_loop_arrival(xb.ctypes.data_as(_DP), P.ctypes.data_as(_DP))
        return xb, P


def compiled_mhe(mhe, model, h: ca.Function) -> CompiledMHE | None:
    """:class:`CompiledMHE` of ``mhe``, or None where there is no C compiler (or ``CARTPOLE_NO_COMPILE`` is set):
    then the estimator runs its Python step (a note on stderr).

    Parameters
    ----------
    mhe : MovingHorizonEstimator
    model : CartPoleModel
    h : casadi.Function

    Returns
    -------
    CompiledMHE or None
    """
    return compiled_or_none(lambda: CompiledMHE(mhe, model, h), "MHE step",
                            "the MHE runs its Python step (same Riccati recursion, slower)")
