"""Does the acrobot's winning swing-up from one start carry over to nearby starts? (docs/dmc.md, "The supervisor on
the acrobot"; claims.toml; issue 42 items 2 and 4.)

For each dm_control seed (its acrobot-swingup start: :func:`cartpole.ocp.dmc.episode_starts`, the first episode of
``task_kwargs={"random": seed}``) the per-start search of ``cartpole score`` (:func:`cartpole.apps.envscore.best_mpc`:
the DDP MPC of each horizon, and near hanging each horizon with more DDP iterations, each run through the whole
episode) picks its winning candidate, and the winner's closed-loop run from the start is stored (states and ctrl of
every 10 ms step). Then from perturbed starts (the shoulder and the elbow each offset by ``delta`` rad, their
signs ``directions``: ``pp`` both +, ``pm``, ``mp``, ``mm``; at rest) four controllers each run one episode in the
toolkit's own MuJoCo run of ``cartpole/assets/dmc_acrobot.xml`` and are scored with dm_control's exact reward
(:func:`cartpole.apps.envscore.episode_return`, as ``choose`` does; dm_control's episode earns the same to the bit):

* ``default``: the supervisor in dm_control's episodes (:func:`cartpole.apps.envscore.supervised`: its swing-up MPC, the
  2 s DDP MPC with one iteration, and the catch), each plan charged nothing (it plans none here);
* ``a_same``: the winning candidate itself (the same horizon and iterations) from the perturbed start;
* ``b_tvlqr``: TVLQR (default weights, :func:`cartpole.riccati.tvlqr.tvlqr` on the stored run as its exact discrete
  reference) along the stored run, the supervisor's catch taking over inside its verified basin and holding from
  then on (:class:`cartpole.control.switching.SwitchingController` with ``release_factor=inf``);
* ``c_warm``: the winner's DDP MPC seeded with the stored run's ctrl (``DDPMPCController(guess=...)``: its first
  solution converged from them, each shifted horizon extended by them while the run lasts).

Prints one JSON document: ``mirror_symmetric`` (:func:`cartpole.planning.library.mirror_symmetric` on the model),
``seeds`` (per seed: ``x0``, ``choice``, ``predicted`` each candidate's return, ``winner_return``, ``default_return``
from the seed's own start, ``b_tvlqr_nominal`` the tracker from the unperturbed start, ``search_s``), ``rows`` (seed,
delta, direction, x0, the seed's ``winner_return`` and each controller's return and wall time), ``summary`` (per
delta, each controller's mean return and mean fraction of the winner's) and ``library_estimate``
(:func:`library_estimate`).

    python tools/acrobot_transfer.py [--seeds 4 6] [--deltas 0.1 0.4] [--directions pp pm] [--winner 4:2.5x3 ...]

``--methods`` runs only those of the four from the perturbed starts; ``--tvlqr-q`` scales ``b_tvlqr``'s state weight.
``--winner SEED:LABEL`` skips the search for that seed and takes ``LABEL`` (``mpc_label``) as its winner (a choice an
earlier run of this tool or of ``cartpole score`` printed); ``--out PATH`` also writes the document after every row.
"""
import argparse
import json
import sys
import time

import numpy as np
from tqdm import tqdm

from cartpole.apps.envscore import (_ddp_mpc, best_mpc, environment, episode_return, supervised)
from cartpole.control.switching import SwitchingController
from cartpole.control.tvlqr import TVLQRController
from cartpole.models import build_model, read_params
from cartpole.mpc.ddp_mpc import DDPMPCController
from cartpole.mpc.options import MPCOptions
from cartpole.ocp.dmc import episode_starts, task
from cartpole.ocp.trajectory import Trajectory, step_grid_trajectory
from cartpole.planning.library import mirror_symmetric
from cartpole.riccati import default_weights
from cartpole.riccati.tvlqr import tvlqr
from cartpole.sim import simulate

ENV = "acrobot-swingup"
SIGNS = {"pp": (1, 1), "pm": (1, -1), "mp": (-1, 1), "mm": (-1, -1)}
METHODS = ("default", "a_same", "b_tvlqr", "c_warm")
#: rad: the starts near hanging (the shoulder within this of hanging, the elbow anywhere), the library's region.
NEAR_HANGING = 0.8
#: rad: the library grid's spacing in each angle of :func:`library_estimate`.
GRID_SPACING = 0.1


def library_estimate(search_s, mirror: bool, spacing: float = GRID_SPACING) -> dict | None:
    """What a library of searched swing-ups over the starts near hanging would cost: ``area_rad2`` (the region,
    halved when the model is mirror symmetric), ``starts`` on a grid of ``spacing`` rad, ``search_s`` (the mean
    measured search per start, s) and ``hours`` offline; None when no search was timed (every winner given)."""
    if not search_s:
        return None
    area = 2 * NEAR_HANGING * 2 * np.pi / (2 if mirror else 1)
    starts = int(np.ceil(area / spacing ** 2))
    mean_s = float(np.mean(search_s))
    return {"spacing": spacing, "area_rad2": round(area, 2), "starts": starts, "search_s": round(mean_s, 1),
            "hours": round(starts * mean_s / 3600, 1)}


def parse_label(label: str) -> tuple[float, int]:
    """``(horizon s, iterations)`` of an ``mpc_label`` (``"2.5"`` or ``"2.5x3"``)."""
    h, _, it = str(label).partition("x")
    return float(h), int(it) if it else 1


def stored_run(mjcf: str, model, controller, x0, duration: float) -> Trajectory:
    """The closed-loop run of ``controller`` from ``x0`` as a Trajectory on the physics step
    (:func:`cartpole.ocp.trajectory.step_grid_trajectory`: knot inputs the ctrl held over each step, the last
    repeated; knot derivatives ``model.f`` there)."""
    roll = simulate(mjcf, controller, x0, duration)
    return step_grid_trajectory(model.f, model.dt, np.column_stack([roll.qpos, roll.qvel]), roll.ctrl)


def tracker_for(model, run: Trajectory, catch, rho: float, q_scale: float = 1.0) -> SwitchingController:
    """TVLQR along ``run`` (its knots an exact discrete reference) until ``catch.cost_to_go(x) < rho``, then the
    catch, held from then on (:class:`~cartpole.control.switching.SwitchingController` with
    ``release_factor=inf``); its state weight ``q_scale`` times the default (:func:`cartpole.riccati.default_weights`),
    the input weight the default."""
    Q, _ = default_weights(model)
    gains = tvlqr(model, run, Q=q_scale * np.asarray(Q), reference=(np.asarray(run.x), np.asarray(run.u)[:-1]))
    return SwitchingController(TVLQRController(run, gains, catch), catch, rho, release_factor=float("inf"))


def warm_mpc(env, model, params, run: Trajectory, x0, label: str, period: float) -> DDPMPCController:
    """The winner's DDP MPC (horizon, iterations of ``label``) seeded with ``run``'s ctrl, converged from ``x0``."""
    h, it = parse_label(label)
    opts = MPCOptions(solver="ddp", objective=env.objective, seed_plan=False, period=period, horizon=h,
                      iterations=it)
    return DDPMPCController(model, params, options=opts, guess=run, x0=x0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[4, 6])
    ap.add_argument("--deltas", type=float, nargs="+", default=[0.1, 0.4])
    ap.add_argument("--directions", nargs="+", default=["pp", "pm"], choices=list(SIGNS))
    ap.add_argument("--winner", nargs="*", default=[], help="SEED:LABEL, the search's winner already known")
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS),
                    help="the controllers run from each perturbed start")
    ap.add_argument("--tvlqr-q", type=float, default=1.0, help="b_tvlqr's state weight, times the default")
    ap.add_argument("--out", default=None, help="also write the document here after every row")
    args = ap.parse_args()
    given = {int(s): lab for s, _, lab in (w.partition(":") for w in args.winner)}

    env = environment(ENV)
    mjcf = "cartpole/assets/" + env.asset
    params = read_params(mjcf)
    model = build_model(mjcf)
    period = float(model.dt)
    T = task(env.objective).steps(model.dt) * float(model.dt)
    doc = {"env": ENV, "mirror_symmetric": bool(mirror_symmetric(model)), "deltas": args.deltas,
           "directions": args.directions, "seeds": {}, "rows": []}

    def ret(controller, x0) -> tuple[float, float]:
        tic = time.perf_counter()
        try:
            r = episode_return(model, mjcf, env.objective, controller, x0)
        finally:  # a supervisor's planning worker ends with its episode
            close = getattr(controller, "close", None)
            if callable(close):
                close()
        return round(r, 4), round(time.perf_counter() - tic, 1)

    def dump() -> None:
        if args.out:
            with open(args.out, "w") as fh:
                json.dump(doc, fh, indent=1)

    bar = tqdm(total=len(args.seeds) * (2 + len(args.deltas) * len(args.directions)), desc="acrobot transfer",
               file=sys.stderr)
    for seed in args.seeds:
        x0 = episode_starts(model, env.objective, 1, seed)[0]
        tic = time.perf_counter()
        if seed in given:
            label, predicted = given[seed], None
            h, it = parse_label(label)
            winner = _ddp_mpc(env, model, x0, period, h, it)
        else:
            chosen = best_mpc(env, model, mjcf, x0, period)
            label, predicted, winner = chosen.choice, chosen.predicted, chosen.controller
        search_s = time.perf_counter() - tic
        run = stored_run(mjcf, model, winner, x0, T)
        sup = supervised(env, mjcf, x0, 1, charged_latency=0.0)
        catch, rho = sup.catch, sup.rho
        sup.close()
        win_r, _ = ret(winner, x0)
        bar.update()
        default_r, _ = ret(supervised(env, mjcf, x0, 1, charged_latency=0.0), x0)
        nominal_b, _ = ret(tracker_for(model, run, catch, rho, args.tvlqr_q), x0)
        bar.update()
        doc["seeds"][str(seed)] = {"x0": [float(v) for v in x0], "choice": label,
                                   "predicted": None if predicted is None else {k: round(v, 4)
                                                                               for k, v in predicted.items()},
                                   "winner_return": win_r, "default_return": default_r,
                                   "b_tvlqr_nominal": nominal_b, "search_s": round(search_s, 1)}
        dump()
        for delta in args.deltas:
            for d in args.directions:
                xp = np.array(x0, float)
                xp[list(model.hinges)] += delta * np.array(SIGNS[d], float)
                row = {"seed": seed, "delta": delta, "direction": d, "x0": [float(v) for v in xp],
                       "winner_return": win_r}
                h, it = parse_label(label)
                makers = {"default": lambda: supervised(env, mjcf, xp, 1, charged_latency=0.0),
                          "a_same": lambda: _ddp_mpc(env, model, xp, period, h, it),
                          "b_tvlqr": lambda: tracker_for(model, run, catch, rho, args.tvlqr_q),
                          "c_warm": lambda: warm_mpc(env, model, params, run, xp, label, period)}
                for name in args.methods:
                    r, wall = ret(makers[name](), xp)
                    row[name], row[name + "_s"] = r, wall
                doc["rows"].append(row)
                dump()
                bar.update()
    bar.close()
    summary = {}
    for delta in args.deltas:
        rows = [r for r in doc["rows"] if r["delta"] == delta]
        summary[str(delta)] = {m: {"mean": round(float(np.mean([r[m] for r in rows])), 1),
                                   "fraction_of_winner": round(float(np.mean(
                                       [r[m] / doc["seeds"][str(r["seed"])]["winner_return"] for r in rows])), 3)}
                               for m in args.methods}
    doc["summary"] = summary
    doc["library_estimate"] = library_estimate([doc["seeds"][str(s)]["search_s"] for s in args.seeds
                                                if s not in given], doc["mirror_symmetric"])
    dump()
    print(json.dumps(doc))


if __name__ == "__main__":
    main()
