"""``cartpole lqr --view web``: the run live in MuJoCo Studio's web viewer, opened in headless Chromium, pushed and
tuned through the page, logged in the JSON's ``live`` and replayed exactly; and the refusals (a port in use, a bad
``--live-seconds``) as one sentence with exit status 2."""
from __future__ import annotations

import io
import json
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "viz"))
from chromium import Chromium, find_chromium  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
DOCS_SHOT = ROOT / "docs" / "img" / "live.png"
#: Seconds the page may take to come up on a loaded machine with software WebGL (measured: 20-40 s on 2 shared cores).
PAGE_TIMEOUT = 180.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(tmp_path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT), MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"),
               CARTPOLE_WEB_WIDGETS=str(tmp_path / "widgets.json"))
    env.pop("DISPLAY", None)
    return env


def _run_cli(tmp_path, *args):
    return subprocess.run([sys.executable, "-m", "cartpole", "lqr", "--no-video", "--json", "--out",
                           str(tmp_path / "out"), *args], capture_output=True, text=True, env=_env(tmp_path),
                          timeout=300)


def test_a_port_in_use_is_one_sentence_and_exit_2(tmp_path):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        res = _run_cli(tmp_path, "--view", "web", "--port", str(port))
    assert res.returncode == 2
    assert res.stdout == ""
    line = res.stderr.strip()
    assert "\n" not in line and "Traceback" not in line
    assert f"--port {port}" in line and "in use" in line
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.csv"))


def test_a_bad_live_length_is_one_sentence_and_exit_2(tmp_path):
    res = _run_cli(tmp_path, "--view", "web", "--live-seconds", "0")
    assert res.returncode == 2
    assert "--live-seconds" in res.stderr and "Traceback" not in res.stderr
    res = _run_cli(tmp_path, "--view", "web", "--live-seconds", "1e9")  # too long a log to hold: refused, not run
    assert res.returncode == 2 and res.stdout == ""
    assert "the live run of 1e+09 s" in res.stderr and "Traceback" not in res.stderr


def test_view_alone_without_a_display_chooses_the_page_and_says_so(tmp_path):
    with socket.socket() as busy:  # a taken port ends the command right after the choice is said
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        res = _run_cli(tmp_path, "--view", "--port", str(busy.getsockname()[1]))
    assert "no display here, so the web page" in res.stderr
    assert res.returncode == 2


def _colour_mask(img, rgb):
    """Pixels whose colour is dominated by the channel that dominates ``rgb`` (a model colour, shaded by light)."""
    main = int(np.argmax(rgb))
    a, b = [c for c in range(3) if c != main]
    return (img[..., main] > 60) & (img[..., main] > 1.8 * img[..., a]) & (img[..., main] > 1.8 * img[..., b])


def _assert_pole_on_cart(png: bytes, colours) -> None:
    """The screenshot shows the cart (a blob in the cart's colour) with the pole standing on it (the pole's colour
    in the columns of the cart, above it); the rail's end stops share the pole's hue but not its place."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
    cart = _colour_mask(img, colours["cart"])
    assert cart.sum() > 150, f"no cart in the screenshot ({int(cart.sum())} pixels of its colour)"
    rows, cols = np.nonzero(cart)
    top, x0, x1 = rows.min(), cols.min(), cols.max()
    pole = _colour_mask(img, colours["pole"])[max(0, top - 300):top + 5, x0:x1 + 1]
    assert pole.sum() > 100, f"no pole on the cart ({int(pole.sum())} pixels of its colour above it)"
    assert pole.any(axis=1).sum() > 30, "the pole's colour above the cart is not a standing pole"


def _model_colours():
    """RGB of the shipped cart's cart and pole geoms, read from the compiled model."""
    import mujoco

    from cartpole.models import SHIPPED_MJCF

    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    out = {}
    for g in range(m.ngeom):
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[g]) or ""
        if body in ("cart", "pole"):
            rgba = m.geom_rgba[g] if m.geom_matid[g] < 0 else m.mat_rgba[m.geom_matid[g]]
            out[body] = np.asarray(rgba[:3], float)
    return out


def _wait_for(predicate, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.5)
    pytest.fail(f"timed out waiting for {what}")


def _panel_drawn(png: bytes, rects) -> bytes | None:
    """``png`` when the page shows the panel (its light background around the push buttons), else None: the page
    draws the UI stream some seconds after it connected."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
    x0, y0, x1, y1 = (int(v) for v in rects["push left"])
    band = img[max(0, y0 - 30):y0 - 2, x0:x1 + 60]
    return png if band.size and band.mean() > 180 else None


def _text_in(png: bytes, rect) -> bytes | None:
    """``png`` when it shows dark text inside ``rect`` (the page draws the UI stream's frames with a lag)."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
    x0, y0, x1, y1 = (int(v) for v in rect)
    box = img[y0:y1 + 1, x0:x1 + 1]
    return png if box.size and (box < 100).mean() > 0.02 else None


def _center(rect, fx: float = 0.5):
    x0, y0, x1, y1 = rect
    return x0 + fx * (x1 - x0), 0.5 * (y0 + y1)


@pytest.mark.slow  # a browser rendering WebGL in software: 40 s to 3 min here, with the page's own start
def test_lqr_view_web_in_chromium_shows_pushes_tunes_and_replays(tmp_path):
    binary = find_chromium()
    if binary is None:
        pytest.skip("Chromium is not installed (apt-get install chromium chromium-driver; .ci/run does it)")
    port = _free_port()
    widgets = tmp_path / "widgets.json"
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "cartpole", "lqr", "--no-video", "--json", "--out", str(out),
                             "--view", "web", "--port", str(port), "--live-seconds", "300"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(tmp_path))
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(proc.stderr.readline, "")), daemon=True)
    reader.start()
    try:
        _wait_for(lambda: any("waiting for a browser" in line for line in err), 240, "the live run to wait")
        with Chromium(binary, width=1100, height=900) as page:
            page.goto(f"http://localhost:{port}/")
            assert page.wait_console("Connected to Studio UI host", PAGE_TIMEOUT), page.console[-5:]
            assert page.wait_console("Model loaded", PAGE_TIMEOUT), page.console[-5:]
            rects = _wait_for(lambda: widgets.exists() and "push right" in (w := _read(widgets)) and w, 60,
                              "the panel's widgets")
            shot = _wait_for(lambda: _panel_drawn(page.screenshot(), rects), PAGE_TIMEOUT, "the panel drawn")
            (tmp_path / "live.png").write_bytes(shot)
            _assert_pole_on_cart(shot, _model_colours())
            page.click(*_center(rects["push right"]), hold=1.0)
            _wait_for(lambda: _read(widgets).get("events shown", [0])[0] >= 1, PAGE_TIMEOUT, "the push listed")
            knob = "Q hinge"
            page.drag(*_center(rects[knob], 0.5), *_center(rects[knob], 0.85))
            _wait_for(lambda: _read(widgets).get("events shown", [0])[0] >= 2, PAGE_TIMEOUT, "the weight listed")
            if os.environ.get("CARTPOLE_DOCS_SCREENSHOT"):  # the page once it draws the weight's event line
                last = _read(widgets)["last event"]
                shot = _wait_for(lambda: _text_in(page.screenshot(), last), PAGE_TIMEOUT, "the page to catch up")
                DOCS_SHOT.parent.mkdir(parents=True, exist_ok=True)
                DOCS_SHOT.write_bytes(shot)
            # the drag slider: held a little right of its middle (0 N) it pushes (a few N: the LQR holds the pole; a
            # mouse move through CDP takes seconds of the real-time run here), released it springs back to 0
            drag = rects["drag to push [N]"]
            page.drag(*_center(drag, 0.5), *_center(drag, 0.56), steps=2, hold=0.3)
            _wait_for(lambda: _read(widgets).get("events shown", [0])[0] >= 4, PAGE_TIMEOUT, "the drag listed")
            shown = _read(widgets)["events shown"][0]
            page.drag(*_center(rects["delay [s]"], 0.0), *_center(rects["delay [s]"], 0.15))
            _wait_for(lambda: _read(widgets).get("events shown", [0])[0] > shown, PAGE_TIMEOUT, "the delay listed")
        stdout = proc.stdout.read()
        proc.wait(120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    reader.join(10)
    (tmp_path / "stderr.txt").write_text("".join(err))
    (tmp_path / "stdout.json").write_text(stdout)
    assert proc.returncode == 0, "".join(err)[-2000:]
    doc = json.loads(stdout)
    live = doc["live"]
    assert live["page_closed"] is True
    kinds = [e["kind"] for e in live["events"]]
    assert "push" in kinds and "knob" in kinds and "drag" in kinds, live["events"]
    drags = [e for e in live["events"] if e["kind"] == "drag"]
    assert drags[0]["force"] > 0 and drags[-1]["force"] == 0.0 and {e["source"] for e in drags} == {"panel"}
    delay = next(e for e in live["events"] if e.get("name") == "delay [s]")
    assert delay["delay"] > 0 and live["loop"]["delay"] == delay["delay"]
    times = [e["t"] for e in live["events"]]
    assert times == sorted(times)
    push = next(e for e in live["events"] if e["kind"] == "push")
    knob_ev = next(e for e in live["events"] if e["kind"] == "knob")
    assert push["force"] > 0
    assert knob_ev["name"] == "Q hinge" and knob_ev["value"] > doc["Q"][1][1]
    assert live["K"] != doc["K"]  # re-designed from the new weight
    forces = np.asarray(live["rollout"]["push"])
    h = live["rollout"]["t"][1] - live["rollout"]["t"][0]
    k = int(round(push["t"] / h))
    assert forces[k] == push["force"]
    pulse = np.count_nonzero(forces[:int(round(drags[0]["t"] / h))])
    assert pulse == int(round(push["seconds"] / h))  # the button's pulse; the drag's force after it
    k0, k1 = (int(round(e["t"] / h)) for e in (drags[0], drags[-1]))
    assert np.all(forces[k0:k1] > 0) and not np.any(forces[k1:])
    assert live["replays"] is True
    from cartpole.sim import replay

    again = replay(doc["mjcf"], np.concatenate([live["rollout"]["qpos"][0], live["rollout"]["qvel"][0]]),
                   np.asarray(live["rollout"]["ctrl"]), push=forces)
    assert np.array_equal(again.qpos, np.asarray(live["rollout"]["qpos"]))
    assert np.array_equal(again.qvel, np.asarray(live["rollout"]["qvel"]))


def _read(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def test_swingup_view_web_starts_with_the_page_and_closing_it_ends_the_run_with_the_steps_kept(tmp_path):
    """The page's state stream (what a browser tab opens) starts the run; closing it ends the run early, the steps
    done logged and replaying exactly; stdout stays the JSON document alone."""
    from websockets.sync.client import connect

    from cartpole.sim import Rollout, replays_exactly

    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "cartpole", "swingup", "--view", "web", "--port", str(port),
                             "--json", "--no-video", "--duration", "60", "--out", str(tmp_path / "out")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(tmp_path))
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(proc.stderr.readline, "")), daemon=True)
    reader.start()
    try:
        _wait_for(lambda: any("waiting for a browser" in line for line in err), 240, "the live run to wait")
        assert any(f"http://localhost:{port}/" in line and "ssh -L 8080:localhost:" in line for line in err)
        with connect(f"ws://127.0.0.1:{port}/state?sid=test", open_timeout=30) as ws:
            t0 = time.monotonic()
            while time.monotonic() - t0 < 2.0:
                try:
                    ws.recv(timeout=0.2)
                except TimeoutError:
                    pass
        stdout = proc.stdout.read()
        proc.wait(120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    reader.join(10)
    assert proc.returncode == 0, "".join(err)[-2000:]
    doc = json.loads(stdout)  # nothing but the document on stdout (Studio's banner went to stderr)
    view = doc["viewer"]
    assert view["url"] == f"http://localhost:{port}/" and view["host"] == "127.0.0.1"
    assert view["page_closed"] is True and view["closed_early"] is True
    ro = doc["rollout"]
    assert 0 < len(ro["ctrl"]) < 60.0 / (ro["t"][1] - ro["t"][0])  # ended early, steps kept
    assert view["steps_shown"] == len(ro["ctrl"])
    run = Rollout(t=ro["t"], qpos=ro["qpos"], qvel=ro["qvel"], ctrl=ro["ctrl"])
    assert replays_exactly(run, doc["mjcf"])


@pytest.mark.slow  # the feedforward study plans first
def test_feedforward_view_web_replays_its_runs_on_the_page_until_it_is_closed(tmp_path):
    """The logged runs replayed on one page (checked identical to the log); closing the page stops the showing and
    the command ends as usual, its JSON on stdout."""
    from websockets.sync.client import connect

    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "cartpole", "feedforward", "--view", "web", "--port", str(port),
                             "--json", "--no-video", "--out", str(tmp_path / "out")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(tmp_path))
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(proc.stderr.readline, "")), daemon=True)
    reader.start()
    try:
        _wait_for(lambda: any("waiting for a browser" in line for line in err), 400, "the live run to wait")
        with connect(f"ws://127.0.0.1:{port}/state?sid=test", open_timeout=30) as ws:
            t0 = time.monotonic()
            while time.monotonic() - t0 < 1.5:
                try:
                    ws.recv(timeout=0.2)
                except TimeoutError:
                    pass
        stdout = proc.stdout.read()
        proc.wait(300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    reader.join(10)
    assert proc.returncode == 0, "".join(err)[-2000:]
    doc = json.loads(stdout)
    assert doc["runs"] and not any("differs" in line for line in err)


def test_ctrl_c_ends_the_live_run_cleanly_with_the_steps_kept(tmp_path):
    """SIGINT while the page watches: no traceback, exit 0, the JSON says interrupted, the steps done replay."""
    import signal

    from websockets.sync.client import connect

    from cartpole.sim import Rollout, replays_exactly

    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "cartpole", "swingup", "--view", "web", "--port", str(port),
                             "--json", "--no-video", "--duration", "60", "--out", str(tmp_path / "out")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(tmp_path))
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(proc.stderr.readline, "")), daemon=True)
    reader.start()
    try:
        _wait_for(lambda: any("waiting for a browser" in line for line in err), 240, "the live run to wait")
        with connect(f"ws://127.0.0.1:{port}/state?sid=test", open_timeout=30) as ws:
            time.sleep(1.5)
            proc.send_signal(signal.SIGINT)
            stdout = proc.stdout.read()
            proc.wait(120)
            del ws
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    reader.join(10)
    assert proc.returncode == 0 and "Traceback" not in "".join(err), "".join(err)[-2000:]
    doc = json.loads(stdout)
    assert doc["viewer"]["interrupted"] is True and doc["viewer"]["page_closed"] is False
    ro = doc["rollout"]
    assert 0 < len(ro["ctrl"]) < 60.0 / (ro["t"][1] - ro["t"][0])
    assert replays_exactly(Rollout(t=ro["t"], qpos=ro["qpos"], qvel=ro["qvel"], ctrl=ro["ctrl"]), doc["mjcf"])


def test_another_host_than_localhost_is_warned_about_on_stderr(capsys):
    import argparse

    from cartpole.commands._view import view_mode

    args = argparse.Namespace(view="web", port=0, host="0.0.0.0", live_seconds=30.0)
    assert view_mode(args, "lqr") == "web"
    err = capsys.readouterr().err
    assert "warning: --host 0.0.0.0" in err and "no authentication" in err
    args.host = "127.0.0.1"
    assert view_mode(args, "lqr") == "web" and capsys.readouterr().err == ""


def test_excite_view_web_replays_the_logged_experiment_on_the_page(tmp_path):
    """The experiment, once logged, replayed on the page (checked identical to the log) until the page closes; the
    command then ends as usual with its JSON on stdout and its CSV written."""
    from websockets.sync.client import connect

    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "cartpole", "excite", "--view", "web", "--port", str(port),
                             "--json", "--duration", "3", "--out", str(tmp_path / "out")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(tmp_path))
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(proc.stderr.readline, "")), daemon=True)
    reader.start()
    try:
        _wait_for(lambda: any("waiting for a browser" in line for line in err), 240, "the live run to wait")
        with connect(f"ws://127.0.0.1:{port}/state?sid=test", open_timeout=30) as ws:
            t0 = time.monotonic()
            while time.monotonic() - t0 < 1.0:
                try:
                    ws.recv(timeout=0.2)
                except TimeoutError:
                    pass
        stdout = proc.stdout.read()
        proc.wait(120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    reader.join(10)
    assert proc.returncode == 0, "".join(err)[-2000:]
    doc = json.loads(stdout)
    assert Path(doc["excite"]["csv"]).exists() and not any("differs" in line for line in err)


def test_compare_pid_view_web_runs_the_pid_live_after_the_lqr_and_both_replay(tmp_path):
    """``lqr --compare-pid --view web``: the LQR's live run, then the PID's on the same page, each with its tuner's
    final state and loop in the JSON, each replaying exactly."""
    from websockets.sync.client import connect

    from cartpole.sim import replay

    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "cartpole", "lqr", "--no-video", "--json", "--compare-pid",
                             "--out", str(tmp_path / "out"), "--view", "web", "--port", str(port),
                             "--live-seconds", "0.5"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(tmp_path))
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(proc.stderr.readline, "")), daemon=True)
    reader.start()
    try:
        _wait_for(lambda: any("waiting for a browser" in line for line in err), 240, "the live run to wait")
        with connect(f"ws://127.0.0.1:{port}/state?sid=test", open_timeout=30) as ws:
            t0 = time.monotonic()
            while proc.poll() is None and time.monotonic() - t0 < 120:
                try:
                    ws.recv(timeout=0.2)
                except TimeoutError:
                    pass
                except Exception:  # the page was closed by the run's end
                    break
        stdout = proc.stdout.read()
        proc.wait(120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    reader.join(10)
    assert proc.returncode == 0, "".join(err)[-2000:]
    doc = json.loads(stdout)
    live = doc["live"]
    assert live["page_closed"] is False and live["loop"] == {"period": pytest.approx(0.005), "delay": 0.0}
    pid = live["pid"]
    assert pid is not None and pid["replays"] is True and pid["events"] == []
    assert pid["gains"]["kp"] == doc["pid"]["gains"]["kp"]
    ro = pid["rollout"]
    assert len(ro["ctrl"]) == int(round(0.5 / (ro["t"][1] - ro["t"][0])))
    again = replay(doc["mjcf"], np.concatenate([ro["qpos"][0], ro["qvel"][0]]), np.asarray(ro["ctrl"]),
                   push=np.asarray(ro["push"]))
    assert np.array_equal(again.qpos, np.asarray(ro["qpos"]))
    assert not np.array_equal(np.asarray(ro["ctrl"]), np.asarray(live["rollout"]["ctrl"]))  # another law ran
