"""Where a sweep's runs run: this process (:func:`run_here`), this process beside worker processes
(:func:`run_pool`), or the workers of a Dask distributed scheduler (:func:`run_dask`). Every run is
:meth:`Runner.run` on the same inputs, so the rows are the same, bit for bit, wherever they ran.

The local pool (``workers = W > 1``): this process runs its share in one thread with the model it has already
built, beside ``W - 1`` worker processes of a :class:`concurrent.futures.ProcessPoolExecutor`; each run goes to
whichever is free, and the rows come back in the order they finish. The worker processes are forked from
multiprocessing's fork server (:mod:`cartpole.apps.forkserver`), which the sweep starts at its beginning (the parent
meanwhile plans the runs and reads the basin), with the toolkit already imported
(:data:`~cartpole.apps.forkserver.PRELOAD`), so a worker starts in milliseconds instead of importing NumPy, SciPy, CasADi, MuJoCo and the toolkit anew; each builds the model once
(:func:`_init_worker`) and keeps it for all its runs. Where the platform has no fork server, the workers are spawned
(the same rows, a slower start). No worker is forked from this process itself: measured, a worker forked from the
parent with its runner built was slower a run than one from the fork server, and slowed the parent as well (the
two processes then share every page of a large heap copy-on-write), besides the threads and library state a fork
copies.

BLAS: a run's linear algebra is small, and OpenBLAS's threads cost more than they save (they spin after each call,
and beside a pool worker they take the core it needs), so the runs here use one OpenBLAS thread
(:func:`one_blas_thread_here`) and the workers start with :data:`WORKER_ENV`, unless the user set those variables.

Interrupts: workers ignore Ctrl-C (SIGINT), which a terminal sends to the whole process group; the parent handles
it, keeps the rows that finished and shuts the pool down (a run under way finishes first). During a pool sweep
SIGTERM is handled the same way. A worker whose parent is gone (killed with SIGKILL, say) exits at once
(:func:`_exit_with_parent`), so no worker outlives its sweep.
"""
from __future__ import annotations

import ctypes
import gc
import math
import multiprocessing
import os
import signal
import socket
import threading
import uuid
from collections import deque
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures import wait as wait_futures
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from multiprocessing.connection import wait as wait_objects

import mujoco
import numpy as np

from cartpole.errors import CartPoleError, first_line
from cartpole.models import CartPoleModel, CartPoleParams, build_model, steps_per_period
from cartpole.sim import replays_exactly
from cartpole.apps.swingup import SwingupOptions, planning_model, run_swingup
from cartpole.control.linear import LinearFeedback
from cartpole.control.switching import SWINGUP_CATCH_R
from cartpole.mpc.options import MPCOptions
from cartpole.ocp.dmc import is_task
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import handover_catch
from cartpole.validation.basin import BasinCache
from cartpole.apps.forkserver import WORKER_ENV, main_thread, sigint_ignored, start_server, worker_env
from cartpole.apps.sweep.plan import LOOP_SETTINGS, SweepError

#: Seconds to wait for a Dask scheduler given by ``address`` before giving up.
CONNECT_TIMEOUT = 10.0
class Runner:
    """One process's share of a sweep: the model (built once), each planning model (built once, on first use), the
    basin cache, and the settings every run shares.

    The same object serves this process (``workers = 1``, and its share of a pool) and each worker process
    (through :func:`_init_worker`), so a run computes the same thing wherever it runs.

    Parameters
    ----------
    params : CartPoleParams
        The cart-pole MuJoCo runs on.
    method : {"energy", "trajopt", "mpc", "supervisor"}
    options : SwingupOptions
        The settings every run starts from (:func:`~cartpole.apps.swingup.run_swingup`'s): a run's swept loop
        settings (:data:`~cartpole.apps.sweep.plan.LOOP_SETTINGS`) replace fields of its ``loop`` (the period and
        delay rounded to whole physics steps), its push and model error the loop's, its other swept settings
        fields of the method's stage options (``energy``, ``plan``, ``mpc``) by name. A dm_control task as the
        objective adds each run's ``return`` and ``return_steps``.
    cache : BasinCache
        The basins the runs use (shipped to the workers with what it holds).
    model : CartPoleModel, optional
        The model of ``params`` when already built.
    """

    def __init__(self, params: CartPoleParams, method: str, options: SwingupOptions, cache: BasinCache,
                 model: CartPoleModel | None = None):
        self.params = params
        self.model = build_model(params) if model is None else model
        self.method = method
        self.options = options
        self.cache = cache
        self.plans = {1.0: self.model}
        self.loop = options.loop
        stage = {"trajopt": options.plan, "mpc": options.mpc}.get(method)
        self.objective = None if stage is None else stage.objective

    def settings(self) -> tuple:
        """``(params, method, options, cache, None)``: what a worker needs to build the same runner (the model,
        None, it builds itself)."""
        return (self.params, self.method, self.options, self.cache, None)

    def plan_model(self, model_error: float) -> CartPoleModel:
        """The planning model of scale ``model_error`` (:func:`~cartpole.apps.swingup.planning_model`), built once."""
        S = float(model_error)
        if S not in self.plans:
            self.plans[S] = planning_model(self.model, S)
        return self.plans[S]

    def basin(self, model_error: float = 1.0):
        """The catch basin the runs of this planning model use (estimated once, then found in the cache): the
        energy method's LQR catch, or for trajopt the hand-over LQR that takes over when the plan ends; None for
        mpc (no catch)."""
        pm = self.plan_model(model_error)
        if self.method == "mpc":
            return None
        if self.method == "trajopt":
            steps = steps_per_period(self.loop.period, self.params.timestep)
            return self.cache.get(self.params, handover_catch(self.params, pm, steps=steps))
        weights = self.options.catch_weights or (None, SWINGUP_CATCH_R)
        catch = LinearFeedback.for_model(pm, *weights, period=self.loop.period)
        return self.cache.get(self.params, catch)

    def run(self, x0, options: dict, push=(), model_error: float = 1.0, settings: dict | None = None) -> dict:
        """One swing-up from ``x0`` ((2 nq,) [m, rad, m/s, rad/s]) with its push (``((T s, F N),)``), model error
        and settings: its row's numbers, ``success``, ``replays``, ``diverged`` (MuJoCo reset the run as blown up:
        never a success), ``diverged_at`` (s or NaN), ``time_to_upright`` (s, NaN unless a success),
        ``caught_at`` (s or NaN), ``cart_clearance`` (m), ``peak_ctrl``, ``rho`` and ``error`` (the sentence of a
        :class:`CartPoleError` the run raised, else None); with a dm_control task's objective also ``return`` and
        ``return_steps`` (NaN when the run raised)."""
        settings = dict(settings or {})
        looped = {k: settings.pop(k) for k in list(settings) if k in LOOP_SETTINGS}
        h = float(self.params.timestep)
        for k, least in (("period", 1), ("delay", 0)):  # a sampled period or delay: the nearest whole steps
            if k in looped:
                looped[k] = max(least, round(float(looped[k]) / h)) * h
        if "encoder_cpr" in looped:
            looped["encoder_cpr"] = max(1, round(float(looped["encoder_cpr"])))
        try:
            res = run_swingup(self.model, self.method, self.run_options(options, push, model_error, settings, looped),
                              x0=x0, basin_cache=self.cache, plan_model=self.plan_model(model_error))
        except CartPoleError as exc:
            return {"success": False, "replays": False, "diverged": False, "diverged_at": math.nan,
                    "time_to_upright": math.nan, "caught_at": math.nan,
                    "cart_clearance": math.nan, "peak_ctrl": math.nan, "rho": math.nan,
                    "error": first_line(exc) + ".", **self._no_return(), **self._knocked()}
        m = res.metrics
        replays = bool(replays_exactly(res.rollout, self.params))
        ok = bool(res.success and replays and not m["diverged"])
        tu = m["time_to_upright"]
        return {"success": ok, "replays": replays, "diverged": bool(m["diverged"]),
                "diverged_at": math.nan if m["diverged_at"] is None else float(m["diverged_at"]),
                "time_to_upright": float(tu) if (ok and tu is not None) else math.nan,
                "caught_at": math.nan if res.caught_at is None else float(res.caught_at),
                "cart_clearance": float(m["cart_clearance"]), "peak_ctrl": float(m["peak_ctrl"]),
                "rho": float(res.basin.rho) if res.basin is not None else math.nan, "error": None,
                **({"return": float(m["return"]), "return_steps": int(m["return_steps"])} if "return" in m
                   else self._no_return()),
                **self._knocked(m)}

    def run_options(self, energy: dict, push, model_error: float, settings: dict, looped: dict) -> SwingupOptions:
        """One run's :class:`~cartpole.apps.swingup.SwingupOptions`: the sweep's, with the run's energy settings
        ``energy`` (energy), push, model error, swept loop fields ``looped`` and the method's swept ``settings``
        (fields of its stage's options, by name)."""
        o = self.options
        loop = o.loop.replace(push=tuple(push or ()), model_error=model_error, **looped)
        if self.method == "energy":
            return o.replace(loop=loop, energy={**energy, **settings})
        if self.method == "trajopt":
            return o.replace(loop=loop, plan=(o.plan or PlanOptions()).replace(**settings))
        if self.method == "mpc":
            return o.replace(loop=loop, mpc=(o.mpc or MPCOptions()).replace(**settings))
        return o.replace(loop=loop)

    def _knocked(self, metrics: dict | None = None) -> dict:
        """A knocked or thrown sweep's row keys (:func:`~cartpole.validation.metrics.uptime_metrics`): ``uptime``
        (the fraction of the run upright; 0 for a run that raised: never counted upright), ``knockdowns`` and
        ``swingups`` (NaN for a run that raised); none without a disturbance."""
        if not self.loop.disturbed:
            return {}
        if metrics is None or "uptime" not in metrics:
            return {"uptime": 0.0, "knockdowns": math.nan, "swingups": math.nan}
        return {"uptime": float(metrics["uptime"]), "knockdowns": int(metrics["knockdowns"]),
                "swingups": int(metrics["swingups"])}

    def _no_return(self) -> dict:
        """A dm_control task's row keys for a run without an episode (NaN), else none."""
        return {"return": math.nan, "return_steps": math.nan} if is_task(self.objective) else {}


# ---- this process ------------------------------------------------------------------------------------------------

def run_here(runner: Runner, jobs, todo, finished) -> None:
    """The runs ``todo`` (indices into ``jobs``, each ``(x0, options, push, model_error, settings)``) one after
    the other in this process; ``finished(i, row)`` after each."""
    with one_blas_thread_here():
        for i in todo:
            finished(i, runner.run(*jobs[i]))


# ---- the local pool ----------------------------------------------------------------------------------------------

def run_pool(runner: Runner, jobs, workers: int, todo, finished, *, context=None) -> None:
    """The runs ``todo`` spread over this process (one thread, ``runner``) and ``workers - 1`` worker processes
    (one :class:`Runner` each, built once); each run goes to whichever is free. ``finished(i, row)`` is called in
    this thread as each run comes back; an exception it raises (KeyboardInterrupt, say) stops the sweep, and the
    workers are shut down before this returns or raises.

    Parameters
    ----------
    context : multiprocessing context, optional
        Where the workers start from (default :func:`~cartpole.apps.forkserver.start_server` of the runner's
        method).

    Raises
    ------
    SweepError
        A worker process died (out of memory, or killed).
    """
    ctx = start_server(runner.method) if context is None else context
    env = dict(os.environ)
    for k, v in WORKER_ENV.items():
        env.setdefault(k, v)
    pool = ProcessPoolExecutor(max_workers=workers - 1, mp_context=ctx, initializer=_init_worker,
                               initargs=(runner.settings(), env))
    here = ThreadPoolExecutor(max_workers=1, thread_name_prefix="cartpole-sweep")
    pending = deque(todo)
    running: dict = {}  # future -> (executor, run index)
    room = {pool: workers - 1, here: 1}
    def feed():  # this process first: a pool's first submit waits until the fork server has imported the toolkit
        for ex in (here, pool):
            while pending and room[ex] > 0:
                i = pending.popleft()
                running[ex.submit(_run_in_worker if ex is pool else runner.run, *jobs[i])] = (ex, i)
                room[ex] -= 1

    try:
        with sigint_ignored(), worker_env():  # the workers start here; spawned ones inherit both from birth
            feed()
        with _sigterm_as_interrupt(), one_blas_thread_here():
            while running:
                done, _ = wait_futures(running, return_when=FIRST_COMPLETED)
                for fut in done:
                    ex, i = running.pop(fut)
                    room[ex] += 1
                    finished(i, fut.result())
                feed()
    except BrokenProcessPool:
        raise SweepError(f"A sweep worker process died (out of memory, or killed); try fewer `workers` than "
                         f"{workers}.") from None
    except BaseException:  # interrupted (Ctrl-C, SIGTERM) or failed: a run under way in a worker is not waited for
        _terminate_workers(pool)
        raise
    finally:
        here.shutdown(wait=True, cancel_futures=True)
        pool.shutdown(wait=True, cancel_futures=True)


def _terminate_workers(pool) -> None:
    """SIGTERM to every worker process of ``pool`` (a :class:`concurrent.futures.ProcessPoolExecutor`), so that an
    interrupted sweep does not wait for the runs under way there (their rows would not be kept anyway)."""
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            proc.terminate()
        except (OSError, ValueError, AttributeError):  # already gone, or closed
            pass


_WORKER: Runner | None = None  # set in each worker process by _init_worker


def _init_worker(settings: tuple, env: dict) -> None:
    """ProcessPoolExecutor initializer: this worker's runner (its model built once) from
    :meth:`Runner.settings`, and the parent's environment ``env`` (a forked worker has the fork server's, from
    when it started).

    MuJoCo's warnings are dropped here (the parent loaded the same MJCF first and reported them), so a worker
    neither prints them nor writes MUJOCO_LOG.TXT into the current directory. Ctrl-C is left to the parent (which
    keeps the finished rows and stops the pool), so a worker does not die of it mid-run."""
    global _WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _exit_with_parent()
    os.environ.clear()
    os.environ.update(env)
    mujoco.set_mju_user_warning(lambda msg: None)
    if not _user_set_blas_threads():  # a fork server another part of the program started lacks WORKER_ENV
        for get, set_threads in _loaded_openblas():
            set_threads(1)
    _WORKER = Runner(*settings)


def _run_in_worker(x0, options, push=(), model_error=1.0, settings=None) -> dict:
    return _WORKER.run(x0, options, push, model_error, settings)


def _exit_with_parent() -> None:
    """In a worker process: a daemon thread that ends the process as soon as its parent is gone. A pool worker
    waits for work on a pipe the parent's death does not close, so without this a killed sweep would leave it
    running."""
    parent = multiprocessing.parent_process()
    if parent is None or parent.sentinel is None:
        return

    def watch():
        wait_objects([parent.sentinel])
        os._exit(1)

    threading.Thread(target=watch, name="cartpole-sweep-parent", daemon=True).start()


#: OpenBLAS's (get, set) thread-count functions, per build: the plain library and the builds that NumPy's and SciPy's
#: wheels bundle (each its own copy, each with its own threads).
OPENBLAS_THREAD_FUNCTIONS = (("openblas_get_num_threads", "openblas_set_num_threads"),
                             ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
                             ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"))


def _loaded_openblas() -> list:
    """``(get, set)`` thread-count functions of every OpenBLAS this process has loaded (found in
    ``/proc/self/maps``; none where there is no such file)."""
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({f[5].strip() for f in (line.split(maxsplit=5) for line in fh)
                            if len(f) == 6 and "openblas" in f[5].lower()})
    except OSError:
        return []
    found = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for get, set_threads in OPENBLAS_THREAD_FUNCTIONS:
            if hasattr(lib, get) and hasattr(lib, set_threads):
                found.append((getattr(lib, get), getattr(lib, set_threads)))
                break
    return found


def _user_set_blas_threads() -> bool:
    return any(k in os.environ for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"))


@contextmanager
def one_blas_thread_here():
    """Inside the block this process's OpenBLAS libraries use one thread each (their counts restored after), unless
    the user set ``OPENBLAS_NUM_THREADS`` or ``OMP_NUM_THREADS``. A run's linear algebra is small (matrices of
    the state's size): OpenBLAS's threads cost more CPU than they save, spinning after each call, and beside a pool
    worker they take the core it needs. The rows do not depend on it."""
    libs = [] if _user_set_blas_threads() else _loaded_openblas()
    before = [get() for get, _ in libs]
    for _, set_threads in libs:
        set_threads(1)
    try:
        yield
    finally:
        for (_, set_threads), count in zip(libs, before):
            set_threads(count)


@contextmanager
def _sigterm_as_interrupt():
    """Inside the block (main thread, SIGTERM at its default): SIGTERM raises KeyboardInterrupt, as Ctrl-C does, so
    the pool is shut down and the finished rows kept instead of the process dying with its workers orphaned."""
    if not main_thread() or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


# ---- a Dask cluster ----------------------------------------------------------------------------------------------

#: Per-process cache of runners on Dask workers, keyed by the sweep's token (models built once per worker).
_RUNNERS: dict = {}
#: How many runners this process has built for Dask tasks (:func:`runners_built`).
_BUILT = [0]


def runners_built() -> int:
    """How many runners this process has built for Dask tasks: one per sweep a Dask worker took part in, not one
    per run (run it on the workers with ``client.run``)."""
    return _BUILT[0]


def _run_on_dask(token: str, settings: tuple, x0, options, push=(), model_error=1.0, run_settings=None) -> dict:
    """One run on a Dask worker: the runner for ``token`` is built on this worker process's first run of the
    sweep (MuJoCo's warnings dropped, as in a pool worker) and reused by every later one."""
    runner = _RUNNERS.get(token)
    if runner is None:
        mujoco.set_mju_user_warning(lambda msg: None)
        _RUNNERS.clear()  # one sweep's model per worker at a time
        runner = _RUNNERS[token] = Runner(*settings)
        _BUILT[0] += 1
    return runner.run(x0, options, push, model_error, run_settings)


#: Dask address schemes a sweep connects to (``host:port`` alone means ``tcp://``).
ADDRESS_SCHEMES = ("tcp", "tls")


def check_address(address: str) -> tuple[str, int]:
    """``(host, port)`` of a Dask scheduler address ``tcp://host:port`` (or ``tls://``, or ``host:port``).

    Raises
    ------
    SweepError
        Not of that form (another scheme such as ``http://``, no port, a port outside 1..65535).
    """
    text = str(address).strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    host, colon, port = rest.rstrip("/").rpartition(":")
    host = host.strip("[]")
    ok = scheme in ADDRESS_SCHEMES and colon and host and port.isdigit() and 1 <= int(port) <= 65535
    if not ok:
        raise SweepError(f"The `address` {text!r} is not a Dask scheduler address; give tcp://HOST:PORT (e.g. "
                         "tcp://127.0.0.1:8786, what `dask scheduler` prints).")
    return host, int(port)


def _connect(Client, address: str):
    """``(client, None)`` connected to the scheduler at ``address``, or ``(None, why)`` when that fails in any way
    (refused, timed out, something that is not a Dask scheduler answering). A Client that failed inside its
    constructor is marked closed and its event loop stopped here, so its ``__del__`` neither waits 20 s to close it
    nor prints "Exception ignored in Client.__del__" after the sweep's sentence."""
    try:
        return Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False), None
    except Exception as exc:  # noqa: BLE001 - anything the connection attempt raises is "cannot reach"
        why = "something there is not a Dask scheduler" if isinstance(exc, MemoryError) else type(exc).__name__
        tb = exc.__traceback__
        while tb is not None:  # the half-built Client is `self` in its constructor's frame
            half = tb.tb_frame.f_locals.get("self")
            if isinstance(half, Client):
                half.status = "closed"
                try:
                    half._loop_runner.stop()
                except Exception:  # noqa: BLE001 - best effort: the loop may never have started
                    pass
            tb = tb.tb_next
        del exc, tb
    gc.collect()
    return None, why


def run_dask(address: str, runner: Runner, jobs, todo, finished) -> None:
    """The runs ``todo`` on the Dask scheduler at ``address`` (``tcp://host:port``); ``finished(i, row)`` as each
    one comes back.

    Raises
    ------
    SweepError
        Dask distributed is not installed, the address is malformed (:func:`check_address`), the scheduler cannot
        be reached within :data:`CONNECT_TIMEOUT` s, or a run failed on the cluster outside :class:`CartPoleError`
        (a worker died, say).
    """
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise SweepError("A Dask `address` needs Dask distributed; install it with `pip install 'dask[distributed]'`.") \
            from None
    host, port = check_address(address)
    advice = "start one (`dask scheduler`, then `dask worker ADDRESS`) or give its tcp://host:port"
    try:  # a plain TCP connection first: a closed port is one sentence at once, with no Client half-built
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT).close()
    except OSError as exc:
        raise SweepError(f"Cannot reach a Dask scheduler at {address} ({exc.strerror or type(exc).__name__}); "
                         f"{advice}.") from None
    client, why = _connect(Client, address)
    if client is None:
        raise SweepError(f"Cannot reach a Dask scheduler at {address} ({why}); {advice}.")
    futures = []
    try:
        [init_f] = client.scatter([runner.settings()], broadcast=True)
        token = uuid.uuid4().hex
        index = {}
        for i in todo:
            x0, options, push, model_error, settings = jobs[i]
            f = client.submit(_run_on_dask, token, init_f, np.asarray(x0), options, push, model_error, settings,
                              pure=False)
            index[f.key] = i
            futures.append(f)
        for fut in as_completed(futures, loop=client.loop):
            try:
                row = fut.result()
            except CartPoleError:
                raise
            except Exception as exc:  # a worker died (KilledWorker), or a run failed outside CartPoleError
                raise SweepError(f"A run failed on the Dask cluster at {address}: {type(exc).__name__}: "
                                 f"{first_line(exc)}.") from None
            finished(index[fut.key], row)
    finally:
        pending = [f for f in futures if not f.done()]
        if pending:
            client.cancel(pending)
        client.close()
