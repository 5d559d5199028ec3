"""Progress of long stages, reported one way everywhere: a live bar on a terminal, one line per stage otherwise.

Every long stage of the toolkit (a basin estimate, batched rollouts, a sweep, a video, a multi-start solve) opens a
:func:`stage` and feeds it the fraction done. What the user then sees depends on the :class:`Reporter` the
caller made current (``with reporting("swingup"): ...``; the command line makes one per command):

* on a terminal (``stderr.isatty()``): a live `tqdm <https://tqdm.github.io>`_ bar on stderr with the elapsed time
  and an ETA, replaced when the stage ends by the same line as below;
* on anything else (a log file, a pipe, CI): nothing while the stage runs, then one line when it ends, e.g.
  ``swingup: basin estimate 300 runs in 2.1 s`` (no carriage returns, nothing glued);
* with ``enabled=False`` (``--json``) or with no reporter at all (a notebook, a test, the library called from
  Python): nothing. Nothing is ever written on stdout.

A stage that fails (its block raises, or its reporter ends before it reaches 1) prints nothing: the error says what
happened. A stage opened while another one is open is silent (it still forwards its fractions to its ``callback``),
so a basin estimate that runs a batch of rollouts shows one bar, not two.

Library functions take ``progress=None`` (a callable ``progress(fraction)``, as before) and wrap their work as::

    with stage("basin estimate", size=f"{n} runs", callback=progress) as tick:
        ...
        tick(k / n)        # fraction done, 0..1

so a caller's own callback (a test's ``seen.append``) keeps receiving the fractions.
"""
from __future__ import annotations

import sys
import time
from contextvars import ContextVar
from typing import Callable, TextIO

from tqdm import tqdm

_CURRENT: ContextVar["Reporter | None"] = ContextVar("cartpole_progress_reporter", default=None)

#: Live bars redraw at most this often (s).
MIN_INTERVAL = 0.1


class Stage:
    """One long stage: call it with the fraction done (0..1); :meth:`close` (or the ``with`` block's end) finishes it.

    Parameters
    ----------
    label : str
        What the stage does, e.g. ``"basin estimate"``.
    size : str
        How much, e.g. ``"300 runs"`` (may be set later through :attr:`size`).
    callback : callable, optional
        ``callback(fraction)``, called with every fraction this stage receives (the library's ``progress=``).
    reporter : Reporter, optional
        Where the stage is shown; None (or a reporter with a stage already open) makes it silent.

    Attributes
    ----------
    elapsed : float, s
        Wall time since the stage opened (frozen when it closes).
    fraction : float
        Largest fraction received so far.
    """

    def __init__(self, label: str, *, size: str = "", callback: Callable[[float], None] | None = None,
                 reporter: "Reporter | None" = None):
        self.label = str(label)
        self.size = str(size)
        self.callback = callback
        self.fraction = 0.0
        self.closed = False
        self._reporter = reporter
        self._bar = None
        self._t0 = time.perf_counter()
        self._t1 = None
        if reporter is not None:
            self._bar = reporter._open_bar(self)

    @property
    def shown(self) -> bool:
        """Whether this stage reports (a reporter took it); a silent stage only forwards to its callback."""
        return self._reporter is not None

    @property
    def elapsed(self) -> float:
        return (self._t1 if self._t1 is not None else time.perf_counter()) - self._t0

    def __call__(self, fraction: float) -> None:
        """Record ``fraction`` done (clipped to [0, 1]); forwards it to the callback and moves the bar."""
        f = min(max(float(fraction), 0.0), 1.0)
        self.fraction = max(self.fraction, f)
        if self.callback is not None:
            self.callback(fraction)
        if self._bar is not None and not self.closed:
            self._bar.update(self.fraction - self._bar.n)

    def line(self) -> str:
        """The finished stage's one line: ``"<prefix>: <label> <size> in <elapsed> s"``."""
        prefix = self._reporter.prefix if self._reporter is not None else ""
        what = " ".join(p for p in (self.label, self.size) if p)
        return f"{prefix + ': ' if prefix else ''}{what} in {self.elapsed:.1f} s"

    def close(self, ok: bool = True) -> None:
        """End the stage: with ``ok`` its line is printed (when shown), else it vanishes silently. Idempotent."""
        if self.closed:
            return
        self.closed = True
        self._t1 = time.perf_counter()
        if self._reporter is not None:
            self._reporter._close(self, ok)

    def __enter__(self) -> "Stage":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(ok=exc_type is None)


class Reporter:
    """Where stages are shown: stderr, as a live bar on a terminal or one line per finished stage elsewhere.

    Parameters
    ----------
    prefix : str
        Put before every line, e.g. the command's name ``"swingup"``.
    enabled : bool
        False shows nothing (``--json``).
    stream : text stream, optional
        Default ``sys.stderr`` as it is when a stage opens (so pytest's capture is honoured). Never stdout.
    live : bool, optional
        Force (True) or forbid (False) the live bar; default: when ``stream.isatty()``.

    Use as a context manager: it becomes the current reporter for :func:`stage` inside the block, and closes
    (silently) any stage still open when the block ends.
    """

    def __init__(self, prefix: str = "", *, enabled: bool = True, stream: TextIO | None = None,
                 live: bool | None = None):
        self.prefix = str(prefix)
        self.enabled = bool(enabled)
        self._stream = stream
        self._live = live
        self._open: list[Stage] = []
        self._token = None

    @property
    def stream(self) -> TextIO:
        return self._stream if self._stream is not None else sys.stderr

    def _is_live(self) -> bool:
        if self._live is not None:
            return self._live
        try:
            return bool(self.stream.isatty())
        except (AttributeError, ValueError):  # a closed or exotic stream
            return False

    def stage(self, label: str, *, size: str = "", callback: Callable[[float], None] | None = None) -> Stage:
        """Open a stage shown by this reporter (silent when disabled or while another stage is open)."""
        shown = self.enabled and not self._open
        return Stage(label, size=size, callback=callback, reporter=self if shown else None)

    def _open_bar(self, st: Stage):
        self._open.append(st)
        if not self._is_live():
            return None

        head = st.line().rsplit(" in ", 1)[0]
        return tqdm(total=1.0, file=self.stream, leave=False, mininterval=MIN_INTERVAL, dynamic_ncols=True,
                    bar_format=head + " {percentage:3.0f}%|{bar}| {elapsed}<{remaining}")

    def _close(self, st: Stage, ok: bool) -> None:
        if st in self._open:
            self._open.remove(st)
        if st._bar is not None:
            st._bar.close()
            st._bar = None
        if ok:
            print(st.line(), file=self.stream, flush=True)

    def write(self, message: str) -> None:
        """Print one line on the stream (not stdout), above a live bar if one is showing; nothing when disabled."""
        if not self.enabled:
            return
        bars = [s._bar for s in self._open if s._bar is not None]
        if bars:
            tqdm.write(message, file=self.stream)
        else:
            print(message, file=self.stream, flush=True)

    def __enter__(self) -> "Reporter":
        self._token = _CURRENT.set(self)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        for st in list(self._open):
            st.close(ok=False)
        if self._token is not None:
            _CURRENT.reset(self._token)
            self._token = None


def reporting(prefix: str = "", *, enabled: bool = True, stream: TextIO | None = None,
              live: bool | None = None) -> Reporter:
    """A :class:`Reporter` to use as ``with reporting("sweep", enabled=not json): ...``."""
    return Reporter(prefix, enabled=enabled, stream=stream, live=live)


def current() -> Reporter | None:
    """The reporter :func:`stage` reports to here, or None (stages are silent)."""
    return _CURRENT.get()


def stage(label: str, *, size: str = "", callback: Callable[[float], None] | None = None) -> Stage:
    """Open a stage on the current reporter (see the module notes); silent when there is none.

    Parameters
    ----------
    label : str
        What the stage does (``"basin estimate"``).
    size : str
        How much (``"300 runs"``), shown in the bar and the final line.
    callback : callable, optional
        ``callback(fraction)`` receives every fraction too (a library function's own ``progress=`` argument).
    """
    rep = _CURRENT.get()
    if rep is None:
        return Stage(label, size=size, callback=callback)
    return rep.stage(label, size=size, callback=callback)
