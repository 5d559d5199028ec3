"""The live viewer: MuJoCo's own window on a virtual X screen, paced in real time, logged so the run replays exactly.

A session fixture starts Xvfb (``-displayfd`` picks a free display, so parallel workers do not collide) unless a
display is already there; the tests point ``DISPLAY`` at it with monkeypatch, so nothing outside this module sees it.
"""
import ctypes
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF
from cartpole.sim import replays_exactly
from cartpole.viz import viewer as viewer_mod
from cartpole.viz.viewer import LiveViewer, ViewerUnavailable, display_available, find_window, watch

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="the viewer tests drive an X server (Linux)")

START = [0.0, 0.2, 0.0, 0.0]  # pole 0.2 rad off upright: LQR has something to do


def _die_with_parent():
    """In the child before exec: SIGTERM it when this test process dies, even by a crash (prctl PR_SET_PDEATHSIG)."""
    ctypes.CDLL(None).prctl(1, signal.SIGTERM)


@pytest.fixture(scope="session")
def x_display():
    """A DISPLAY with GLX for the viewer: the session's own if it has one, else a fresh Xvfb killed afterwards."""
    own = os.environ.get("DISPLAY")
    if own:
        yield own
        return
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb; .ci/run installs it), so no screen for the viewer")
    r, w = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            preexec_fn=_die_with_parent)
    os.close(w)
    number = b""
    deadline = time.monotonic() + 20
    while not number.endswith(b"\n") and time.monotonic() < deadline:
        chunk = os.read(r, 16)
        if not chunk:
            break
        number += chunk
    os.close(r)
    if not number.strip():
        proc.kill()
        pytest.fail("Xvfb did not start (no display number on -displayfd)")
    try:
        yield ":" + number.decode().strip()
    finally:
        if "glfw" in sys.modules:  # drop GLFW's X connection first, or Xlib kills this process at exit (XIO error)
            sys.modules["glfw"].terminate()
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()


@pytest.fixture
def screen(x_display, monkeypatch):
    monkeypatch.setenv("DISPLAY", x_display)
    monkeypatch.delenv("XDG_SESSION_TYPE", raising=False)
    assert display_available(), f"DISPLAY={x_display} is up but has no GLX"
    return x_display


@pytest.fixture(scope="module")
def lqr():
    from cartpole.control import LinearFeedback

    return LinearFeedback.for_model(SHIPPED_MJCF)


def _timed(controller):
    """The controller, recording the wall time of each call."""
    calls = []

    def c(t, x):
        calls.append(time.perf_counter())
        return controller(t, x)

    return c, calls


def test_watch_shows_the_cart_in_the_real_window_and_the_run_replays_exactly(screen, lqr, tmp_path):
    shot = tmp_path / "viewer.png"
    run = watch(SHIPPED_MJCF, lqr, START, 1.0, screenshot=shot)
    assert run.ctrl.shape == (200, 1) and run.qpos.shape == (201, 2) and run.t[-1] == pytest.approx(1.0)
    assert replays_exactly(run)
    assert abs(run.qpos[-1, 1]) < abs(START[1])  # the LQR was really in the loop: the pole came back up
    assert not run.info["closed_early"] and run.info["frames"] >= 10
    # the picture is the X screen inside the window titled "MuJoCo : cartpole", not an offscreen render
    x, y, w, h = run.info["window"]
    assert w >= 320 and h >= 240 and run.info["screenshot"] == str(shot)
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    assert img.shape[:2] == (h, w)
    lit = (img.max(axis=2) > 30).mean()
    red = (img[..., 0] > img[..., 1] + 60) & (img[..., 0] > img[..., 2] + 60)
    assert lit > 0.05, f"only {lit:.1%} of the window is not black"
    assert red.sum() >= 100, "the pole's red is not in the window"
    assert find_window("MuJoCo") is None  # and the window is gone once watch returns


def test_without_a_display_watch_refuses_in_one_sentence_before_touching_mujoco(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("XDG_SESSION_TYPE", raising=False)
    monkeypatch.setattr(viewer_mod, "simulate", lambda *a, **k: pytest.fail("watch touched MuJoCo"))
    assert not display_available()
    with pytest.raises(ViewerUnavailable) as err:
        watch(SHIPPED_MJCF, lambda t, x: np.zeros(1), START, 1.0)
    msg = str(err.value)
    assert "DISPLAY is not set" in msg and "xvfb-run" in msg
    assert "\n" not in msg and "Traceback" not in msg and msg.endswith(".") and msg.count(". ") == 0


def test_a_display_nobody_serves_is_refused_instead_of_ending_the_process(monkeypatch):
    """GLFW failing inside the viewer's thread makes MuJoCo exit the process; the display is checked first."""
    free = next(n for n in range(590, 690) if not os.path.exists(f"/tmp/.X11-unix/X{n}")
                and not os.path.exists(f"/tmp/.X{n}-lock"))
    monkeypatch.setenv("DISPLAY", f":{free}")
    monkeypatch.delenv("XDG_SESSION_TYPE", raising=False)
    with pytest.raises(ViewerUnavailable, match=f"cannot open the X display DISPLAY=:{free}"):
        watch(SHIPPED_MJCF, lambda t, x: np.zeros(1), START, 0.1)


def test_one_second_of_simulation_takes_a_second_of_wall_time(screen, lqr):
    paced, calls = _timed(lqr)
    run = watch(SHIPPED_MJCF, paced, START, 1.0)
    span = calls[-1] - calls[0]  # first to last control step: 0.995 s of simulated time
    assert span >= 0.9 * run.t[-2], f"1 s of simulation took {span:.2f} s of wall time"
    # the sleeping is the viewer's pacing, not the machine being slow: unpaced, the same run is quicker
    fast, calls_fast = _timed(lqr)
    again = watch(SHIPPED_MJCF, fast, START, 1.0, realtime=False)
    assert calls_fast[-1] - calls_fast[0] < 0.9 * span
    np.testing.assert_array_equal(again.x, run.x)  # pacing changes nothing in the physics


def test_closing_the_window_ends_the_run_early_and_the_log_still_replays(screen, lqr, monkeypatch):
    import mujoco.viewer

    handles = []
    launch = mujoco.viewer.launch_passive
    monkeypatch.setattr(mujoco.viewer, "launch_passive", lambda *a, **k: handles.append(launch(*a, **k)) or handles[-1])

    def closes_at_half_a_second(t, x):
        if t >= 0.5 and handles[0].is_running():
            handles[0].close()  # what the window's close button does: the viewer's exit request
        return lqr(t, x)

    run = watch(SHIPPED_MJCF, closes_at_half_a_second, START, 3.0)
    assert run.info["closed_early"] and 0.5 <= run.t[-1] < 1.0
    assert replays_exactly(run)


def test_what_the_user_does_in_the_window_does_not_change_the_run(screen, lqr, monkeypatch):
    """A sync that edits the state (slider, Reset, mouse drag) is undone: the log is the controller's alone."""
    real_sync = LiveViewer._sync

    def meddling_sync(self, m, d):
        orig = self._viewer.sync

        def sync(*a, **k):
            orig(*a, **k)
            d.qpos[1] += 0.3          # a joint slider
            d.xfrc_applied[2, 0] = 5  # a mouse perturbation on the pole
            d.ctrl[0] = -1.0
        self._viewer.sync = sync
        try:
            real_sync(self, m, d)
        finally:
            self._viewer.sync = orig

    monkeypatch.setattr(LiveViewer, "_sync", meddling_sync)
    run = watch(SHIPPED_MJCF, lqr, START, 0.5)  # real time: frames all through the run, each one meddled with
    assert run.info["frames"] >= 10 and replays_exactly(run)


def test_a_push_is_a_world_x_force_on_the_cart_and_is_logged(screen):
    still = [0.0, 0.0, 0.0, 0.0]
    run = watch(SHIPPED_MJCF, lambda t, x: np.zeros(1), still, 0.2, realtime=False,
                push=lambda t: 2.0 if t < 0.1 else 0.0)
    push = run.info["push"]
    assert push.shape == (40,) and push[:20].tolist() == [2.0] * 20 and not push[20:].any()
    assert run.qvel[-1, 0] > 0.1  # 2 N for 0.1 s on about 1.1 kg: the cart moves off to +x


def test_the_egl_offscreen_renderer_works_beside_the_viewer_in_one_process(screen, lqr):
    """The viewer draws through GLFW/GLX whatever MUJOCO_GL says; the offscreen renderer keeps its EGL context."""
    import mujoco

    from cartpole.sim import make_mujoco

    assert os.environ.get("MUJOCO_GL") == "egl"
    m, d = make_mujoco(SHIPPED_MJCF)
    d.qpos[:] = START[:2]
    mujoco.mj_forward(m, d)

    def frame():
        with mujoco.Renderer(m, height=120, width=160) as r:
            r.update_scene(d, camera="track")
            return r.render().copy()

    before = frame()
    watch(SHIPPED_MJCF, lqr, START, 0.2, realtime=False)
    after = frame()
    assert before.std() > 0
    np.testing.assert_array_equal(after, before)
