"""Sweep throughput: runs per second on 1 and 2 local workers and on a Dask LocalCluster, and the engines' own
per-run cost.

The workload is real swing-ups (default ``energy``: 10 s MuJoCo runs from seeded starts; ``--method trajopt``: a plan
+ TVLQR + 3 s after it per run), so the runs dominate. The basin is estimated once before timing (on disk), the
Dask cluster (2 worker processes, 1 thread each, loopback) is started once and warmed by one sweep; then the three
are timed alternately, ``--rounds`` times, and the medians reported, because the machine is shared. Two rates: the
whole sweep (the pool's time includes spawning its workers, each importing the toolkit and building the model once;
the Dask workers are already running) and first to last finished run, ``(n - 1) / (t_last - t_first)``, which leaves
start-up out for all three.

    python benchmarks/bench_sweep.py --n 100 --rounds 3 [--method energy] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time


def _trivial(i):
    return {"i": i}


def engine_overhead(runs: int = 2000) -> dict:
    """ms per trivial task (a function returning a dict) on a 2-process spawn pool and on a 2-worker Dask
    LocalCluster, after warm-up."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from distributed import Client, LocalCluster

    out = {}
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        list(pool.map(_trivial, range(50)))
        t0 = time.perf_counter()
        for f in [pool.submit(_trivial, i) for i in range(runs)]:
            f.result()
        out["pool_ms"] = 1e3 * (time.perf_counter() - t0) / runs
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None,
                      silence_logs=50) as cluster, Client(cluster) as client:
        client.gather([client.submit(_trivial, i, pure=False) for i in range(50)])
        t0 = time.perf_counter()
        client.gather([client.submit(_trivial, i, pure=False) for i in range(runs)])
        out["dask_ms"] = 1e3 * (time.perf_counter() - t0) / runs
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--method", default="energy")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)

    from distributed import LocalCluster

    from cartpole.apps.sweep import swingup_sweep

    kw = dict(method=a.method, n=a.n, seed=0)
    swingup_sweep(None, **{**kw, "n": 1})  # basin on disk, compiled functions built
    times = {"1": [], "2": [], "dask": []}
    steady = {"1": [], "2": [], "dask": []}  # (n - 1) / (last row - first row): without pool start-up
    rows = {}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None,
                      silence_logs=50) as cluster:
        addr = cluster.scheduler_address
        swingup_sweep(None, **{**kw, "n": 4}, address=addr)  # warm the Dask workers (imports)
        for r in range(a.rounds):
            for where in ("1", "2", "dask"):
                stamps = []
                t0 = time.perf_counter()
                res = swingup_sweep(None, **kw, **({"address": addr} if where == "dask" else {"workers": int(where)}),
                                    on_row=lambda i, x0, row: stamps.append(time.perf_counter()))
                times[where].append(time.perf_counter() - t0)
                steady[where].append((len(stamps) - 1) / (stamps[-1] - stamps[0]))
                rows.setdefault(where, res.rows())
                print(f"round {r + 1} {where:>4}: {a.n / times[where][-1]:.2f} runs/s whole sweep, "
                      f"{steady[where][-1]:.2f} runs/s first to last run (load {os.getloadavg()[0]:.1f})",
                      flush=True)
    same = rows["1"] == rows["2"] == rows["dask"]
    med = {k: a.n / statistics.median(v) for k, v in times.items()}
    doc = {"method": a.method, "n": a.n, "rounds": a.rounds, "runs_per_s_median": med,
           "runs_per_s": {k: [a.n / t for t in v] for k, v in times.items()},
           "speedup_2_workers": med["2"] / med["1"], "speedup_dask": med["dask"] / med["1"], "same_rows": same,
           "round_ratios_2_workers": [b / a for a, b in zip(times["2"], times["1"])],
           "round_ratios_dask": [b / a for a, b in zip(times["dask"], times["1"])],
           "steady_runs_per_s_median": {k: statistics.median(v) for k, v in steady.items()},
           "steady_runs_per_s": steady,
           "steady_speedup_2_workers": statistics.median(steady["2"]) / statistics.median(steady["1"]),
           "steady_speedup_dask": statistics.median(steady["dask"]) / statistics.median(steady["1"]),
           "load_after": os.getloadavg(),
           "engine_ms_per_run": engine_overhead(), "cpu_count": os.cpu_count()}
    print(json.dumps(doc, indent=None if a.json else 2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
