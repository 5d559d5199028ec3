"""Speed of the trajectory-optimisation pipeline next to the naive CasADi baseline, measured in one run
(``cartpole bench`` and ``benchmarks/bench_trajopt.py`` run this).

Standard problem: the given MJCF (default the shipped asset; any model with a cart), from hanging rest
(``model.x_hanging``, ``[0, pi, 0, 0]`` for one pole) to the upright equilibrium ``model.x_eq`` in ``T = 2 s``
with ``N = 100`` Hermite-Simpson intervals, ``|ctrl| <= 1`` for every actuator, ``|cart| <= 1.4 m`` (other
limited joints inside their ranges), minimising ``integral ctrl'ctrl dt``.

* Baseline: what a CasADi user writes first - ``casadi.Opti`` with one Hermite-Simpson constraint per
  interval built from calls of the model's SX Function ``f`` on MX variables, IPOPT, no ``expand``.
* Ours: :class:`~cartpole.ocp.collocation.DirectCollocation` (built once: ``map`` over knots and intervals,
  expanded to SX, scaled), IPOPT, first without and then with the interval functions compiled to C
  (:mod:`cartpole.ocp.compiled`, the default); plus the latter warm-started from the previous solution, and
  fatrop.

Both solve from the SAME initial guess (the warm-start row re-plans from a moved start); every timed solve
reuses a solver that already exists (the first, building call is not timed). Times are medians of ``repeats`` wall-clock solves, including each tool's Python overhead.
"""
from __future__ import annotations

import statistics
import sys
import time

import casadi as ca
import numpy as np

from cartpole.lqr import lab_weights, tvlqr
from cartpole.models import build_model, read_params
from cartpole.ocp.bounds import OCPBounds, bounds_from_model
from cartpole.ocp.collocation import DirectCollocation
from cartpole.ocp.guess import initial_guesses
from cartpole.sim import replay_benchmark


def _median_ms(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        tic = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - tic)
    return 1e3 * statistics.median(times), out


class NaiveOptiBaseline:
    """The Hermite-Simpson swing-up as a first ``casadi.Opti`` script (see the module docstring).

    ``bounds`` (:class:`~cartpole.ocp.bounds.OCPBounds`) give the ctrl bounds per actuator and the joint bounds;
    ``x0``, ``x_goal`` (nx,) the boundary states (goal default ``model.x_eq``).
    """

    def __init__(self, model, N: int, T: float, bounds: OCPBounds, x0, x_goal=None):
        f = model.f
        opti = ca.Opti()
        X = opti.variable(model.nx, N + 1)
        U = opti.variable(model.nu, N + 1)
        h = T / N
        J = 0
        for k in range(N):
            fk = f(X[:, k], U[:, k])
            fk1 = f(X[:, k + 1], U[:, k + 1])
            xc = 0.5 * (X[:, k] + X[:, k + 1]) + h / 8 * (fk - fk1)
            uc = 0.5 * (U[:, k] + U[:, k + 1])
            fc = f(xc, uc)
            opti.subject_to(X[:, k + 1] == X[:, k] + h / 6 * (fk + 4 * fc + fk1))
            J = J + h / 6 * ca.sum1(U[:, k] ** 2 + 4 * uc**2 + U[:, k + 1] ** 2)
        for j in range(model.nu):
            opti.subject_to(opti.bounded(bounds.u_low[j], U[j, :], bounds.u_high[j]))
        for i in bounds.bounded_joints:
            opti.subject_to(opti.bounded(bounds.q_low[i], X[i, :], bounds.q_high[i]))
        opti.subject_to(X[:, 0] == np.asarray(x0, float))
        opti.subject_to(X[:, N] == np.asarray(model.x_eq if x_goal is None else x_goal, float))
        opti.minimize(J)
        opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes"})
        self.opti, self.X, self.U = opti, X, U

    def solve(self, guess) -> tuple[float, int, bool]:
        """Solve from ``guess`` (Trajectory on the same knots); returns (objective, iterations, success)."""
        self.opti.set_initial(self.X, guess.x.T)
        self.opti.set_initial(self.U, guess.u.T)
        try:
            sol = self.opti.solve()
            st = sol.stats()
            return float(sol.value(self.opti.f)), int(st["iter_count"]), bool(st["success"])
        except RuntimeError:
            st = self.opti.stats()
            return float(self.opti.debug.value(self.opti.f)), int(st.get("iter_count", -1)), False


def run(mjcf=None, *, N: int = 100, T: float = 2.0, u_max: float = 1.0, cart_max: float = 1.4,
        repeats: int = 5, replay: bool = True, replay_repeats: int | None = None, replay_rollouts: int = 256,
        progress=None) -> dict:
    """Measure the standard problem (module docstring); return the ``cartpole bench`` JSON document.

    Parameters
    ----------
    mjcf : path, optional
        Cart-pole MJCF (default the shipped asset), any number of poles and motors.
    N, T, u_max, cart_max : problem size (intervals, s, ctrl bound of every actuator, m).
    repeats : int
        Timed solves per method (medians reported; at least 5 for the published figures).
    replay : bool
        Also run the batched replay benchmark (``cartpole.sim.batch.replay_benchmark``).
    replay_repeats, replay_rollouts : int
        Its repetitions (default ``repeats``) and batch size.
    progress : callable, optional
        ``progress(message)`` for progress lines (the command sends them to stderr).

    Returns
    -------
    dict
        ``mjcf``, ``trajopt`` {``solve_ms_median``, ``objective``, ``N``, ``T``, ``solver``, ``iterations``,
        ``baseline_solve_ms_median``, ``baseline_objective``, ``baseline_iterations``, ``speedup``,
        ``objective_rel_diff``, ``warm_start_solve_ms_median``, ``warm_start_speedup``, ``fatrop_...``},
        ``tvlqr`` {``ms_median``, ``steps``, ``dt``}, ``replay`` {...} (or None when not run).
    """
    say = progress or (lambda msg: None)
    repeats = max(1, int(repeats))
    params = read_params(mjcf)
    model = build_model(params)
    x0 = np.array(model.x_hanging)
    bounds = bounds_from_model(model, u_max=u_max, cart_max=cart_max, cart_margin=0.0)
    guess = initial_guesses(model, x0, model.x_eq, T, N, bounds=bounds, count=1)[0]

    say(f"building our collocation NLP (N = {N}, T = {T} s) ...")
    ocp = DirectCollocation(model, N=N, T=T, bounds=bounds)
    traj, info = ocp.solve_once(x0, guess=guess)  # builds the solver (not timed)
    say(f"ours (ipopt, from the guess): {repeats} solves ...")
    ours_ms, (traj, info) = _median_ms(lambda: ocp.solve_once(x0, guess=guess), repeats)
    # Warm start, honestly: a NEW problem (start moved by 2 cm and 0.05 rad, as in re-planning) started from
    # the primal-dual solution of the nominal one; the nominal solution is restored before every timed solve.
    nominal = ocp._last
    x0_moved = x0.copy()
    if model.slide is not None:
        x0_moved[model.slide] += 0.02
    x0_moved[model.hinges[0]] += 0.05

    def warm_solve():
        ocp._last = nominal
        return ocp.solve_once(x0_moved, warm=True)

    say(f"ours (ipopt, warm-started from the nominal solution, moved start): {repeats} solves ...")
    warm_solve()  # builds the warm-start solver (not timed)
    warm_ms, (_, warm_info) = _median_ms(warm_solve, repeats)

    say(f"ours without the compiled interval functions (SX virtual machine): {repeats} solves ...")
    sx_ocp = DirectCollocation(model, N=N, T=T, bounds=bounds, compiled=False)
    sx_ocp.solve_once(x0, guess=guess)
    sx_ms, (_, sx_info) = _median_ms(lambda: sx_ocp.solve_once(x0, guess=guess), repeats)

    say("building the naive casadi.Opti baseline ...")
    base = NaiveOptiBaseline(model, N, T, bounds, x0)
    base.solve(guess)  # builds IPOPT (not timed)
    say(f"baseline (Opti, no expand): {repeats} solves ...")
    base_ms, (base_obj, base_it, base_ok) = _median_ms(lambda: base.solve(guess), repeats)

    fatrop = {}
    if ca.has_nlpsol("fatrop"):
        say(f"ours (fatrop): {repeats} solves ...")
        focp = DirectCollocation(model, N=N, T=T, bounds=bounds, solver="fatrop")
        focp.solve_once(x0, guess=guess)
        f_ms, (_, finfo) = _median_ms(lambda: focp.solve_once(x0, guess=guess), repeats)
        fatrop = {"fatrop_solve_ms_median": f_ms, "fatrop_objective": finfo.objective,
                  "fatrop_success": finfo.success, "fatrop_iterations": finfo.iterations}

    say(f"TVLQR synthesis along the plan at dt = {model.dt} s: {max(repeats, 20)} runs ...")
    Q, R = lab_weights(model)
    tvlqr(model, traj, Q, R)  # builds the mapped ABd (not timed)
    tv_ms, gains = _median_ms(lambda: tvlqr(model, traj, Q, R), max(repeats, 20))

    replay_doc = None
    if replay:
        say(f"batched replay: {replay_rollouts} rollouts x 2 s ...")
        replay_doc = replay_benchmark(params, rollouts=replay_rollouts, seconds=2.0,
                                      repeats=replay_repeats or repeats)

    return {
        "mjcf": params.mjcf,
        "trajopt": {
            "solve_ms_median": ours_ms, "objective": info.objective, "N": N, "T": T, "solver": "ipopt",
            "iterations": info.iterations, "success": info.success,
            "baseline_solve_ms_median": base_ms, "baseline_objective": base_obj, "baseline_iterations": base_it,
            "baseline_success": base_ok, "speedup": base_ms / ours_ms,
            "objective_rel_diff": abs(info.objective - base_obj) / abs(base_obj),
            "warm_start_solve_ms_median": warm_ms, "warm_start_iterations": warm_info.iterations,
            "warm_start_objective": warm_info.objective, "warm_start_success": warm_info.success,
            "warm_start_speedup": base_ms / warm_ms, "compiled": ocp.compiled_library is not None,
            "sx_solve_ms_median": sx_ms, "sx_iterations": sx_info.iterations, "sx_objective": sx_info.objective,
            "sx_speedup": base_ms / sx_ms, "repeats": repeats, "u_max": u_max, "cart_max": cart_max,
            **fatrop,
        },
        "tvlqr": {"ms_median": tv_ms, "steps": int(gains.t.size), "dt": gains.dt},
        "replay": replay_doc,
    }


def print_table(doc: dict, file=None) -> None:
    """Prose table of a :func:`run` document, on ``file`` (default the current ``sys.stdout``)."""
    file = sys.stdout if file is None else file
    tr, tv, rp = doc["trajopt"], doc["tvlqr"], doc["replay"]
    w = file.write
    w(f"MJCF: {doc['mjcf']}\n")
    w(f"Swing-up OCP: N = {tr['N']}, T = {tr['T']} s, |ctrl| <= {tr['u_max']}, |cart| <= {tr['cart_max']} m, "
      f"min integral ctrl^2; medians of {tr['repeats']} warm solves from the same guess\n\n")
    w(f"{'method':44s} {'solve ms':>10s} {'iters':>6s} {'objective':>12s} {'speedup':>8s}\n")
    w(f"{'baseline: casadi.Opti, SX f calls, no expand':44s} {tr['baseline_solve_ms_median']:10.1f} "
      f"{tr['baseline_iterations']:6d} {tr['baseline_objective']:12.6f} {1.0:8.1f}\n")
    if "sx_solve_ms_median" in tr:
        w(f"{'ours, SX only: map + expand + scaling, IPOPT':44s} {tr['sx_solve_ms_median']:10.1f} "
          f"{tr['sx_iterations']:6d} {tr['sx_objective']:12.6f} {tr['sx_speedup']:8.1f}\n")
    label = "ours: + compiled interval functions, IPOPT" if tr.get("compiled") else "ours (no C compiler), IPOPT"
    w(f"{label:44s} {tr['solve_ms_median']:10.1f} {tr['iterations']:6d} "
      f"{tr['objective']:12.6f} {tr['speedup']:8.1f}\n")
    w(f"{'ours, warm-started, start moved 2 cm/0.05 rad':44s} {tr['warm_start_solve_ms_median']:10.1f} "
      f"{tr['warm_start_iterations']:6d} {tr['warm_start_objective']:12.6f} {tr['warm_start_speedup']:8.1f}\n")
    if "fatrop_solve_ms_median" in tr:
        w(f"{'ours, fatrop (tol 1e-6)':44s} {tr['fatrop_solve_ms_median']:10.1f} {tr['fatrop_iterations']:6d} "
          f"{tr['fatrop_objective']:12.6f} {tr['baseline_solve_ms_median'] / tr['fatrop_solve_ms_median']:8.1f}\n")
    w(f"\nobjective ours vs baseline: relative difference {tr['objective_rel_diff']:.2e}\n")
    w(f"TVLQR synthesis ({tv['steps']} steps at dt = {tv['dt']} s): {tv['ms_median']:.2f} ms (median)\n")
    if rp:
        w(f"Batched replay: {rp['steps_per_s']:.3g} closed-loop steps/s ({rp['rollouts']} rollouts x "
          f"{rp['seconds_each']} s)")
        if "open_loop_steps_per_s" in rp:
            w(f", open loop {rp['open_loop_steps_per_s']:.3g} steps/s, ratio {rp.get('ratio', float('nan')):.2f}")
        w("\n")
