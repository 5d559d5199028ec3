"""Sweep throughput: whole-sweep wall time on 1 and 2 local workers (and on a Dask cluster), their ratio, and
the engines' own per-run cost.

The workload is real swing-ups (default ``energy``: 10 s MuJoCo runs from seeded starts; ``--method trajopt``: a plan
+ TVLQR + 3 s after it per run), so the runs dominate. The basin is estimated once before timing (on disk), the
Dask cluster (a scheduler and 2 worker processes of 1 thread each, on loopback, each its own process:
:func:`start_dask_cluster`) is started once and warmed by one sweep; then the
executors are timed alternately, ``--rounds`` times, in this process, and the medians reported, because the machine
is shared. Two rates: the whole sweep (a local pool's time includes starting its workers, each building the model
once; the fork server the workers start from is started by the first pool sweep of the process, so round 1 of
``2`` pays for it and is reported on its own as ``first_round``; the Dask workers are already running) and first to
last finished run, ``(n - 1) / (t_last - t_first)``, which leaves start-up out. ``--fresh`` also times each
executor's sweep as ``cartpole sweep`` runs it, in a new process (the fork server started before the imports, as
the command does; the imports not timed; the model, the basin read from disk, the runs, the results file and the
success map timed), and ``--command`` the whole command from launch to exit, interpreter and imports included.

Beside them, the machine's own parallel capacity (:func:`parallel_capacity`): the wall time of one fixed CPU-bound
task in one process against two copies of it in two processes at once, timed in the same rounds. On a shared machine
whose two CPUs do not run two processes at full speed each (hyperthreads of one core, a neighbour on the host), no
pool can reach 2x, and this ratio says how much room there was.

Run by ``benchmarks/bench_sweep.py``::

    python benchmarks/bench_sweep.py --n 24 --rounds 7 --where 1 2 --fresh 5 --command 5   # worker start-up
    python benchmarks/bench_sweep.py --n 100 --rounds 3 [--method energy] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

from cartpole.apps.forkserver import start_server
from cartpole.apps.sweep import SweepError, SweepRuns, swingup_sweep


def _trivial(i):
    return {"i": i}


def engine_overhead(runs: int = 2000) -> dict:
    """ms per trivial task (a function returning a dict) on a 2-process pool started as the sweep's are
    (:func:`cartpole.apps.forkserver.start_server`) and on a 2-worker Dask LocalCluster, after warm-up."""
    from distributed import Client, LocalCluster

    out = {}
    with ProcessPoolExecutor(2, mp_context=start_server("energy")) as pool:
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


#: Dask settings of the benchmark's cluster and client (environment variables, so the ``dask scheduler`` and
#: ``dask worker`` processes read them too): comm timeouts well above distributed's 30 s, since on a loaded machine a
#: worker or scheduler starved of CPU for a while must not be declared dead (its scattered data then goes with it, and
#: every run that needs it is cancelled, "already forgotten").
DASK_ENV = {"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "120s", "DASK_DISTRIBUTED__COMM__TIMEOUTS__TCP": "300s",
            "DASK_DISTRIBUTED__SCHEDULER__WORKER_TTL": "15 minutes"}
#: Times a Dask round's sweep is run again, on a fresh cluster, after a run failed on the cluster (counted in the
#: JSON's ``dask_retries``): the benchmark measures throughput, not the cluster's survival of the machine's load.
DASK_RETRIES = 2


def start_dask_cluster(workers: int = 2, *, timeout: float = 60.0) -> tuple[list, str]:
    """A Dask scheduler and ``workers`` single-threaded worker processes on loopback, each in a process of its own
    (``dask scheduler``, ``dask worker``, with :data:`DASK_ENV`); returns ``(processes, address)`` once every worker
    has joined."""
    import dask
    from distributed import Client

    os.environ.update({k: os.environ.get(k, v) for k, v in DASK_ENV.items()})
    dask.config.refresh()  # this process's client reads them too

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    addr = f"tcp://127.0.0.1:{port}"
    dask = os.path.join(os.path.dirname(sys.executable), "dask")
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              **quiet)]
    procs.append(subprocess.Popen([dask, "worker", addr, "--nworkers", str(workers), "--nthreads", "1",
                                   "--no-dashboard"], **quiet))
    try:
        with Client(addr, timeout=timeout) as client:
            client.wait_for_workers(workers, timeout=timeout)
    except BaseException:
        stop_dask_cluster(procs)
        raise
    return procs, addr


def stop_dask_cluster(procs: list) -> None:
    """Terminate the processes :func:`start_dask_cluster` started (workers first) and wait for them."""
    for proc in reversed(procs):
        proc.terminate()
    for proc in reversed(procs):
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def timed_sweep(kw: dict, where: str, address: str | None = None) -> tuple[float, float, list]:
    """``(seconds, runs per s first to last run, rows)`` of one :func:`~cartpole.apps.sweep.swingup_sweep` on
    ``where`` (``"1"``, ``"2"``: local workers; ``"dask"``: the cluster at ``address``)."""
    stamps = []
    t0 = time.perf_counter()
    res = swingup_sweep(None, kw["method"], runs=SweepRuns(n=kw["n"], seed=kw["seed"]),
                        **({"address": address} if where == "dask" else {"workers": int(where)}),
                        on_row=lambda i, x0, row: stamps.append(time.perf_counter()))
    seconds = time.perf_counter() - t0
    steady = (len(stamps) - 1) / (stamps[-1] - stamps[0]) if len(stamps) > 1 else float("nan")
    return seconds, steady, res.rows()


def fresh_sweep(kw: dict, where: str) -> float:
    """Seconds of one sweep as ``cartpole sweep`` runs it, in a new Python process: the pool's fork server started
    first, before the heavy imports (as the command does), then the imports (not timed), then the timed part: the
    model, the basin read from disk, the runs, the results file and the success map
    (:func:`~cartpole.apps.sweep.run.recorded_sweep`, into a scratch directory)."""
    code = ("import json, sys, tempfile, time\n"
            "from pathlib import Path\n"
            "kw, where = %r, %r\n"
            "if where != '1':\n"
            "    from cartpole.apps.forkserver import start_server\n"
            "    start_server(kw['method'])\n"
            "from cartpole.apps.sweep import SweepRuns, recorded_sweep\n"
            "from cartpole.models import read_params\n"
            "with tempfile.TemporaryDirectory() as tmp:\n"
            "    t0 = time.perf_counter()\n"
            "    recorded_sweep(read_params(None), kw['method'], runs=SweepRuns(n=kw['n'], seed=kw['seed']),\n"
            "                   workers=int(where), results=Path(tmp) / 'r.csv', figure=Path(tmp) / 'f.png')\n"
            "    print(json.dumps(time.perf_counter() - t0))\n" % (kw, where))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})
    return float(out.stdout.strip().splitlines()[-1])


def command_sweep(kw: dict, where: str) -> float:
    """Wall seconds of the whole command ``cartpole sweep --method M --n N --seed S --workers W --json`` (into a
    scratch ``--out``), from launch to exit, as a user timing it sees: the interpreter, the imports, everything."""
    exe = os.path.join(os.path.dirname(sys.executable), "cartpole")
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [exe, "sweep", "--method", kw["method"], "--n", str(kw["n"]), "--seed", str(kw["seed"]),
               "--workers", where, "--json", "--out", tmp]
        t0 = time.perf_counter()
        subprocess.run(cmd, capture_output=True, text=True, check=True,
                       env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})
        return time.perf_counter() - t0


def _alternated(label: str, rounds: int, where, timed) -> dict:
    """``{executor: [seconds per round]}`` of ``timed(executor)`` for the local executors of ``where``, alternated
    within each of ``rounds`` rounds (each printed on stderr with the load); empty for no rounds."""
    out = {k: [] for k in where if k != "dask"} if rounds else {}
    for r in range(rounds):
        for k in out:
            out[k].append(timed(k))
            print(f"{label} {r + 1} {k:>4}: {out[k][-1]:.2f} s (load {os.getloadavg()[0]:.1f})", file=sys.stderr,
                  flush=True)
    return out


def _burn(n: int) -> float:
    """A fixed CPU-bound task (pure Python arithmetic); returns its own wall time in s."""
    t0 = time.perf_counter()
    s = 0
    for i in range(n):
        s += i * i
    return time.perf_counter() - t0


def parallel_capacity(n: int = 2_000_000, rounds: int = 3) -> dict:
    """How much faster two processes finish two copies of :func:`_burn` than one process finishes one copy twice:
    ``ratio = 2 t_one / t_two`` (2 on two free cores, 1 on one), medians of ``rounds`` alternated timings, with
    ``t_one`` the task alone in one process and ``t_two`` the wall time of two processes running it at once."""
    one, two = [], []
    with ProcessPoolExecutor(2) as pool:
        list(pool.map(_burn, [1000, 1000]))  # both started
        for _ in range(rounds):
            one.append(pool.submit(_burn, n).result())
            t0 = time.perf_counter()
            list(pool.map(_burn, [n, n]))
            two.append(time.perf_counter() - t0)
    t1, t2 = statistics.median(one), statistics.median(two)
    return {"one_s": t1, "two_s": t2, "ratio": 2 * t1 / t2}


def main(argv=None) -> int:
    """``benchmarks/bench_sweep.py``: parse ``argv`` (``--n``, ``--rounds``, ``--method``, ``--where``, ``--fresh``,
    ``--command``, ``--no-engine``, ``--json``), time the sweeps, print one JSON document (times in s, rates in runs/s, ratios to
    one worker) on stdout and the rounds on stderr; returns the exit status."""
    ap = argparse.ArgumentParser(prog="bench_sweep.py", description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--method", default="energy")
    ap.add_argument("--where", nargs="+", choices=("1", "2", "dask"), default=["1", "2", "dask"],
                    help="executors to time (1 is always timed: the baseline)")
    ap.add_argument("--fresh", type=int, default=0, metavar="R",
                    help="also R alternated rounds of each local executor in a new process per sweep")
    ap.add_argument("--command", type=int, default=0, metavar="R",
                    help="also R alternated rounds of the whole `cartpole sweep` command per local executor")
    ap.add_argument("--no-engine", action="store_true", help="skip the trivial-task engine overhead")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    where = list(dict.fromkeys(["1", *a.where]))

    kw = dict(method=a.method, n=a.n, seed=0)
    load_before = os.getloadavg()
    swingup_sweep(None, a.method, runs=SweepRuns(n=1))  # basin on disk, compiled functions built
    times = {k: [] for k in where}
    steady = {k: [] for k in where}  # (n - 1) / (last row - first row): without pool start-up
    rows = {}
    cluster = None
    addr = None
    if "dask" in where:
        # scheduler and workers in processes of their own, as a deployed cluster runs: a LocalCluster's scheduler
        # would run in this process's event-loop thread and slow the local pool's runs in this process (measured:
        # 1.34x one worker beside it against 1.8x without it)
        cluster, addr = start_dask_cluster(2)
        swingup_sweep(None, a.method, runs=SweepRuns(n=4), address=addr)  # warm the Dask workers (imports)
    retries = 0
    try:
        for r in range(a.rounds):
            for k in where:
                for attempt in range(DASK_RETRIES + 1 if k == "dask" else 1):
                    try:
                        seconds, rate, rows_k = timed_sweep(kw, k, addr)
                        break
                    except SweepError as exc:  # a run lost on the cluster: again on a fresh one, said on stderr
                        if attempt == DASK_RETRIES or "on the Dask cluster" not in str(exc):
                            raise
                        print(f"round {r + 1} dask: {exc} Again on a fresh cluster.", file=sys.stderr, flush=True)
                        retries += 1
                        stop_dask_cluster(cluster)
                        cluster, addr = start_dask_cluster(2)
                        swingup_sweep(None, a.method, runs=SweepRuns(n=4), address=addr)
                times[k].append(seconds)
                steady[k].append(rate)
                rows.setdefault(k, rows_k)
                print(f"round {r + 1} {k:>4}: {seconds:.2f} s, {a.n / seconds:.2f} runs/s whole sweep, "
                      f"{rate:.2f} runs/s first to last run (load {os.getloadavg()[0]:.1f})", file=sys.stderr,
                      flush=True)
    finally:
        if cluster is not None:
            stop_dask_cluster(cluster)
    # new processes: each local executor's sweep as the command runs it, then the whole command
    fresh = _alternated("fresh", a.fresh, where, lambda k: fresh_sweep(kw, k))
    command = _alternated("command", a.command, where, lambda k: command_sweep(kw, k))
    same = all(v == rows["1"] for v in rows.values())
    med = {k: a.n / statistics.median(v) for k, v in times.items()}
    steady_med = {k: statistics.median(v) for k, v in steady.items()}
    doc = {"method": a.method, "n": a.n, "rounds": a.rounds, "where": where, "seconds": times,
           "seconds_median": {k: statistics.median(v) for k, v in times.items()},
           "runs_per_s_median": med, "runs_per_s": {k: [a.n / t for t in v] for k, v in times.items()},
           "same_rows": same, "steady_runs_per_s_median": steady_med, "steady_runs_per_s": steady,
           "dask_retries": retries}
    for k, name in (("2", "2_workers"), ("dask", "dask")):
        if k in times:  # whole-sweep ratios to one worker: of the medians, per round, and round 1 alone
            doc[f"speedup_{name}"] = med[k] / med["1"]
            doc[f"round_ratios_{name}"] = [b / c for c, b in zip(times[k], times["1"])]
            doc[f"first_round_speedup_{name}"] = times["1"][0] / times[k][0]
            doc[f"steady_speedup_{name}"] = steady_med[k] / steady_med["1"]
    for name, seconds in (("fresh", fresh), ("command", command)):
        if seconds:
            doc[f"{name}_seconds"] = seconds
            doc[f"{name}_seconds_median"] = {k: statistics.median(v) for k, v in seconds.items()}
            if "2" in seconds:
                doc[f"{name}_speedup_2_workers"] = (statistics.median(seconds["1"])
                                                    / statistics.median(seconds["2"]))
                doc[f"{name}_round_ratios_2_workers"] = [b / c for c, b in zip(seconds["2"], seconds["1"])]
    doc.update(load_before=load_before, load_after=os.getloadavg(), cpu_count=os.cpu_count(),
               parallel_capacity=parallel_capacity())
    if not a.no_engine:
        doc["engine_ms_per_run"] = engine_overhead()
    print(json.dumps(doc, indent=None if a.json else 2))
    return 0
