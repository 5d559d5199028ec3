"""Batched closed-loop replay throughput (:func:`cartpole.sim.simulate_batch_linear`) next to MuJoCo's own open-loop
``mujoco.rollout.rollout`` and, optionally, the plain per-rollout Python ``mj_step`` loop a user would write first:
the ``replay`` row of ``cartpole bench``."""
from __future__ import annotations

import time

import mujoco
import mujoco.rollout
import numpy as np

from cartpole.control.linear import LinearFeedback
from cartpole.models import build_model, plant_params
from cartpole.sim.batch import default_threads, initial_states, random_starts, simulate_batch_linear
from cartpole.sim.rollout import make_mujoco


def replay_benchmark(plant=None, *, rollouts: int = 256, seconds: float = 2.0, repeats: int = 5,
                     python_loop: bool = False) -> dict:
    """Closed-loop batch replay throughput next to MuJoCo's open-loop ``mujoco.rollout.rollout``.

    Both run the same model, the same ``rollouts`` random starts (:func:`random_starts`), ``seconds`` each, with
    the same number of threads, ``repeats`` times in this process; the medians are reported. The open loop
    replays random ctrl sequences in one ``rollout`` call (persistent pool), the closed loop runs the lab's
    LQR (:meth:`~cartpole.control.linear.LinearFeedback.for_model`, about the model's ``x_eq``) with
    :func:`simulate_batch_linear`. Any number of poles and actuators.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    rollouts : int
        Batch size.
    seconds : float
        Simulated seconds per rollout.
    repeats : int
        Timed repetitions (medians reported).
    python_loop : bool
        Also time the plain per-rollout Python ``mj_step`` loop with the same law (once; slow).

    Returns
    -------
    dict
        ``steps_per_s`` (closed loop, median), ``open_loop_steps_per_s`` (median), ``ratio`` (closed / open),
        ``rollouts``, ``seconds_each``, ``nthread``, ``physics_steps`` (per repetition) and, with
        ``python_loop``, ``python_loop_steps_per_s``.
    """
    params = plant_params(plant)
    model = build_model(params)
    law = LinearFeedback.for_model(model)
    X0 = random_starts(rollouts, model=model)
    m, _ = make_mujoco(params)
    n = int(round(seconds / m.opt.timestep))
    total = rollouts * n
    nthread = default_threads()

    S0 = initial_states(m, X0)
    U = np.random.default_rng(1).uniform(-1, 1, size=(rollouts, n, m.nu))
    datas = [mujoco.MjData(m) for _ in range(nthread)]
    closed, opened = [], []
    try:
        # interleaved, so both see the same load on a shared machine
        for _ in range(repeats):
            t0 = time.perf_counter()
            simulate_batch_linear(params, law, X0, seconds, nthread=nthread)
            closed.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            mujoco.rollout.rollout(m, datas, S0, U, persistent_pool=True)
            opened.append(time.perf_counter() - t0)
    finally:
        mujoco.rollout.shutdown_persistent_pool()

    doc = {
        "steps_per_s": total / float(np.median(closed)),
        "open_loop_steps_per_s": total / float(np.median(opened)),
        "rollouts": int(rollouts),
        "seconds_each": float(seconds),
        "nthread": nthread,
        "physics_steps": total,
    }
    doc["ratio"] = doc["steps_per_s"] / doc["open_loop_steps_per_s"]
    if python_loop:
        doc["python_loop_steps_per_s"] = _python_loop_rate(m, law, X0, n)
    return doc


def _python_loop_rate(m, law: LinearFeedback, X0, n: int) -> float:
    """Steps/s of the naive baseline: for each run, a Python loop of feedback + ``mj_step`` on one MjData."""
    d = mujoco.MjData(m)
    t0 = time.perf_counter()
    for x0 in X0:
        mujoco.mj_resetData(m, d)
        d.qpos[:] = x0[:m.nq]
        d.qvel[:] = x0[m.nq:]
        for _ in range(n):
            d.ctrl[:] = law(0.0, np.concatenate([d.qpos, d.qvel]))
            mujoco.mj_step(m, d)
    return X0.shape[0] * n / (time.perf_counter() - t0)
