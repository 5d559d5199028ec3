"""A sparse dm_control reward's own plan: into the task's box as early as the exact discrete model allows, and in it
from then on.

A sparse task (``dmc_cartpole_swingup_sparse``, ``dmc_pendulum_swingup``, ``dmc_acrobot_swingup_sparse``) pays 1
for each control step whose state lies in a box (:func:`cartpole.ocp.dmc.sparse_box`: ``lower <= g(x) <= upper``)
and 0 otherwise. The planner first maximises a smooth surrogate of it (the indicator has no gradient); the
surrogate's optimum is not the indicator's: it enters the box later than it must. Over a plan of ``n`` control
steps that ends at the goal (upright at rest, inside the box), the steps paid are ``n - K + 1`` for the first step
``K`` from which the plan stays in the box, so the sparse optimum is the smallest ``K`` for which

    x_0 = x0,  x_k+1 = step(x_k, u_k),  x_n = x_goal,  u_low <= u_k <= u_high,  q_low <= q_k <= q_high,
    lower + m <= g(x_k) <= upper - m   for every k >= K

has a solution (``m`` a hair, so that tracking's round-off stays inside dm_control's closed bounds). Feasibility
is monotone in ``K`` (a plan in the box from ``K`` on is in it from ``K + 1`` on), so ``K`` is searched downward
from the surrogate plan's own entry, galloping (1, 2, 4, ... steps earlier) until a ``K`` is refused, then by
bisection, each problem solved by IPOPT on the exact step (multiple shooting, the model's ``step``) from the last
feasible plan, the ctrl kept nearest the surrogate plan's (``min sum |u_k - u_ref,k|^2 dt``), within
:data:`MAX_STEPS` solves and :data:`MAX_SECONDS`. A refusal is a local solver's answer, so the plan returned is the
earliest entry found, not one proven earliest.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from cartpole.codegen import model_key
from cartpole.ocp.bounds import shooting_bounds
from cartpole.ocp.dmc import sparse_box

#: Distance kept inside the box's bounds (in g's units: m, cosine, m^2).
BOX_MARGIN = 1e-6
#: Most IPOPT solves of the entry search, and its wall-time budget in s (the plan found so far is kept).
MAX_STEPS = 30
MAX_SECONDS = 60.0


def _box_rows(Gx, lower, upper, on, margin: float):
    """The box as constraints ``>= 0`` on every knot's box quantities ``Gx`` (m, n+1), ``margin`` inside its finite
    bounds ``lower``, ``upper`` (m,), relaxed where ``on`` (1, n+1) is 0 by a bound no state reaches."""
    big = 1e6
    rows = []
    for i in range(lower.size):  # only the bounds that can bind (sparse_box gives the others as infinite)
        if np.isfinite(lower[i]):
            rows.append(Gx[i, :] - (lower[i] + margin) + big * (1 - on))
        if np.isfinite(upper[i]):
            rows.append((upper[i] - margin) - Gx[i, :] + big * (1 - on))
    return ca.vec(ca.horzcat(*rows))


#: The entry problems built so far, by the model's hash, task, steps and margin (:func:`entry_solver`), and the
#: tasks' boxes, by ``"box"``, the model's hash and task (:func:`box_function`).
_SOLVERS: dict = {}


def box_function(model, name: str) -> tuple:
    """The sparse task ``name``'s box on ``model`` (:func:`cartpole.ocp.dmc.sparse_box`), built once per model (hash)
    and task and kept: ``(g, lower (m,), upper (m,))``, ``g`` the CasADi Function ``x (nx,) -> g(x) (m,)`` (its
    ``map(n)`` takes ``n`` states as columns) and the box's bounds in ``g``'s units (m, cosine, m^2; read-only)."""
    key = ("box", model_key(model), str(name))
    if key not in _SOLVERS:
        xs = ca.SX.sym("x", model.nx)
        g_expr, lower, upper = sparse_box(model, name, xs)
        lower, upper = np.array(lower, dtype=float), np.array(upper, dtype=float)
        lower.setflags(write=False)
        upper.setflags(write=False)
        _SOLVERS[key] = (ca.Function("box", [xs], [g_expr]), lower, upper)
    return _SOLVERS[key]


def entry_solver(model, name: str, n: int, margin: float = BOX_MARGIN, fast: dict | None = None,
                 elastic: float | None = None):
    """The entry problem of the module doc over ``n`` steps of ``model.step`` for the sparse task ``name``, built
    once per model (hash), task, ``n``, ``margin`` and settings and kept: ``(solver, lbg, ubg)``, the IPOPT solver of
    the variables ``[vec(X) (nx, n+1), vec(U) (nu, n)]`` (column-major; with ``elastic`` then one slack >= 0 per box
    row) with the parameter ``[on (n+1,), vec(u_ref) (n nu,)]`` (``on`` 1 at the knots where the box holds; the cost
    ``sum |u_k - u_ref,k|^2 dt``) and the bounds of its constraints (the step's defects, then the box rows).
    ``fast``: IPOPT options over the search's own; ``elastic``: each box row may be missed by its slack at this cost
    per unit (an exact penalty: the box is kept wherever it can be, and the solve never ends infeasible)."""
    key = (model_key(model), str(name), int(n), float(margin), None if fast is None else tuple(sorted(fast.items())),
           elastic)
    if key not in _SOLVERS:
        nx, nu, dt = model.nx, model.nu, float(model.dt)
        g_fun, lower, upper = box_function(model, name)
        X, U = ca.MX.sym("X", nx, n + 1), ca.MX.sym("U", nu, n)
        K_par = ca.MX.sym("on", 1, n + 1)  # 1 where the box holds
        U_ref = ca.MX.sym("u_ref", nu, n)
        gap = ca.vec(model.step.map(n)(X[:, :-1], U) - X[:, 1:])
        box_rows = _box_rows(g_fun.map(n + 1)(X), lower, upper, K_par, margin)
        w, f = ca.veccat(X, U), ca.sumsqr(U - U_ref) * dt
        if elastic is not None:
            S = ca.MX.sym("s", box_rows.numel())
            w, f, box_rows = ca.veccat(w, S), f + float(elastic) * ca.sum1(S), box_rows + S
        solver = ca.nlpsol("box_entry", "ipopt", {"x": w, "p": ca.veccat(K_par, U_ref), "f": f,
                                                  "g": ca.vertcat(gap, box_rows)},
                           {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.max_iter": 200,
                            "ipopt.tol": 1e-10, "ipopt.constr_viol_tol": 1e-10, **(fast or {})})
        ng = nx * n
        _SOLVERS[key] = (solver, np.r_[np.zeros(ng), np.zeros(box_rows.numel())],
                         np.r_[np.zeros(ng), np.full(box_rows.numel(), np.inf)])
    return _SOLVERS[key]


def entry_step(model, name: str, x, margin: float = BOX_MARGIN) -> int | None:
    """The first knot of the states ``x`` (n+1, nx) from which every one is inside the sparse task ``name``'s box
    (``margin`` inside its bounds; :func:`box_function`, built once per model and task), or None when the last is
    outside."""
    g_fun, lower, upper = box_function(model, name)
    x = np.asarray(x, float)
    G = np.asarray(g_fun.map(x.shape[0])(x.T)).T  # (n+1, m)
    inside = np.all((G >= lower + margin) & (G <= upper - margin), axis=1)
    if not inside[-1]:
        return None
    out = np.flatnonzero(~inside)
    return int(out[-1] + 1) if out.size else 0


def box_entry_plan(model, name: str, x0, x_ref, u_ref, x_goal, bounds, *, max_steps: int = MAX_STEPS,
                   max_seconds: float = MAX_SECONDS, margin: float = BOX_MARGIN):
    """The plan of the module doc: the earliest box entry found, or None when it enters no earlier than ``x_ref``.

    Parameters
    ----------
    model : CartPoleModel
        The planning model; its ``step`` (one step of ``model.dt`` s) is the dynamics, on the plan's grid.
    name : str
        A sparse dm_control task (:func:`cartpole.ocp.dmc.sparse_box`).
    x0, x_goal : (nx,) arrays
        Start and final state ``[qpos, qvel]``.
    x_ref, u_ref : (n+1, nx), (n, nu) arrays
        The surrogate's plan on the step grid (a guess: it need not satisfy the step exactly).
    bounds : OCPBounds
        ctrl and joint bounds.
    max_steps : int
        Most IPOPT solves.
    max_seconds : float
        Wall-time budget in s: no new solve starts after it (the earliest entry found so far is returned).
    margin : float
        Kept inside the box's bounds.

    Returns
    -------
    (x (n+1, nx), u (n, nu), K, K_ref, info) or None
        The plan, its first step in the box from which it stays (``K``), the surrogate's (``K_ref``), and
        ``info`` {``iterations``, ``solves``, ``solve_time_s``, ``status``}. None: the surrogate plan never stays in
        the box, or no earlier entry was found.
    """
    tic = time.perf_counter()
    nx, nu = model.nx, model.nu
    x_ref, u_ref = np.asarray(x_ref, float), np.asarray(u_ref, float).reshape(-1, nu)
    n = u_ref.shape[0]
    K_ref = entry_step(model, name, x_ref, margin)
    if not K_ref:
        return None
    solver, lbg, ubg = entry_solver(model, name, n, margin)
    lw, hw = shooting_bounds(bounds, nx, n, x0, x_goal)
    w = np.clip(np.r_[x_ref.ravel(), u_ref.ravel()], lw, hw)
    solves, iters, status = 0, 0, "not tried"

    def feasible(K: int):
        nonlocal solves, iters, status
        on = np.r_[(np.arange(n + 1) >= K).astype(float), u_ref.ravel()]
        sol = solver(x0=w, p=on, lbx=lw, ubx=hw, lbg=lbg, ubg=ubg)
        stats = solver.stats()
        solves += 1
        iters += int(stats.get("iter_count", 0))
        status = str(stats.get("return_status"))
        return np.asarray(sol["x"], float).ravel() if stats.get("success", False) else None

    # galloping down from the surrogate's entry (1, 2, 4, ... steps earlier), then bisection between the earliest
    # entry found and the first refused; each solve from the last feasible plan
    good, bad, step = K_ref, 0, 1
    while good - step > bad and solves < int(max_steps) and time.perf_counter() - tic < max_seconds:
        found = feasible(good - step)
        if found is None:
            bad = good - step
            break
        w, good, step = found, good - step, 2 * step
    while good - bad > 1 and solves < int(max_steps) and time.perf_counter() - tic < max_seconds:
        mid = (good + bad) // 2
        found = feasible(mid)
        if found is None:
            bad = mid
        else:
            w, good = found, mid
    if good == K_ref:
        return None
    x, u, K = w[:nx * (n + 1)].reshape(n + 1, nx), w[nx * (n + 1):].reshape(n, nu), good
    info = {"iterations": iters, "solves": solves, "solve_time_s": time.perf_counter() - tic, "status": status}
    return x, u, K, K_ref, info


def box_entry_at(model, name: str, x0, x_ref, u_ref, bounds, K: int, *, margin: float = BOX_MARGIN,
                 fast: dict | None = None, elastic: float | None = None):
    """One problem of the module doc: the plan from ``x0`` to ``x_ref``'s last state, in the box from step ``K`` on,
    the ctrl nearest ``u_ref``'s, started from ``(x_ref, u_ref)`` (a plan from a nearby start entering at ``K``: e.g.
    the rest of a stored entry plan), by one IPOPT solve (:func:`entry_solver`, built once per model, task and
    length).

    Parameters
    ----------
    model, name, x0, x_ref, u_ref, bounds, margin
        As :func:`box_entry_plan` (``x_ref`` (n+1, nx), ``u_ref`` (n, nu)).
    K : int
        The first step in the box (0 <= K <= n).
    fast, elastic
        As :func:`entry_solver` (with ``elastic`` the plan may leave the box where it cannot keep it).

    Returns
    -------
    (x (n+1, nx), u (n, nu), info) or None
        The plan and ``info`` {``iterations``, ``solve_time_s``, ``status``}; None when IPOPT did not converge.
    """
    tic = time.perf_counter()
    nx, nu = model.nx, model.nu
    x_ref, u_ref = np.asarray(x_ref, float), np.asarray(u_ref, float).reshape(-1, nu)
    n = u_ref.shape[0]
    solver, lbg, ubg = entry_solver(model, name, n, margin, fast, elastic)
    lw, hw = shooting_bounds(bounds, nx, n, x0, x_ref[-1])
    w = np.clip(np.r_[x_ref.ravel(), u_ref.ravel()], lw, hw)
    if elastic is not None:  # the slacks, from 0
        extra = lbg.size - nx * n
        lw, hw, w = np.r_[lw, np.zeros(extra)], np.r_[hw, np.full(extra, np.inf)], np.r_[w, np.zeros(extra)]
    on = np.r_[(np.arange(n + 1) >= int(K)).astype(float), u_ref.ravel()]
    sol = solver(x0=w, p=on, lbx=lw, ubx=hw, lbg=lbg, ubg=ubg)
    stats = solver.stats()
    info = {"iterations": int(stats.get("iter_count", 0)), "solve_time_s": time.perf_counter() - tic,
            "status": str(stats.get("return_status"))}
    if not stats.get("success", False):
        return None
    w = np.asarray(sol["x"], float).ravel()
    return w[:nx * (n + 1)].reshape(n + 1, nx), w[nx * (n + 1):nx * (n + 1) + nu * n].reshape(n, nu), info
