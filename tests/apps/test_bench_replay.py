"""The batched replay benchmark: its keys, counts and ratio."""
import numpy as np
import pytest

from cartpole.apps.bench.replay import replay_benchmark

def test_replay_benchmark_reports_its_keys():
    r = replay_benchmark(rollouts=4, seconds=0.05, repeats=1)
    for key in ("steps_per_s", "open_loop_steps_per_s", "ratio", "rollouts", "seconds_each"):
        assert key in r
    assert r["rollouts"] == 4 and r["seconds_each"] == 0.05 and r["physics_steps"] == 4 * 10
    assert r["ratio"] == pytest.approx(r["steps_per_s"] / r["open_loop_steps_per_s"])
    assert np.isfinite(r["steps_per_s"]) and r["steps_per_s"] > 0
