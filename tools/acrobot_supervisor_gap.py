"""Why the supervisor earns less on dm_control's acrobot-swingup than its own MPC run alone from the same starts
(issue 42, item 4; docs/dmc.md, "The supervisor on the acrobot"; claims.toml).

For each seed, the start dm_control's ``acrobot-swingup`` resets to (its own code, as ``cartpole score`` does) is run
for the whole 10 s episode in the toolkit's MuJoCo run of ``dmc_acrobot.xml`` (dm_control's physics to the bit:
``cartpole score``'s ``replays``) and scored with dm_control's exact reward (:func:`cartpole.apps.envscore.
episode_return`) under each of:

- ``supervisor``: the supervisor as ``cartpole score --controller supervisor`` runs it
  (:func:`cartpole.apps.envscore.supervised`);
- ``supervisor_mpc``: its swing-up MPC alone, no catch (:func:`cartpole.supervise.supervisor.swingup_mpc` on the
  task's objective: its solution the upright's inputs, improved one DDP iteration a step in the loop);
- ``mpc_from_start``: the 2 s, one-iteration DDP MPC of ``cartpole score`` (``design.predicted['2']``: its first
  solution converged offline from the start before the episode, not charged);
- ``supervisor_mpc_from_start``: the supervisor with that MPC as its swing-up MPC (it takes over at t = 0, where its
  solution is the one converged from the start);
- ``converged_<L>`` for each ``--latency L``: the supervisor with ``mpc_converge`` (its solution converged at the
  take-over from the state predicted ``L`` s ahead under the brake, charged ``L`` s: ``charged_latency``, so the run
  does not depend on the machine's speed).

Prints one JSON document: ``seeds``, ``returns`` (variant -> one return per seed), ``mean`` (variant -> mean),
``catch_t`` (variant -> the time of each episode's first catch, null when none), ``kinds`` (variant -> each
episode's decision kinds, in order; the supervisors only) and ``converge`` (``L`` -> each episode's take-over solve:
``iterations``) and ``start_iterations`` (the DDP iterations of ``mpc_from_start``'s offline solve, one per seed).

    python tools/acrobot_supervisor_gap.py [--n 10] [--seed 0] [--latency 0.1 0.3]
"""
import argparse
import json

import numpy as np

from cartpole.apps import envscore
from cartpole.models import build_model
from cartpole.supervise.supervisor import swingup_mpc

ENV = envscore.environment("acrobot-swingup")


def start(seed: int) -> np.ndarray:
    """(nx,) the start dm_control's acrobot-swingup resets to with ``seed``, read from its own MuJoCo data."""
    return envscore._DMC(ENV, seed).state()[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--latency", type=float, nargs="*", default=[])
    args = ap.parse_args(argv)
    mjcf = str(envscore.ASSETS / ENV.asset)
    model = build_model(mjcf)
    dt = float(model.dt)
    seeds = list(range(args.seed, args.seed + args.n))
    returns, catch_t, kinds, converge, start_iterations = {}, {}, {}, {}, []

    def record(name, controller, x0, sup=None):
        returns.setdefault(name, []).append(round(envscore.episode_return(model, mjcf, ENV.objective, controller,
                                                                          x0), 4))
        if sup is not None:
            caught = [d.t for d in sup.decisions if d.kind == "catch"]
            catch_t.setdefault(name, []).append(round(caught[0], 4) if caught else None)
            kinds.setdefault(name, []).append([d.kind for d in sup.decisions])

    for seed in seeds:
        x0 = start(seed)
        sup = envscore.supervised(ENV, mjcf, x0, 1)
        record("supervisor", sup, x0, sup)
        record("supervisor_mpc", swingup_mpc(model.params, model, None, objective=ENV.objective), x0)
        from_start = envscore._ddp_mpc(ENV, model, x0, dt, 2.0)
        start_iterations.append(int(from_start.init_info["iterations"]))
        record("mpc_from_start", from_start, x0)
        sup = envscore.supervised(ENV, mjcf, x0, 1)
        sup.mpc = envscore._ddp_mpc(ENV, model, x0, dt, 2.0)
        record("supervisor_mpc_from_start", sup, x0, sup)
        for lat in args.latency:
            sup = envscore.supervised(ENV, mjcf, x0, 1)
            sup.options = sup.options.replace(mpc_converge=True, charged_latency=float(lat))
            name = f"converged_{lat:g}"
            record(name, sup, x0, sup)
            converge.setdefault(f"{lat:g}", []).append(
                [d.detail.get("iterations") for d in sup.decisions if d.kind == "mpc"])
    mean = {k: round(float(np.mean(v)), 4) for k, v in returns.items()}
    print(json.dumps({"seeds": seeds, "returns": returns, "mean": mean, "catch_t": catch_t, "kinds": kinds,
                      "converge": converge, "start_iterations": start_iterations}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
