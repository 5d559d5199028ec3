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


def _bench_one(mjcf) -> dict:
    import mujoco

    from cartpole.models import build_model, read_params

    build_s = _median_per_call(lambda: build_model(read_params(mjcf)), number=3)
    model = build_model(mjcf)
    rng = np.random.default_rng(0)
    x = model.x_eq + rng.uniform(-0.3, 0.3, model.nx)
    u = model.u_eq + 0.2
    nq = model.nq
    ab_s = _median_per_call(lambda: model.AB(x, u), number=2000)
    abd_s = _median_per_call(lambda: model.ABd(x, u), number=500)
    lin_np_s = _median_per_call(lambda: model.linearize(x, u), number=2000)

    m = mujoco.MjModel.from_xml_path(str(mjcf))
    d = mujoco.MjData(m)
    A = np.zeros((model.nx, model.nx))
    B = np.zeros((model.nx, model.nu))

    def transition_fd():
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:nq], x[nq:], u
        mujoco.mjd_transitionFD(m, d, 1e-6, True, A, B, None, None)

    def forward_fd():
        eps = 1e-6
        for i in range(model.nx):
            for sgn in (1, -1):
                xx = x.copy()
                xx[i] += sgn * eps
                d.qpos[:], d.qvel[:], d.ctrl[:] = xx[:nq], xx[nq:], u
                mujoco.mj_forward(m, d)
        for k in range(model.nu):
            for sgn in (1, -1):
                uu = u.copy()
                uu[k] += sgn * eps
                d.qpos[:], d.qvel[:], d.ctrl[:] = x[:nq], x[nq:], uu
                mujoco.mj_forward(m, d)

    tfd_s = _median_per_call(transition_fd, number=500) if model.integrator != "RK4" else float("nan")
    ffd_s = _median_per_call(forward_fd, number=500)
    return {
        "poles": len(model.hinges),
        "integrator": model.integrator,
        "model_ready_s": build_s,
        "AB_eval_us": ab_s * 1e6,
        "ABd_eval_us": abd_s * 1e6,
        "linearize_numpy_us": lin_np_s * 1e6,
        "mjd_transitionFD_us": tfd_s * 1e6,
        "mj_forward_central_diff_us": ffd_s * 1e6,
        "ABd_speedup_vs_transitionFD": tfd_s / abd_s,
        "AB_speedup_vs_forward_fd": ffd_s / ab_s,
    }


def run() -> dict:
    """Benchmark figures (seconds, microseconds) and ratios against MuJoCo finite differences, per shipped cart."""
    from cartpole.models import SHIPPED_MJCF

    names = {"1 pole": SHIPPED_MJCF, "2 poles": SHIPPED_MJCF.with_name("cartpole_two_pole.xml"),
             "3 poles": SHIPPED_MJCF.with_name("cartpole_three_pole.xml")}
    return {name: _bench_one(path) for name, path in names.items()}


if __name__ == "__main__":
    res = run()
    if "--json" in sys.argv:
        print(json.dumps(res))
    else:
        print("model       ready ms   A,B us   Ad,Bd us   mjd_transitionFD us   central diff of mj_forward us")
        for name, r in res.items():
            print(f"{name:10s} {r['model_ready_s'] * 1e3:8.2f} {r['AB_eval_us']:8.1f} {r['ABd_eval_us']:10.1f}"
                  f" {r['mjd_transitionFD_us']:21.1f} {r['mj_forward_central_diff_us']:31.1f}")
        print("targets: three-pole model ready < 500 ms, its A, B < 100 us; the single pole no slower than before")
