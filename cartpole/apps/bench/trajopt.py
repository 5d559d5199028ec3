"""Speed of the trajectory-optimisation pipeline next to the naive CasADi baseline, measured in one run
(``cartpole bench`` and ``benchmarks/bench_trajopt.py`` run this).

Standard problem: the given MJCF (default the shipped asset; any model with a cart), from hanging rest
(``model.x_hanging``, ``[0, pi, 0, 0]`` for one pole) to the upright equilibrium ``model.x_eq`` in ``T = 2 s``
with ``N = 100`` Hermite-Simpson intervals, ``|ctrl| <= 1`` for every actuator, ``|cart| <= 1.4 m`` (other
limited joints inside their ranges), minimising ``integral ctrl'ctrl dt``.

* Baselines: what a CasADi user writes first - ``casadi.Opti`` with one Hermite-Simpson constraint per
  interval built from calls of the model's SX Function ``f`` on MX variables (``f`` once per knot and once per
  midpoint), IPOPT with its defaults; then the same script with ``expand=True`` (the one-option fix a user finds
  next: the MX graph expanded to SX before IPOPT).
* Ours: :class:`~cartpole.ocp.collocation.DirectCollocation` (built once: ``map`` over knots and intervals,
  expanded to SX, scaled), IPOPT, first without and then with the interval functions compiled to C
  (:mod:`cartpole.ocp.compiled_nlp`, the default); plus the latter warm-started from the previous solution,
  fatrop (the structure-exploiting interior point CasADi ships), and the SQP on the stage-structured QP of the same
  NLP (:mod:`cartpole.solvers.sqp`).

All solve from the SAME initial guess; the warm-start rows re-plan from a moved start (2 cm, 0.05 rad), ours
from our nominal primal-dual solution, the ``expand=True`` script from its own with the same IPOPT warm-start
settings, and are compared only with each other. Every timed solve
reuses a solver that already exists (the first, building call is not timed). Times are medians of ``repeats`` wall-clock solves, including each tool's Python overhead.
"""
from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

import casadi as ca
import mujoco
import numpy as np

from cartpole.apps.bench.replay import replay_benchmark
from cartpole.models import SHIPPED_MJCF, build_model, mujoco_model, planning_limits, plant_params, read_params
from cartpole.ocp.bounds import OCPBounds, bounds_from_model
from cartpole.ocp.collocation import CollocationOptions, DirectCollocation
from cartpole.ocp.guess import initial_guesses
from cartpole.planning.trajopt import SQP_MAX_ITER, SQP_MAX_UNSETTLED, trajopt_swingup
from cartpole.riccati import default_weights, tvlqr
from cartpole.riccati.tvlqr import reference as _on_step_grid
from cartpole.sim import replays_exactly, simulate
from cartpole.solvers.ddp import ddp_for_model
from cartpole.solvers.sqp import CollocationSQP, SQPError, SQPOptions
from cartpole.validation.metrics import swingup_metrics


def median_ms(fn, repeats: int, *, min_seconds: float = 0.0) -> tuple[float, object]:
    """``(median wall time in ms of the calls of fn(), the last call's result)``: ``repeats`` calls, and more until
    ``min_seconds`` have passed (a fast solver's median then spans as long a window as a slow baseline's, so a
    passing load on the shared machine weighs on both alike; each call still runs warm after the last)."""
    times, out = [], None
    start = time.perf_counter()
    while len(times) < repeats or time.perf_counter() - start < min_seconds:
        tic = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - tic)
    return 1e3 * statistics.median(times), out


def hand_typed_cartpole(params) -> ca.Function | None:
    """The one-pole cart-pole's equations of motion typed by hand, as a user writes them for the naive script.

    ``M(theta) [s_dd, theta_dd] = tau - c``, with the 2x2 mass matrix ``M = [[m, a cos(theta)], [a cos(theta),
    J]]`` solved in closed form (its determinant ``m J - a^2 cos^2(theta)``), the velocity product
    ``c_s = -a sin(theta) theta_dot^2``, gravity ``c_theta = k sin(theta)``, and ``tau = [gear u - b_s s_dot,
    -b_theta theta_dot]``. The numbers ``m`` (kg), ``a`` (kg m), ``J`` (kg m^2), ``k`` (N m), the dampings and
    the gear are read off MuJoCo's compiled model of the file (``mj_fullM`` upright, ``qfrc_bias`` with the pole
    horizontal), so the hand-typed equations are the file's (the bench's test checks them against the model's
    ``f`` at many states).

    Parameters
    ----------
    params : CartPoleParams
        A cart with one hinge and one actuator on the slide (the lab's cart-pole), upright at ``qpos = 0``.

    Returns
    -------
    casadi.Function or None
        ``f(x (4,), u (1,)) -> xdot (4,)`` as one SX Function, or None for any other shape (then the generic
        baseline is the only one).
    """
    if params.nq != 2 or params.nu != 1 or params.slide is None:
        return None
    mj = mujoco_model(params)
    if mj.nq != 2 or mj.nu != 1 or int(mj.actuator_trnid[0, 0]) != params.slide:
        return None
    s, h = int(params.slide), 1 - int(params.slide)
    data = mujoco.MjData(mj)
    mujoco.mj_forward(mj, data)
    M = np.zeros((2, 2))
    mujoco.mj_fullM(mj, data, M)
    if not np.allclose(np.asarray(data.qpos), 0.0) or abs(float(data.qfrc_bias[h])) > 1e-12:
        return None  # upright is not qpos = 0: not the script the issue means
    data.qpos[h] = 0.5 * np.pi
    mujoco.mj_forward(mj, data)
    k = -float(data.qfrc_bias[h])  # MuJoCo: M qdd + bias = tau; gravity pulls the pole over: bias = -k sin
    m_, a, J = float(M[s, s]), float(M[s, h]), float(M[h, h])
    b_s, b_h = float(mj.dof_damping[s]), float(mj.dof_damping[h])
    gear = float(mj.actuator_gear[0, 0])
    x, u = ca.SX.sym("x", 4), ca.SX.sym("u", 1)
    q = [x[0], x[1]]
    qd = [x[2], x[3]]
    th, thd, sd = q[h], qd[h], qd[s]
    c, sn = ca.cos(th), ca.sin(th)
    m12 = a * c
    tau_s = gear * u[0] - b_s * sd + a * sn * thd ** 2
    tau_h = -b_h * thd + k * sn
    det = m_ * J - m12 ** 2
    acc_s = (J * tau_s - m12 * tau_h) / det
    acc_h = (m_ * tau_h - m12 * tau_s) / det
    acc = [None, None]
    acc[s], acc[h] = acc_s, acc_h
    return ca.Function("f_hand", [x, u], [ca.vertcat(qd[0], qd[1], acc[0], acc[1])], ["x", "u"], ["xdot"])


class NaiveOptiBaseline:
    """The Hermite-Simpson swing-up as a first ``casadi.Opti`` script (see the module docstring).

    ``bounds`` (:class:`~cartpole.ocp.bounds.OCPBounds`) give the ctrl bounds per actuator and the joint bounds;
    ``x0``, ``x_goal`` (nx,) the boundary states (goal default ``model.x_eq``), ``N`` intervals over ``T`` s.
    ``expand=True`` is the same script with Opti's ``expand`` option (the MX graph expanded to SX for IPOPT).
    ``f`` replaces the model's dynamics Function (``(x, u) -> xdot``, e.g. :func:`hand_typed_cartpole`).
    ``objective`` (an :class:`~cartpole.ocp.objectives.Objective`, default effort): a running cost is integrated by
    Simpson's rule on the same knots and midpoints (its SX Function called per knot and midpoint), ``time`` makes
    ``T`` a variable (``T`` its initial value, ``h = T / N``) and minimises ``T + w effort``, ``w`` the collocation's
    default :attr:`~cartpole.ocp.collocation.CollocationOptions.time_effort_weight`, as
    :class:`~cartpole.ocp.collocation.DirectCollocation` does.
    """

    def __init__(self, model, N: int, T: float, bounds: OCPBounds, x0, x_goal=None, *, expand: bool = False,
                 warm: bool = False, f: ca.Function | None = None, objective=None):
        f = model.f if f is None else f
        kind = "effort" if objective is None else objective.kind
        opti = ca.Opti()
        X = opti.variable(model.nx, N + 1)
        U = opti.variable(model.nu, N + 1)
        P0 = opti.parameter(model.nx)  # the start: a parameter, so a re-plan from a moved start reuses the solver
        Tv = opti.variable() if kind == "time" else T
        h = Tv / N
        J, L = 0, objective.running if kind == "running" else None
        # f (and a running cost) once per knot (each knot's shared by its two intervals), once per midpoint
        F = [f(X[:, k], U[:, k]) for k in range(N + 1)]
        Lk = [L(X[:, k], U[:, k]) for k in range(N + 1)] if L is not None else None
        for k in range(N):
            xc = 0.5 * (X[:, k] + X[:, k + 1]) + h / 8 * (F[k] - F[k + 1])
            uc = 0.5 * (U[:, k] + U[:, k + 1])
            fc = f(xc, uc)
            opti.subject_to(X[:, k + 1] == X[:, k] + h / 6 * (F[k] + 4 * fc + F[k + 1]))
            if L is None:
                J = J + h / 6 * ca.sum1(U[:, k] ** 2 + 4 * uc**2 + U[:, k + 1] ** 2)
            else:
                J = J + h / 6 * (Lk[k] + 4 * L(xc, uc) + Lk[k + 1])
        if kind == "time":
            opti.subject_to(opti.bounded(0.1 * T, Tv, 10.0 * T))
            opti.set_initial(Tv, T)
            J = Tv + CollocationOptions.time_effort_weight * J
        for j in range(model.nu):
            opti.subject_to(opti.bounded(bounds.u_low[j], U[j, :], bounds.u_high[j]))
        for i in bounds.bounded_joints:
            opti.subject_to(opti.bounded(bounds.q_low[i], X[i, :], bounds.q_high[i]))
        opti.subject_to(X[:, 0] == P0)
        opti.subject_to(X[:, N] == np.asarray(model.x_eq if x_goal is None else x_goal, float))
        opti.minimize(J)
        opti.set_value(P0, np.asarray(x0, float))
        ip = {"print_level": 0, "sb": "yes"}
        if warm:  # IPOPT's warm start, with the same settings as ours (cartpole.ocp.collocation)
            ip.update({"warm_start_init_point": "yes", "warm_start_bound_push": 1e-9,
                       "warm_start_mult_bound_push": 1e-9, "mu_init": 1e-6})
        opti.solver("ipopt", {"print_time": False, "expand": bool(expand)}, ip)
        self.opti, self.X, self.U, self.P0, self.T = opti, X, U, P0, Tv
        self.solution = None  # (x, u, lam_g) of the last solve

    def solve(self, guess, x0=None, *, duals=None) -> tuple[float, int, bool]:
        """Solve from ``guess`` (Trajectory on the same knots), optionally from another start ``x0`` (nx,) and with
        initial constraint multipliers ``duals`` (a warm start); returns (objective, iterations, success)."""
        if x0 is not None:
            self.opti.set_value(self.P0, np.asarray(x0, float))
        self.opti.set_initial(self.X, guess.x.T)
        self.opti.set_initial(self.U, guess.u.T)
        if isinstance(self.T, ca.MX):
            self.opti.set_initial(self.T, guess.duration)
        if duals is not None:
            self.opti.set_initial(self.opti.lam_g, duals)
        try:
            sol = self.opti.solve()
            st = sol.stats()
            self.solution = (np.asarray(sol.value(self.X)).T, np.asarray(sol.value(self.U)).reshape(self.U.shape).T,
                             np.asarray(sol.value(self.opti.lam_g)).ravel())
            return float(sol.value(self.opti.f)), int(st["iter_count"]), bool(st["success"])
        except RuntimeError:
            st = self.opti.stats()
            return float(self.opti.debug.value(self.opti.f)), int(st.get("iter_count", -1)), False


@dataclass(frozen=True)
class _Standard:
    """One run's standard problem (module docstring): the MJCF's parameters and model, ``N`` intervals over ``T`` s,
    the bounds, the start ``x0`` and the moved start of the warm-start rows (nx,), the shared guess, the timed solves
    per method and the progress callback."""
    params: object
    model: object
    N: int
    T: float
    bounds: OCPBounds
    x0: np.ndarray
    x0_moved: np.ndarray
    guess: object
    repeats: int
    say: object


def run(plant=None, *, N: int = 100, T: float = 2.0, u_max: float = 1.0, cart_max: float = 1.4,
        repeats: int = 5, replay: bool = True, replay_repeats: int | None = None, replay_rollouts: int = 256,
        progress=None) -> dict:
    """Measure the standard problem (module docstring); return the ``cartpole bench`` JSON document.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        Cart-pole MJCF (default the shipped asset), any number of poles and motors.
    N, T, u_max, cart_max : problem size (intervals, s, ctrl bound of every actuator, m).
    repeats : int
        Timed solves per method (medians reported; at least 5 for the published figures).
    replay : bool
        Also run the batched replay benchmark (``cartpole.apps.bench.replay.replay_benchmark``).
    replay_repeats, replay_rollouts : int
        Its repetitions (default ``repeats``) and batch size.
    progress : callable, optional
        ``progress(message)`` for progress lines (the command sends them to stderr).

    Returns
    -------
    dict
        ``mjcf``, ``trajopt`` {``solve_ms_median``, ``objective``, ``N``, ``T``, ``solver``, ``iterations``,
        ``baseline_solve_ms_median``, ``baseline_objective``, ``baseline_iterations``, ``speedup``,
        ``objective_rel_diff``, ``warm_start_solve_ms_median``, ``warm_start_speedup``, ``fatrop_...``,
        ``sqp_solve_ms_median``, ``sqp_iterations``, ``sqp_objective``, ``sqp_success``, ``sqp_status``,
        ``sqp_speedup`` (naive Opti / SQP), ``sqp_speedup_vs_expand``, ``sqp_vs_ipopt`` (our IPOPT / SQP; the
        three None when the SQP did not converge), ``sqp_objective_rel_diff`` (vs our IPOPT)},
        ``tvlqr`` {``ms_median``, ``steps``, ``dt``}, ``replay`` {...} (or None when not run).
    """
    say = progress or (lambda msg: None)
    repeats = max(1, int(repeats))
    params = plant_params(plant)
    model = build_model(params)
    x0 = np.array(model.x_hanging)
    bounds = bounds_from_model(model, u_max=u_max, cart_max=cart_max, cart_margin=0.0)
    guess = initial_guesses(model, x0, model.x_eq, T, N, bounds=bounds, count=1)[0]
    # the warm-start rows re-plan from a start moved by 2 cm and 0.05 rad
    x0_moved = x0.copy()
    if model.slide is not None:
        x0_moved[model.slide] += 0.02
    x0_moved[model.hinges[0]] += 0.05
    p = _Standard(params=params, model=model, N=N, T=T, bounds=bounds, x0=x0, x0_moved=x0_moved, guess=guess,
                  repeats=repeats, say=say)

    ocp, traj, ours = _ours(p)
    naive = _naive(p)
    # the baseline the ratios are taken against: the hand-typed script for one pole, else the generic one
    ref_ms = naive.get("hand_baseline_solve_ms_median", naive["baseline_solve_ms_median"])
    fatrop = _fatrop(p, ref_ms)
    sqp = _sqp(p, ocp, ours, naive, ref_ms)
    say(f"the default planner (solver 'auto': the SQP, IPOPT behind it): {repeats} solves ...")
    default = default_planner_row(ocp, x0, guess, repeats, ref_ms)
    default.pop("trajectory")
    ddp_doc = _ddp(p, ours["objective"], ref_ms)

    say(f"TVLQR synthesis along the plan at dt = {model.dt} s: {max(repeats, 20)} runs ...")
    Q, R = default_weights(model)
    tvlqr(model, traj, Q, R)  # builds the mapped ABd (not timed)
    tv_ms, gains = median_ms(lambda: tvlqr(model, traj, Q, R), max(repeats, 20))

    replay_doc = None
    if replay:
        say(f"batched replay: {replay_rollouts} rollouts x 2 s ...")
        replay_doc = replay_benchmark(params, rollouts=replay_rollouts, seconds=2.0,
                                      repeats=replay_repeats or repeats)
    trajopt = _trajopt_row(ours, naive)
    trajopt.update({"repeats": repeats, "u_max": u_max, "cart_max": cart_max})
    trajopt.update(_reference_row(ours, naive, ref_ms))
    return {
        "mjcf": params.mjcf,
        "trajopt": {**trajopt, **fatrop, **sqp, **ddp_doc, **default},
        "tvlqr": {"ms_median": tv_ms, "steps": int(gains.t.size), "dt": gains.dt},
        "replay": replay_doc,
    }


def _ours(p: _Standard) -> tuple[DirectCollocation, object, dict]:
    """Our collocation by IPOPT from the guess, warm-started from the nominal solution at the moved start, and
    without the compiled interval functions: ``(the problem, its plan, the rows' numbers)``."""
    say, repeats, x0, guess = p.say, p.repeats, p.x0, p.guess
    say(f"building our collocation NLP (N = {p.N}, T = {p.T} s) ...")
    ocp = DirectCollocation(p.model, N=p.N, T=p.T, bounds=p.bounds)
    traj, info = ocp.solve_once(x0, guess=guess)  # builds the solver (not timed)
    say(f"ours (ipopt, from the guess): {repeats} solves ...")
    ours_ms, (traj, info) = median_ms(lambda: ocp.solve_once(x0, guess=guess), repeats)
    # Warm start, honestly: a NEW problem (start moved by 2 cm and 0.05 rad, as in re-planning) started from
    # the primal-dual solution of the nominal one; the nominal solution is restored before every timed solve.
    nominal = ocp._last

    def warm_solve():
        ocp._last = nominal
        return ocp.solve_once(p.x0_moved, warm=True)

    say(f"ours (ipopt, warm-started from the nominal solution, moved start): {repeats} solves ...")
    warm_solve()  # builds the warm-start solver (not timed)
    warm_ms, (_, warm_info) = median_ms(warm_solve, repeats)

    say(f"ours without the compiled interval functions (SX virtual machine): {repeats} solves ...")
    sx_ocp = DirectCollocation(p.model, N=p.N, T=p.T, bounds=p.bounds, options=CollocationOptions(compiled=False))
    sx_ocp.solve_once(x0, guess=guess)
    sx_ms, (_, sx_info) = median_ms(lambda: sx_ocp.solve_once(x0, guess=guess), repeats)
    return ocp, traj, {"solve_ms_median": ours_ms, "objective": info.objective, "N": p.N, "T": p.T,
                       "iterations": info.iterations, "success": info.success, "warm_start_solve_ms_median": warm_ms,
                       "warm_start_iterations": warm_info.iterations, "warm_start_objective": warm_info.objective,
                       "warm_start_success": warm_info.success, "compiled": ocp.compiled_library is not None,
                       "sx_solve_ms_median": sx_ms, "sx_iterations": sx_info.iterations,
                       "sx_objective": sx_info.objective}


def _naive(p: _Standard) -> dict:
    """The naive Opti script: as written, with ``expand=True``, that one warm-started at the moved start from its own
    nominal solution, and (one pole) on the hand-typed equations; the rows' numbers."""
    say, repeats, guess = p.say, p.repeats, p.guess
    say("building the naive casadi.Opti baseline ...")
    base = NaiveOptiBaseline(p.model, p.N, p.T, p.bounds, p.x0)
    base.solve(guess)  # builds IPOPT (not timed)
    say(f"baseline (Opti, no expand): {repeats} solves ...")
    base_ms, (base_obj, base_it, base_ok) = median_ms(lambda: base.solve(guess), repeats)
    exp = NaiveOptiBaseline(p.model, p.N, p.T, p.bounds, p.x0, expand=True)
    exp.solve(guess)
    say(f"baseline (Opti, expand=True): {repeats} solves ...")
    exp_ms, (exp_obj, exp_it, exp_ok) = median_ms(lambda: exp.solve(guess), repeats)
    # Warm against warm: the expand=True script re-planning from the same moved start, from its own nominal
    # primal-dual solution, with IPOPT's warm start set as ours is.
    wexp = NaiveOptiBaseline(p.model, p.N, p.T, p.bounds, p.x0, expand=True, warm=True)
    wexp.solve(guess)
    nom_x, nom_u, nom_lam = exp.solution if exp.solution is not None else (guess.x, guess.u, None)
    nominal_guess = type(guess)(t=guess.t, x=nom_x, u=nom_u, xdot=guess.xdot)

    def warm_base():
        return wexp.solve(nominal_guess, p.x0_moved, duals=nom_lam)

    warm_base()
    say(f"baseline (Opti, expand=True, warm-started the same way): {repeats} solves ...")
    wexp_ms, (wexp_obj, wexp_it, wexp_ok) = median_ms(warm_base, repeats)
    doc = {"baseline_solve_ms_median": base_ms, "baseline_objective": base_obj, "baseline_iterations": base_it,
           "baseline_success": base_ok, "expand_baseline_solve_ms_median": exp_ms,
           "expand_baseline_objective": exp_obj, "expand_baseline_iterations": exp_it,
           "expand_baseline_success": exp_ok, "warm_baseline_solve_ms_median": wexp_ms,
           "warm_baseline_iterations": wexp_it, "warm_baseline_objective": wexp_obj,
           "warm_baseline_success": wexp_ok}
    f_hand = hand_typed_cartpole(p.params)
    if f_hand is not None:
        say("building the hand-typed naive casadi.Opti baseline (one pole's 2x2 equations as one SX Function) ...")
        hb = NaiveOptiBaseline(p.model, p.N, p.T, p.bounds, p.x0, f=f_hand)
        hb.solve(guess)  # builds IPOPT (not timed)
        say(f"baseline (Opti, hand-typed equations, IPOPT defaults): {repeats} solves ...")
        h_ms, (h_obj, h_it, h_ok) = median_ms(lambda: hb.solve(guess), repeats)
        doc.update({"hand_baseline_solve_ms_median": h_ms, "hand_baseline_objective": h_obj,
                    "hand_baseline_iterations": h_it, "hand_baseline_success": h_ok})
    return doc


def _fatrop(p: _Standard, ref_ms: float) -> dict:
    """Our collocation by fatrop, where CasADi has the plugin (else no rows)."""
    if not ca.has_nlpsol("fatrop"):
        return {}
    p.say(f"ours (fatrop): {p.repeats} solves ...")
    focp = DirectCollocation(p.model, N=p.N, T=p.T, bounds=p.bounds, options=CollocationOptions(solver="fatrop"))
    focp.solve_once(p.x0, guess=p.guess)
    f_ms, (_, finfo) = median_ms(lambda: focp.solve_once(p.x0, guess=p.guess), p.repeats)
    return {"fatrop_solve_ms_median": f_ms, "fatrop_objective": finfo.objective,
            "fatrop_success": finfo.success, "fatrop_iterations": finfo.iterations,
            "fatrop_speedup_vs_reference": ref_ms / f_ms if finfo.success else None}


def _sqp(p: _Standard, ocp: DirectCollocation, ours: dict, naive: dict, ref_ms: float) -> dict:
    """The SQP on the same problem object (same NLP, same scaling) from the guess."""
    p.say(f"ours (SQP on the stage-structured QP): {p.repeats} solves ...")
    sqp_solver = CollocationSQP(ocp)
    sqp_solver.solve_once(p.x0, guess=p.guess)  # builds the QP solvers (not timed)
    s_ms, (_, s_info) = median_ms(lambda: sqp_solver.solve_once(p.x0, guess=p.guess), p.repeats)
    ok = s_info.success  # ratios only for a converged solve (a failed one is not a faster way to the plan)
    return {"sqp_solve_ms_median": s_ms, "sqp_iterations": s_info.iterations, "sqp_objective": s_info.objective,
            "sqp_success": s_info.success, "sqp_status": s_info.status, "sqp_qp_solver": sqp_solver.qp_solver,
            "sqp_speedup": naive["baseline_solve_ms_median"] / s_ms if ok else None,
            "sqp_speedup_vs_expand": naive["expand_baseline_solve_ms_median"] / s_ms if ok else None,
            "sqp_vs_ipopt": ours["solve_ms_median"] / s_ms if ok else None,
            "sqp_objective_rel_diff": abs(s_info.objective - ours["objective"]) / abs(ours["objective"]),
            "sqp_speedup_vs_reference": ref_ms / s_ms if ok else None}


def _ddp(p: _Standard, objective: float, ref_ms: float) -> dict:
    """Box-DDP on the exact discrete step, from the guess's ctrl and from rest (our IPOPT's ``objective`` beside)."""
    p.say(f"ours (box-DDP on the exact discrete step, from the guess's ctrl): {p.repeats} solves ...")
    ddp = ddp_for_model(p.model, p.T, bounds=p.bounds)
    _, _, u_guess = _on_step_grid(p.guess, ddp.dt)
    ddp.solve(p.x0, u_guess)  # loads (or compiles) its library (not timed)
    d_ms, d_res = median_ms(lambda: ddp.solve(p.x0, u_guess), p.repeats)
    doc = {"ddp_solve_ms_median": d_ms, "ddp_iterations": d_res.iterations, "ddp_objective": d_res.cost,
           "ddp_success": d_res.converged, "ddp_status": d_res.status, "ddp_steps": ddp.N, "ddp_dt": ddp.dt,
           # DDP solves the exact discrete problem, not the collocation's: its optimum differs slightly, and from
           # the guess's ctrl run open loop it can land in another local minimum (this says which)
           "ddp_objective_rel_diff": abs(d_res.cost - objective) / abs(objective),
           "ddp_speedup_vs_reference": ref_ms / d_ms if d_res.converged else None}
    p.say(f"ours (box-DDP on the exact discrete step, from rest: zero ctrl): {p.repeats} solves ...")
    r_ms, r_res = median_ms(lambda: ddp.solve(p.x0, None), p.repeats)
    doc.update({"ddp_rest_solve_ms_median": r_ms, "ddp_rest_iterations": r_res.iterations,
                "ddp_rest_objective": r_res.cost, "ddp_rest_success": r_res.converged,
                "ddp_rest_speedup_vs_reference": ref_ms / r_ms if r_res.converged else None})
    return doc


def _trajopt_row(ours: dict, naive: dict) -> dict:
    """The ``trajopt`` document's rows of our IPOPT beside the naive script's, in the document's order."""
    o, n = ours, naive
    return {
        "solve_ms_median": o["solve_ms_median"], "objective": o["objective"], "N": o["N"], "T": o["T"],
        "solver": "ipopt", "iterations": o["iterations"], "success": o["success"],
        "baseline_solve_ms_median": n["baseline_solve_ms_median"], "baseline_objective": n["baseline_objective"],
        "baseline_iterations": n["baseline_iterations"], "baseline_success": n["baseline_success"],
        "speedup": n["baseline_solve_ms_median"] / o["solve_ms_median"],
        **{k: n[k] for k in ("expand_baseline_solve_ms_median", "expand_baseline_objective",
                             "expand_baseline_iterations", "expand_baseline_success")},
        "speedup_vs_expand": n["expand_baseline_solve_ms_median"] / o["solve_ms_median"],
        "objective_rel_diff": abs(o["objective"] - n["baseline_objective"]) / abs(n["baseline_objective"]),
        **{k: o[k] for k in ("warm_start_solve_ms_median", "warm_start_iterations", "warm_start_objective",
                             "warm_start_success")},
        "warm_start_speedup": n["warm_baseline_solve_ms_median"] / o["warm_start_solve_ms_median"],
        "compiled": o["compiled"],
        **{k: n[k] for k in ("warm_baseline_solve_ms_median", "warm_baseline_iterations", "warm_baseline_objective",
                             "warm_baseline_success")},
        **{k: o[k] for k in ("sx_solve_ms_median", "sx_iterations", "sx_objective")},
        "sx_speedup": n["baseline_solve_ms_median"] / o["sx_solve_ms_median"],
    }


def _reference_row(ours: dict, naive: dict, ref_ms: float) -> dict:
    """The hand-typed baseline's rows (one pole) and which baseline the ratios are taken against."""
    hand = {k: v for k, v in naive.items() if k.startswith("hand_baseline_")}
    return {**hand, "reference_baseline": "hand" if hand else "generic", "reference_solve_ms_median": ref_ms,
            "speedup_vs_reference": ref_ms / ours["solve_ms_median"] if ours["success"] else None}


def default_planner_row(ocp: DirectCollocation, x0, guess, repeats: int, ref_ms: float) -> dict:
    """The problem ``ocp`` (any objective: effort, a running cost, or ``time`` with ``guess``'s duration the guess of
    T) solved as the planner's default (``solver="auto"``) solves it from one guess:
    :class:`~cartpole.solvers.sqp.CollocationSQP` (at most
    :data:`cartpole.planning.trajopt.SQP_MAX_ITER` iterations and :data:`~cartpole.planning.trajopt.SQP_MAX_UNSETTLED`
    QPs handed to DAQP), IPOPT from the same guess when it does not converge, the two timed together.

    Parameters
    ----------
    ocp : DirectCollocation
        The problem.
    x0 : (nx,) array
        Start state ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    guess : Trajectory
        The initial guess both solvers start from.
    repeats : int
        Timed solves (the median is reported); more until they span the reference's ``repeats`` solves' time.
    ref_ms : float
        The reference baseline's solve time in ms (the ratio's numerator).

    Returns
    -------
    dict
        ``default_solver`` (whose plan it was: ``sqp`` or ``ipopt``), ``default_solve_ms_median`` (ms),
        ``default_iterations``, ``default_objective`` (as ``SolveInfo.objective``: ctrl^2 s for effort),
        ``default_success``,
        ``default_speedup_vs_reference`` (``ref_ms`` over it; None when no plan), and under ``"trajectory"`` the
        plan (not JSON: the caller pops it).
    """
    try:
        solver = CollocationSQP(ocp, options=SQPOptions(max_iter=SQP_MAX_ITER, max_unsettled=SQP_MAX_UNSETTLED))
    except SQPError:  # a problem the SQP does not take here (time without a C compiler): IPOPT's, as the planner
        solver = None

    def solve():
        if solver is None:
            return ocp.solve_once(x0, guess=guess)
        try:
            return solver.solve(x0, guess=guess, fallback=True)
        except SQPError:
            return None, None

    solve()  # builds (not timed)
    ms, (traj, info) = median_ms(solve, repeats, min_seconds=1e-3 * ref_ms * repeats)
    ok = info is not None and info.success
    return {"default_solver": info.solver if ok else None, "default_solve_ms_median": ms,
            "default_iterations": info.iterations if ok else None, "default_objective": info.objective if ok else None,
            "default_success": ok, "default_speedup_vs_reference": ref_ms / ms if ok else None,
            "trajectory": traj if ok else None}


#: The shipped carts the plan-time benchmark swings up: (label, asset file name).
PLAN_MODELS = (("1 pole", "cartpole.xml"), ("2 poles", "cartpole_two_pole.xml"), ("3 poles", "cartpole_three_pole.xml"))


def shipped_plan_models() -> list[tuple[str, str]]:
    """(label, path) of each shipped cart in :data:`PLAN_MODELS`."""
    return [(label, str(SHIPPED_MJCF.parent / name)) for label, name in PLAN_MODELS]


def plan_benchmark(mjcfs=None, *, repeats: int = 3, command: bool = True, progress=None, u_max=None,
                   cart_max: float | None = None) -> list[dict]:
    """Swing-up plan time, all initial guesses included, and time to upright, for carts with 1, 2 and 3 poles.

    Each repeat reads the MJCF anew, builds the model, plans (:func:`cartpole.planning.trajopt.trajopt_swingup`
    from hanging rest: the minimum-time solve, every guess it tries, the effort solve, TVLQR), runs the plan in
    MuJoCo for the plan + 3 s and checks that the log replays exactly; the compiled interval functions come
    from the on-disk cache after the first build (the cold figure is the first repeat's). With ``command`` the
    whole command ``cartpole swingup --method trajopt --no-video --json`` is also timed once in a fresh Python
    process (imports, basin estimate or its cache, JSON included).

    Parameters
    ----------
    mjcfs : sequence of (label, path), optional
        Default :data:`PLAN_MODELS` (the shipped 1-, 2- and 3-pole carts).
    repeats : int
        Repeats per model; medians reported.
    command : bool
        Also time the whole command once per model.
    progress : callable, optional
        ``progress(message)``.
    u_max, cart_max : optional
        The bounds each plan keeps to (:func:`cartpole.models.planning_limits`: the file's, else a stated default;
        each row's ``limits``); passed on to the timed command as ``--u-max``, ``--cart-max``.

    Returns
    -------
    list of dict
        Per model: ``model``, ``mjcf``, ``limits``, ``plan_s_median`` (s: read + build + plan), ``plan_s`` (every repeat, the
        first cold), ``verify_s_median`` (MuJoCo run + exact replay, s), ``total_s_median``, ``T`` (plan, s),
        ``T_min`` (s), ``time_to_upright`` (s, of the MuJoCo run), ``success``, ``replays``, ``attempts`` (solves
        tried by the last plan), ``command_s`` (or None).
    """
    say = progress or (lambda msg: None)
    items = shipped_plan_models() if mjcfs is None else list(mjcfs)
    bound_flags = ([] if u_max is None else ["--u-max", *map(str, np.ravel(u_max))]) + (
        [] if cart_max is None else ["--cart-max", str(cart_max)])
    rows = []
    for label, path in items:
        say(f"swing-up plan, {label}: {repeats} plans + MuJoCo runs ...")
        plan_s, verify_s, last = [], [], None
        for _ in range(max(1, int(repeats))):
            tic = time.perf_counter()
            params, limits = planning_limits(read_params(path), u_max=u_max, cart_max=cart_max)
            sp = trajopt_swingup(params, plan_model=build_model(params))
            toc = time.perf_counter()
            run = simulate(params, sp.controller, sp.model.x_hanging, sp.T + 3.0)
            ok = replays_exactly(run, params)
            plan_s.append(toc - tic)
            verify_s.append(time.perf_counter() - toc)
            last = (params, sp, run, ok)
        params, sp, run, ok = last
        met = swingup_metrics(run, params)
        cmd_s = None
        if command:
            say(f"the whole command on {label} ...")
            with tempfile.TemporaryDirectory() as out:
                tic = time.perf_counter()
                done = subprocess.run([sys.executable, "-m", "cartpole", "swingup", "--method", "trajopt",
                                       "--mjcf", path, "--no-video", "--json", "--out", out, *bound_flags],
                                      capture_output=True, text=True)
                cmd_s = time.perf_counter() - tic if done.returncode == 0 else None
        attempts = getattr(sp.solve_info, "attempts", None)
        rows.append({"model": label, "mjcf": params.mjcf, "limits": limits.to_dict(), "plan_s_median": statistics.median(plan_s),
                     "plan_s": plan_s, "verify_s_median": statistics.median(verify_s),
                     "total_s_median": statistics.median([a + b for a, b in zip(plan_s, verify_s)]),
                     "T": sp.T, "T_min": sp.T_min, "time_to_upright": met["time_to_upright"],
                     "success": bool(met["success"]), "replays": bool(ok),
                     "attempts": None if attempts is None else len(attempts), "command_s": cmd_s})
    return rows


def print_plan_table(rows: list[dict], file=None) -> None:
    """Prose table of :func:`plan_benchmark` rows."""
    w = (sys.stdout if file is None else file).write
    w(f"\n{'swing-up from hanging (trajopt + TVLQR)':40s} {'plan s':>8s} {'+ verify s':>10s} {'command s':>10s} "
      f"{'T plan s':>9s} {'upright s':>10s} {'success':>8s}\n")
    for r in rows:
        cmd = "-" if r["command_s"] is None else f"{r['command_s']:.2f}"
        up = "-" if r["time_to_upright"] is None else f"{r['time_to_upright']:.2f}"
        w(f"{r['model']:40s} {r['plan_s_median']:8.2f} {r['total_s_median']:10.2f} {cmd:>10s} {r['T']:9.2f} "
          f"{up:>10s} {str(r['success'] and r['replays']):>8s}\n")


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
    if "hand_baseline_solve_ms_median" in tr:
        w(f"{'baseline: Opti, hand-typed 2x2 equations (ref.)':44s} {tr['hand_baseline_solve_ms_median']:10.1f} "
          f"{tr['hand_baseline_iterations']:6d} {tr['hand_baseline_objective']:12.6f} "
          f"{tr['baseline_solve_ms_median'] / tr['hand_baseline_solve_ms_median']:8.1f}\n")
    if "expand_baseline_solve_ms_median" in tr:
        w(f"{'baseline: the same casadi.Opti, expand=True':44s} {tr['expand_baseline_solve_ms_median']:10.1f} "
          f"{tr['expand_baseline_iterations']:6d} {tr['expand_baseline_objective']:12.6f} "
          f"{tr['baseline_solve_ms_median'] / tr['expand_baseline_solve_ms_median']:8.1f}\n")
    if "sx_solve_ms_median" in tr:
        w(f"{'ours, SX only: map + expand + scaling, IPOPT':44s} {tr['sx_solve_ms_median']:10.1f} "
          f"{tr['sx_iterations']:6d} {tr['sx_objective']:12.6f} {tr['sx_speedup']:8.1f}\n")
    label = "ours: + compiled interval functions, IPOPT" if tr.get("compiled") else "ours (no C compiler), IPOPT"
    w(f"{label:44s} {tr['solve_ms_median']:10.1f} {tr['iterations']:6d} "
      f"{tr['objective']:12.6f} {tr['speedup']:8.1f}\n")
    if "fatrop_solve_ms_median" in tr:
        w(f"{'ours, fatrop (tol 1e-6)':44s} {tr['fatrop_solve_ms_median']:10.1f} {tr['fatrop_iterations']:6d} "
          f"{tr['fatrop_objective']:12.6f} {tr['baseline_solve_ms_median'] / tr['fatrop_solve_ms_median']:8.1f}\n")
    if "sqp_solve_ms_median" in tr:
        label = f"ours, SQP on the stage QP ({tr['sqp_qp_solver']})" + ("" if tr["sqp_success"] else ", FAILED")
        ratio = "-" if tr["sqp_speedup"] is None else f"{tr['sqp_speedup']:.1f}"
        w(f"{label:44s} {tr['sqp_solve_ms_median']:10.1f} {tr['sqp_iterations']:6d} {tr['sqp_objective']:12.6f} "
          f"{ratio:>8s}\n")
    if "ddp_solve_ms_median" in tr:
        label = f"ours, box-DDP, exact step ({tr['ddp_steps']} steps)" + ("" if tr["ddp_success"] else ", FAILED")
        w(f"{label:44s} {tr['ddp_solve_ms_median']:10.1f} {tr['ddp_iterations']:6d} {tr['ddp_objective']:12.6f} "
          f"{tr['baseline_solve_ms_median'] / tr['ddp_solve_ms_median']:8.1f}\n")
    if "ddp_rest_solve_ms_median" in tr:
        label = "ours, box-DDP, exact step, from zero ctrl" + ("" if tr["ddp_rest_success"] else ", FAILED")
        w(f"{label:44s} {tr['ddp_rest_solve_ms_median']:10.1f} {tr['ddp_rest_iterations']:6d} "
          f"{tr['ddp_rest_objective']:12.6f} {tr['baseline_solve_ms_median'] / tr['ddp_rest_solve_ms_median']:8.1f}\n")
    if "default_solve_ms_median" in tr:
        ok = tr["default_success"]
        label = f"the default planner (auto: {tr['default_solver'] or 'FAILED'})"
        ratio = "-" if tr["default_speedup_vs_reference"] is None else f"{tr['default_speedup_vs_reference']:.1f}"
        w(f"{label:44s} {tr['default_solve_ms_median']:10.1f} {tr['default_iterations'] if ok else -1:6d} "
          f"{tr['default_objective'] if ok else float('nan'):12.6f} {ratio:>8s} (vs the reference)\n")
    ratios = [(k[:-len('_speedup_vs_reference')] or 'ipopt', v) for k, v in tr.items()
              if k.endswith("speedup_vs_reference") and v is not None]
    w(f"\nratios against the {tr.get('reference_baseline', 'generic')} naive baseline "
      f"({tr.get('reference_solve_ms_median', float('nan')):.1f} ms): "
      + ", ".join(f"{k} {v:.1f}x" for k, v in ratios) + "\n")
    w("\nwarm starts (start moved 2 cm / 0.05 rad, from the nominal primal-dual solution; speed-up against the "
      "warm baseline)\n")
    if "warm_baseline_solve_ms_median" in tr:
        w(f"{'baseline: Opti, expand=True, IPOPT warm start':44s} {tr['warm_baseline_solve_ms_median']:10.1f} "
          f"{tr['warm_baseline_iterations']:6d} {tr['warm_baseline_objective']:12.6f} {1.0:8.1f}\n")
    w(f"{'ours, warm-started, start moved 2 cm/0.05 rad':44s} {tr['warm_start_solve_ms_median']:10.1f} "
      f"{tr['warm_start_iterations']:6d} {tr['warm_start_objective']:12.6f} {tr['warm_start_speedup']:8.1f}\n")
    w(f"\nobjective ours vs baseline: relative difference {tr['objective_rel_diff']:.2e}\n")
    w(f"TVLQR synthesis ({tv['steps']} steps at dt = {tv['dt']} s): {tv['ms_median']:.2f} ms (median)\n")
    if rp:
        w(f"Batched replay: {rp['steps_per_s']:.3g} closed-loop steps/s ({rp['rollouts']} rollouts x "
          f"{rp['seconds_each']} s)")
        if "open_loop_steps_per_s" in rp:
            w(f", open loop {rp['open_loop_steps_per_s']:.3g} steps/s, ratio {rp.get('ratio', float('nan')):.2f}")
        w("\n")
