"""Headless Chromium driven over the Chrome DevTools Protocol (CDP), for the web viewer's tests.

Plain CDP over a WebSocket (``websockets``' synchronous client, already installed with MuJoCo Studio): no browser
driver to match to the browser's version. Chromium is Debian's (``/usr/bin/chromium``), started with the flags the
closed network here needs (no background networking, component updates, sync or QUIC) and a fresh profile.
"""
from __future__ import annotations

import base64
import itertools
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")


def find_chromium() -> str | None:
    """The path of a Chromium binary, or None (``CARTPOLE_CHROMIUM`` first, then Debian's and the usual names)."""
    env = os.environ.get("CARTPOLE_CHROMIUM")
    for path in ((env,) if env else ()) + CHROMIUM_CANDIDATES:
        if path and os.access(path, os.X_OK):
            return path
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


class Chromium:
    """One headless Chromium with one page, driven over CDP: ``goto``, ``screenshot``, ``click``, ``drag``."""

    def __init__(self, binary: str, *, width: int = 1200, height: int = 800, timeout: float = 30.0):
        from websockets.sync.client import connect

        self._profile = tempfile.mkdtemp(prefix="cartpole-chromium-")
        args = [binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-dev-shm-usage", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
                f"--user-data-dir={self._profile}", f"--window-size={width},{height}",
                "--remote-debugging-port=0", "--remote-allow-origins=*", "about:blank"]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = Path(self._profile) / "DevToolsActivePort"
        deadline = time.monotonic() + timeout
        while not (port_file.exists() and port_file.read_text().strip()):
            if time.monotonic() > deadline or self.proc.poll() is not None:
                self.close()
                raise RuntimeError("Chromium did not start its DevTools endpoint")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        targets = json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/json", timeout=10).read())
        page = next(t for t in targets if t.get("type") == "page")
        self._conn = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=timeout)
        self._ws = self._conn.__enter__()
        self._ids = itertools.count(1)
        self.width, self.height = width, height
        self.console: list[str] = []
        self.call("Runtime.enable")
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1,
                  mobile=False)

    def call(self, method: str, timeout: float = 30.0, **params):
        """Send one CDP command and return its result (events arriving meanwhile are dropped)."""
        ident = next(self._ids)
        self._ws.send(json.dumps({"id": ident, "method": method, "params": params}))
        deadline = time.monotonic() + timeout
        while True:
            msg = json.loads(self._ws.recv(timeout=max(0.1, deadline - time.monotonic())))
            self._note(msg)
            if msg.get("id") == ident:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def _note(self, msg: dict) -> None:
        if msg.get("method") == "Runtime.consoleAPICalled":
            self.console.append(" ".join(str(a.get("value", a.get("description", "")))
                                         for a in msg["params"].get("args", [])))

    def wait_console(self, text: str, timeout: float) -> bool:
        """Wait until the page's console has printed a line containing ``text``; False after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while not any(text in line for line in self.console):
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            try:
                self._note(json.loads(self._ws.recv(timeout=min(1.0, left))))
            except TimeoutError:
                pass
        return True

    def goto(self, url: str) -> None:
        """Open ``url`` in the page."""
        self.call("Page.navigate", url=url)

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page."""
        res = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return res.get("result", {}).get("value")

    def screenshot(self) -> bytes:
        """A PNG of the page as it is drawn now."""
        return base64.b64decode(self.call("Page.captureScreenshot", timeout=120.0, format="png")["data"])

    def _mouse(self, kind: str, x: float, y: float, buttons: int) -> None:
        self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left" if kind != "mouseMoved" or buttons
                  else "none", buttons=buttons, clickCount=1 if kind != "mouseMoved" else 0)

    def click(self, x: float, y: float, hold: float = 0.15) -> None:
        """Move to ``(x, y)`` (CSS pixels), press the left button, hold, release."""
        self._mouse("mouseMoved", x, y, 0)
        time.sleep(0.1)
        self._mouse("mousePressed", x, y, 1)
        time.sleep(hold)
        self._mouse("mouseReleased", x, y, 0)

    def drag(self, x0: float, y0: float, x1: float, y1: float, steps: int = 8, hold: float = 0.1) -> None:
        """Press at ``(x0, y0)``, move in ``steps`` to ``(x1, y1)``, hold ``hold`` s, release there."""
        self._mouse("mouseMoved", x0, y0, 0)
        time.sleep(0.1)
        self._mouse("mousePressed", x0, y0, 1)
        time.sleep(0.1)
        for i in range(1, steps + 1):
            self._mouse("mouseMoved", x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * i / steps, 1)
            time.sleep(0.05)
        time.sleep(hold)
        self._mouse("mouseReleased", x1, y1, 0)

    def close(self) -> None:
        """Close the page's connection, stop Chromium and remove its profile."""
        try:
            self._conn.__exit__(None, None, None)
        except Exception:
            pass
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
