"""Swing-up plan time for carts with 1, 2 and 3 poles, from a fresh process to a verified MuJoCo rollout
(``benchmarks/bench_swingup_chains.py`` runs this).

Each run is a new Python process (as ``cartpole swingup --method trajopt`` is): import, read the MJCF, plan with
:func:`cartpole.planning.trajopt.trajopt_swingup` (every guess of the minimum-time multi-start, its refinement, the
effort plan, TVLQR), then one MuJoCo rollout from hanging rest checked with ``replays_exactly`` and
``swingup_metrics`` (3 s hold). Reported per cart, medians over the runs: ``wall_s`` (process start to the verified
rollout, interpreter start-up included), ``import_s``, ``plan_s`` (reading the MJCF and planning), ``rollout_s``,
and the plan's ``T_min``, ``T``, ``time_to_upright``, solver calls and iterations. The compile cache is whatever
the machine has: run once before to measure warm (the first run after a model change compiles its library).

A baseline (another checkout's code, e.g. ``git archive <commit> cartpole | tar -x -C ROOT``) is run the same
way, alternating with ours run by run, so both see the same machine load.
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cartpole.apps.bench.trajopt import shipped_plan_models
from cartpole.models import read_params

#: What each fresh process runs (``python -c``, the MJCF path as its argument); it prints one JSON line.
_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
from cartpole.models import build_model, read_params
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.metrics import swingup_metrics
t1 = time.perf_counter()
params = read_params(sys.argv[1])
plan = trajopt_swingup(params)
t2 = time.perf_counter()
model = build_model(params)
ro = simulate(params, plan.controller, model.x_hanging, plan.T + 5.0)
replays = replays_exactly(ro, params)
m = swingup_metrics(ro, model, hold=3.0)
t3 = time.perf_counter()
info = plan.solve_info
attempts = getattr(info, "attempts", ())
print(json.dumps({"import_s": t1 - t0, "plan_s": t2 - t1, "rollout_s": t3 - t2, "T_min": plan.T_min, "T": plan.T,
                  "time_to_upright": m["time_to_upright"], "success": bool(m["success"] and replays),
                  "objective": info.objective, "solves": len(attempts) or None,
                  "iterations": sum(a.iterations for a in attempts) if attempts else info.iterations}))
"""


def shipped_chain_carts() -> dict[int, str]:
    """Path of each shipped cart by its number of poles (1, 2, 3), read from the MJCFs
    (:func:`cartpole.apps.bench.trajopt.shipped_plan_models`)."""
    return {len(read_params(path).hinges): path for _, path in shipped_plan_models()}


def _run_once(path, code_root: str | None) -> dict:
    """One fresh process planning and verifying ``path``; ``code_root`` (a checkout's root) is put first on its
    path to measure that code instead of the installed one."""
    env = dict(os.environ)
    if code_root:
        env["PYTHONPATH"] = code_root + os.pathsep + env.get("PYTHONPATH", "")
    with tempfile.TemporaryDirectory() as cwd:  # not the checkout: python -c puts the cwd first on sys.path
        tic = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", _CHILD, str(path)], capture_output=True, text=True, env=env,
                             cwd=cwd, check=True).stdout
        wall = time.perf_counter() - tic
    return {**json.loads(out.strip().splitlines()[-1]), "wall_s": wall}


def _summary(runs: list[dict]) -> dict:
    med = {k: statistics.median(r[k] for r in runs) for k in ("wall_s", "import_s", "plan_s", "rollout_s")}
    last = runs[-1]
    return {**med, "wall_s_runs": [r["wall_s"] for r in runs], "plan_s_runs": [r["plan_s"] for r in runs],
            **{k: last[k] for k in ("T_min", "T", "time_to_upright", "success", "objective", "solves", "iterations")},
            "all_succeeded": all(r["success"] for r in runs)}


def measure(path, repeats: int, baseline: str | None = None) -> dict:
    """Medians over ``repeats`` fresh processes planning and verifying the swing-up of ``path``.

    Parameters
    ----------
    path : str or Path
        The cart's MJCF.
    repeats : int
        Fresh processes (medians reported).
    baseline : str, optional
        Another checkout's root: its code is run too, alternating with ours, and reported under ``"baseline"``.

    Returns
    -------
    dict
        ``wall_s``, ``import_s``, ``plan_s``, ``rollout_s`` (s, medians), ``wall_s_runs``, ``plan_s_runs`` (s, every
        run), the last run's ``T_min``, ``T``, ``time_to_upright`` (s), ``success``, ``objective``, ``solves``,
        ``iterations``, and ``all_succeeded``; ``baseline`` (the same keys) when asked for.
    """
    ours, theirs = [], []
    for _ in range(repeats):
        ours.append(_run_once(path, None))
        if baseline:
            theirs.append(_run_once(path, baseline))
    out = _summary(ours)
    if baseline:
        out["baseline"] = _summary(theirs)
    return out


def swingup_chains_benchmark(poles=None, *, repeats: int = 5, baseline: str | None = None) -> dict:
    """:func:`measure` for each shipped cart asked for.

    Parameters
    ----------
    poles : sequence of int, optional
        Numbers of poles of the carts to run (default 1, 2, 3: every shipped cart, :func:`shipped_chain_carts`).
    repeats, baseline
        As :func:`measure`.

    Returns
    -------
    dict
        ``repeats``, ``python`` (the interpreter the processes ran), ``baseline``, and ``carts``: per number of
        poles, ``mjcf`` and :func:`measure`'s figures.
    """
    carts = shipped_chain_carts()
    poles = sorted(carts) if poles is None else [int(n) for n in poles]
    missing = [n for n in poles if n not in carts]
    if missing:
        raise ValueError(f"No shipped cart has {missing[0]} poles; choose among {sorted(carts)}.")
    return {"repeats": repeats, "python": sys.executable, "baseline": baseline,
            "carts": {n: {"mjcf": str(Path(carts[n])), **measure(carts[n], repeats, baseline)} for n in poles}}


def print_chains_table(doc: dict, file=None) -> None:
    """Prose table of :func:`swingup_chains_benchmark` (one row per cart, and one per baseline)."""
    w = (sys.stdout if file is None else file).write
    w(f"{'poles':>5} {'wall s':>7} {'import':>7} {'plan s':>7} {'rollout':>7} {'T_min':>6} {'T':>6} "
      f"{'upright':>7} {'solves':>6} {'iters':>6} ok\n")
    for n, cart in doc["carts"].items():
        for label, r in [("", cart), (" base", cart.get("baseline"))]:
            if r is None:
                continue
            w(f"{str(n) + label:>5} {r['wall_s']:7.2f} {r['import_s']:7.2f} {r['plan_s']:7.2f} "
              f"{r['rollout_s']:7.2f} {r['T_min']:6.3f} {r['T']:6.3f} "
              f"{r['time_to_upright'] or float('nan'):7.3f} {r['solves'] or '-':>6} {r['iterations']:6d} "
              f"{r['all_succeeded']}\n")
