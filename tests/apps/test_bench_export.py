"""The bench's export row: the C step timed in C replays the loop's ctrl exactly, beside the Python path."""
from cartpole.apps.bench.export import export_benchmark


def test_export_row_times_the_c_step_on_the_loop_measurements():
    doc = export_benchmark(quick=True)
    r = doc["lqr_kf"]
    assert r["replayed_same_ctrl"] and r["max_ctrl_diff"] <= 1e-9
    assert r["steps"] == round(1.0 / doc["period"])
    assert 0 < r["c_step_us_median"] <= r["c_step_us_max"]
    assert r["python_step_us_median"] > 0 and doc["nmpc"] is None  # --quick: LQR + KF only
