"""Benchmark of the nonlinear MPC in the MuJoCo loop: real-time iteration against IPOPT re-solves.

:func:`run_mpc_benchmark` swings the single pole up from hanging rest in MuJoCo twice, in one process, from the same
first iterate (the offline plan converged for the start state, :func:`cartpole.mpc.nmpc.nmpc_swingup`): once under
:class:`~cartpole.mpc.nmpc.NMPCController` (one Gauss-Newton step on the condensed QP per period) and once under
:class:`~cartpole.mpc.ipopt_baseline.IpoptMPC` (the same NLP re-solved by IPOPT from the shifted previous solution each
period: what a do-mpc user gets). Each controller's per-control-step solve times (wall clock, ms) are pooled over
``repeats`` runs; medians and maxima are reported, the speed-up is the ratio of medians. Timings are noisy on a
shared machine: compare medians, in one process.
"""
from __future__ import annotations

import time

import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model, planning_limits, plant_params, read_params
from cartpole.mpc.ddp_mpc import DDPMPCController
from cartpole.mpc.ipopt_baseline import IpoptMPC
from cartpole.mpc.nmpc import NMPCController
from cartpole.mpc.options import MPCOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import simulate
from cartpole.validation.metrics import swingup_success


def _runs(controller, params, x0, duration: float, repeats: int, calls: list | None = None) -> tuple[list, list]:
    """Solve times (ms, pooled) and successes of ``repeats`` runs; with ``calls`` also, for each instant that
    solved, the pair (wall time of the whole ``controller(t, x)`` call, the C step's own time or NaN), ms, appended
    to it."""
    times, ok = [], []
    for _ in range(repeats):
        controller.reset()
        if calls is None:
            ro = simulate(params, controller, x0, duration)
        else:
            run_calls = []

            def timed(t, x):
                n, t0 = len(controller.solve_ms), time.perf_counter()
                u = controller(t, x)
                if len(controller.solve_ms) > n:
                    run_calls.append(1e3 * (time.perf_counter() - t0))
                return u
            ro = simulate(params, timed, x0, duration)
        times.extend(controller.solve_ms)
        if calls is not None:
            c_ms = list(getattr(controller, "step_c_ms", None) or [])
            c_ms += [float("nan")] * (len(run_calls) - len(c_ms))
            calls.extend(zip(run_calls, c_ms))
        ok.append(swingup_success(ro, params))
    return times, ok


def _stats(times) -> dict:
    return {"solve_ms_median": float(np.median(times)), "solve_ms_max": float(np.max(times)),
            "solve_ms_p99": float(np.percentile(times, 99)), "steps": len(times)}


def _overhead(rti, calls: list) -> dict | None:
    """Python's share of a control step: the whole call's wall time minus the compiled step's own (timed inside
    the C, ``rti.step_c_ms``), instant by instant, medians in microseconds; None on the Python step."""
    if rti.step_implementation != "c" or not calls:
        return None
    call, c = (np.array(v, dtype=float) for v in zip(*calls))
    return {"call_us_median": 1e3 * float(np.median(call)), "c_us_median": 1e3 * float(np.median(c)),
            "python_us_median": 1e3 * float(np.median(call - c))}


def _rti_vs_ipopt(params, model, plan, options, x0, duration: float, repeats: int, baseline_repeats: int) -> dict:
    """The RTI NMPC and the IPOPT re-solve baseline on the same swing-up, in this process (see the module doc)."""
    rti = NMPCController(model, params, options=options, guess=plan.trajectory, x0=x0)
    calls: list = []
    t_rti, ok_rti = _runs(rti, params, x0, duration, max(1, int(repeats)), calls)
    base = IpoptMPC(model, params, options=options.replace(qp_solver=None, c_step=False), guess=plan.trajectory,
                    x0=x0)
    t_base, ok_base = _runs(base, params, x0, duration, max(1, int(baseline_repeats)))
    base_doc = {**_stats(t_base), "success": all(ok_base), "unconverged": len(base.unconverged), "solver": "ipopt"}
    return {**_stats(t_rti), "success": all(ok_rti), "failures": len(rti.failures), "N": rti.N,
            "implementation": rti.step_implementation, "overhead": _overhead(rti, calls), "baseline": base_doc,
            "speedup_median": base_doc["solve_ms_median"] / float(np.median(t_rti))}


def run_mpc_benchmark(plant=None, *, period: float = 0.02, horizon: float = 1.2, repeats: int = 3,
                      duration: float = 4.0, baseline_repeats: int = 1, qp_solver: str | None = None,
                      baseline: bool = True, ddp_two_pole: bool = True, u_max=None,
                      cart_max: float | None = None, two_pole: bool = True, ddp: bool = True) -> dict:
    """Per-control-step solve time of the NMPC over a single-pole swing-up in MuJoCo, and of the IPOPT baseline.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (default the shipped single pole).
    period, horizon : float
        Control period and prediction horizon in s (rounded as :class:`~cartpole.mpc.nmpc.NMPCController` does).
    repeats : int
        Closed-loop runs of the NMPC (times pooled); ``baseline_repeats`` those of the baseline (slower).
    duration : float
        s of each run, from hanging rest.
    qp_solver : {'daqp', 'qpoases'}, optional
        The NMPC's QP solver (default :class:`~cartpole.mpc.nmpc.NMPCController`'s).
    baseline : bool
        False skips the IPOPT runs (``baseline`` and ``speedup_median`` are then None).
    ddp_two_pole : bool
        Also time the DDP MPC on the shipped two-pole cart.
    u_max, cart_max : optional
        The bounds ``plant``'s swing-up plans within (:func:`cartpole.models.planning_limits`: the file's, else a
        stated default; the JSON's ``limits``).
    ddp : bool
        False skips the DDP rows (``ddp`` is then None).
    two_pole : bool
        Also the RTI NMPC against the IPOPT baseline on the shipped two-pole cart (6 s runs).

    Returns
    -------
    dict
        ``solve_ms_median``, ``solve_ms_max``, ``solve_ms_p99`` (ms per control step, pooled), ``steps`` (control
        steps timed), ``baseline`` {``solve_ms_median``, ``solve_ms_max``, ``solve_ms_p99``, ``steps``, ``success``,
        ``unconverged`` (instants IPOPT did not converge), ``solver``},
        ``speedup_median`` (baseline median / NMPC median), ``period``, ``horizon`` (s), ``N``, ``qp_solver``,
        ``compiled`` (bool), ``success`` (every NMPC run swung up and held, :func:`swingup_success`),
        ``failures`` (NMPC instants that took the safe action), ``repeats``, ``duration``, ``implementation``
        (``"c"``: the compiled step of ``cartpole/csrc/nmpc.c.jinja``, or ``"python"``), ``overhead`` (with the C
        step: ``call_us_median`` the whole ``controller(t, x)`` call, ``c_us_median`` the C step timed inside the
        C, ``python_us_median`` their difference: Python's overhead per step), ``two_pole`` (the same RTI and
        IPOPT rows on the two-pole cart: the keys above with ``baseline`` and ``speedup_median``); ``ddp``
        {``one_pole``, ``two_pole``: the same swing-up under :class:`~cartpole.mpc.ddp_mpc.DDPMPCController` (one warm-started DDP
        iteration a period), each {``solve_ms_median``, ``solve_ms_max``, ``steps``, ``period``, ``success``,
        ``failures``}}.
    """
    params, limits = planning_limits(plant_params(plant), u_max=u_max, cart_max=cart_max)
    model = build_model(params)
    x0 = model.x_hanging
    plan = trajopt_swingup(params, x0=x0, plan_model=model)
    options = MPCOptions(period=period, horizon=horizon, qp_solver=qp_solver)
    rti = NMPCController(model, params, options=options, guess=plan.trajectory, x0=x0)
    calls: list = []
    t_rti, ok_rti = _runs(rti, params, x0, duration, max(1, int(repeats)), calls)
    failures = len(rti.failures)
    overhead = _overhead(rti, calls)
    med = float(np.median(t_rti))
    base_doc = None
    if baseline:
        base = IpoptMPC(model, params, options=options.replace(qp_solver=None, c_step=False), guess=plan.trajectory,
                        x0=x0)
        t_base, ok_base = _runs(base, params, x0, duration, max(1, int(baseline_repeats)))
        base_doc = {"solve_ms_median": float(np.median(t_base)), "solve_ms_max": float(np.max(t_base)),
                    "solve_ms_p99": float(np.percentile(t_base, 99)), "steps": len(t_base),
                    "success": all(ok_base), "unconverged": len(base.unconverged), "solver": "ipopt"}
    two_doc = None
    if two_pole or (ddp and ddp_two_pole):
        p2 = read_params(SHIPPED_MJCF.with_name("cartpole_two_pole.xml"))
        m2 = build_model(p2)
        plan2 = trajopt_swingup(p2, x0=m2.x_hanging, plan_model=m2)
    if two_pole:  # the double takes longer to swing up: 6 s so that its last second is the hold success needs
        two_doc = _rti_vs_ipopt(p2, m2, plan2, options, m2.x_hanging, max(duration, 6.0), repeats, baseline_repeats)
    ddp_doc = {"one_pole": _ddp_row(params, model, plan, options, x0, duration, repeats)} if ddp else None
    if ddp and ddp_two_pole:
        ddp_doc["two_pole"] = _ddp_row(p2, m2, plan2, options.replace(qp_solver=None), m2.x_hanging,
                                       max(duration, 6.0), repeats)
    return {"solve_ms_median": med, "solve_ms_max": float(np.max(t_rti)), "limits": limits.to_dict(),
            "ddp": ddp_doc,
            "solve_ms_p99": float(np.percentile(t_rti, 99)), "steps": len(t_rti), "baseline": base_doc,
            "speedup_median": None if base_doc is None else base_doc["solve_ms_median"] / med,
            "period": rti.period, "horizon": rti.horizon, "N": rti.N,
            "qp_solver": rti.qp_solver, "compiled": rti.library is not None, "success": all(ok_rti),
            "failures": failures, "repeats": int(repeats), "duration": float(duration),
            "implementation": rti.step_implementation, "overhead": overhead, "two_pole": two_doc}


def _ddp_row(params, model, plan, options, x0, duration: float, repeats: int) -> dict:
    ddp = DDPMPCController(model, params, options=options.replace(solver="ddp"), guess=plan.trajectory, x0=x0)
    times, ok = _runs(ddp, params, x0, duration, max(1, int(repeats)))
    return {"solve_ms_median": float(np.median(times)), "solve_ms_max": float(np.max(times)), "steps": len(times),
            "period": ddp.period, "success": all(ok), "failures": len(ddp.failures)}
