"""How soon dm_control's acrobot can be up from hanging, measured: the most energy box-DDP finds its motor can put in
within T seconds (docs/dmc.md, "Why the acrobot stays below 711.5 here"; claims.toml).

From a start (default hanging at rest), for each ``--T``, a box-DDP on the MJCF's exact step (|ctrl| <= 1, the 2 N m
of the elbow's motor) maximises the energy gained over ``T``, ``E(x_N) - E(x_0)`` (the running cost ``-(E(step(x, u))
- E(x)) / dt``, which sums to it exactly, plus ``1e-4 u^2``), from ``--guesses`` bang-bang guesses at random multiples of
the hanging mode's frequency (seeded). ``E`` is the acrobot's energy, zero at upright rest (hanging: -39.2 J).
dm_control pays its full reward only with the tip within the target's radius (0.2 m), which needs at least the
potential energy ``E_target`` (the least over the configurations with the tip there, on a 721 x 721 grid of the two
hinges). ``E_max`` is energy some input sequence reaches within ``T`` (an exact rollout): the motor can put in at
least that much, so once ``E_max >= E_target`` the energy does not forbid the tip at the target by ``T``. A local
method from a few guesses finds the most energy only approximately (``at_best`` says how many guesses reached the
best): it does not bound it from above, and so bounds no return. ``reward_max`` is the most dm_control's reward pays
in any configuration of potential energy at most ``E_max`` (on the same grid). Prints one JSON document.

    python tools/acrobot_energy.py [--T 1 2 3 3.5 4] [--guesses 4] [--x0 3.14159265 0 0 0]
"""
import argparse
import json

import casadi as ca
import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.dmc import rewards
from cartpole.planning.pumping import hanging_mode, pump_energy
from cartpole.solvers.ddp import DDPOptions, ddp_for_model


def configurations(model, grid: int = 721) -> tuple:
    """Every configuration at rest on a ``grid`` x ``grid`` grid of the two hinges: its potential energy (J, zero at
    upright rest) and the reward dm_control pays there (:func:`cartpole.ocp.dmc.rewards`, zero ctrl)."""
    q1, q2 = np.meshgrid(np.linspace(-np.pi, np.pi, grid), np.linspace(-np.pi, np.pi, grid))
    x = np.column_stack([q1.ravel(), q2.ravel(), np.zeros((q1.size, model.nv))])
    return pump_energy(model, x), rewards(model, "dmc_acrobot_swingup", x, np.zeros((q1.size, model.nu)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--T", type=float, nargs="+", default=[1.0, 2.0, 3.0, 3.5, 4.0], help="horizons in s")
    ap.add_argument("--guesses", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--x0", type=float, nargs=4, default=None, help="start [shoulder, elbow, rates] (default hanging)")
    args = ap.parse_args()
    model = build_model(SHIPPED_MJCF.with_name("dmc_acrobot.xml"))
    dt = float(model.dt)
    x0 = np.asarray(model.x_hanging if args.x0 is None else args.x0, float)

    def gained(x, u):
        return -(model.energy(model.step(x, u)) - model.energy(x)) / dt + 1e-4 * ca.sumsqr(u)

    V, paid = configurations(model)
    omega = hanging_mode(model)[0]
    rng = np.random.default_rng(args.seed)
    rows = []
    for T in args.T:
        ddp = ddp_for_model(model, T, objective=gained, x_goal=False, options=DDPOptions(max_iterations=500, max_outer=1))
        tt = np.arange(ddp.N) * dt
        ends = []
        for _ in range(args.guesses):
            w, phase = omega * rng.uniform(0.7, 2.5), rng.uniform(0, 2 * np.pi)
            r = ddp.solve(x0, np.repeat(np.sign(np.sin(w * tt + phase))[:, None], model.nu, axis=1))
            if np.all(np.isfinite(r.x)):
                ends.append(float(pump_energy(model, np.asarray(r.x)[-1:])[0]))
        best = max(ends)
        rows.append({"T": T, "E_max": round(best, 2), "at_best": int(sum(e >= best - 0.01 for e in ends)),
                     "guesses": len(ends), "reward_max": round(float(np.max(paid[V <= best], initial=0.0)), 4)})
    print(json.dumps({"x0": [float(v) for v in x0], "E_start": round(float(pump_energy(model, x0[None])[0]), 2),
                      "E_target": round(float(np.min(V[paid >= 1.0])), 2), "rows": rows}))


if __name__ == "__main__":
    main()
