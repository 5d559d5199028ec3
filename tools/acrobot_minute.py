"""The acrobot's knocked-down minute, per seed, in MuJoCo (tests/supervise/test_knockdown_runs.py's seed table;
docs/recovery.md; claims.toml).

For each seed, dm_control's acrobot starts upright under the supervisor the acrobot's knockdown test runs
(:func:`cartpole.supervise.supervisor_for` with the test's options: each plan charged ``LATENCY`` s of simulated time,
its wall time allowed 300 s; the library's plan from hanging, built once per model and kept on disk) and is knocked by
``Knockdown(3, 0.3, seed)`` for 60 s. Prints one JSON document: ``seeds``, and per seed (``runs``, in seed order)
``knockdowns``, ``recovered``, ``uptime``, ``unrecovered_at`` (s, each knock not followed by a swing-up) with
``left_s`` (s of the minute left after each), ``failures`` (decision kind -> count: ``plan_failed``, ``lost``,
``replan_failed``, ``calm_timeout``, ``plan_timeout``, ``mpc_failed``), ``mpcs`` (swing-ups the MPC took over),
``mpc_swingup_s`` (s from each MPC take-over to the catch it handed to), ``mpc_ms`` (its wall time per control
step: median, max), ``plans``, ``plan_s`` (median wall time of a plan, s),
``wall_s`` (the run's wall time) and ``decisions`` with ``--decisions`` (each ``t``, ``kind`` and its details but
the state); then totals:
``knockdowns``, ``recovered``, ``uptime_median``, ``missed_with_time`` (knocks unrecovered with at least
``LATE`` s of the minute left, summed over seeds), ``seeds_all_recovered_with_time`` (seeds whose every knock with
``LATE`` s left was recovered), ``mpc_swingup_s`` (``min``, ``median``, ``max``, ``count`` over every seed).

``--no-mpc``: the supervisor without its swing-up MPC (``swingup_mpc=False``), as it was before it.

    python tools/acrobot_minute.py [--seeds 0 1 ... 11] [--duration 60] [--decisions] [--no-mpc]
"""
import argparse
import json
import sys
import time

import numpy as np
from tqdm import tqdm

from cartpole.codegen import model_key
from cartpole.models import build_model, read_params
from cartpole.planning.library import cached_library, library_path, library_starts
from cartpole.planning.options import PlanOptions
from cartpole.sim import Knockdown, simulate
from cartpole.supervise import SupervisorOptions, supervisor_for
from cartpole.supervise.supervisor import hinge_options
from cartpole.validation import uptime_metrics

ACROBOT = "cartpole/assets/dmc_acrobot.xml"
AFTER, LENGTH = 3.0, 0.3
#: s of simulated time each plan is charged (as the test's).
LATENCY = 2.0
#: s: a knock unrecovered with at least this much of the minute left counts as missed (less is one swing-up's worth:
#: the library's plan from hanging, 12.4 s, and its latency).
LATE = 15.0
FAILURES = ("plan_failed", "lost", "replan_failed", "calm_timeout", "plan_timeout", "mpc_failed")


def acrobot_options(mpc: bool = True) -> SupervisorOptions:
    """The options the acrobot's knockdown test runs the supervisor with (``mpc`` False: without the swing-up MPC,
    every recovery planned, as before it)."""
    return hinge_options(charged_latency=LATENCY, plan_budget=300.0, swingup_mpc=mpc)


def acrobot_library(params, model):
    """The library of one plan from hanging, as the test keeps it on disk."""
    default = library_path(model_key(model))
    return cached_library(params, model, library_starts(model, 1),
                          options=PlanOptions(exact_discrete=False, search_s=900.0),
                          path=default.with_name(f"hanging-{default.name}"))


def one_run(params, model, library, seed: int, duration: float, decisions: bool, mpc: bool = True
            ) -> dict:
    """One knocked minute from upright: its row (module docstring)."""
    tic = time.perf_counter()
    sup = supervisor_for(params, model, options=acrobot_options(mpc), library=library)
    force = Knockdown(AFTER, LENGTH, seed=seed).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, sup, np.asarray(model.x_eq, float), duration, disturbance=force)
    m = uptime_metrics(run, model, events=force.events, duration=duration)
    kinds = [d.kind for d in sup.decisions]
    took = [(d.t, nxt) for d, nxt in zip(sup.decisions, sup.decisions[1:]) if d.kind == "mpc"]
    row = {"seed": seed, "knockdowns": m["knockdowns"], "recovered": m["recoveries"], "uptime": m["uptime"],
           "unrecovered_at": m["unrecovered_at"], "left_s": [duration - a for a in m["unrecovered_at"]],
           "failures": {k: kinds.count(k) for k in FAILURES}, "mpcs": kinds.count("mpc"),
           "mpc_swingup_s": [nxt.t - t for t, nxt in took if nxt.kind == "catch"],
           "mpc_ms": sup.summary()["mpc_ms"], "plans": sup.plans,
           "plan_s": float(np.median(sup.plan_seconds)) if sup.plan_seconds else None,
           "diverged": bool(run.info.get("diverged", False)), "wall_s": time.perf_counter() - tic}
    if decisions:
        row["decisions"] = [{k: v for k, v in d.to_dict().items() if k != "x0"} for d in sup.decisions]
    return row


def _spread(values) -> dict | None:
    """``min``, ``median``, ``max`` and ``count`` of ``values``, or None when there are none."""
    if not values:
        return None
    return {"min": float(np.min(values)), "median": float(np.median(values)), "max": float(np.max(values)),
            "count": len(values)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(12)))
    ap.add_argument("--duration", type=float, default=60.0, help="s of MuJoCo per seed")
    ap.add_argument("--decisions", action="store_true", help="each run's decisions too")
    ap.add_argument("--no-mpc", action="store_true", help="without the swing-up MPC: every recovery planned")
    args = ap.parse_args()
    params = read_params(ACROBOT)
    model = build_model(params)
    library = acrobot_library(params, model)
    rows = [one_run(params, model, library, s, args.duration, args.decisions, not args.no_mpc)
            for s in tqdm(args.seeds, desc="acrobot minutes", file=sys.stderr)]
    missed = [sum(1 for left in r["left_s"] if left >= LATE) for r in rows]
    print(json.dumps({"seeds": args.seeds, "runs": rows, "knockdowns": sum(r["knockdowns"] for r in rows),
                      "recovered": sum(r["recovered"] for r in rows),
                      "uptime_median": float(np.median([r["uptime"] for r in rows])),
                      "missed_with_time": sum(missed),
                      "mpc_swingup_s": _spread([v for r in rows for v in r["mpc_swingup_s"]]),
                      "seeds_all_recovered_with_time": sum(1 for k in missed if not k)},
                     default=float))


if __name__ == "__main__":
    main()
