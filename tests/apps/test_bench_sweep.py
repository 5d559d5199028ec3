"""The sweep benchmark: one timed sweep gives its seconds, a first-to-last rate and the rows; the parallel-capacity
baseline gives both timings and their ratio (no timing is asserted: the machine is shared); a Dask round whose run
was lost on the cluster is run again on a fresh cluster and counted."""
import json
import math

import pytest

from cartpole.apps.bench import sweep as bench_sweep
from cartpole.apps.bench.sweep import parallel_capacity, timed_sweep
from cartpole.apps.sweep import SweepError


def test_a_timed_sweep_returns_its_seconds_rate_and_rows():
    seconds, rate, rows = timed_sweep(dict(method="energy", n=2, seed=0), "1")
    assert seconds > 0 and len(rows) == 2 and (math.isnan(rate) or rate > 0)
    assert all("success" in row for row in rows)


def test_parallel_capacity_reports_one_and_two_process_timings_and_their_ratio():
    doc = parallel_capacity(n=20_000, rounds=1)
    assert set(doc) == {"one_s", "two_s", "ratio"}
    assert doc["one_s"] > 0 and doc["two_s"] > 0
    assert doc["ratio"] == 2 * doc["one_s"] / doc["two_s"]


def _fake_cluster(monkeypatch, failures: list):
    """The benchmark's cluster, sweeps and capacity replaced by stand-ins; each Dask sweep fails while ``failures``
    has entries (popping one), with the sentence of a run lost on the cluster; returns the clusters started."""
    started = []
    monkeypatch.setattr(bench_sweep, "swingup_sweep", lambda *a, **k: None)
    monkeypatch.setattr(bench_sweep, "start_dask_cluster", lambda n: (started.append(n) or ["procs"], "tcp://x:1"))
    monkeypatch.setattr(bench_sweep, "stop_dask_cluster", lambda procs: None)
    monkeypatch.setattr(bench_sweep, "parallel_capacity", lambda: {})

    def timed(kw, where, addr=None):
        if where == "dask" and failures:
            raise SweepError(f"A run failed on the Dask cluster at tcp://x:1: {failures.pop()}.")
        return 1.0, 1.0, [{"success": True}]

    monkeypatch.setattr(bench_sweep, "timed_sweep", timed)
    return started


def test_a_dask_round_that_lost_a_run_is_run_again_on_a_fresh_cluster_and_counted(monkeypatch, capsys):
    started = _fake_cluster(monkeypatch, ["FutureCancelledError: cancelled for reason: already forgotten"])
    assert bench_sweep.main(["--n", "2", "--rounds", "1", "--where", "dask", "--no-engine", "--json"]) == 0
    out = capsys.readouterr()
    doc = json.loads(out.out)
    assert doc["dask_retries"] == 1 and doc["same_rows"] and len(started) == 2
    assert "already forgotten" in out.err and "fresh cluster" in out.err


def test_a_dask_round_that_keeps_losing_runs_still_fails(monkeypatch):
    _fake_cluster(monkeypatch, ["KilledWorker"] * (bench_sweep.DASK_RETRIES + 1))
    with pytest.raises(SweepError, match="on the Dask cluster"):
        bench_sweep.main(["--n", "2", "--rounds", "1", "--where", "dask", "--no-engine", "--json"])
