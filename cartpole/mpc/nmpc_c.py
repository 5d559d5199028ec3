"""The NMPC's real-time iteration as C: one source (``cartpole/csrc/nmpc.c.jinja`` with the dual active-set QP of
``cartpole/csrc/qp_dual.c``) rendered for one controller, which :class:`CompiledNMPC` builds into a shared library
for the MuJoCo loop (``cartpole/csrc/nmpc_loop.c.jinja``, called through ctypes by
:class:`cartpole.mpc.nmpc.NMPCController`) and :mod:`cartpole.export.nmpc` copies into the exported folder. The two
are the same C compiled with the same floating-point semantics (``-std=c99``: no contraction into fused
multiply-adds), so the loop's ctrl and the export's are equal.

The model's maths are CasADi-generated: one stage (``cp_nmpc_lin``: the period's physics steps chained, its value
and exact Jacobians ``A_k``, ``B_k``) and the reseed rollout (``cp_nmpc_rollout``).
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np

from cartpole.codegen import (build_loop_library, compiled_or_none, generated_code, load_private_copy, qp_fields,
                              qp_source, render)
from cartpole.mpc.stage_functions import stage_expression, stage_rollout

#: The safe action of a failed solve (``cp_nmpc_state``'s return, ``cp_nmpc_eval``'s ``action``).
ACTIONS = {1: "previous plan", 2: "upright LQR"}
#: Why a solve failed (``cp_nmpc_state``'s ``status``, ``nmpc.c.jinja``'s ``mp_status``).
STATUS_REASONS = {1: "the QP solver (C dual active set) found the Hessian not positive definite",
                  2: "the QP solver (C dual active set) found the QP infeasible",
                  3: "the QP solver (C dual active set) reached its iteration limit",
                  4: "the QP's solution or the predicted states were not finite",
                  5: "the measured state is not finite"}


#: ``cp_nmpc_state(long* solves, double* t, double* seconds, int* status, int* qp_iterations)``'s argument types (it
#: returns the action).
NMPC_STATE_ARGTYPES = [ctypes.POINTER(ctypes.c_long), ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                       ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]


@dataclass(frozen=True)
class SolveRecord:
    """The last solve of the compiled NMPC step, read from the C (``cp_nmpc_state``).

    Attributes
    ----------
    solves : int
        Solves since the reset (a held ctrl is not one).
    t : float
        Time (s) of the last solve.
    seconds : float
        Its wall time timed inside the C (``cp_clock_seconds``), s.
    status : int
        0 solved, else a key of :data:`STATUS_REASONS`.
    action : int
        0 solved, else the safe action taken (a key of :data:`ACTIONS`).
    qp_iterations : int
        Active-set changes the QP took (summed over the solve's Gauss-Newton iterations; warm-started from the last
        solve's active set, ``qp_dual.c``).
    """

    solves: int
    t: float
    seconds: float
    status: int
    action: int
    qp_iterations: int = 0

    def failure(self) -> dict | None:
        """``{"t", "reason", "action"}`` (as :attr:`cartpole.mpc.nmpc.NMPCController.failures`) when the solve
        took the safe action, else None."""
        if self.status == 0 and self.action == 0:
            return None
        return {"t": self.t, "reason": STATUS_REASONS.get(self.status, f"status {self.status}"),
                "action": ACTIONS.get(self.action, "upright LQR")}


def state_function(lib) -> ctypes._CFuncPtr:
    """``cp_nmpc_state`` of the loaded library ``lib`` (the loop's or an exported program's), typed.

    Parameters
    ----------
    lib : ctypes.CDLL

    Returns
    -------
    ctypes function
        Call it through :func:`read_state`.
    """
    fn = lib.cp_nmpc_state
    fn.argtypes, fn.restype = NMPC_STATE_ARGTYPES, ctypes.c_int
    return fn


def read_state(fn) -> SolveRecord:
    """The :class:`SolveRecord` of the last solve from ``fn`` (:func:`state_function`).

    Parameters
    ----------
    fn : ctypes function

    Returns
    -------
    SolveRecord
    """
    solves, t, seconds, status, iters = (ctypes.c_long(), ctypes.c_double(), ctypes.c_double(), ctypes.c_int(),
                                         ctypes.c_int())
    action = fn(ctypes.byref(solves), ctypes.byref(t), ctypes.byref(seconds), ctypes.byref(status),
                 ctypes.byref(iters))
    return SolveRecord(int(solves.value), float(t.value), float(seconds.value), int(status.value), int(action),
                       int(iters.value))


def row_len(N: int, nu: int, nb: int, pre: bool) -> list:
    """Causal length of each general row of the condensed QP: the pre-stabilised ctrl rows of stage ``k``, then
    the rail rows (upper, then lower) of stage ``k``, reach the first ``(k + 1) nu`` unknowns.

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


@dataclass(frozen=True)
class NMPCSource:
    """One controller's NMPC as C (see the module doc).

    Attributes
    ----------
    code : str
        Tables, the QP solver and the NMPC's static functions (``ctrl_eval``, ``mp_constants``, ``mp_reset``...).
    fields : tuple of str
        Members of the state struct ``S``.
    reset : str
        Statements a reset runs on the zeroed ``S``.
    functions : tuple of casadi.Function
        The CasADi Functions it calls (``cp_nmpc_lin``, ``cp_nmpc_rollout``).
    """

    code: str
    fields: tuple
    reset: str
    functions: tuple


def _flat(a) -> list:
    return np.asarray(a, dtype=float).ravel(order="C").tolist()


def nmpc_source(ctl, plan, *, runtime_data: bool = False) -> NMPCSource:
    """The C of :class:`~cartpole.mpc.nmpc.NMPCController` ``ctl`` (just reset) whose offline plan is ``plan``.

    Parameters
    ----------
    ctl : NMPCController
        Plain or pre-stabilised condensing (``ctl.prestabilize``).
    plan : Trajectory or None
        The offline plan whose inputs extend the shifted tail.
    runtime_data : bool
        The first iterate and the plan are pointers set at run time (the loop's library, one per model and
        settings) instead of tables (the export).

    Returns
    -------
    NMPCSource
    """
    pre = bool(ctl.prestabilize)
    p = ctl.problem
    N, steps, nx, nu = int(ctl.N), int(ctl.steps), p.nx, p.nu
    nzu = N * nu
    nz = nzu + 1
    nb = len(p.bounded)
    nuc = nzu if pre else 0  # pre-stabilised: the ctrl bounds are the first nuc rows
    nr = nuc + 2 * N * nb
    lin = stage_expression(ctl.model, steps, "cp_nmpc_lin")  # (x_next, A, B); A, B dense, column-major
    roll = stage_rollout(ctl.model, steps, N, "cp_nmpc_rollout")
    S0, U0 = ctl.plan
    fb = ctl.lqr
    has_plan = plan is not None
    code = qp_source(nz, nr, row_len(N, nu, nb, pre)) + render(
        "nmpc.c.jinja", pre=pre, nb=nb, nu=nu, N=N, steps=steps, nzu=nzu, nuc=nuc, nh=len(p.hinges),
        iters=int(ctl.iterations), has_plan=has_plan, runtime_data=runtime_data,
        plan_n=int(plan.N) if has_plan else 0, plan_t=_flat(plan.t) if has_plan else [],
        plan_u=_flat(plan.u) if has_plan else [], S0=_flat(S0), U0=_flat(U0), Qs=_flat(p.Qs), Rs=_flat(p.Rs),
        P=_flat(p.P), x_goal=_flat(p.x_goal), u_goal=_flat(p.u_goal), u_low=_flat(p.u_low), u_high=_flat(p.u_high),
        hinges=list(p.hinges) or [-1], bounded=list(p.bounded), q_low=_flat(p.q_low), q_high=_flat(p.q_high),
        dt=float(p.dt), tol=float(ctl.tol), rho1=float(p.rho1), rho2=float(p.rho2), lqr_K=_flat(fb.K),
        lqr_xeq=_flat(fb.x_eq), lqr_ueq=_flat(fb.u_eq), lqr_lo=_flat(fb.u_low), lqr_hi=_flat(fb.u_high),
        lin=lin.name(), lin_arg=max(1, lin.sz_arg()), lin_res=max(1, lin.sz_res()), roll=roll.name(),
        roll_arg=max(1, roll.sz_arg()), roll_res=max(1, roll.sz_res()))
    fields = (f"cp_real mp_S[{(N + 1) * nx}];", f"cp_real mp_U[{nzu}];", f"cp_real mp_Sa[{(N + 1) * nx}];",
              f"cp_real mp_Sn[{(N + 1) * nx}];", f"cp_real mp_Un[{nzu}];", f"cp_real mp_St[{(N + 1) * nx}];",
              f"cp_real mp_Ut[{nzu}];", "long mp_k_plan;", "long mp_k_last;", "int mp_has_last;", "int mp_age;",
              "int mp_action;", "int mp_status;", "int mp_qp_iters;", "long mp_solves;", "double mp_t;",
              "double mp_seconds;",
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
    return NMPCSource(code=code, fields=fields, reset="    mp_constants();\n    mp_reset();\n",
                      functions=(lin, roll))


def loop_source(ctl, plan) -> str:
    """The translation unit of the loop's library (``cartpole/csrc/nmpc_loop.c.jinja``) for ``ctl`` and ``plan``.

    Parameters
    ----------
    ctl : NMPCController
    plan : Trajectory or None

    Returns
    -------
    str
    """
    src = nmpc_source(ctl, plan, runtime_data=True)
    p = ctl.problem
    wrap = [1 if i < ctl.model.nq and i in p.hinges else 0 for i in range(p.nx)]
    return render("nmpc_loop.c.jinja", wrap=wrap, fields=src.fields,
                  sz_w=max([1] + [int(f.sz_w()) for f in src.functions]),
                  sz_iw=max([1] + [int(f.sz_iw()) for f in src.functions]),
                  generated=generated_code(src.functions), controller=src.code, has_plan=plan is not None)


_DP = ctypes.POINTER(ctypes.c_double)
#: The package's C files the loop's library links beside its unit (:func:`~cartpole.codegen.build_loop_library`).
CLOCK_SHARED = ("cp_common", "cp_clock")


class CompiledNMPC:
    """The loop's NMPC step: the library of :func:`loop_source`, loaded privately (its own copy of the static state,
    so two controllers never share one), with this run's first iterate and plan.

    Parameters
    ----------
    ctl : NMPCController
        The controller (just reset: its ``plan`` is the first iterate).
    plan : Trajectory or None
        Its offline plan.
    """

    def __init__(self, ctl, plan):
        p = ctl.problem
        self.library = build_loop_library(loop_source(ctl, plan), "nmpc_step", nx=p.nx, nq=ctl.model.nq, nu=p.nu,
                                          steps=ctl.steps, shared=CLOCK_SHARED)
        lib = load_private_copy(self.library, "nmpc_step_")
        lib.cp_nmpc_set_data.argtypes = [_DP, _DP, _DP, _DP, ctypes.c_long]
        lib.cp_nmpc_set_data.restype = None
        lib.cp_nmpc_reset.argtypes = []
        lib.cp_nmpc_reset.restype = None
        lib.cp_nmpc_eval.argtypes = [ctypes.c_double, _DP, _DP, ctypes.POINTER(ctypes.c_int)]
        lib.cp_nmpc_eval.restype = ctypes.c_int
        lib.cp_nmpc_plan.argtypes = [_DP, _DP]
        lib.cp_nmpc_plan.restype = None
        self._state = state_function(lib)
        self._lib = lib
        S0, U0 = ctl.plan
        self._data = [np.ascontiguousarray(S0, dtype=float), np.ascontiguousarray(U0, dtype=float)]
        if plan is not None:
            self._data += [np.ascontiguousarray(plan.t, dtype=float), np.ascontiguousarray(plan.u, dtype=float)]
            n = int(plan.N)
        else:
            self._data += [np.zeros(1), np.zeros(1)]
            n = 0
        lib.cp_nmpc_set_data(*(d.ctypes.data_as(_DP) for d in self._data), n)
        self._x = np.zeros(p.nx)
        self._u = np.zeros(p.nu)
        self._action = ctypes.c_int(0)
        self._xp, self._up = self._x.ctypes.data_as(_DP), self._u.ctypes.data_as(_DP)
        self._shape = (ctl.N + 1, p.nx), (ctl.N, p.nu)
        self.reset()

    def reset(self) -> None:
        """Start a new run (back to the first iterate)."""
        self._lib.cp_nmpc_reset()

    def step(self, t: float, x) -> tuple[int, np.ndarray, int]:
        """``(code, u, action)`` of ``ctrl_eval`` at ``t`` (s) for the state ``x`` (nx,): code 0 solved, 3 the safe
        action (``action`` 1 the previous plan's input, 2 the upright LQR); ``u`` (nu,) is a new array."""
        self._x[:] = x
        code = self._lib.cp_nmpc_eval(float(t), self._xp, self._up, ctypes.byref(self._action))
        return int(code), self._u.copy(), int(self._action.value)

    def last_solve(self) -> SolveRecord:
        """The last solve as the C recorded it (its wall time timed inside the library, ``cp_clock_seconds``)."""
        return read_state(self._state)

    def plan(self) -> tuple[np.ndarray, np.ndarray]:
        """The current iterate: nodes (N+1, nx) and inputs (N, nu), new arrays."""
        S, U = np.zeros(self._shape[0]), np.zeros(self._shape[1])
        self._lib.cp_nmpc_plan(S.ctypes.data_as(_DP), U.ctypes.data_as(_DP))
        return S, U


def compiled_nmpc(ctl, plan) -> CompiledNMPC | None:
    """:class:`CompiledNMPC` of ``ctl`` and ``plan``, or None where there is no C compiler (or
    ``CARTPOLE_NO_COMPILE`` is set): then the controller runs its Python step (a note on stderr).

    Parameters
    ----------
    ctl : NMPCController
    plan : Trajectory or None

    Returns
    -------
    CompiledNMPC or None
    """
    return compiled_or_none(lambda: CompiledNMPC(ctl, plan), "NMPC step",
                            "the NMPC runs its Python step (same QP, slower)")
