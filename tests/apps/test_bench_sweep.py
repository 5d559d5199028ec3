"""The sweep benchmark: one timed sweep gives its seconds, a first-to-last rate and the rows; the parallel-capacity
baseline gives both timings and their ratio (no timing is asserted: the machine is shared)."""
import math

from cartpole.apps.bench.sweep import parallel_capacity, timed_sweep


def test_a_timed_sweep_returns_its_seconds_rate_and_rows():
    seconds, rate, rows = timed_sweep(dict(method="energy", n=2, seed=0), "1")
    assert seconds > 0 and len(rows) == 2 and (math.isnan(rate) or rate > 0)
    assert all("success" in row for row in rows)


def test_parallel_capacity_reports_one_and_two_process_timings_and_their_ratio():
    doc = parallel_capacity(n=20_000, rounds=1)
    assert set(doc) == {"one_s", "two_s", "ratio"}
    assert doc["one_s"] > 0 and doc["two_s"] > 0
    assert doc["ratio"] == 2 * doc["one_s"] / doc["two_s"]
