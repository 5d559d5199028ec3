"""The model benchmark (build time, exact A, B against MuJoCo's finite differences): its keys and ratios, run at a tiny
size; no timing is asserted."""
import io

import numpy as np
import pytest

from cartpole.apps.bench.model import model_benchmark, print_model_table, shipped_model_benchmarks
from cartpole.models import build_model

KEYS = ("poles", "integrator", "model_ready_s", "AB_eval_us", "ABd_eval_us", "linearize_numpy_us",
        "mjd_transitionFD_us", "mj_forward_central_diff_us", "ABd_speedup_vs_transitionFD", "AB_speedup_vs_forward_fd")


def test_shipped_model_benchmarks_report_every_cart_with_its_keys_and_ratios():
    res = shipped_model_benchmarks(repeat=1, calls=4, builds=1)
    assert list(res) == ["1 pole", "2 poles", "3 poles"]
    for label, r in res.items():
        assert tuple(r) == KEYS
        assert r["poles"] == int(label.split()[0])
        times = [r[k] for k in KEYS[2:8]]
        assert all(np.isfinite(v) and v > 0 for v in times), r  # the shipped carts are not RK4
        assert r["ABd_speedup_vs_transitionFD"] == pytest.approx(r["mjd_transitionFD_us"] / r["ABd_eval_us"])
        assert r["AB_speedup_vs_forward_fd"] == pytest.approx(r["mj_forward_central_diff_us"] / r["AB_eval_us"])
    out = io.StringIO()
    print_model_table(res, file=out)
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("model") and [ln.split()[0] for ln in lines[1:4]] == ["1", "2", "3"]


def test_an_rk4_cart_has_no_transition_fd_baseline(chain_dir):
    """MuJoCo's mjd_transitionFD refuses RK4: the figure is NaN, the rest is measured."""
    path = chain_dir / "dmc_1pole.xml"
    assert build_model(str(path)).integrator == "RK4"
    r = model_benchmark(str(path), repeat=1, calls=4, builds=1)
    assert np.isnan(r["mjd_transitionFD_us"]) and np.isnan(r["ABd_speedup_vs_transitionFD"])
    assert np.isfinite(r["AB_speedup_vs_forward_fd"]) and r["poles"] == 1
