"""Many closed-loop MuJoCo runs at once: linear feedback over a batch, stepped in lockstep.

A Python loop of ``mj_step`` per rollout spends most of its time in the interpreter. Here all ``B`` runs advance
together: each physics step is one call of MuJoCo's threaded ``mujoco.rollout`` with ``nstep=1`` over the whole
batch (one persistent thread pool, one reused ``MjData`` per thread, preallocated state buffers), and the
feedback law ``u = u* - K (x - x*)`` is evaluated for all runs at once in numpy between calls. The physics is
MuJoCo's own ``mj_step``, so each run equals :func:`~cartpole.sim.rollout.simulate` with
:class:`~cartpole.control.linear.LinearFeedback` (a test checks 1e-12).

One caveat: ``mujoco.rollout`` restores the physics state but not the constraint solver's warm start, which
stays per thread; while a joint limit is active the solver may therefore land a few ulp (within its tolerance)
from a single-``MjData`` run. Runs that stay off their limits are identical.
"""
from __future__ import annotations

import os
import time

import numpy as np

from cartpole.control.linear import LinearFeedback
from cartpole.errors import CartPoleError
from cartpole.lqr import Q_LAB, R_LAB, lqr
from cartpole.models import CartPoleParams, build_model, read_params, wrap_angle
from cartpole.sim.rollout import make_mujoco


def _nthread_default() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _initial_states(m, X0: np.ndarray) -> np.ndarray:
    """Full physics states (B, nstate) at t = 0 for starts X0 (B, 4)."""
    import mujoco

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    d = mujoco.MjData(m)
    S0 = np.empty((X0.shape[0], mujoco.mj_stateSize(m, spec)))
    for i, x in enumerate(X0):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = x[:2]
        d.qvel[:] = x[2:]
        mujoco.mj_getState(m, d, S0[i], spec)
    return S0


def simulate_batch_linear(source, K, X0, duration: float, *, x_eq=None, u_eq: float = 0.0, u_limits=None,
                          nthread: int | None = None, progress=None) -> tuple[np.ndarray, np.ndarray]:
    """Run ``u = u* - K (x - x*)`` (angle error wrapped, ctrl clipped to ``ctrlrange``) from every row of ``X0``.

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
        The cart-pole (None = shipped asset).
    K : (1, 4) or (4,) array
        Gain in ctrl per [m, rad, m/s, rad/s].
    X0 : (B, 4) array
        Start states ``[s, theta, s_dot, theta_dot]``.
    duration : float, s
        Rounded to whole physics steps ``n``.
    x_eq : (4,) array, optional
        Equilibrium (default the origin).
    u_eq : float
        Equilibrium ctrl (default 0).
    u_limits : (2,) array, optional
        ``[low, high]`` ctrl clip applied before MuJoCo's ``ctrlrange`` clip, as
        :class:`~cartpole.control.linear.LinearFeedback` does (default none).
    nthread : int, optional
        Threads of MuJoCo's rollout pool (default: the CPUs this process may use; 0 = calling thread).
    progress : callable, optional
        Called with the fraction of physics steps done (about every 5 %).

    Returns
    -------
    states : (B, n+1, 4) array
        ``[qpos, qvel]`` at every physics step, row 0 the start.
    ctrl : (B, n, 1) array
        ctrl applied (after clipping) during each step.
    """
    import mujoco
    import mujoco.rollout

    K = np.asarray(K, dtype=float).reshape(-1)
    X0 = np.atleast_2d(np.asarray(X0, dtype=float))
    if K.shape != (4,) or X0.ndim != 2 or X0.shape[1] != 4:
        raise CartPoleError(f"Need K with 4 entries and X0 of shape (B, 4); got K {K.shape} and X0 {X0.shape}.")
    if not (np.all(np.isfinite(X0)) and np.all(np.isfinite(K))):
        raise CartPoleError("K or X0 contains NaN or inf; give finite gains and start states.")
    x_eq = np.zeros(4) if x_eq is None else np.asarray(x_eq, dtype=float)
    m, _ = make_mujoco(source)
    h = float(m.opt.timestep)
    n = int(round(duration / h))
    if n < 1:
        raise CartPoleError(f"Duration {duration} s is shorter than one physics step ({h} s); give a longer one.")
    lo, hi = m.actuator_ctrlrange[0] if m.actuator_ctrllimited[0] else (-np.inf, np.inf)
    u_lo, u_hi = (-np.inf, np.inf) if u_limits is None else (float(u_limits[0]), float(u_limits[1]))
    nthread = _nthread_default() if nthread is None else int(nthread)
    nb = X0.shape[0]
    # two state buffers used in turn: the output of one step is the input of the next, no copies
    bufs = (_initial_states(m, X0), np.empty((nb, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))))
    states = np.empty((nb, n + 1, 4))
    ctrl = np.empty((nb, n, 1))
    states[:, 0] = bufs[0][:, 1:5]
    u = np.empty((nb, 1, 1))
    models = [m] * nb
    datas = [mujoco.MjData(m) for _ in range(max(1, nthread))]
    chunk = max(1, nb // max(1, nthread))
    spec = int(mujoco.mjtState.mjSTATE_CTRL)
    every = max(1, n // 20)
    with mujoco.rollout.Rollout(nthread=nthread) as pool:
        for k in range(n):
            S, nxt = bufs[k % 2], bufs[(k + 1) % 2]
            e = S[:, 1:5] - x_eq  # full state layout: [time, qpos (2), qvel (2)]
            e[:, 1] = wrap_angle(e[:, 1])
            # same arithmetic as LinearFeedback: u* - K e clipped to its limits, then MuJoCo's clip to ctrlrange
            u[:, 0, 0] = np.clip(np.clip(u_eq - e @ K, u_lo, u_hi), lo, hi)
            pool.rollout(models, datas, S, u, nstep=1, state=nxt, skip_checks=True, chunk_size=chunk,
                         control_spec=spec)
            ctrl[:, k] = u[:, 0]
            states[:, k + 1] = nxt[:, 1:5]
            if progress is not None and ((k + 1) % every == 0 or k + 1 == n):
                progress((k + 1) / n)
    if not np.all(np.isfinite(states)):
        raise CartPoleError("MuJoCo's state became NaN/inf in the batch; the gain or the model is unstable.")
    return states, ctrl


def _lab_gain(params):
    A, B = build_model(params).linearize()
    return lqr(A, B, Q_LAB, R_LAB).K


def random_starts(rollouts: int, *, seed: int = 0) -> np.ndarray:
    """(rollouts, 4) starts uniform in +-[0.5 m, 0.15 rad, 0.3 m/s, 0.3 rad/s], reproducible from ``seed``."""
    span = np.array([0.5, 0.15, 0.3, 0.3])
    return np.random.default_rng(seed).uniform(-span, span, size=(rollouts, 4))


def replay_benchmark(source=None, *, rollouts: int = 256, seconds: float = 2.0, repeats: int = 5,
                     python_loop: bool = False) -> dict:
    """Closed-loop batch replay throughput next to MuJoCo's open-loop ``mujoco.rollout.rollout``.

    Both run the same model, the same ``rollouts`` random starts (:func:`random_starts`), ``seconds`` each, with
    the same number of threads, ``repeats`` times in this process; the medians are reported. The open loop
    replays random ctrl sequences in one ``rollout`` call (persistent pool), the closed loop runs the lab's
    LQR with :func:`simulate_batch_linear`.

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
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
    import mujoco
    import mujoco.rollout

    params = source if isinstance(source, CartPoleParams) else read_params(source)
    K = _lab_gain(params)
    X0 = random_starts(rollouts)
    m, _ = make_mujoco(params)
    n = int(round(seconds / m.opt.timestep))
    total = rollouts * n
    nthread = _nthread_default()

    S0 = _initial_states(m, X0)
    U = np.random.default_rng(1).uniform(-1, 1, size=(rollouts, n, m.nu))
    datas = [mujoco.MjData(m) for _ in range(nthread)]
    closed, opened = [], []
    try:
        # interleaved, so both see the same load on a shared machine
        for _ in range(repeats):
            t0 = time.perf_counter()
            simulate_batch_linear(params, K, X0, seconds, nthread=nthread)
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
        doc["python_loop_steps_per_s"] = _python_loop_rate(m, K, X0, n)
    return doc


def _python_loop_rate(m, K, X0, n: int) -> float:
    """Steps/s of the naive baseline: for each run, a Python loop of feedback + ``mj_step`` on one MjData."""
    import mujoco

    ctrl = LinearFeedback(K)
    d = mujoco.MjData(m)
    t0 = time.perf_counter()
    for x0 in X0:
        mujoco.mj_resetData(m, d)
        d.qpos[:] = x0[:2]
        d.qvel[:] = x0[2:]
        for _ in range(n):
            d.ctrl[0] = ctrl(0.0, np.concatenate([d.qpos, d.qvel]))
            mujoco.mj_step(m, d)
    return X0.shape[0] * n / (time.perf_counter() - t0)
