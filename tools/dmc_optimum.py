"""How much dm_control's cart-pole swing-up can pay at most, measured: box-DDP on the exact discrete step from many
guesses, from each of the episodes' starts (docs/dmc.md, "What the physics pays"; claims.toml).

For each start of ``cartpole sweep --objective TASK --n N --seed 0`` (dm_control's first N episodes), a DDP
(:func:`cartpole.solvers.ddp.ddp_for_model`: the MJCF's own step, which is MuJoCo's to round-off, |ctrl| <= 1, the cart
inside its rail, no terminal goal) maximises the task's smooth reward (a sparse task is refused: its surrogate's
optimum bounds nothing) over the first ``--window`` seconds of the episode, from zero ctrl and from ``--guesses - 1`` random
pumping guesses (bang-bang at a random frequency, phase, amplitude and length, seeded). Each plan's predicted states
are scored with dm_control's exact reward (the state reached after each control step and the action held), and the
rest of the episode is counted at the most a step pays, 1: ``bound = window return + (1000 - window steps)``. No
controller on this model earns more from that start than the bound of the best window plan, if that plan is the
window's global optimum; a local method from many guesses measures it, it does not prove it (the output says how
many guesses reached the best cost). Prints one JSON document: per start the bound and that count, and the mean.

    python tools/dmc_optimum.py [--task dmc_cartpole_swingup] [--n 10] [--guesses 20] [--window 3]
"""
import argparse
import json

import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.bounds import bounds_from_model
from cartpole.ocp.dmc import episode_starts, rewards, task
from cartpole.solvers.ddp import ddp_for_model


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
    if t.sparse:
        ap.error(f"{t.name} pays an indicator: the best of its smooth surrogate bounds nothing; give a smooth task "
                 "(dmc_cartpole_swingup).")
    dt = float(model.params.timestep)
    steps = t.steps(dt)
    b = bounds_from_model(model, cart_margin=0.0)
    ddp = ddp_for_model(model, min(args.window, steps * t.control_dt(dt)), objective=args.task, x_goal=False, bounds=b)
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
                results.append((float(r.cost), window))
        best = min(c for c, _ in results)
        window = max(w for c, w in results if c <= best + 1e-6 * abs(best))
        rows.append({"x0": [float(v) for v in x0], "bound": round(window + (steps - ddp.N), 2),
                     "at_best": int(sum(c <= best + 1e-6 * abs(best) for c, _ in results)), "guesses": len(results)})
    print(json.dumps({"task": args.task, "n": args.n, "guesses": args.guesses, "window": ddp.N * ddp.dt,
                      "mean_bound": round(float(np.mean([r["bound"] for r in rows])), 2), "rows": rows}))


if __name__ == "__main__":
    main()
