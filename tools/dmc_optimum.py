"""How much dm_control's cart-pole swing-up can pay at most, measured: box-DDP on the exact discrete step from many
guesses, from each of the episodes' starts (docs/dmc.md, "What the physics pays"; claims.toml).

For each start of ``cartpole sweep --objective TASK --n N --seed 0`` (dm_control's first N episodes), a DDP
(:func:`cartpole.solvers.ddp.ddp_for_model`: the MJCF's own step, which is MuJoCo's to round-off, |ctrl| <= 1, the cart
inside its rail, no terminal goal) maximises the task's planning reward (the smooth reward; for swingup_sparse its
surrogate) over the first ``--window`` seconds of the episode, from zero ctrl and from ``--guesses - 1`` random
pumping guesses (bang-bang at a random frequency, phase, amplitude and length, seeded). Each plan's predicted states
are scored with dm_control's exact reward (the state reached after each control step and the action held), and the
rest of the episode is counted at the most a step pays, 1: ``bound = window return + (1000 - window steps)``. No
controller on this model earns more from that start than the bound of the best window plan, if that plan is the
window's global optimum; a local method from many guesses measures it, it does not prove it (the output says how
many guesses reached the best cost). Prints one JSON document: per start the bound and that count, and the mean.

For ``dmc_cartpole_swingup_sparse`` the surrogate's best is not the sparse reward's best, so the output adds a second
bound that is the sparse reward's own: the sparse reward pays nothing before the state first enters its box (cart
within 0.25 m, pole cosine >= 0.995), so ``return <= 1000 - (K - 1)`` for the fewest control steps K that reach the box.
K is searched downward from the best window plan's first entry: IPOPT (multiple shooting on the same exact step,
|ctrl| <= 1, the rail) asked to be in the box after K - 1 steps, from that plan's ctrl, until it finds no such motion
(a local solver's "no", so again measured, not proven). JSON ``entry_bound`` per start and ``mean_entry_bound``.

    python tools/dmc_optimum.py [--task dmc_cartpole_swingup] [--n 10] [--guesses 20] [--window 3]
"""
import argparse
import json

import casadi as ca
import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.bounds import bounds_from_model
from cartpole.ocp.dmc import episode_starts, rewards, task
from cartpole.solvers.ddp import ddp_for_model


def _reaches_box(model, x0, U, K: int, cart: float, cos_min: float, b) -> np.ndarray | None:
    """ctrl (K, nu) that brings ``x0`` into the sparse box after exactly K steps of the exact step, or None."""
    nx, nu = model.nx, model.nu
    opti = ca.Opti()
    X, V = opti.variable(nx, K + 1), opti.variable(nu, K)
    opti.subject_to(X[:, 0] == x0)
    F = model.step.map(K)
    opti.subject_to(X[:, 1:] == F(X[:, :-1], V))
    opti.subject_to(opti.bounded(b.u_low[0], ca.vec(V), b.u_high[0]))
    s = model.slide
    opti.subject_to(opti.bounded(b.q_low[s], X[s, :], b.q_high[s]))
    opti.subject_to(opti.bounded(-cart, X[s, K], cart))
    for h in model.hinges[:1]:
        opti.subject_to(ca.cos(X[h, K]) >= cos_min)
    opti.minimize(ca.sumsqr(V) * 1e-3)
    x = np.array(x0, float)
    Xg = [x]
    for k in range(K):
        x = np.asarray(model.step(x, U[k])).ravel()
        Xg.append(x)
    opti.set_initial(X, np.array(Xg).T)
    opti.set_initial(V, U[:K].T)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "max_iter": 300})
    try:
        sol = opti.solve()
    except RuntimeError:
        return None
    return np.atleast_2d(sol.value(V)).reshape(nu, K).T


def _entry_bound(model, x0, U, steps: int, b) -> tuple[float, int]:
    """``(1000 - (K - 1), K)`` for the fewest steps K found to reach the sparse box (module doc)."""
    cart, cos_min = 0.25, 0.995
    x, k_in = np.array(x0, float), None
    for k in range(U.shape[0]):
        x = np.asarray(model.step(x, U[k])).ravel()
        if abs(x[model.slide]) < cart and np.cos(x[model.hinges[0]]) > cos_min:
            k_in = k + 1
            break
    if k_in is None:
        return float("nan"), -1
    K, best = k_in, U
    while K > 1:
        V = _reaches_box(model, x0, best, K - 1, cart, cos_min, b)
        if V is None:
            break
        K, best = K - 1, V
    return float(steps - (K - 1)), K


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="dmc_cartpole_swingup")
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--guesses", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--window", type=float, default=3.0, help="seconds planned (the rest counted at 1 a step)")
    args = ap.parse_args()
    mjcf = SHIPPED_MJCF.with_name("dmc_cartpole.xml")
    model = build_model(mjcf)
    t = task(args.task)
    dt = float(model.params.timestep)
    steps = t.steps(dt)
    b = bounds_from_model(model, cart_margin=0.0)
    ddp = ddp_for_model(model, min(args.window, steps * t.control_dt(dt)), objective=args.task, x_goal=False, bounds=b)
    sparse = t.name == "dmc_cartpole_swingup_sparse"
    rng = np.random.default_rng(args.seed)
    tt = np.arange(ddp.N) * ddp.dt
    rows = []
    for x0 in episode_starts(model, args.task, args.n, seed=args.seed):
        results = []
        for g in range(args.guesses):
            if g == 0:
                U = np.zeros((ddp.N, model.nu))
            else:
                w, ph, a, stop = rng.uniform(2, 8), rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 1.0), rng.uniform(0.5, 2)
                U = np.repeat((a * np.sign(np.sin(w * tt + ph)) * (tt < stop))[:, None], model.nu, axis=1)
            r = ddp.solve(x0, U)
            if np.all(np.isfinite(r.u)) and r.violation <= 1e-6:
                window = float(np.sum(rewards(model, args.task, np.asarray(r.x)[1:], np.asarray(r.u))))
                results.append((float(r.cost), window, np.array(r.u)))
        best = min(c for c, _, _ in results)
        window, u_best = max(((w, u) for c, w, u in results if c <= best + 1e-6 * abs(best)), key=lambda wu: wu[0])
        row = {"x0": [float(v) for v in x0], "bound": round(window + (steps - ddp.N), 2),
               "at_best": int(sum(c <= best + 1e-6 * abs(best) for c, _, _ in results)), "guesses": len(results)}
        if sparse:
            row["entry_bound"], row["entry_steps"] = _entry_bound(model, x0, u_best, steps, b)
        rows.append(row)
    doc = {"task": args.task, "n": args.n, "guesses": args.guesses, "window": ddp.N * ddp.dt,
           "mean_bound": round(float(np.mean([r["bound"] for r in rows])), 2), "rows": rows}
    if sparse:
        doc["mean_entry_bound"] = round(float(np.mean([r["entry_bound"] for r in rows])), 2)
    print(json.dumps(doc))


if __name__ == "__main__":
    main()
