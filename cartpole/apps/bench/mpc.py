"""Benchmark of the nonlinear MPC in the MuJoCo loop: the compiled real-time iteration against IPOPT re-solves.

:func:`run_mpc_benchmark` swings the single pole up from hanging rest in MuJoCo twice, in one process, from the same
first iterate (the offline plan converged for the start state, :func:`cartpole.mpc.nmpc.nmpc_swingup`): once under
the NMPC as the MuJoCo loop runs it, the exported program's ``cp_step`` compiled once
(:func:`cartpole.export.inloop.in_loop`: one Gauss-Newton step on the condensed QP per period, ``nmpc.c.jinja``; the
Python :class:`~cartpole.mpc.nmpc.NMPCController` without a C compiler), and once under
:class:`~cartpole.mpc.ipopt_baseline.IpoptMPC` (the same NLP re-solved by IPOPT from the shifted previous solution each
period: what a do-mpc user writes first). The compiled step's time is measured inside the C (``cp_clock.c`` around the
step); the whole call from Python around it is timed too, and their difference instant by instant is Python's
overhead. Each controller's per-control-step solve times (ms) are pooled over ``repeats`` runs; medians, p99 and
maxima are reported, the speed-up is the ratio of medians, beside the load average of the machine (timings are
noisy on a shared machine: compare medians, in one process).
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, replace

import numpy as np

from cartpole.export.inloop import in_loop
from cartpole.models import SHIPPED_MJCF, build_model, planning_limits, plant_params, read_params
from cartpole.mpc.ddp_mpc import DDPMPCController
from cartpole.mpc.ipopt_baseline import IpoptMPC
from cartpole.mpc.nmpc import NMPCController
from cartpole.mpc.options import MPCOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import simulate
from cartpole.validation.metrics import swingup_success

#: Issue 39's targets for the compiled step against the IPOPT re-solve (ratios of medians; the one-pole p99, ms).
TARGETS = {"speedup_median": 50.0, "p99_ms": 0.3, "two_pole_speedup_median": 20.0}


@dataclass(frozen=True)
class MPCBenchOptions:
    """Settings of :func:`run_mpc_benchmark`.

    Attributes
    ----------
    period, horizon : float
        Control period and prediction horizon in s (rounded as :class:`~cartpole.mpc.nmpc.NMPCController` does).
    repeats : int
        Closed-loop runs of the NMPC (times pooled); ``baseline_repeats`` those of the baseline (slower).
    duration : float
        s of each run, from hanging rest (6 s at least on two poles).
    qp_solver : {'daqp', 'qpoases'}, optional
        A Python QP solver: the NMPC then runs its Python step (not the compiled program). Default the compiled C.
    baseline : bool
        False skips the IPOPT runs (``baseline`` and ``speedup_median`` are then None).
    two_pole : bool
        Also the NMPC against the IPOPT baseline on the shipped two-pole cart.
    ddp, ddp_two_pole : bool
        Also the DDP MPC rows (on one pole; on the two-pole cart).
    u_max, cart_max : optional
        The bounds ``plant``'s swing-up plans within (:func:`cartpole.models.planning_limits`: the file's, else a
        stated default; the JSON's ``limits``).
    """

    period: float = 0.02
    horizon: float = 1.2
    repeats: int = 3
    duration: float = 4.0
    baseline_repeats: int = 1
    qp_solver: str | None = None
    baseline: bool = True
    two_pole: bool = True
    ddp: bool = True
    ddp_two_pole: bool = True
    u_max: object = None
    cart_max: float | None = None

    def replace(self, **changes) -> MPCBenchOptions:
        """A copy with ``changes``."""
        return replace(self, **changes)


def _runs(controller, params, x0, duration: float, repeats: int, calls: list | None = None,
          iterations: list | None = None, per_run: list | None = None) -> tuple[list, list]:
    """Solve times (ms, pooled) and successes of ``repeats`` runs; with ``calls`` also, for each instant that
    solved, the pair (wall time of the whole ``controller(t, x)`` call, the C step's own time or NaN), ms, appended
    to it; with ``iterations`` the QP's active-set changes of each solve, where the controller records them; with
    ``per_run`` each run's solve times (a list per run)."""
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
        if per_run is not None:
            per_run.append(list(controller.solve_ms))
        if iterations is not None:
            iterations.extend(getattr(controller, "qp_iterations", ()))
        if calls is not None:
            c_ms = list(getattr(controller, "step_c_ms", None) or [])
            c_ms += [float("nan")] * (len(run_calls) - len(c_ms))
            calls.extend(zip(run_calls, c_ms))
        ok.append(swingup_success(ro, params))
    return times, ok


def _stats(times) -> dict:
    return {"solve_ms_median": float(np.median(times)), "solve_ms_max": float(np.max(times)),
            "solve_ms_p99": float(np.percentile(times, 99)), "steps": len(times)}


def _best_of(per_run: list) -> dict:
    """``solve_ms_best_median``, ``solve_ms_best_p99``: over the control steps, each step's fastest time among the
    repeated runs (the runs are the same: the same states, the same QPs), which leaves out a shared machine's
    preemptions; None with one run or runs of different lengths."""
    n = {len(r) for r in per_run}
    if len(per_run) < 2 or len(n) != 1:
        return {"solve_ms_best_median": None, "solve_ms_best_p99": None}
    best = np.min(np.array(per_run, dtype=float), axis=0)
    return {"solve_ms_best_median": float(np.median(best)), "solve_ms_best_p99": float(np.percentile(best, 99))}


def _overhead(rti, calls: list) -> dict | None:
    """Python's share of a control step: the whole call's wall time minus the compiled step's own (timed inside
    the C, ``rti.step_c_ms``), instant by instant, medians in microseconds; None on the Python step."""
    if getattr(rti, "step_implementation", "python") != "c" or not calls:
        return None
    call, c = (np.array(v, dtype=float) for v in zip(*calls))
    return {"call_us_median": 1e3 * float(np.median(call)), "c_us_median": 1e3 * float(np.median(c)),
            "python_us_median": 1e3 * float(np.median(call - c))}


def _rti_vs_ipopt(model, plan, options: MPCOptions, duration: float, bench: MPCBenchOptions) -> dict:
    """The NMPC as the loop runs it (the compiled program, :func:`~cartpole.export.inloop.in_loop`) and the IPOPT
    re-solve baseline on the same swing-up from hanging, in this process (see the module doc)."""
    params, x0 = model.params, model.x_hanging
    rti = NMPCController(model, params, options=options, guess=plan.trajectory, x0=x0)
    loop = rti if options.qp_solver is not None else in_loop(model, rti)[0]
    calls, iters, per_run = [], [], []
    t_rti, ok_rti = _runs(loop, params, x0, duration, max(1, int(bench.repeats)), calls, iters, per_run)
    doc = {**_stats(t_rti), **_best_of(per_run), "success": all(ok_rti), "failures": len(loop.failures), "N": rti.N,
           "qp_iterations_median": float(np.median(iters)) if iters else None,
           "qp_iterations_p99": float(np.percentile(iters, 99)) if iters else None,
           "qp_iterations_max": int(max(iters)) if iters else None,
           "period": rti.period, "horizon": rti.horizon, "qp_solver": loop.qp_solver,
           "implementation": getattr(loop, "step_implementation", "python"),
           "in_loop_program": loop is not rti, "overhead": _overhead(loop, calls), "baseline": None,
           "speedup_median": None}
    if bench.baseline:
        base = IpoptMPC(model, params, options=options.replace(qp_solver=None, c_step=False), guess=plan.trajectory,
                        x0=x0)
        t_base, ok_base = _runs(base, params, x0, duration, max(1, int(bench.baseline_repeats)))
        doc["baseline"] = {**_stats(t_base), "success": all(ok_base), "unconverged": len(base.unconverged),
                           "solver": "ipopt"}
        doc["speedup_median"] = doc["baseline"]["solve_ms_median"] / doc["solve_ms_median"]
    return doc


def run_mpc_benchmark(plant=None, options: MPCBenchOptions | None = None) -> dict:
    """Per-control-step solve time of the NMPC in the MuJoCo loop over a swing-up from hanging, and of the IPOPT
    baseline, on one pole (and two).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (default the shipped single pole).
    options : MPCBenchOptions, optional
        Period, horizon, runs and rows (default ``MPCBenchOptions()``: 20 ms, 1.2 s, three runs, every row).

    Returns
    -------
    dict
        ``solve_ms_median``, ``solve_ms_p99``, ``solve_ms_max`` (ms per control step, pooled; the compiled step's
        time measured inside the C), ``solve_ms_best_median``, ``solve_ms_best_p99`` (the same over each step's
        fastest time among the repeated runs, which are the same runs: the step's own tail without a shared
        machine's preemptions; None with one run), ``steps`` (control steps timed), ``baseline`` {``solve_ms_median``,
        ``solve_ms_max``, ``solve_ms_p99``, ``steps``, ``success``, ``unconverged`` (instants IPOPT did not
        converge), ``solver``}, ``speedup_median`` (baseline median / NMPC median), ``period``, ``horizon`` (s),
        ``N``, ``qp_solver`` (``"c"``: ``qp_dual.c``), ``qp_iterations_median``, ``qp_iterations_p99``,
        ``qp_iterations_max`` (the compiled QP's active-set changes per step, warm-started; None on the Python
        step), ``compiled`` (bool), ``in_loop_program`` (the step timed is
        the exported program's ``cp_step`` as the MuJoCo loop calls it), ``implementation`` (``"c"`` or
        ``"python"``), ``success`` (every NMPC run swung up and held, :func:`swingup_success`), ``failures`` (NMPC
        instants that took the safe action), ``repeats``, ``duration``, ``overhead`` (with the C step:
        ``call_us_median`` the whole ``controller(t, x)`` call from Python, ``c_us_median`` the step timed inside
        the C, ``python_us_median`` their difference: Python's overhead per step), ``two_pole`` (the same keys on
        the two-pole cart, 6 s runs), ``targets`` (:data:`TARGETS`) and ``met`` (each target held, or None when
        not measured; ``p99_best_ms`` the target on ``solve_ms_best_p99``), ``load_average`` (the 1-minute load
        average before and after the runs), ``limits``;
        ``ddp`` {``one_pole``, ``two_pole``: the same swing-up under :class:`~cartpole.mpc.ddp_mpc.DDPMPCController`
        (one warm-started DDP iteration a period), each {``solve_ms_median``, ``solve_ms_max``, ``steps``,
        ``period``, ``success``, ``failures``}}.
    """
    bench = MPCBenchOptions() if options is None else options
    load0 = _load()
    params, limits = planning_limits(plant_params(plant), u_max=bench.u_max, cart_max=bench.cart_max)
    model = build_model(params)
    plan = trajopt_swingup(params, x0=model.x_hanging, plan_model=model)
    mpc = MPCOptions(period=bench.period, horizon=bench.horizon, qp_solver=bench.qp_solver)
    doc = _rti_vs_ipopt(model, plan, mpc, bench.duration, bench)
    if bench.two_pole or (bench.ddp and bench.ddp_two_pole):
        m2 = build_model(read_params(SHIPPED_MJCF.with_name("cartpole_two_pole.xml")))
        plan2 = trajopt_swingup(m2.params, x0=m2.x_hanging, plan_model=m2)
    two = None
    if bench.two_pole:  # the double takes longer to swing up: 6 s so that its last second is the hold success needs
        two = _rti_vs_ipopt(m2, plan2, mpc, max(bench.duration, 6.0), bench)
    ddp = {"one_pole": _ddp_row(model, plan, mpc, bench.duration, bench.repeats)} if bench.ddp else None
    if bench.ddp and bench.ddp_two_pole:
        ddp["two_pole"] = _ddp_row(m2, plan2, mpc.replace(qp_solver=None), max(bench.duration, 6.0), bench.repeats)
    doc.update({"limits": limits.to_dict(), "ddp": ddp, "two_pole": two, "compiled": doc["implementation"] == "c",
                "repeats": int(bench.repeats), "duration": float(bench.duration), "targets": dict(TARGETS),
                "met": _met(doc, two), "load_average": [load0, _load()]})
    return doc


def _met(one: dict, two: dict | None) -> dict:
    """Whether each of :data:`TARGETS` held (None where not measured)."""
    def ratio(doc):
        return None if doc is None or doc["speedup_median"] is None else doc["speedup_median"]
    r1, r2 = ratio(one), ratio(two)
    return {"speedup_median": None if r1 is None else r1 >= TARGETS["speedup_median"],
            "p99_ms": one["solve_ms_p99"] < TARGETS["p99_ms"],
            "p99_best_ms": None if one["solve_ms_best_p99"] is None else one["solve_ms_best_p99"] < TARGETS["p99_ms"],
            "two_pole_speedup_median": None if r2 is None else r2 >= TARGETS["two_pole_speedup_median"]}


def _load() -> float | None:
    """The machine's 1-minute load average, or None where the platform has none."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return None


def _ddp_row(model, plan, options: MPCOptions, duration: float, repeats: int) -> dict:
    params, x0 = model.params, model.x_hanging
    ddp = DDPMPCController(model, params, options=options.replace(solver="ddp"), guess=plan.trajectory, x0=x0)
    times, ok = _runs(ddp, params, x0, duration, max(1, int(repeats)))
    return {"solve_ms_median": float(np.median(times)), "solve_ms_max": float(np.max(times)), "steps": len(times),
            "period": ddp.period, "success": all(ok), "failures": len(ddp.failures)}


def mpc_benchmark(plant=None, *, quick: bool = False, progress=None, u_max=None,
                  cart_max: float | None = None) -> dict:
    """The NMPC row of ``cartpole bench`` (:func:`run_mpc_benchmark`): per-control-step solve time over a
    single-pole swing-up in MuJoCo against IPOPT re-solving the same NLP from the shifted guess.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    quick : bool
        One run instead of three, and not the two-pole rows.
    progress : callable, optional
        ``progress(message)``.
    u_max : float or (nu,) array, optional
        ``|ctrl|`` bound (MuJoCo ctrl) the plan keeps to (default the file's, else a stated default).
    cart_max : float, optional
        m the cart may travel either side of its range's centre (default the file's, else a stated default).

    Returns
    -------
    dict
    """
    (progress or (lambda msg: None))("NMPC in the MuJoCo loop vs IPOPT re-solves ...")
    return run_mpc_benchmark(plant, MPCBenchOptions(repeats=1 if quick else 3, u_max=u_max, cart_max=cart_max,
                                                    two_pole=not quick))


def mpc_lines(doc: dict) -> list:
    """Prose lines of a :func:`run_mpc_benchmark` document: the compiled step's median and p99 against IPOPT, the
    two-pole row, Python's overhead, the DDP rows and the load average.

    Parameters
    ----------
    doc : dict

    Returns
    -------
    list of str
    """
    nan = float("nan")
    base = doc.get("baseline") or {}
    where = ("the exported program's cp_step as the loop calls it, timed inside the C" if doc.get("in_loop_program")
             else f"the {doc.get('implementation')} step")
    best = ("" if doc.get("solve_ms_best_p99") is None else
            f"; each step's fastest of the repeated runs: median {doc['solve_ms_best_median']:.3f} ms, p99 "
            f"{doc['solve_ms_best_p99']:.3f} ms")
    lines = [f"NMPC in the MuJoCo loop ({doc.get('N')} stages, horizon {doc.get('horizon')} s, period "
             f"{doc.get('period')} s; {where}): median {doc.get('solve_ms_median', nan):.3f} ms, p99 "
             f"{doc.get('solve_ms_p99', nan):.3f} ms, max {doc.get('solve_ms_max', nan):.3f} ms over "
             f"{doc.get('steps')} steps; IPOPT re-solving from the shifted guess: median "
             f"{base.get('solve_ms_median', nan):.2f} ms, p99 {base.get('solve_ms_p99', nan):.2f} ms; speed-up "
             f"{doc.get('speedup_median') or nan:.1f}x (targets: >= {TARGETS['speedup_median']:g}x, p99 < "
             f"{TARGETS['p99_ms']:g} ms){best}"]
    if doc.get("qp_iterations_max") is not None:
        lines.append(f"  the QP (warm-started dual active set): {doc['qp_iterations_median']:g} active-set changes a "
                     f"step at the median, p99 {doc['qp_iterations_p99']:.0f}, max {doc['qp_iterations_max']}")
    over = doc.get("overhead")
    if over:
        lines.append(f"  {over['c_us_median']:.1f} us inside the C, {over['call_us_median']:.1f} us the whole call "
                     f"from Python: Python's overhead {over['python_us_median']:.1f} us a step (medians)")
    two = doc.get("two_pole")
    if two:
        lines.append(f"  two poles: median {two['solve_ms_median']:.3f} ms, p99 {two['solve_ms_p99']:.3f} ms; IPOPT "
                     f"median {(two['baseline'] or {}).get('solve_ms_median', nan):.2f} ms; speed-up "
                     f"{two['speedup_median'] or nan:.1f}x (target >= {TARGETS['two_pole_speedup_median']:g}x)")
    for name, row in (doc.get("ddp") or {}).items():
        lines.append(f"MPC by DDP ({name.replace('_', ' ')}, one warm-started iteration a period): median "
                     f"{row['solve_ms_median']:.3f} ms, max {row['solve_ms_max']:.3f} ms over {row['steps']} steps, "
                     f"{'swings up and holds' if row['success'] else 'FAILED'}")
    load = doc.get("load_average") or [None, None]
    if None not in load:
        lines.append(f"  load average (1 min) {load[0]:.2f} before, {load[1]:.2f} after")
    return lines


def print_mpc_table(doc: dict, file=None) -> None:
    """:func:`mpc_lines` of ``doc`` on ``file`` (default the current ``sys.stdout``), a blank line before."""
    w = (sys.stdout if file is None else file).write
    w("\n" + "".join(line + "\n" for line in mpc_lines(doc)))
