"""The fork server a sweep's pool workers start from (multiprocessing's own, with the toolkit imported before it
forks any worker), and the environment and signals they start with."""
from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
from contextlib import contextmanager
from multiprocessing import forkserver

#: Modules the pool's fork server imports before it forks any worker, per method: what a worker and its runs
#: import (the executors module brings the swing-up, the model and CasADi; MuJoCo and the method's own modules are imported
#: lazily, on first use, so they are named here).
PRELOAD = {
    "energy": ("cartpole.apps.sweep.executors", "mujoco", "cartpole.control.switching", "cartpole.control.energy",
               "cartpole.validation.metrics"),
    "trajopt": ("cartpole.apps.sweep.executors", "mujoco", "cartpole.planning.trajopt",
                "cartpole.validation.metrics"),
    "mpc": ("cartpole.apps.sweep.executors", "mujoco", "cartpole.mpc.nmpc", "cartpole.planning.trajopt",
            "cartpole.validation.metrics"),
}
#: Environment of a pool worker: one BLAS / OpenMP thread (what Dask's nanny gives its workers too). OpenBLAS's
#: threads spin after each call; two workers with two each on two cores take turns instead of running.
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def start_server(method: str):
    """The multiprocessing context the pool's workers start from, its fork server started now if it is not running
    yet: with :data:`PRELOAD` of ``method`` imported, :data:`WORKER_ENV` in its environment (unless the user set
    those variables) and Ctrl-C ignored, all of which the workers it forks inherit. Returns at once: the server
    imports in the background while the caller goes on; the first worker waits for it. Without a fork server on
    this platform: the ``spawn`` context (each worker then imports the toolkit itself).

    The fork server is multiprocessing's own, one per process, and it stays up for later sweeps; where another
    part of the program started it first, its workers import what it lacks on their first run. It (and so every
    worker) starts with its stderr on ``/dev/null``: a worker reports through its results (a run that raises is a row
    with its sentence, a worker that dies is the parent's one sentence), and a worker still starting when the sweep
    is interrupted must not print multiprocessing's traceback after the sweep's sentence."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")

    ctx = multiprocessing.get_context("forkserver")
    with sigint_ignored(), worker_env(), _quiet_stderr():
        ctx.set_forkserver_preload(list(PRELOAD.get(method, PRELOAD["energy"])))  # read only by a server not yet up
        forkserver.ensure_running()
    return ctx


@contextmanager
def _quiet_stderr():
    """File descriptor 2 on ``/dev/null`` inside the block (processes started there inherit it); restored after."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:  # no stderr to protect
        yield
        return
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


@contextmanager
def worker_env():
    """Processes started inside get :data:`WORKER_ENV` (unless the user set those variables); this process's own
    environment is restored after the block."""
    added = {k: v for k, v in WORKER_ENV.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for k in added:
            os.environ.pop(k, None)


def main_thread() -> bool:
    """Whether the caller runs in the main thread (signal handlers can be set only there)."""
    return threading.current_thread() is threading.main_thread()


@contextmanager
def sigint_ignored():
    """Ignore Ctrl-C (SIGINT) inside the block, in the main thread (elsewhere: no change). Processes started inside
    inherit the ignored signal, so a Ctrl-C that reaches the whole process group cannot kill a worker while it is
    still importing (a traceback on stderr); the parent alone handles it and keeps the finished rows."""
    if not main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
