"""Watch, push and tune a run live in a browser, in MuJoCo Studio's own web viewer (``--view web``).

:class:`WebLive` is a hook ``on_step(m, d) -> bool`` for :func:`~cartpole.sim.rollout.simulate` (``SimOptions.on_step``,
as :class:`cartpole.viz.viewer.LiveViewer`, whose real-time pacing it shares): the physics and the log are simulate's,
every physics step logged, so the rollout replays exactly with ``mj_step`` and its logged pushes. What the browser
shows is MuJoCo Studio's web viewer (``mujoco.studio``, in the ``mujoco`` 4 wheel): a WebAssembly client that renders
the scene with Filament in WebGL and overlays a Dear ImGui panel built here, in Python, on a headless ImGui context
whose frames Studio streams over one WebSocket port (the page, ``/ui``, ``/state``).

What Studio gives and what is built here (``mujoco`` 4.0.1, measured; see docs/live.md):

- ``mujoco.studio.launch_thread.launch_thread`` runs a viewer in a daemon thread and hands back a ``ViewerHandle``;
  ``web_viewer.WebViewer`` serves it. Its host is hard-wired to ``'::'`` (every interface) in this release;
  :class:`_BoundWebViewer` binds ``127.0.0.1`` (or ``host``) instead, so nothing is reachable from the network
  unless asked: Studio has no authentication and no encryption (its own banner says so).
- The sim side: the viewer is built on the run's model (served from the start, so the page never reloads for it);
  the handle is given no model at all: each shown frame sends a copy of the state (``StateSnapshot``, MuJoCo's
  integration state) and ``sync()`` only trades messages. So nothing in the page (Studio's reset, drag or state
  edits act on the handle's model, which is None) can touch the logged run.
- Plugins: a ``ViewerPlugin`` (:class:`_Panel`) builds the ImGui window and ImPlot plots on every UI frame and
  sends the page's actions as Studio ``Event`` messages (:class:`PushEvent`, :class:`KnobEvent`) to a
  ``SimPlugin`` (:class:`_Inbox`) on the simulation thread; the simulation side sends a latest-wins ``Snapshot``
  (:class:`StatusSnapshot`: the recent history, the controller's lines, the knobs) to the panel.
- A push from the page becomes ``push(t)``, the world-x force on the cart simulate logs in the rollout's ``push``
  column: the push buttons (a pulse of :data:`PUSH_SECONDS`) and the panel's "drag to push" slider (the force
  follows the mouse while it is held, back to 0 on release). A drag in the 3-D scene is not wired: the page's
  client moves the camera with the mouse itself and passes no pick or Ctrl-drag to the viewer side here. A
  knob released becomes ``tuner.set(name, value, t)`` (the LQR re-designed, the PID's gains, the control period or
  the delay). Each is logged in :attr:`WebLive.events` with its time (s of simulated time).
- :meth:`WebLive.attach` tells the page which controller runs (a swing-up's switching law, its TVLQR, the supervisor):
  the panel shows it and its state (swing-up, tracking, catch, brake...) through ``describe``.
- Closing the page (no browser for :data:`GONE_SECONDS`) or Ctrl-C (SIGINT) ends the run after the step being
  done: simulate then returns the steps done.
"""
from __future__ import annotations

import contextlib
import dataclasses
import inspect
import json
import os
import signal
import socket
import sys
import threading
import time
from typing import Protocol

import mujoco
import numpy as np

from cartpole._files import atomic_write
from cartpole.errors import CartPoleError, first_line
from cartpole.viz.viewer import LiveViewer

#: Host the web viewer binds unless told otherwise: this machine only (reach it from elsewhere by an SSH tunnel).
LOCALHOST = "127.0.0.1"
#: Seconds without any browser on the page (after one came) that end the run.
GONE_SECONDS = 2.0
#: Seconds a push from the page lasts (a pulse of constant force on the cart).
PUSH_SECONDS = 0.1
#: Largest push force the page offers, in N.
MAX_PUSH = 50.0
#: Smallest change of the drag slider's force the panel sends (N); the release (back to 0) is always sent.
DRAG_STEP = 0.5
#: Seconds of history the plots show.
PLOT_SECONDS = 10.0
#: Most points a plot gets (the page's UI stream carries every vertex each frame).
PLOT_POINTS = 150
#: Height of each plot on the page, px.
PLOT_HEIGHT = 85
#: ImPlot's ImPlotFlags_NoLegend.
PLOT_NO_LEGEND = 1 << 1
#: Smallest height of a joint's plot, in m or rad.
MIN_SPAN = 0.1
#: Seconds to wait for Studio's viewer thread to bind its port and come up.
START_TIMEOUT = 30.0


def _accepts(host: str, port: int, timeout: float) -> bool:
    """Does a TCP connection to ``host:port`` (loopback for a wildcard bind) succeed within ``timeout`` s? Studio's
    server starts listening on its own thread a little after the viewer object exists."""
    target = "127.0.0.1" if host in ("0.0.0.0", "", "::") else host
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((target, port), timeout=1.0):
                return True
        except OSError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)
#: Environment variable naming a JSON file where the panel writes its widgets' page rectangles ``[x0, y0, x1, y1]``
#: in CSS pixels, by label, and the number of events it lists ("events shown") (automation, tests).
WIDGETS_ENV = "CARTPOLE_WEB_WIDGETS"


class WebUnavailable(CartPoleError):
    """The web viewer cannot start here (no MuJoCo Studio, the port taken); the message is one sentence."""


@dataclasses.dataclass(frozen=True)
class Knob:
    """A slider in the page's panel: ``name``, current ``value``, range ``[low, high]``, logarithmic or not."""

    name: str
    value: float
    low: float
    high: float
    log: bool = False


class Tuner(Protocol):
    """What a controller exposes to the page: its knobs, its status lines, and how a knob changes it."""

    def knobs(self) -> list[Knob]:
        """The sliders to show, with their current values."""

    def status(self, t: float, x: np.ndarray) -> list[str]:
        """Lines describing the controller now (its name, mode, gains, closed-loop eigenvalues)."""

    def set(self, name: str, value: float, t: float) -> dict:
        """Apply a knob released at ``value`` at time ``t`` (s); returns what changed (logged with the event)."""


def _studio():
    """The Studio modules used here, or WebUnavailable (one sentence) when this MuJoCo has none."""
    try:
        from mujoco.studio import launch_thread, messages, plugin, viewer_protocol, web_viewer
        from mujoco.studio.dear_imgui import dear_imgui
        from mujoco.studio.implot import implot
    except Exception as exc:  # an older MuJoCo, a wheel without Studio
        raise WebUnavailable(f"MuJoCo Studio's web viewer is not available ({first_line(exc)}); install "
                             "mujoco 4 with its studio package, or run without the web view.") from None
    return launch_thread, messages, plugin, viewer_protocol, web_viewer, dear_imgui, implot


def port_free(host: str, port: int) -> bool:
    """True when a TCP server could bind ``(host, port)`` now (``port`` 0: always)."""
    if port == 0:
        return True
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def _messages():
    """The Studio message classes of the panel (defined once, on first use: Studio is imported lazily)."""
    global _MSG
    if _MSG is None:
        _, messages, _, _, _, _, _ = _studio()

        @dataclasses.dataclass(frozen=True)
        class PushEvent(messages.Event):
            """The page's push button: a pulse of ``force`` N on the cart along world x."""
            force: float = 0.0

        @dataclasses.dataclass(frozen=True)
        class DragEvent(messages.Event):
            """The panel's drag slider: the force in N held on the cart from now on (0 on release)."""
            force: float = 0.0

        @dataclasses.dataclass(frozen=True)
        class KnobEvent(messages.Event):
            """A slider released at ``value``."""
            name: str = ""
            value: float = 0.0

        @dataclasses.dataclass(frozen=True)
        class StatusSnapshot(messages.Snapshot):
            """What the panel draws: history (t, columns), their names, ctrl range, status lines, knobs, events."""
            t: tuple = ()
            series: tuple = ()
            names: tuple = ()
            ctrl_range: tuple = ()
            lines: tuple = ()
            knobs: tuple = ()
            events: tuple = ()
            pushable: bool = False

        _MSG = _namespace(PushEvent=PushEvent, DragEvent=DragEvent, KnobEvent=KnobEvent,
                          StatusSnapshot=StatusSnapshot)
    return _MSG


_MSG = None


def _namespace(**kw):
    """A read-only namespace of ``kw`` (the Studio message classes)."""
    return type("Messages", (), kw)


def _handles(messages, cls):
    """Studio's ``messages.handler`` for a method handling ``cls`` (its annotation set here: this module's
    annotations are strings, which Studio resolves in the module's globals, where Studio's classes are not)."""
    def deco(fn):
        name = list(inspect.signature(fn).parameters)[1]
        fn.__annotations__ = {name: cls, "return": None}
        return messages.handler(fn)
    return deco


def _draw_plots(im, ip, s) -> None:
    """The panel's plots (ImGui ``im``, ImPlot ``ip``): one per series of the status ``s`` against its time, the
    ctrl's with its range drawn."""
    t = list(s.t)
    for i, name in enumerate(s.names):
        ys = [row[i] for row in s.series]
        if ip.BeginPlot(f"##{name}", im.Vec2(-1, PLOT_HEIGHT), PLOT_NO_LEGEND):
            ctrl = name.startswith("ctrl")
            ip.SetupAxes("t [s]", name, 0, 0)
            if ys and not ctrl:  # at least MIN_SPAN tall: rounding noise at rest stays flat
                mid, half = 0.5 * (max(ys) + min(ys)), 0.55 * max(max(ys) - min(ys), MIN_SPAN)
                ip.SetupAxisLimits(3, mid - half, mid + half, 1)
            if t:
                ip.SetupAxisLimits(0, t[0], max(t[-1], t[0] + 1e-3), 1)  # ImPlotCond_Always
            if ctrl and s.ctrl_range:
                lo, hi = s.ctrl_range[0]
                ip.SetupAxisLimits(3, lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), 1)
                if t:
                    ip.PlotLine("low", [t[0], t[-1]], [lo, lo])
                    ip.PlotLine("high", [t[0], t[-1]], [hi, hi])
            if t:
                ip.PlotLine(name, t, ys)
            ip.EndPlot()


def _draw_push(panel, im, M) -> None:
    """The panel's push controls: a force slider with push-left and push-right buttons, and a drag slider that
    pushes while held (messages ``M`` sent through ``panel.viewer``)."""
    changed, panel.force = im.SliderFloat("push force [N]", panel.force, 1.0, MAX_PUSH, "%.1f")
    if im.Button("push left"):
        panel.viewer.send_to_sim(M.PushEvent(force=-panel.force))
    panel._rect("push left")
    im.SameLine()
    if im.Button("push right"):
        panel.viewer.send_to_sim(M.PushEvent(force=panel.force))
    panel._rect("push right")
    changed, panel.drag = im.SliderFloat("drag to push [N]", panel.drag, -MAX_PUSH, MAX_PUSH, "%+.1f")
    if im.IsItemActive():
        if abs(panel.drag - panel.drag_sent) >= DRAG_STEP:
            panel.drag_sent = panel.drag
            panel.viewer.send_to_sim(M.DragEvent(force=panel.drag))
    else:
        if panel.drag_sent != 0.0:
            panel.viewer.send_to_sim(M.DragEvent(force=0.0))
        panel.drag = panel.drag_sent = 0.0
    panel._rect("drag to push [N]")


def _draw_knobs(panel, im, s, M) -> None:
    """The panel's knobs: one slider per knob of the status ``s`` (log-scaled where the knob says so), its value
    sent to the run when the edit ends."""
    for k in s.knobs:
        name, value, low, high, log = k
        shown = panel.values.get(name, value)
        if log:
            changed, v = im.SliderFloat(name, float(np.log10(shown)), float(np.log10(low)),
                                        float(np.log10(high)), f"{shown:.3g}")
            new = float(10.0 ** v)
        else:
            changed, new = im.SliderFloat(name, float(shown), float(low), float(high), "%.3g")
        if changed:
            panel.values[name] = new
        if im.IsItemDeactivatedAfterEdit():
            panel.viewer.send_to_sim(M.KnobEvent(name=name, value=panel.values.get(name, new)))
        elif not im.IsItemActive():
            panel.values[name] = value
        panel._rect(name)


def _make_plugins(live: "WebLive"):
    """The viewer-side panel and the sim-side inbox, as Studio plugin instances."""
    _, messages, plugin, _, _, im, ip = _studio()
    M = _messages()

    class _Panel(plugin.ViewerPlugin):
        """The ImGui window on the page: status, plots, push, knobs (viewer thread)."""

        def __init__(self):
            self.status = None
            self.force = 10.0
            self.drag = 0.0
            self.drag_sent = 0.0
            self.values: dict[str, float] = {}
            self.widgets: dict[str, list[float]] = {}

        @_handles(messages, M.StatusSnapshot)
        def on_status(self, snap) -> None:
            self.status = snap

        @_handles(messages, plugin.ViewerInitEvent)
        def on_init(self, event) -> None:
            from mujoco.studio import ux

            ux.setup_theme(ux.GuiTheme.LIGHT)
            model = event.viewer.model
            cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "track")
            if cam >= 0:
                ux.set_camera(model, event.viewer.camera, cam)
            else:
                mujoco.mjv_defaultFreeCamera(model, event.viewer.camera)

        def _rect(self, name: str) -> None:
            lo, hi = im.GetItemRectMin(), im.GetItemRectMax()
            self.widgets[name] = [float(lo.x), float(lo.y), float(hi.x), float(hi.y)]

        @_handles(messages, messages.BuildGuiEvent)
        def on_gui(self, _) -> None:
            im.SetNextWindowPos(im.Vec2(8, 8), 4)   # ImGuiCond_FirstUseEver
            im.SetNextWindowSize(im.Vec2(440, 780), 4)
            im.Begin("cartpole live")
            s = self.status
            if s is None:
                im.Text("waiting for the run...")
                im.End()
                return
            for line in s.lines:
                im.Text(line)
            im.Separator()
            _draw_plots(im, ip, s)
            im.Separator()
            if s.pushable:
                _draw_push(self, im, M)
            if s.knobs:
                im.Separator()
            _draw_knobs(self, im, s, M)
            if s.events:
                im.Separator()
                for line in s.events[-6:]:
                    im.Text(line)
                self._rect("last event")
            self.widgets["events shown"] = [float(len(s.events))] * 4
            im.End()
            if live.widgets_file:
                with contextlib.suppress(OSError):
                    atomic_write(live.widgets_file, lambda fh: fh.write(json.dumps(self.widgets).encode()))

    class _Inbox(plugin.SimPlugin):
        """The page's actions, received on the simulation thread (during the handle's ``sync``)."""

        @_handles(messages, M.PushEvent)
        def on_push(self, event) -> None:
            live._push_from_page(float(event.force))

        @_handles(messages, M.DragEvent)
        def on_drag(self, event) -> None:
            live._drag_from_page(float(event.force), "panel")

        @_handles(messages, M.KnobEvent)
        def on_knob(self, event) -> None:
            live._knob_from_page(str(event.name), float(event.value))

    return _Panel(), _Inbox()


class WebLive(LiveViewer):
    """MuJoCo Studio's web viewer driven from a physics loop: pass as ``on_step`` (and :meth:`push` as ``push``).

    The first call starts Studio's web viewer in a thread on ``host:port`` (printed on stderr), then, with
    ``wait=True``, waits for a browser to open the page before the run goes on (Ctrl-C gives up). Each call paces
    the run to wall time (:class:`~cartpole.viz.viewer.LiveViewer`'s clock) and, at most 60 times a second, shows
    the state and trades messages with the page. Returns False once the page has been closed (no browser for
    :data:`GONE_SECONDS`) or after Ctrl-C: the loop stops there with the steps done logged.

    Parameters
    ----------
    port : int
        TCP port; 0 picks the first free one from 8080 (Studio's scan).
    host : str
        Interface to bind, default :data:`LOCALHOST` (this machine only).
    tuner : Tuner, optional
        The controller's knobs and status for the panel (e.g. :class:`cartpole.apps.live.LQRTuner`); without one the
        panel shows the state and offers pushes only.
    wait : bool
        Hold the run at its start until a browser opens the page (default True).
    realtime : bool
        Sleep so simulated time tracks wall time (default True).
    title : str
        The page's title.
    describe : callable, optional
        ``describe(controller, t, x) -> list of str``: the lines the panel shows about a controller given to
        :meth:`attach` (its name and state: swing-up, tracking, catch, brake...).

    Attributes
    ----------
    url : str
        ``http://localhost:PORT/`` once started.
    events : list of dict
        Every action from the page, in order, each with its time ``t`` (s, simulated, the first physics step it acts
        on), ``run`` (which run on this page, from 1: one per :meth:`attach`) and ``kind``: ``push`` (``force`` N for ``seconds``), ``drag`` (``force`` N held from ``t`` until the next
        drag event; ``source`` ``"panel"``), ``knob`` (``name``, ``value`` and what the tuner
        changed, or ``rejected``: why not).
    page_closed, interrupted : bool
        Why the run ended early, if it did.
    """

    def __init__(self, *, port: int = 0, host: str = LOCALHOST, tuner: Tuner | None = None, wait: bool = True,
                 realtime: bool = True, title: str = "cartpole live", describe=None):
        super().__init__(realtime=realtime)
        if not (0 <= int(port) <= 65535):
            raise WebUnavailable(f"Port {port} is not a TCP port; give one from 1 to 65535, or 0 for the first "
                                 "free one from 8080.")
        self.port, self.host, self.tuner, self.wait, self.title = int(port), str(host), tuner, bool(wait), title
        self.url = ""
        self.events: list[dict] = []
        self.page_closed = False
        self.interrupted = False
        self.widgets_file = os.environ.get(WIDGETS_ENV) or None
        self._handle = None
        self._server = None
        self._state_msg = None
        self.pushable = False  # the run takes push(t) (simulate calls it): the page offers push buttons
        self._pending_push: list[float] = []
        self._push_until = -1.0
        self._push_force = 0.0
        self._pending_drag: tuple | None = None  # (force N, source) not yet applied
        self._drag_force = 0.0
        self.controller = None
        self.describe = describe
        self.runs = 0
        self._h = 0.0
        self._t_now = 0.0
        self._x_now = None
        self._hist_t: list[float] = []
        self._hist: list[list[float]] = []
        self._names: tuple = ()
        self._ctrl_range: tuple = ()
        self._seen_browser = False
        self._last_browser = 0.0
        self._old_sigint = None
        self._stdout = None
        self._state = None
        self._spec = None

    # -- start ----------------------------------------------------------------------------------------------
    def open(self, m, d) -> None:
        """Start the web viewer on ``(m, d)`` (done by the first call); raises WebUnavailable (one sentence) when
        Studio is missing or the port is taken."""
        launch_thread, messages, plugin, viewer_protocol, web_viewer, _, _ = _studio()
        if not port_free(self.host, self.port):
            raise WebUnavailable(f"Port {self.port} on {self.host} is in use; pass another port (0 picks the first "
                                 "free one from 8080).")
        host = self.host

        class _BoundWebViewer(web_viewer.WebViewer):
            """Studio's WebViewer bound to ``host`` instead of every interface ('::' is hard-wired in 4.0.1)."""

            @property
            def _host(self):
                return host

            @_host.setter
            def _host(self, value):
                pass

        config = viewer_protocol.ViewerConfig(title=self.title, gfx="web", http_port=self.port)
        panel, inbox = _make_plugins(self)
        started = threading.Event()
        box: dict = {}

        def target(endpoint):
            try:  # the model is served from the start: no page reload when it would arrive later
                viewer = _BoundWebViewer(config, endpoint, model=m, plugins=[panel])
            except BaseException as exc:  # the bind failed, Studio's assets missing...
                box["error"] = exc
                started.set()
                raise
            box["viewer"] = viewer
            started.set()
            viewer_protocol.run_viewer_loop(viewer)

        # Studio prints its banner and notes on stdout: keep stdout for the command's own output (--json).
        self._stdout = sys.stdout
        sys.stdout = sys.stderr
        try:
            handle = launch_thread.launch_thread(target, sim_plugins=[inbox])
            if not started.wait(START_TIMEOUT) or "error" in box:
                why = first_line(box["error"]) if "error" in box else f"no answer within {START_TIMEOUT:.0f} s"
                with contextlib.suppress(BaseException):
                    handle.close()
                raise WebUnavailable(f"MuJoCo Studio's web viewer did not start on {self.host}:{self.port} ({why}); "
                                     "pass another port, or run without the web view.")
        except BaseException:
            self._restore_stdout()
            raise
        self._handle = handle
        self._server = box["viewer"]
        self.port = int(self._server.port)
        self.url = f"http://localhost:{self.port}/"
        if not _accepts(self.host, self.port, START_TIMEOUT):  # the address is printed only once it answers
            self._restore_stdout()
            with contextlib.suppress(BaseException):
                handle.close()
            raise WebUnavailable(f"MuJoCo Studio's web viewer did not accept connections on {self.host}:{self.port} "
                                 f"within {START_TIMEOUT:.0f} s; pass another port, or run without the web view.")
        self._spec = mujoco.mjtState.mjSTATE_INTEGRATION
        self._state = np.empty(mujoco.mj_stateSize(m, self._spec))
        self._h = float(m.opt.timestep)
        self._names = _plot_names(m)
        self._ctrl_range = tuple((float(lo), float(hi)) for lo, hi in
                                 (m.actuator_ctrlrange if m.nu else np.zeros((0, 2))))
        self._viewer = handle  # LiveViewer's clock asks it is_running()
        self._state_msg = messages.StateSnapshot
        self._install_sigint()
        where = "" if self.host == LOCALHOST else (f" (bound to {self.host}: anyone who can reach this port can "
                                                    "watch and push the run, there is no authentication)")
        print(f"Live view: open {self.url} in a browser{where}; from another machine tunnel it first: "
              f"ssh -L 8080:localhost:{self.port} HOST, then open http://localhost:8080/. Closing the page or "
              "Ctrl-C ends the run, keeping the steps done.", file=sys.stderr, flush=True)
        self._show(m, d)
        if self.wait:
            self._wait_for_browser(m, d)
        self._opened = True
        self._anchor = self._opened_at = time.perf_counter()
        self._t0 = float(d.time)
        self._next_frame = self._anchor + 1.0 / 60.0

    def _wait_for_browser(self, m, d) -> None:
        print("Live view: waiting for a browser to open the page (the run starts then).", file=sys.stderr,
              flush=True)
        while not self.interrupted and self._handle.is_running():
            self._show(m, d)
            if self._browsers() > 0:
                self._seen_browser = True
                self._last_browser = time.monotonic()
                return
            time.sleep(1.0 / 30.0)

    def _browsers(self) -> int:
        server = getattr(self._server, "_web_server", None)  # Studio's WebServer; None once stopped
        return 0 if server is None else int(server.viewer_count)

    def _install_sigint(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return

        def on_sigint(signum, frame):
            self.interrupted = True

        self._old_sigint = signal.signal(signal.SIGINT, on_sigint)

    # -- each step ------------------------------------------------------------------------------------------
    def _show(self, m, d) -> None:
        """Hand the viewer a copy of the state now and trade messages with the page (the run's MjData is never
        given to Studio: the handle holds no model, so nothing from the page can reset or move the run)."""
        mujoco.mj_getState(m, d, self._state, self._spec)
        self._handle.send_to_viewer(self._state_msg(state=self._state.copy(), state_sig=int(self._spec)))
        self._t_now = float(d.time)
        self._x_now = np.concatenate([d.qpos, d.qvel])
        self._record(m, d)
        self._handle.send_to_viewer(self._status())
        self._handle.sync()
        self.frames += 1

    def _sync(self, m, d) -> None:  # LiveViewer's frame hook
        self._show(m, d)

    def _record(self, m, d) -> None:
        row = [float(v) for v in d.qpos] + [float(v) for v in d.ctrl]
        if self._hist_t and float(d.time) < self._hist_t[-1]:  # a new run on the same page
            self._hist_t.clear()
            self._hist.clear()
        self._hist_t.append(float(d.time))
        self._hist.append(row)
        while self._hist_t and self._hist_t[0] < self._hist_t[-1] - PLOT_SECONDS:
            self._hist_t.pop(0)
            self._hist.pop(0)

    def _status(self):
        M = _messages()
        lines = [f"t = {self._t_now:6.2f} s   {self.url}"]
        knobs: tuple = ()
        if self.controller is not None and self.describe is not None:
            lines += list(self.describe(self.controller, self._t_now, self._x_now))
        if self.tuner is not None:
            lines += list(self.tuner.status(self._t_now, self._x_now))
            knobs = tuple((k.name, float(k.value), float(k.low), float(k.high), bool(k.log))
                          for k in self.tuner.knobs())
        if self._t_now < self._push_until:
            lines.append(f"pushing {self._push_force:+.1f} N")
        if self._drag_force:
            lines.append(f"dragging {self._drag_force:+.1f} N")
        ev = tuple(_event_line(e) for e in self.events)
        every = max(1, len(self._hist_t) // PLOT_POINTS)
        return M.StatusSnapshot(t=tuple(self._hist_t[::every]), series=tuple(tuple(r) for r in self._hist[::every]),
                                names=self._names, ctrl_range=self._ctrl_range, lines=tuple(lines), knobs=knobs,
                                events=ev, pushable=self.pushable)

    def __call__(self, m, d) -> bool:
        """After one physics step: pace, maybe show and read the page. False when the run should stop."""
        if self.interrupted:
            return False
        if self._handle is None and not self._opened:
            self.open(m, d)
            self._md = (m, d)
            return not self.interrupted and self._handle.is_running()
        if self._handle is None:
            return False
        now = time.monotonic()
        if self._browsers() > 0:
            self._seen_browser = True
            self._last_browser = now
        elif self._seen_browser and now - self._last_browser > GONE_SECONDS:
            self.page_closed = self.closed = True
            return False
        if not self._handle.is_running():
            self.closed = True
            return False
        going = super().__call__(m, d)
        return going and not self.interrupted

    @property
    def is_running(self) -> bool:
        """The viewer is up."""
        return self._handle is not None and self._handle.is_running()

    # -- the page's actions (simulation thread) -------------------------------------------------------------
    def _push_from_page(self, force: float) -> None:
        force = float(np.clip(force, -MAX_PUSH, MAX_PUSH))
        self._pending_push.append(force)

    def _drag_from_page(self, force: float, source: str) -> None:
        force = float(np.clip(force, -MAX_PUSH, MAX_PUSH)) if np.isfinite(force) else 0.0
        self._pending_drag = (force, source)

    def attach(self, controller, push=None):
        """Show ``controller`` (the law about to run) on the page, and return the ``push(t)`` to give the run: the
        page's pushes added to ``push`` (a scheduled ``push(t) -> N``, or None), all logged in one push column."""
        self.controller = controller
        self.runs += 1
        self._pending_push.clear()  # a new run on the page starts unpushed
        self._pending_drag, self._drag_force, self._push_until = None, 0.0, -1.0
        if push is None:
            return self.push

        def both(t: float) -> float:
            return float(push(t)) + self.push(t)
        return both

    def _knob_from_page(self, name: str, value: float) -> None:
        event = {"t": self._t_now, "kind": "knob", "name": name, "value": float(value), "run": max(1, self.runs)}
        if self.tuner is not None:
            try:
                event.update(self.tuner.set(name, float(value), self._t_now))
            except CartPoleError as exc:
                event["rejected"] = first_line(exc)
        self.events.append(event)

    def push(self, t: float) -> float:
        """``push(t) -> force [N]`` for :func:`~cartpole.sim.rollout.simulate`: the page's pushes, each a pulse of
        :data:`PUSH_SECONDS` starting at the first physics step after the button was pressed, plus the drag's force
        in force (from the first physics step after it changed); each change logged in :attr:`events`."""
        self.pushable = True
        if self._pending_drag is not None:
            force, source = self._pending_drag
            self._pending_drag = None
            if force != self._drag_force:
                self._drag_force = force
                self.events.append({"t": float(t), "kind": "drag", "force": force, "source": source,
                                    "run": max(1, self.runs)})
        if self._pending_push:
            self._push_force = self._pending_push.pop(0)
            self._push_until = t + PUSH_SECONDS - 0.5 * self._h
            self.events.append({"t": float(t), "kind": "push", "force": self._push_force,
                                "seconds": PUSH_SECONDS, "run": max(1, self.runs)})
        return (self._push_force if t < self._push_until else 0.0) + self._drag_force

    # -- end ------------------------------------------------------------------------------------------------
    def finish(self, m=None, d=None, *, settle: float = 0.0) -> None:
        """Show the last state once more (and wait ``settle`` s)."""
        if self._handle is not None and self._handle.is_running() and self._md is not None:
            m, d = (m, d) if m is not None else self._md
            self._show(m, d)
            if settle > 0:
                time.sleep(settle)
        if self._opened:
            self.wall_time = time.perf_counter() - self._opened_at

    def close(self) -> None:
        """Stop the web viewer (the page shows it has ended), put back Ctrl-C and stdout."""
        handle, self._handle = self._handle, None
        self._viewer = None
        if handle is not None:
            with contextlib.suppress(BaseException):
                handle.close(reason="The run has ended.")
        if self._old_sigint is not None:
            signal.signal(signal.SIGINT, self._old_sigint)
            self._old_sigint = None
        self._restore_stdout()

    def _restore_stdout(self) -> None:
        if self._stdout is not None:
            sys.stdout = self._stdout
            self._stdout = None

    def summary(self) -> dict:
        """The live run's JSON part: ``url``, ``events``, ``frames``, ``wall_time`` (s), ``page_closed``,
        ``interrupted``."""
        return {"url": self.url, "host": self.host, "port": self.port, "events": list(self.events),
                "frames": self.frames, "wall_time": self.wall_time, "page_closed": self.page_closed,
                "interrupted": self.interrupted}


def _event_line(e: dict) -> str:
    if e["kind"] == "push":
        return f"{e['t']:6.2f} s  push {e['force']:+.1f} N for {e['seconds']:g} s"
    if e["kind"] == "drag":
        return f"{e['t']:6.2f} s  drag {e['force']:+.1f} N ({e['source']})"
    text = f"{e['t']:6.2f} s  {e['name']} = {e['value']:.3g}"
    if "rejected" in e:
        return text + f"  (rejected: {e['rejected']})"
    if "eigenvalues" in e:
        text += "  eig " + ", ".join(_complex_text(c) for c in e["eigenvalues"][:4])
    return text


def _complex_text(c) -> str:
    re_, im_ = (c if isinstance(c, (list, tuple)) else (complex(c).real, complex(c).imag))
    return f"{re_:.3g}" if abs(im_) < 1e-12 else f"{re_:.3g}{im_:+.3g}j"


def _plot_names(m) -> tuple:
    names = []
    for j in range(m.njnt):
        unit = "m" if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE else "rad"
        names.append(f"{mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f'qpos{j}'} [{unit}]")
    for a in range(m.nu):
        names.append("ctrl " + (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or str(a)))
    return tuple(names)


