"""``--view [desktop|web]``, ``--port`` and ``--host``: which live view a command opens, shared by the commands that
run MuJoCo. ``--view`` alone picks MuJoCo's desktop window where a display exists and the browser page
(:mod:`cartpole.viz.web`) otherwise, and says which on stderr."""
from __future__ import annotations

import sys

from cartpole.apps.live import controller_status, watch_lab
from cartpole.commands._flags import as_flags
from cartpole.commands._rollouts import live_viewer, rollout_doc, show_logged
from cartpole.errors import CartPoleError, first_line
from cartpole.sim import SimOptions, replays_exactly, simulate
from cartpole.viz.viewer import display_available
from cartpole.viz.web import WebLive, WebUnavailable, port_free

VIEWS = ("auto", "desktop", "web")
LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")


def add_view_arguments(parser, help: str, *, live_seconds: bool = False) -> None:
    """Add ``--view [auto|desktop|web]`` (``help`` says what is shown), ``--port`` and ``--host``, and with
    ``live_seconds`` ``--live-seconds`` (the web run's length, for commands without a ``--duration``)."""
    parser.add_argument("--view", nargs="?", const="auto", default=None, choices=VIEWS,
                        help=help + "; --view web shows it in a browser page served by MuJoCo Studio (watch, push "
                             "and tune it from any machine), --view desktop in MuJoCo's window, --view alone the "
                             "window where a display exists, else the page")
    if live_seconds:
        parser.add_argument("--live-seconds", type=float, default=30.0, metavar="S",
                            help="--view web: length of the live run in s (default 30; closing the page or Ctrl-C "
                                 "ends it sooner, keeping the steps done)")
    parser.add_argument("--port", type=int, default=0, metavar="N",
                        help="--view web: TCP port of the page (default 0: the first free one from 8080)")
    parser.add_argument("--host", default="127.0.0.1", metavar="ADDR",
                        help="--view web: interface to bind (default 127.0.0.1, this machine only; reach it from "
                             "another one with `ssh -L 8080:localhost:PORT HOST`); anything else is reachable by "
                             "anyone on that network, with no authentication")


def view_mode(args, command: str) -> str | None:
    """``"desktop"``, ``"web"`` or None (no ``--view``), checking ``--port``/``--host`` and saying on stderr what
    ``--view`` alone chose. Raises CartPoleError (one sentence) for a port that is not free."""
    view = getattr(args, "view", None)
    if not view:
        return None
    if view == "auto":
        view = "desktop" if display_available() else "web"
        why = "a display is available" if view == "desktop" else "no display here"
        print(f"cartpole {command}: --view: {why}, so the {'desktop window' if view == 'desktop' else 'web page'} "
              f"(--view {'web' if view == 'desktop' else 'desktop'} for the other).", file=sys.stderr)
    if view == "web":
        if not (0 <= args.port <= 65535):
            raise CartPoleError(f"--port {args.port} is not a TCP port; give one from 1 to 65535, or 0 for the "
                                "first free one from 8080.")
        if not port_free(args.host, args.port):
            raise CartPoleError(f"--port {args.port} on {args.host} is in use or cannot be bound; pass another "
                                "--port (0 picks the first free one from 8080).")
        if getattr(args, "live_seconds", 1.0) <= 0:
            raise CartPoleError(f"--live-seconds {args.live_seconds} must be positive; give e.g. 30.")
        if args.host not in LOCAL_HOSTS:
            print(f"cartpole {command}: warning: --host {args.host} serves the live page to anyone who can reach "
                  "this machine on that interface, with no authentication or encryption (MuJoCo Studio's own "
                  "warning); prefer the default 127.0.0.1 and an SSH tunnel.", file=sys.stderr)
    return view


def view_web(lab, args, pid=None) -> dict | None:
    """``--view web`` for a lab: its LQR run live in the browser (:func:`cartpole.apps.live.watch_lab`), returned as
    the JSON's ``live``: the page's address, ``events`` (pushes, drags, weight, period and delay changes, with their
    times), the final ``K``, ``eigenvalues`` and ``loop``, the ``rollout`` (every physics step, pushes in its
    ``push`` column) and ``replays`` (the log replayed with ``mj_step`` gives every state again, bit for bit); with
    ``pid`` (``--compare-pid``) the PID run live after it on the same page, as ``pid`` (the same keys, ``gains``
    instead of ``K``; null when the page was closed first). None, with one sentence on stderr, when the viewer
    cannot start."""
    try:
        run, live = watch_lab(lab, port=args.port, host=args.host, duration=args.live_seconds, pid=pid)
    except WebUnavailable as exc:
        print(f"cartpole {args.command}: no live view: {as_flags(first_line(exc))}", file=sys.stderr)
        return None
    live["rollout"] = rollout_doc(run)
    live["replays"] = bool(replays_exactly(run))
    live["steps"] = int(len(run.ctrl))
    if live.get("pid") is not None:
        prun = live["pid"]["rollout"]
        live["pid"].update(rollout=rollout_doc(prun), replays=bool(replays_exactly(prun)), steps=int(len(prun.ctrl)))
    return live


def live_sentence(live: dict) -> str:
    """One line of prose about a live web run: how long, how it ended, how many pushes and changes, replayed."""
    def counts(ev):
        pushes = sum(e["kind"] in ("push", "drag") for e in ev)
        return f"{pushes} push(es) or drag change(s) and {len(ev) - pushes} setting change(s)"

    end = (" (page closed)" if live["page_closed"] else " (Ctrl-C)" if live["interrupted"] else "")
    text = (f"Live run at {live['url']}: {live['steps']} physics steps{end}, {counts(live['events'])} logged; the "
            f"log replays exactly: {live['replays']}.")
    pid = live.get("pid")
    if pid is not None:
        text += (f" Then the PID: {pid['steps']} physics steps, {counts(pid['events'])}; replays exactly: "
                 f"{pid['replays']}.")
    return text


def live_view(command: str, args):
    """The ``on_step`` hook for ``--view``: a :class:`~cartpole.viz.web.WebLive` (``web``; the page shows the run,
    its plots and, when the run :meth:`~cartpole.viz.web.WebLive.attach`-es its controller, which law is in charge;
    its pushes and drags join the run's logged push column), a :class:`~cartpole.viz.viewer.LiveViewer` (``desktop``), or None (no
    ``--view``, or no display for the desktop window: its one sentence on stderr)."""
    mode = view_mode(args, command)
    if mode == "web":
        return WebLive(port=args.port, host=args.host, title=f"cartpole {command} live", describe=controller_status)
    if mode == "desktop":
        return live_viewer(command)
    return None


def web_summary(viewer) -> dict:
    """The web page's part of a command's ``viewer`` JSON (``url``, ``page_closed``, ``interrupted``...), or {}."""
    summary = getattr(viewer, "summary", None)
    return {} if summary is None else {k: v for k, v in summary().items() if k not in ("frames", "wall_time")}


def show_runs(params, rollouts, mode: str, args, *, command: str) -> None:
    """Show logged runs one after the other, each replayed from its log in real time
    (:func:`cartpole.commands._rollouts.show_logged`, which checks the run shown is the run logged): in MuJoCo's
    window (``mode="desktop"``) or on one web page for all of them (``"web"``; closing it or Ctrl-C stops showing)."""
    if mode != "web":
        for r in rollouts:
            if show_logged(params, r, command=command) is None:
                break  # no display: said once
        return

    live = WebLive(port=args.port, host=args.host, title=f"cartpole {command} live")

    def on_page(source, controller, x0, duration, push=None):
        return simulate(source, controller, x0, duration, push=push, options=SimOptions(on_step=live))

    try:
        for r in rollouts:
            show_logged(params, r, command=command, watcher=on_page)
            if live.page_closed or live.interrupted:
                break
    finally:
        live.close()
