"""The most any policy can earn in dm_control's pendulum swing-up: the optimal value by value iteration, from each of
dm_control's starts and over its start distribution, at several grid resolutions (docs/dmc.md; claims.toml).

For each grid (``--grids 100 200 400``: angle nodes, rate nodes one more) :func:`cartpole.planning.value_iteration.
hinge_values` solves dm_control's reward (cosine within 8 degrees of upright, paid after each 20 ms step) over the
episode's 1000 steps on ``cartpole/assets/dmc_pendulum.xml`` (dm_control's physics to the bit). Per grid it prints

* ``value``: the optimal return the grid's value gives at the starts of reset seeds ``--seed .. --seed + n - 1``
  (dm_control's ``suite.load('pendulum', 'swingup', task_kwargs={'random': S})``, its first episode: uniform
  angle, at rest) and its mean;
* ``returns``: what the grid's policy (:class:`~cartpole.planning.value_iteration.ValuePolicy`) earns from those
  starts in MuJoCo over the 1000 steps (achieved, so a lower bound on the optimum; the value converges to it as the
  grid is refined) and its mean; ``max_gap`` the largest difference between the two over those starts;
* ``expected_value`` and ``expected_return``: the same averaged over the start distribution (``--angles`` starts
  at evenly spaced angles over the turn, at rest: the integral over the uniform angle, midpoint rule);
* ``p_mean10_above``: the chance that ten episodes from random starts, under the grid's policy, average more than
  ``--reference`` (TD-MPC2's best evaluation, 906.2; each of its evaluations is ten such episodes), and the chance
  that at least one of ``--evaluations`` (120: its three seeds' 40 evaluations each) does (resampled from the
  returns at the evenly spaced angles, ``--draws`` times, seeded).

With ``--hold 2 --every-step`` the policies are those that hold each action for two of dm_control's steps and the
return sums both steps' rewards: TD-MPC2's own setting (its environment wrapper repeats each action twice).

    python tools/pendulum_ceiling.py [--grids 100 200 400] [--n 10] [--seed 0] [--angles 360] [--hold 2 --every-step]
"""
import argparse
import json
import time

import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.dmc import episode_starts
from cartpole.planning.value_iteration import (DMCReward, ValueIterationOptions, ValuePolicy, hinge_values,
                                               policy_returns)

TASK = "dmc_pendulum_swingup"


def _grid_row(model, reward, size: int, starts: np.ndarray, spread: np.ndarray, steps: int, period=None,
              every_step: bool = False) -> dict:
    tic = time.perf_counter()
    opts = ValueIterationOptions(angles=size, rates=size + 1, horizon=steps, every_step=every_step)
    values = hinge_values(model, reward, period=period, options=opts)
    policy = ValuePolicy(values, model, reward)
    both = policy_returns(policy, np.vstack([starts, spread]), steps)
    returns, over = both[:len(starts)], both[len(starts):]
    value = values.value_at(starts)
    return {"angles": size, "rates": size + 1, "solve_s": round(values.solve_s, 1), "iterations": values.iterations,
            "value": [round(float(v), 1) for v in value], "mean_value": round(float(np.mean(value)), 1),
            "returns": [float(r) for r in returns], "mean_return": round(float(np.mean(returns)), 1),
            "max_gap": round(float(np.max(np.abs(value - returns))), 1),
            "expected_value": round(float(np.mean(values.value_at(spread))), 1),
            "expected_return": round(float(np.mean(over)), 1), "spread_returns": over,
            "seconds": round(time.perf_counter() - tic, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grids", type=int, nargs="+", default=[100, 200, 400])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--seed", type=int, nargs="+", default=[0, 10], help="first reset seed of each set of n")
    ap.add_argument("--angles", type=int, default=360, help="starts over the turn for the distribution's mean")
    ap.add_argument("--reference", type=float, default=906.2)
    ap.add_argument("--evaluations", type=int, default=120)
    ap.add_argument("--draws", type=int, default=20000)
    ap.add_argument("--hold", type=int, default=1, help="dm_control steps each action is held (TD-MPC2: 2)")
    ap.add_argument("--every-step", action="store_true",
                    help="pay every dm_control step of a held action, summed (an action-repeat wrapper's return)")
    args = ap.parse_args()
    model = build_model(SHIPPED_MJCF.with_name("dmc_pendulum.xml"))
    reward = DMCReward(model, TASK)
    seeds = [s for first in args.seed for s in range(first, first + args.n)]
    starts = np.array([episode_starts(model, TASK, 1, seed=s)[0] for s in seeds])
    theta = -np.pi + (np.arange(args.angles) + 0.5) * 2 * np.pi / args.angles
    spread = np.tile(np.asarray(model.x_eq, float), (args.angles, 1))
    spread[:, model.hinges[0]] += theta
    hold = max(1, args.hold)
    period = hold * float(model.dt) if hold > 1 else None
    rows = [_grid_row(model, reward, g, starts, spread, 1000 // hold, period, args.every_step) for g in args.grids]
    best = rows[-1]
    rng = np.random.default_rng(0)
    means = np.asarray(best["spread_returns"])[rng.integers(0, args.angles, (args.draws, 10))].mean(axis=1)
    p10 = float(np.mean(means > args.reference))
    for r in rows:
        r.pop("spread_returns")
    def mean(key, i):
        return round(float(np.mean(best[key][i * args.n:(i + 1) * args.n])), 1)

    sets = {f"seeds_{a}_{a + args.n - 1}": {"value": mean("value", i), "return": mean("returns", i)}
            for i, a in enumerate(args.seed)}
    print(json.dumps({"task": TASK, "seeds": seeds, "hold": hold, "every_step": args.every_step,
                      "reference": args.reference, "grids": rows, "finest": best,
                      "sets": sets, "p_mean10_above": round(p10, 4),
                      "p_any_of_evaluations_above": round(1.0 - (1.0 - p10) ** args.evaluations, 4),
                      "evaluations": args.evaluations}))


if __name__ == "__main__":
    main()
