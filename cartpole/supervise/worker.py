"""One planning call in a child process, polled without blocking and killed once it is over its wall-time budget.

The supervisor's planner is a closure over compiled CasADi functions, a model and a plan library: the child is made
by ``fork`` (the closure is not pickled; the child has the parent's memory as it was), runs the call once, sends its
result back through a pipe (pickled: a :class:`~cartpole.planning.trajopt.SwingupPlan` pickles whole) and exits. The
parent polls (:meth:`PlanWorker.poll`, never blocking), takes the result (:meth:`PlanWorker.result`), or kills the
child (SIGKILL: a solver deep in C code does not stop for SIGTERM's Python handler) and reaps it, so that no process
is left running and no zombie remains. :func:`run_planner` is the blocking form with a hard bound: a call over its
budget raises :class:`PlanTimeout` at the budget, not when the planner would have returned.

What the child computes is lost with it except the result: a solver the child built (an in-memory cache) is built
again by the next child. Fork copies only the calling thread; a planner must not wait on a lock another thread of the
parent holds (the toolkit's planners take none).
"""
from __future__ import annotations

import multiprocessing
import os
import signal
import time
import traceback
from typing import Callable

from cartpole.errors import CartPoleError

#: s between two polls of :func:`run_planner` while it waits for the child.
POLL_INTERVAL = 0.005
#: s the parent waits for a killed child to be reaped before it says so.
REAP_TIMEOUT = 5.0


class PlanTimeout(CartPoleError):
    """A planning call that ran over its wall-time budget and was stopped."""


class PlanWorkerError(CartPoleError):
    """The planning child died without an answer (killed from outside, out of memory) or its answer could not be
    sent back."""


def _child(call: Callable, conn) -> None:
    """In the child: ``call()`` once and its outcome through ``conn``: ``("ok", value)``, ``("fail", sentence)`` for
    a :class:`CartPoleError` (a plan not found) or ``("crash", traceback text)`` for any other exception."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the parent, which kills the child
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        outcome = ("ok", call())
    except CartPoleError as exc:
        outcome = ("fail", str(exc))
    except BaseException:  # noqa: BLE001  sent to the parent, which raises it there
        outcome = ("crash", traceback.format_exc())
    try:
        conn.send(outcome)
    except Exception as exc:  # noqa: BLE001  the answer does not pickle
        conn.send(("fail", f"the planning worker's answer could not be sent back ({type(exc).__name__}: {exc})."))
    conn.close()


class PlanWorker:
    """One call of ``call()`` in a forked child process.

    Parameters
    ----------
    call : callable
        ``call() -> result``, run once in the child; ``result`` must pickle. A :class:`CartPoleError` it raises is
        raised again by :meth:`result` (same sentence).

    Attributes
    ----------
    started : float
        ``time.perf_counter()`` at the start, s.
    """

    def __init__(self, call: Callable):
        ctx = multiprocessing.get_context("fork")
        self._recv, send = ctx.Pipe(duplex=False)
        self._process = ctx.Process(target=_child, args=(call, send), daemon=True, name="cartpole-plan")
        self.started = time.perf_counter()
        self._process.start()
        self._pid = self._process.pid
        self._exitcode = None
        send.close()  # the child holds the writing end: its exit without an answer reads as EOF here
        self._outcome = None
        self._reaped = False

    @property
    def elapsed(self) -> float:
        """s of wall time since the start."""
        return time.perf_counter() - self.started

    @property
    def pid(self) -> int | None:
        """The child's process id."""
        return self._pid

    def poll(self) -> bool:
        """Whether the answer is in (or the child has died without one), without blocking."""
        if self._outcome is not None:
            return True
        if self._reaped:  # killed before it answered
            self._outcome = ("died", None)
            return True
        if self._recv.poll():
            try:
                self._outcome = self._recv.recv()
            except EOFError:
                self._outcome = ("died", None)
            self._reap()
            return True
        return False

    def result(self):
        """The call's result once :meth:`poll` is True; raises :class:`CartPoleError` with the call's sentence when it
        raised one, :class:`PlanWorkerError` when the child died without answering, ``RuntimeError`` (the child's
        traceback) for any other exception in the call."""
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
        """Stop the child now (SIGKILL) and reap it; nothing is left running. Harmless when it has ended."""
        if self._reaped:
            return
        if self._process.is_alive():
            self._process.kill()
        self._reap()

    def _reap(self) -> None:
        if self._reaped:
            return
        self._reaped = True
        self._process.join(REAP_TIMEOUT)
        if self._process.exitcode is None:  # still writing its answer after the answer was read: cannot happen
            self._process.kill()
            self._process.join()
        self._exitcode = self._process.exitcode
        self._process.close()
        self._recv.close()


def run_planner(call: Callable, budget: float, *, on_timeout: Callable | None = None):
    """``call()`` in a :class:`PlanWorker`, waited for at most ``budget`` s of wall time.

    Parameters
    ----------
    call : callable
        ``call() -> result`` (a plan); its result must pickle.
    budget : float
        s of wall time; the child is killed once it has run longer.
    on_timeout : callable, optional
        ``on_timeout(wall_s)``, called when the budget stopped the call (e.g. to log the decision).

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
    worker = PlanWorker(call)
    try:
        while not worker.poll():
            if worker.elapsed > budget:
                worker.kill()
                wall = worker.elapsed
                if on_timeout is not None:
                    on_timeout(wall)
                raise PlanTimeout(timeout_sentence(wall, budget))
            time.sleep(POLL_INTERVAL)
    except BaseException:
        worker.kill()  # Ctrl-C or a timeout: nothing left running
        raise
    return worker.result()


def timeout_sentence(wall: float, budget: float) -> str:
    """The sentence of a plan stopped after ``wall`` s of wall time, over its ``budget`` s."""
    return f"The plan was stopped after {wall:.1f} s of wall time, over the budget of {budget:g} s (plan_budget)."


def fork_available() -> bool:
    """Whether this platform can fork (POSIX), which :class:`PlanWorker` needs."""
    return hasattr(os, "fork") and "fork" in multiprocessing.get_all_start_methods()
