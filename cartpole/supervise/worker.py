"""Planning calls in a child process, polled without blocking and killed once one is over its wall-time budget.

The supervisor's planner is a closure over compiled CasADi functions, a model and a plan library: the child is made
by ``fork`` (nothing of it is pickled; the child has the parent's memory as it was) and then serves requests one at
a time: a request (picklable: the start state, a warm start) goes down a pipe, the child runs ``handler(request)``
and sends the result back (pickled: a :class:`~cartpole.planning.trajopt.SwingupPlan` pickles whole). The child is
kept between requests, so what it builds in memory for one plan (solvers, loaded libraries, the model's derived
functions: a cold plan's first call builds them for tens of seconds, every later one reuses them) serves the next.
The parent polls (:meth:`PlanWorker.poll`, never blocking), takes the result (:meth:`PlanWorker.result`), or kills
the child (SIGKILL: a solver deep in C code does not stop for a Python signal handler) and reaps it, so that no
process is left running and no zombie remains; the next request forks a new child, as warm as the parent: what the
parent built before the fork (the planner's solvers, the compiled C loaded, the model's functions: a plan made in
the parent first, :meth:`cartpole.supervise.Supervisor.prepare`) every child has from its start, copy-on-write.
:meth:`PlanWorker.wait` is the blocking form with a hard bound: a request over its budget raises
:class:`PlanTimeout` at the budget, not when the planner would have returned.

No child outlives its use: :meth:`PlanWorker.close` ends it (the supervisor's ``close``, or its ``with`` block); one
whose :class:`PlanWorker` is garbage-collected is ended then; at the parent's exit (a SIGTERM the command line turns
into an exception, an exception in the loop) multiprocessing ends it; and on Linux a child is killed by the kernel
as soon as its parent dies, however (``PR_SET_PDEATHSIG``), so even a parent killed by SIGKILL leaves no planner
running (strictly, when the parent's thread that forked it ends: use a supervisor from one thread).

Fork copies only the calling thread: a handler must not wait on a lock another thread of the parent holds (the
toolkit's planners take none). The child sees the parent as it was when it was forked: send what changes since (a
warm start from a library that has grown) in the request.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
import weakref
from typing import Callable

from cartpole.errors import CartPoleError

#: s between two polls of :meth:`PlanWorker.wait` while it waits for the child.
POLL_INTERVAL = 0.005
#: s the parent waits for a child to exit after it closed its pipe, before it kills it.
REAP_TIMEOUT = 5.0
#: Linux's ``prctl`` option that sends the child a signal when its parent dies.
PR_SET_PDEATHSIG = 1


class PlanTimeout(CartPoleError):
    """A planning call that ran over its wall-time budget and was stopped."""


class PlanWorkerError(CartPoleError):
    """The planning child died without an answer (killed from outside, out of memory), or was asked out of turn."""


def _serve(handler: Callable, conn, parent_end, parent: int) -> None:
    """In the child: for each request from ``conn``, ``handler(request)``'s outcome back through it:
    ``("ok", value)``, ``("fail", sentence)`` for a :class:`CartPoleError` (a plan not found) or ``("crash",
    traceback text)`` for any other exception; ends when the parent closes its end (``parent_end``, whose copy the
    fork gave the child is closed first, else the child would never see the pipe close); ``parent`` is the parent's pid
    taken before the fork: read in the child, a parent already killed would give the pid of its new parent."""
    parent_end.close()
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the parent, which kills the child
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    while True:
        try:
            request = conn.recv()
        except (EOFError, OSError):
            break
        try:
            outcome = ("ok", handler(request))
        except CartPoleError as exc:
            outcome = ("fail", str(exc))
        except Exception:  # noqa: BLE001  sent to the parent, which raises it there
            outcome = ("crash", traceback.format_exc())
        try:
            conn.send(outcome)
        except (EOFError, OSError):
            break
        except Exception as exc:  # noqa: BLE001  the answer does not pickle
            conn.send(("fail", f"the planning worker's answer could not be sent back ({type(exc).__name__}: "
                               f"{exc})."))
    conn.close()


def _die_with_parent(parent: int) -> None:
    """In the child, on Linux: ask the kernel for SIGKILL when the parent dies (``PR_SET_PDEATHSIG``), and end now
    if the parent ``parent`` died before the request was in place (the child was then re-parented). Elsewhere
    nothing: the pipe's end (EOF) and the parent's exit end the child."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # no libc to ask: the pipe's EOF still ends an idle child
        return
    if os.getppid() != parent:
        os._exit(0)


def _end_child(process, conn) -> None:
    """End ``process`` (a child of a :class:`PlanWorker` that was garbage-collected without ``close``): its pipe
    closed, killed if it does not exit at once, reaped."""
    try:
        conn.close()
        if process.is_alive():
            process.kill()
        process.join(REAP_TIMEOUT)
    except (OSError, ValueError, AssertionError):  # already closed or reaped, or this is not its parent (a fork)
        pass


class PlanWorker:
    """A forked child process that runs ``handler(request)`` for one request at a time, kept between requests.

    Parameters
    ----------
    handler : callable
        ``handler(request) -> result``, run in the child (as the parent was when the child was forked, at the first
        request or the first after a kill); ``request`` and ``result`` must pickle. A :class:`CartPoleError` it
        raises is raised again by :meth:`result` (same sentence).

    Attributes
    ----------
    started : float
        ``time.perf_counter()`` when the request being answered was sent, s.
    forks : int
        Children forked so far (one, plus one after each kill).
    """

    def __init__(self, handler: Callable):
        self._handler = handler
        self._process = None
        self._conn = None
        self._outcome = None
        self._busy = False
        self.started = time.perf_counter()
        self.forks = 0
        self._pid = None
        self._exitcode = None
        self._finalizer = None

    def _fork(self) -> None:
        ctx = multiprocessing.get_context("fork")
        self._conn, child_end = ctx.Pipe()
        self._process = ctx.Process(target=_serve, args=(self._handler, child_end, self._conn, os.getpid()),
                                    daemon=True, name="cartpole-plan")
        self._process.start()
        child_end.close()  # the child holds its end: its exit reads as EOF here
        self._pid = self._process.pid
        self.forks += 1
        self._finalizer = weakref.finalize(self, _end_child, self._process, self._conn)

    @property
    def elapsed(self) -> float:
        """s of wall time since the request being answered was sent."""
        return time.perf_counter() - self.started

    @property
    def pid(self) -> int | None:
        """The child's process id (the last one's, once it has ended), None before the first request."""
        return self._pid

    @property
    def busy(self) -> bool:
        """Whether a request is out and not yet answered."""
        return self._busy

    def submit(self, request) -> None:
        """Send ``request`` to the child (forked now if none is running); returns at once."""
        if self._busy:
            raise PlanWorkerError("The planning worker is still answering a request; wait for it or kill it first.")
        if self._process is None:
            self._fork()
        self._outcome, self._busy, self.started = None, True, time.perf_counter()
        try:
            self._conn.send(request)
        except (EOFError, OSError):  # the child is gone: poll() says so
            pass

    def poll(self) -> bool:
        """Whether the answer to the request is in (or the child has died without one), without blocking."""
        if not self._busy:
            return self._outcome is not None
        if self._conn.poll():
            try:
                self._outcome = self._conn.recv()
            except (EOFError, OSError):
                self._outcome = ("died", None)
                self.kill()
            self._busy = False
            return True
        return False

    def result(self):
        """The request's result once :meth:`poll` is True; raises :class:`CartPoleError` with the handler's
        sentence when it raised one, :class:`PlanWorkerError` when the child died (or was killed) without answering,
        ``RuntimeError`` (the child's traceback) for any other exception in the handler."""
        if not self.poll():
            raise PlanWorkerError("The planning worker has not answered yet; call result() once poll() is True.")
        kind, value = self._outcome
        if kind == "ok":
            return value
        if kind == "fail":
            raise CartPoleError(value)
        if kind == "crash":
            raise RuntimeError(f"The planner raised in its worker process:\n{value}")
        raise PlanWorkerError(f"The planning worker (pid {self.pid}) died without an answer (exit code "
                              f"{self._exitcode}).")

    def kill(self) -> None:
        """Stop the child now (SIGKILL) and reap it; nothing is left running, a request out counts as unanswered.
        Harmless when no child runs."""
        if self._process is not None and self._process.is_alive():
            self._process.kill()
        self._reap()

    def close(self) -> None:
        """End the child: let an idle one exit (its pipe closed), kill a busy one; reaped either way."""
        if self._busy:
            self.kill()
        self._reap()

    def _reap(self) -> None:
        if self._busy:
            self._outcome, self._busy = ("died", None), False
        if self._finalizer is not None:
            self._finalizer.detach()
            self._finalizer = None
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        if self._process is None:
            return
        self._process.join(REAP_TIMEOUT)
        if self._process.exitcode is None:  # did not end when its pipe closed
            self._process.kill()
            self._process.join()
        self._exitcode = self._process.exitcode
        self._process.close()
        self._process = None

    def wait(self, request, budget: float, *, on_timeout: Callable | None = None):
        """Submit ``request`` and wait for its result at most ``budget`` s of wall time.

        Parameters
        ----------
        request : object
            What the handler is called with (pickled).
        budget : float
            s of wall time; the child is killed once the request has run longer.
        on_timeout : callable, optional
            ``on_timeout(wall_s)``, called when the budget stopped the request (e.g. to log the decision).

        Returns
        -------
        object
            What the handler returned.

        Raises
        ------
        PlanTimeout
            The request ran over ``budget`` and the child was killed.
        CartPoleError
            The handler raised one (its sentence), or the child died without an answer.
        """
        self.submit(request)
        try:
            while not self.poll():
                if self.elapsed > budget:
                    self.kill()
                    wall = self.elapsed
                    if on_timeout is not None:
                        on_timeout(wall)
                    raise PlanTimeout(timeout_sentence(wall, budget))
                time.sleep(POLL_INTERVAL)
        except BaseException:
            self.kill()  # Ctrl-C or a timeout: nothing left running
            raise
        return self.result()


def run_planner(call: Callable, budget: float, *, on_timeout: Callable | None = None):
    """``call()`` once in a child process of its own (:class:`PlanWorker`), waited for at most ``budget`` s of wall
    time, the child ended after.

    Parameters
    ----------
    call : callable
        ``call() -> result`` (a plan); its result must pickle.
    budget : float
        s of wall time; the child is killed once it has run longer.
    on_timeout : callable, optional
        ``on_timeout(wall_s)``, called when the budget stopped the call.

    Returns
    -------
    object
        What ``call()`` returned.

    Raises
    ------
    PlanTimeout
        The call ran over ``budget`` and was killed.
    CartPoleError
        The call raised one (its sentence), or the child died without an answer.
    """
    worker = PlanWorker(lambda _: call())
    try:
        return worker.wait(None, budget, on_timeout=on_timeout)
    finally:
        worker.close()


class _OverBudget(BaseException):
    """Raised by :func:`run_within`'s alarm into the call it bounds (a BaseException: a planner's ``except
    Exception`` does not swallow it)."""


def run_within(call: Callable, budget: float) -> bool:
    """``call()`` in this process (what it builds stays here, unlike :func:`run_planner`), stopped once it has run
    ``budget`` s of wall time: a SIGALRM timer raises into it at its first Python step after the budget (a solver deep
    in C code returns first). Only the main thread of a POSIX process can take the alarm, and only when no other
    ``ITIMER_REAL`` is running (pytest-timeout's, say: it is left untouched); elsewhere ``call()`` runs to its end
    and the budget is checked after it.

    Parameters
    ----------
    call : callable
        ``call()``; its result is dropped, its exceptions are raised.
    budget : float
        s of wall time, > 0.

    Returns
    -------
    bool
        True when ``call()`` ended within ``budget``; False when it was stopped there (or, without the alarm, ran over).
    """
    start = time.perf_counter()
    armed = threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")
    if armed and signal.getitimer(signal.ITIMER_REAL)[0] > 0:
        armed = False  # someone else's timer: leave it be
    done = [False]

    def _stop(signum, frame):
        if not done[0]:
            raise _OverBudget

    previous = signal.signal(signal.SIGALRM, _stop) if armed else None
    try:
        if armed:
            signal.setitimer(signal.ITIMER_REAL, float(budget))
        call()
        done[0] = True
    except _OverBudget:
        return False
    finally:
        done[0] = True
        if armed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
    return time.perf_counter() - start <= budget


def timeout_sentence(wall: float, budget: float) -> str:
    """The sentence of a plan stopped after ``wall`` s of wall time, over its ``budget`` s."""
    return f"The plan was stopped after {wall:.1f} s of wall time, over the budget of {budget:g} s (plan_budget)."


def fork_available() -> bool:
    """Whether this platform can fork (POSIX), which :class:`PlanWorker` needs."""
    return hasattr(os, "fork") and "fork" in multiprocessing.get_all_start_methods()
