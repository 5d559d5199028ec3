"""Model readiness and linearisation speed (issue 2).

Times, as medians of several runs in one process: reading the MJCF + building every CasADi Function, and one
evaluation of the exact ``A, B`` - next to the baseline people use without a symbolic model, MuJoCo's own
finite-difference ``mjd_transitionFD`` (discrete Jacobians) and a central difference of ``mj_forward`` (continuous).

Run: ``python benchmarks/bench_model.py`` (add ``--json`` for machine-readable output).
"""
from __future__ import annotations

import json
import sys
import timeit

import numpy as np


def _median_per_call(fn, number: int, repeat: int = 7) -> float:
    return float(np.median(timeit.repeat(fn, number=number, repeat=repeat)) / number)


def run() -> dict:
    """Return the benchmark figures (seconds) and ratios against MuJoCo finite differences."""
    import mujoco

    from cartpole.models import SHIPPED_MJCF, build_model, read_params

    build_s = _median_per_call(lambda: build_model(read_params()), number=3)
    model = build_model()
    x = np.array([0.1, 0.2, 0.3, -0.4])
    u = np.array([0.2])
    ab_s = _median_per_call(lambda: model.AB(x, u), number=2000)
    abd_s = _median_per_call(lambda: model.ABd(x, u), number=2000)
    lin_np_s = _median_per_call(lambda: model.linearize(x, u), number=2000)

    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    d = mujoco.MjData(m)
    A = np.zeros((4, 4))
    B = np.zeros((4, 1))

    def transition_fd():
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:2], x[2:], u
        mujoco.mjd_transitionFD(m, d, 1e-6, True, A, B, None, None)

    def forward_fd():
        eps = 1e-6
        for i in range(4):
            for sgn in (1, -1):
                xx = x.copy()
                xx[i] += sgn * eps
                d.qpos[:], d.qvel[:], d.ctrl[:] = xx[:2], xx[2:], u
                mujoco.mj_forward(m, d)
        for sgn in (1, -1):
            d.qpos[:], d.qvel[:], d.ctrl[:] = x[:2], x[2:], u + sgn * eps
            mujoco.mj_forward(m, d)

    tfd_s = _median_per_call(transition_fd, number=2000)
    ffd_s = _median_per_call(forward_fd, number=500)
    return {
        "model_ready_s": build_s,
        "AB_eval_us": ab_s * 1e6,
        "ABd_eval_us": abd_s * 1e6,
        "linearize_numpy_us": lin_np_s * 1e6,
        "mjd_transitionFD_us": tfd_s * 1e6,
        "mj_forward_central_diff_us": ffd_s * 1e6,
        "ABd_speedup_vs_transitionFD": tfd_s / abd_s,
        "AB_speedup_vs_forward_fd": ffd_s / ab_s,
    }


if __name__ == "__main__":
    res = run()
    if "--json" in sys.argv:
        print(json.dumps(res))
    else:
        print(f"model ready (read MJCF + build Functions): {res['model_ready_s'] * 1e3:8.2f} ms   (target < 200 ms)")
        print(f"A, B evaluated (CasADi call):               {res['AB_eval_us']:8.2f} us   (target < 50 us)")
        print(f"Ad, Bd evaluated (CasADi call):             {res['ABd_eval_us']:8.2f} us")
        print(f"model.linearize (numpy in/out):             {res['linearize_numpy_us']:8.2f} us")
        print(f"baseline mjd_transitionFD (Ad, Bd by FD):   {res['mjd_transitionFD_us']:8.2f} us"
              f"   -> exact Ad, Bd {res['ABd_speedup_vs_transitionFD']:.1f}x faster")
        print(f"baseline central diff of mj_forward (A, B): {res['mj_forward_central_diff_us']:8.2f} us"
              f"   -> exact A, B {res['AB_speedup_vs_forward_fd']:.1f}x faster")
