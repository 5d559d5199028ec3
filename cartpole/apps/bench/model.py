"""Model readiness and linearisation speed against MuJoCo's own finite differences (``benchmarks/bench_model.py``
runs this).

For each cart, as medians of several timed runs in one process (``timeit.repeat``, each run a batch of calls, the
median divided by the batch):

* ``model_ready_s``: reading the MJCF and building every CasADi Function of the symbolic model
  (:func:`cartpole.models.build_model` of :func:`cartpole.models.read_params`);
* ``AB_eval_us``, ``ABd_eval_us``, ``linearize_numpy_us``: one evaluation of the exact continuous ``A, B``
  (``model.AB``), of the exact discrete ``Ad, Bd`` (one step of the MJCF's integrator, ``model.ABd``) and of
  ``model.linearize`` (numpy arrays out);
* the baselines people use without a symbolic model, in the same process on the same state: MuJoCo's
  ``mjd_transitionFD`` (discrete Jacobians by centred finite differences; not run for ``RK4``, which MuJoCo's
  function refuses, and reported as NaN) and a central difference of ``mj_forward`` over every state and input
  (continuous), with the ratios ``ABd_speedup_vs_transitionFD`` and ``AB_speedup_vs_forward_fd``.

The state is ``x_eq`` moved by a fixed random draw (seed 0, +-0.3 in every entry) and ``u_eq + 0.2``: away from
upright, so no evaluation is special-cased.
"""
from __future__ import annotations

import sys
import timeit

import mujoco
import numpy as np

from cartpole.apps.bench.trajopt import shipped_plan_models
from cartpole.models import build_model, plant_model, plant_params


def _median_per_call(fn, number: int, repeat: int) -> float:
    """s per call of ``fn``: the median over ``repeat`` runs of ``number`` calls each, divided by ``number``."""
    return float(np.median(timeit.repeat(fn, number=number, repeat=repeat)) / number)


def model_benchmark(plant, *, repeat: int = 7, calls: int = 2000, builds: int = 3) -> dict:
    """Model readiness and linearisation figures of one cart (see the module notes).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole MJCF.
    repeat : int
        Timed runs per figure; the median is reported.
    calls : int
        Calls per run of the cheap evaluations (``AB``, ``linearize``); the discrete Jacobians and both finite
        differences make ``calls // 4`` calls per run (at least 1).
    builds : int
        Model builds per run.

    Returns
    -------
    dict
        ``poles``, ``integrator``, ``model_ready_s`` (s), ``AB_eval_us``, ``ABd_eval_us``, ``linearize_numpy_us``,
        ``mjd_transitionFD_us`` (NaN for RK4), ``mj_forward_central_diff_us`` (microseconds per evaluation),
        ``ABd_speedup_vs_transitionFD``, ``AB_speedup_vs_forward_fd`` (ratios of those times).
    """
    repeat, calls, builds = max(1, int(repeat)), max(1, int(calls)), max(1, int(builds))
    slow = max(1, calls // 4)
    build_s = _median_per_call(lambda: build_model(plant_params(plant)), number=builds, repeat=repeat)
    model = plant_model(plant)
    rng = np.random.default_rng(0)
    x = model.x_eq + rng.uniform(-0.3, 0.3, model.nx)
    u = model.u_eq + 0.2
    nq = model.nq
    ab_s = _median_per_call(lambda: model.AB(x, u), number=calls, repeat=repeat)
    abd_s = _median_per_call(lambda: model.ABd(x, u), number=slow, repeat=repeat)
    lin_np_s = _median_per_call(lambda: model.linearize(x, u), number=calls, repeat=repeat)

    m = mujoco.MjModel.from_xml_path(str(plant_params(plant).mjcf))
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

    tfd_s = _median_per_call(transition_fd, number=slow, repeat=repeat) if model.integrator != "RK4" \
        else float("nan")
    ffd_s = _median_per_call(forward_fd, number=slow, repeat=repeat)
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


def shipped_model_benchmarks(mjcfs=None, *, repeat: int = 7, calls: int = 2000, builds: int = 3) -> dict:
    """:func:`model_benchmark` of each cart, keyed by its label.

    ``mjcfs``: a sequence of ``(label, path)``; default the shipped 1-, 2- and 3-pole carts
    (:func:`cartpole.apps.bench.trajopt.shipped_plan_models`: "1 pole", "2 poles", "3 poles"). The other
    parameters as :func:`model_benchmark`.
    """
    items = shipped_plan_models() if mjcfs is None else list(mjcfs)
    return {label: model_benchmark(path, repeat=repeat, calls=calls, builds=builds) for label, path in items}


def print_model_table(res: dict, file=None) -> None:
    """Prose table of :func:`shipped_model_benchmarks` (ms to build, microseconds per evaluation), with the targets."""
    w = (sys.stdout if file is None else file).write
    w("model       ready ms   A,B us   Ad,Bd us   mjd_transitionFD us   central diff of mj_forward us\n")
    for name, r in res.items():
        w(f"{name:10s} {r['model_ready_s'] * 1e3:8.2f} {r['AB_eval_us']:8.1f} {r['ABd_eval_us']:10.1f}"
          f" {r['mjd_transitionFD_us']:21.1f} {r['mj_forward_central_diff_us']:31.1f}\n")
    w("targets: three-pole model ready < 500 ms, its A, B < 100 us; the single pole no slower than before\n")
