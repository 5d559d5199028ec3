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
    nx, nu, dt = model.nx, model.nu, float(model.dt)
    xs = ca.SX.sym("x", nx)
    g_expr, lower, upper = sparse_box(model, name, xs)
    g_fun = ca.Function("box", [xs], [g_expr])
    x_ref, u_ref = np.asarray(x_ref, float), np.asarray(u_ref, float).reshape(-1, nu)
    n = u_ref.shape[0]
    G = np.asarray(g_fun.map(n + 1)(x_ref.T)).T  # (n+1, m)
    inside = np.all((G >= lower + margin) & (G <= upper - margin), axis=1)
    if not inside[-1]:
        return None
    out = np.flatnonzero(~inside)
    K_ref = int(out[-1] + 1) if out.size else 0
    if K_ref == 0:
        return None
    X, U = ca.MX.sym("X", nx, n + 1), ca.MX.sym("U", nu, n)
    K_par = ca.MX.sym("on", 1, n + 1)  # 1 where the box holds
    gap = ca.vec(model.step.map(n)(X[:, :-1], U) - X[:, 1:])
    Gx = g_fun.map(n + 1)(X)  # (m, n+1)
    box_rows = _box_rows(Gx, lower, upper, K_par, margin)
    cost = ca.sumsqr(U - u_ref.T) * dt
    lw, hw = shooting_bounds(bounds, nx, n, x0, x_goal)
    solver = ca.nlpsol("box_entry", "ipopt", {"x": ca.veccat(X, U), "p": K_par, "f": cost,
                                              "g": ca.vertcat(gap, box_rows)},
                       {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.max_iter": 200,
                        "ipopt.tol": 1e-10, "ipopt.constr_viol_tol": 1e-10})
    ng = nx * n
    lbg = np.r_[np.zeros(ng), np.zeros(box_rows.numel())]
    ubg = np.r_[np.zeros(ng), np.full(box_rows.numel(), np.inf)]
    w = np.clip(np.r_[x_ref.ravel(), u_ref.ravel()], lw, hw)
    solves, iters, status = 0, 0, "not tried"

    def feasible(K: int):
        nonlocal solves, iters, status
        on = (np.arange(n + 1) >= K).astype(float)[None, :]
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
