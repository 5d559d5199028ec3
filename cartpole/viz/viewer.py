"""Watch a controller run live in MuJoCo's own interactive viewer (``--view``), in real time, logged like ``simulate``.

:func:`watch` runs ``u = controller(t, x)`` in MuJoCo exactly as :func:`~cartpole.sim.rollout.simulate` does (same
start, same ``mj_step`` sequence, every physics step logged) while ``mujoco.viewer.launch_passive`` shows it: the
loop sleeps so simulated time tracks wall time and hands the viewer a frame at most 60 times a second
(``viewer.sync()``). Closing the window ends the run early, cleanly: the rollout holds the steps done. The window is
a view only: after each ``sync`` the physics state is put back as it was (``mj_getState``/``mj_setState``), so
dragging a body with the mouse, the joint and control sliders and the Reset button change nothing in the run and the
log replays exactly with ``mj_step``. Disturbances go through ``push`` instead.

The per-frame work is :class:`LiveViewer`, a hook ``view(m, d) -> bool`` to call after each physics step; a
simulate loop that accepts such a hook gets the live viewer for free (see :func:`watch`).

OpenGL, as measured here (MuJoCo 4.0.0, the ``glfw`` 2.11 wheel, Mesa 22.3 llvmpipe, Xvfb 21.1):

- ``mujoco.viewer`` draws through GLFW (the ``glfw`` package's own ``libglfw``, its X11 build unless
  ``XDG_SESSION_TYPE=wayland``) and GLX on ``DISPLAY``. It never reads ``MUJOCO_GL``: that variable only chooses
  the context ``mujoco.Renderer`` makes. So with the package's default ``MUJOCO_GL=egl`` the viewer works under
  Xvfb, and an EGL offscreen renderer works in the same process before, during and after the viewer window (same
  frames), so videos and the live view need no switching. Nothing has to be set for the viewer.
- Without a reachable X server GLFW's initialisation fails inside the viewer's thread and MuJoCo ends the whole
  process ("ERROR: could not initialize GLFW", exit status 1): there is no exception to catch. So
  :func:`display_available` opens the display with Xlib and looks for its GLX extension first, and :func:`watch`
  raises :class:`ViewerUnavailable` (one sentence) before it touches MuJoCo.
- Leaving the process while the viewer's thread is still destroying its window can crash the interpreter at exit
  (seen: a segmentation fault); :func:`watch` closes the viewer and joins that thread before it returns.
- GLFW stays initialised after the window closes: ``glfw.terminate()`` followed by a second window in the same
  process aborts it, while several windows one after another without it work. The price: GLFW holds its X
  connection until exit, and if that X server stops first (an Xvfb killed before the process ends) Xlib ends the
  process at exit with "XIO: fatal IO error", status 1; whoever stops the server calls ``glfw.terminate()`` first
  (the tests do).
- MuJoCo's default free camera frames this scene from under the raised rail, everything grey; the viewer starts
  on the MJCF's ``track`` camera when it has one (the one the videos use; Esc gives the free camera back).
- Screenshots read the X screen itself (Pillow's ``ImageGrab.grab(xdisplay=...)``) cropped to the window titled
  ``MuJoCo : <model>``, so a screenshot is proof that the real window was on screen.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import threading
import time
from pathlib import Path
from typing import Callable

import mujoco
import numpy as np
from PIL import ImageGrab

from cartpole._files import atomic_write
from cartpole.errors import FOREIGN_WIDTH, CartPoleError, first_line
from cartpole.models import Plant
from cartpole.sim import Rollout, SimOptions, simulate

#: Most frames a second handed to the viewer (``viewer.sync()``); physics steps in between are not drawn.
MAX_FPS = 60.0
#: Seconds the run may fall behind wall time before the clock is re-anchored instead of rushing to catch up.
MAX_LAG = 0.1
#: Seconds to wait for the viewer window to open.
OPEN_TIMEOUT = 20.0

_HINT = "the run continues without it: run under a desktop session or `xvfb-run`."


class ViewerUnavailable(CartPoleError):
    """No display (or no GLX on it) for MuJoCo's live viewer; the message is one sentence, the run can go on."""


# ---- is there a screen? ------------------------------------------------------------------------------------

class _XWindowAttributes(ctypes.Structure):
    _fields_ = [("x", ctypes.c_int), ("y", ctypes.c_int), ("width", ctypes.c_int), ("height", ctypes.c_int),
                ("border_width", ctypes.c_int), ("depth", ctypes.c_int), ("visual", ctypes.c_void_p),
                ("root", ctypes.c_ulong), ("class_", ctypes.c_int), ("bit_gravity", ctypes.c_int),
                ("win_gravity", ctypes.c_int), ("backing_store", ctypes.c_int), ("backing_planes", ctypes.c_ulong),
                ("backing_pixel", ctypes.c_ulong), ("save_under", ctypes.c_int), ("colormap", ctypes.c_ulong),
                ("map_installed", ctypes.c_int), ("map_state", ctypes.c_int), ("all_event_masks", ctypes.c_long),
                ("your_event_mask", ctypes.c_long), ("do_not_propagate_mask", ctypes.c_long),
                ("override_redirect", ctypes.c_int), ("screen", ctypes.c_void_p)]


def _xlib():
    """libX11 through ctypes with the few signatures used here, or None when it is not installed."""
    name = ctypes.util.find_library("X11")
    if name is None:
        return None
    x = ctypes.cdll.LoadLibrary(name)
    vp, ul, ui = ctypes.c_void_p, ctypes.c_ulong, ctypes.c_uint
    x.XOpenDisplay.restype, x.XOpenDisplay.argtypes = vp, [ctypes.c_char_p]
    x.XCloseDisplay.argtypes = [vp]
    x.XDefaultRootWindow.restype, x.XDefaultRootWindow.argtypes = ul, [vp]
    x.XQueryExtension.argtypes = [vp, ctypes.c_char_p] + [ctypes.POINTER(ctypes.c_int)] * 3
    x.XQueryTree.argtypes = [vp, ul, ctypes.POINTER(ul), ctypes.POINTER(ul), ctypes.POINTER(ctypes.POINTER(ul)),
                             ctypes.POINTER(ui)]
    x.XFetchName.argtypes = [vp, ul, ctypes.POINTER(ctypes.c_char_p)]
    x.XFree.argtypes = [vp]
    x.XGetWindowAttributes.argtypes = [vp, ul, ctypes.POINTER(_XWindowAttributes)]
    x.XTranslateCoordinates.argtypes = [vp, ul, ul, ctypes.c_int, ctypes.c_int, ctypes.POINTER(ctypes.c_int),
                                        ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ul)]
    return x


def _display_problem() -> str | None:
    """Why the live viewer cannot open here (a clause for :class:`ViewerUnavailable`), or None when it can."""
    if sys.platform in ("darwin", "win32"):
        return None  # GLFW's native back ends; mujoco.viewer reports its own needs (mjpython on macOS)
    if os.environ.get("XDG_SESSION_TYPE") == "wayland" and os.environ.get("WAYLAND_DISPLAY"):
        return None  # the glfw package then loads its Wayland build
    display = os.environ.get("DISPLAY", "")
    if not display:
        return "DISPLAY is not set"
    x = _xlib()
    if x is None:
        return "libX11 is not installed"
    dpy = x.XOpenDisplay(display.encode())
    if not dpy:
        return f"cannot open the X display DISPLAY={display}"
    try:
        op, ev, err = ctypes.c_int(), ctypes.c_int(), ctypes.c_int()
        if not x.XQueryExtension(dpy, b"GLX", ctypes.byref(op), ctypes.byref(ev), ctypes.byref(err)):
            return f"the X display DISPLAY={display} has no GLX extension"
    finally:
        x.XCloseDisplay(dpy)
    return None


def display_available() -> bool:
    """True when MuJoCo's viewer can open a window here: a reachable X display with GLX (or a Wayland session)."""
    return _display_problem() is None


def _unavailable(why: str) -> ViewerUnavailable:
    return ViewerUnavailable(f"No display for the live viewer ({why}); {_HINT}")


# ---- the window on the X screen (screenshots) ----------------------------------------------------------------

def find_window(title_prefix: str = "MuJoCo") -> tuple[int, int, int, int] | None:
    """``(x, y, width, height)`` in screen pixels of the first viewable X window whose title starts with
    ``title_prefix`` (MuJoCo's viewer is titled ``MuJoCo : <model>``), or None (no X display, no such window)."""
    display = os.environ.get("DISPLAY", "")
    x = _xlib() if display else None
    dpy = x.XOpenDisplay(display.encode()) if x is not None else None
    if not dpy:
        return None
    ul = ctypes.c_ulong
    try:
        root = x.XDefaultRootWindow(dpy)
        todo = [root]
        while todo:
            w = todo.pop(0)
            name = ctypes.c_char_p()
            if w != root and x.XFetchName(dpy, w, ctypes.byref(name)) and name.value is not None:
                title = name.value.decode(errors="replace")
                x.XFree(name)
                attrs = _XWindowAttributes()
                if title.startswith(title_prefix) and x.XGetWindowAttributes(dpy, w, ctypes.byref(attrs)) \
                        and attrs.map_state == 2:  # IsViewable
                    ox, oy, child = ctypes.c_int(), ctypes.c_int(), ul()
                    x.XTranslateCoordinates(dpy, w, root, 0, 0, ctypes.byref(ox), ctypes.byref(oy),
                                            ctypes.byref(child))
                    return ox.value, oy.value, attrs.width, attrs.height
            r, p, kids, n = ul(), ul(), ctypes.POINTER(ul)(), ctypes.c_uint()
            if x.XQueryTree(dpy, w, ctypes.byref(r), ctypes.byref(p), ctypes.byref(kids), ctypes.byref(n)):
                todo.extend(kids[i] for i in range(n.value))
                if kids:
                    x.XFree(kids)
    finally:
        x.XCloseDisplay(dpy)
    return None


def grab_screen(box: tuple[int, int, int, int] | None = None):
    """A PIL image of what the X screen (``DISPLAY``) shows inside ``box = (x, y, width, height)``, e.g. a window
    :func:`find_window` found, or the whole screen (``box=None``). Raises ViewerUnavailable when the screen cannot be
    read."""
    display = os.environ.get("DISPLAY", "")
    try:
        screen = ImageGrab.grab(xdisplay=display or None)
    except Exception as exc:  # Pillow without XCB, a Wayland session...
        raise ViewerUnavailable("Cannot read the screen for a screenshot of the viewer "
                                f"({first_line(exc, FOREIGN_WIDTH)}); "
                                "run under X (DISPLAY, e.g. `xvfb-run`).") from None
    if box is None:
        return screen
    x0, y0, w, h = box
    x0, y0 = max(0, x0), max(0, y0)
    x1, y1 = min(screen.width, x0 + w), min(screen.height, y0 + h)
    return screen.crop((x0, y0, x1, y1)) if x1 > x0 and y1 > y0 else screen


# ---- the hook: pacing, frames, closing ---------------------------------------------------------------------

class LiveViewer:
    """MuJoCo's passive viewer driven from a physics loop: call ``view(m, d)`` after every ``mj_step``.

    The first call opens the window (``mujoco.viewer.launch_passive``); each call then sleeps so that ``d.time``
    tracks wall time (``realtime=True``) and, at most :data:`MAX_FPS` times a second, hands the viewer a frame.
    Around each ``sync`` the integration state (``mj_getState``, ``mjSTATE_INTEGRATION``: qpos, qvel, ctrl, applied
    forces, warm start, time...) is saved and put back, so what the user does in the window never changes the run.
    Returns False once the window has been closed: the loop should stop there.

    Parameters
    ----------
    realtime : bool
        Sleep so simulated time tracks wall time (default); False runs as fast as the loop goes.
    show_ui : bool
        Show MuJoCo's side panels (default hidden; Tab / Shift+Tab toggle them in the window).
    camera : str or None
        Camera the window starts on; default the MJCF's ``track`` camera when it has one, else the free camera.

    Attributes
    ----------
    frames : int
        Frames handed to the viewer.
    closed : bool
        The user closed the window before the loop ended.
    wall_time : float, s
        Wall time from the window opening to the last call.
    """

    def __init__(self, *, realtime: bool = True, show_ui: bool = False, camera: str | None = None):
        self.realtime = bool(realtime)
        self.show_ui = bool(show_ui)
        self.camera = camera
        self.frames = 0
        self.closed = False
        self.wall_time = 0.0
        self._viewer = None
        self._thread = None
        self._opened = False
        self._anchor = 0.0     # wall time at which d.time == self._t0 (moved on when the run falls behind)
        self._opened_at = 0.0
        self._t0 = 0.0
        self._next_frame = 0.0
        self._state = None
        self._spec = None
        self._md = None

    # -- window ------------------------------------------------------------------------------------------------
    def open(self, m, d) -> None:
        """Open the window on ``(m, d)`` (done by the first call). Raises ViewerUnavailable without a display."""
        why = _display_problem()
        if why is not None:
            raise _unavailable(why)
        try:
            import mujoco.viewer
        except Exception as exc:  # no glfw wheel, no libglfw handle
            raise _unavailable(f"mujoco.viewer cannot load GLFW: {first_line(exc, FOREIGN_WIDTH)}") from None
        before = set(threading.enumerate())
        got: list = []
        opener = threading.Thread(target=lambda: got.append(mujoco.viewer.launch_passive(
            m, d, show_left_ui=self.show_ui, show_right_ui=self.show_ui)), daemon=True)
        opener.start()
        opener.join(OPEN_TIMEOUT)
        if not got:
            raise ViewerUnavailable(f"The live viewer window did not open within {OPEN_TIMEOUT:.0f} s; "
                                    f"{_HINT}")
        self._viewer = got[0]
        self._opened = True
        new = [t for t in set(threading.enumerate()) - before if t is not opener and "_launch_internal" in t.name]
        self._thread = new[0] if new else None
        cam = self.camera if self.camera is not None else "track"
        cam_id = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, cam)
        if cam_id >= 0:
            with self._viewer.lock():
                self._viewer.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
                self._viewer.cam.fixedcamid = cam_id
        elif self.camera is not None:
            self.close()
            raise ViewerUnavailable(f"The MJCF has no camera named '{self.camera}'; pass camera=None for the "
                                    "default view.")
        self._spec = mujoco.mjtState.mjSTATE_INTEGRATION
        self._state = np.empty(mujoco.mj_stateSize(m, self._spec))
        self._sync(m, d)
        self._anchor = self._opened_at = time.perf_counter()
        self._t0 = float(d.time)
        self._next_frame = self._anchor + 1.0 / MAX_FPS

    def _sync(self, m, d) -> None:
        mujoco.mj_getState(m, d, self._state, self._spec)
        self._viewer.sync()
        mujoco.mj_setState(m, d, self._state, self._spec)
        self.frames += 1

    @property
    def is_running(self) -> bool:
        """The window is open."""
        return self._viewer is not None and self._viewer.is_running()

    def __call__(self, m, d) -> bool:
        """After one physics step: pace, maybe draw. False when the window is closed (stop the loop)."""
        self._md = (m, d)
        if self._viewer is None:
            if self._opened:  # closed already
                return False
            self.open(m, d)
        now = time.perf_counter()
        if now >= self._next_frame:
            if not self._viewer.is_running():
                self.closed = True
                return False
            self._sync(m, d)
            self._next_frame = now + 1.0 / MAX_FPS
        if self.realtime:
            ahead = (float(d.time) - self._t0) - (now - self._anchor)
            if ahead > 1e-3:
                time.sleep(ahead)
            elif ahead < -MAX_LAG:  # the controller is slower than real time: show it slow, do not rush
                self._anchor = now - (float(d.time) - self._t0)
        self.wall_time = time.perf_counter() - self._opened_at
        return True

    def finish(self, m=None, d=None, *, settle: float = 0.0) -> None:
        """Draw the last state (and wait ``settle`` s so the window shows it, e.g. before a screenshot); ``m, d``
        default to those of the last call."""
        if m is None or d is None:
            if self._md is None:
                return
            m, d = self._md
        if self.realtime and self._viewer is not None:
            ahead = (float(d.time) - self._t0) - (time.perf_counter() - self._anchor)
            if ahead > 0:
                time.sleep(ahead)
        if self.is_running:
            self._sync(m, d)
            if settle > 0:
                time.sleep(settle)
        elif self._viewer is not None:
            self.closed = True
        if self._viewer is not None:
            self.wall_time = time.perf_counter() - self._opened_at

    def close(self) -> None:
        """Close the window and wait for the viewer's thread to end (leaving it running can crash the exit).

        GLFW itself stays initialised (MuJoCo's viewer registers ``glfw.terminate`` at exit; terminating it earlier
        makes the next window in the same process abort), so its X connection lives until the interpreter exits.
        """
        viewer, self._viewer = self._viewer, None
        if viewer is None:
            return
        viewer.close()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# ---- the run ----------------------------------------------------------------------------------------------

def require_display() -> None:
    """Raise :class:`ViewerUnavailable` (one sentence) unless a display the viewer can open is there."""
    why = _display_problem()
    if why is not None:
        raise _unavailable(why)


def watch(plant: Plant, controller: Callable, x0, duration: float, *,
          push: Callable[[float], float] | None = None, options: SimOptions = SimOptions(), realtime: bool = True,
          screenshot: str | Path | None = None, show_ui: bool = False, camera: str | None = None) -> Rollout:
    """Run ``u = controller(t, x)`` in MuJoCo from ``x0`` for ``duration`` s, live in MuJoCo's viewer.

    The physics and the log are :func:`~cartpole.sim.rollout.simulate`'s: same start (``qpos``, ``qvel``, ``time =
    0``, ``mj_forward``), ctrl clipped to ``ctrlrange`` and held for ``options.control_period``, every physics step
    logged, so
    the rollout replays exactly with :func:`~cartpole.sim.rollout.replays_exactly` (unless ``push`` is given: replay
    does not apply pushes). Closing the window ends the run early; the rollout then holds the steps done.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole MuJoCo runs (None = shipped asset).
    controller : callable
        ``controller(t [s], x (nq+nv,)) -> ctrl (nu,)`` (a scalar when nu = 1).
    x0 : (nq+nv,) array
        Start state ``[qpos, qvel]`` in MuJoCo's order.
    duration : float, s
        Simulated time; rounded to whole physics steps.
    push : callable, optional
        ``push(t [s]) -> force [N]``: world-x force on the cart body during the step from ``t``; logged as
        ``rollout.info["push"]`` (n,).
    options : SimOptions, optional
        As :func:`~cartpole.sim.rollout.simulate`'s: the control period (held ctrl, whole physics steps; default
        every physics step), ``stop(t, x) -> bool`` ending the run early (after logging that state), ``progress``,
        and an ``on_step`` hook called after the viewer's own (either returning False ends the run).
    realtime : bool
        Sleep so simulated time tracks wall time (default True); False runs as fast as possible, still drawn.
    screenshot : str or Path, optional
        After the run, save a PNG of the viewer window as the X screen shows it (written whole or not at all); the
        path, or None when the window was closed first, is ``rollout.info["screenshot"]``, and the window's
        ``(x, y, width, height)`` on the screen ``rollout.info["window"]``.
    show_ui : bool
        Show MuJoCo's side panels (default hidden).
    camera : str, optional
        Camera the window starts on (default the MJCF's ``track`` camera, if any).

    Returns
    -------
    Rollout
        ``t`` (n+1,), ``qpos`` (n+1, nq), ``qvel`` (n+1, nv), ``ctrl`` (n, nu); ``info`` has ``viewer`` (True),
        ``closed_early`` (bool), ``frames`` (frames drawn), ``wall_time`` (s), ``screenshot``, ``window`` and
        ``push`` (with a push only).

    Raises
    ------
    ViewerUnavailable
        No display (checked before MuJoCo is touched): one sentence, the caller can run :func:`simulate` instead.
    CartPoleError
        Bad start state or duration, a controller returning the wrong shape or NaN, an unstable run.

    Notes
    -----
    The run is :func:`~cartpole.sim.rollout.simulate` with the hook :class:`LiveViewer` as its ``on_step``.
    """
    require_display()
    view = LiveViewer(realtime=realtime, show_ui=show_ui, camera=camera)
    shot = window = None
    try:
        run = simulate(plant, controller, x0, duration, push=push, options=options.replace(
            on_step=view if options.on_step is None else _both(view, options.on_step)))
        view.finish(settle=0.3 if screenshot is not None else 0.0)
        if screenshot is not None and view.is_running:
            window = find_window("MuJoCo")
            image = grab_screen(window)
            shot = atomic_write(screenshot, lambda fh: image.save(fh, format="PNG"))
    finally:
        view.close()
    run.info.update({"viewer": True, "closed_early": view.closed, "frames": view.frames,
                     "wall_time": view.wall_time, "screenshot": None if shot is None else str(shot),
                     "window": window})
    return run


def _both(first, then):
    """An ``on_step(m, d)`` hook calling ``first`` and then ``then``; False (the run ends) when either says so."""
    def on_step(m, d):
        shown = first(m, d)
        return not (then(m, d) is False or shown is False)
    return on_step
