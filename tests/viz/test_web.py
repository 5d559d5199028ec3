"""cartpole.viz.web without a browser: Studio's web viewer serves the run on 127.0.0.1 only, keeps stdout clean, the
page's pushes become pulses in the rollout's push column and the run replays exactly; a taken port is one sentence."""
from __future__ import annotations

import socket
import urllib.request

import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF
from cartpole.sim import SimOptions, replays_exactly, simulate
from cartpole.viz.web import PUSH_SECONDS, WebLive, WebUnavailable, port_free


def _zero(t, x):
    return np.zeros(1)


def _free_port() -> int:
    """A port the OS has just handed out (the default, the first free one from 8080, races another test worker)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_run_served_headless_logs_the_pages_push_and_replays(capsys):
    live = WebLive(wait=False, realtime=False, port=_free_port())
    served = {}

    def on_step(m, d):
        going = live(m, d)
        k = int(round(d.time / m.opt.timestep))
        if k == 1:
            served["page"] = urllib.request.urlopen(live.url, timeout=30).status
            served["lan"] = _reachable_off_loopback(live.port)
            live._push_from_page(7.5)  # what the panel's push button sends, received on the sim thread
        return going

    try:
        run = simulate(SHIPPED_MJCF, _zero, np.zeros(4), 0.3, push=live.push, options=SimOptions(on_step=on_step))
    finally:
        live.close()
    assert capsys.readouterr().out == ""  # Studio's banner went to stderr
    assert served["page"] == 200 and served["lan"] is False
    h = run.t[1] - run.t[0]
    forces = run.info["push"]
    assert np.count_nonzero(forces) == int(round(PUSH_SECONDS / h))
    assert set(forces[forces != 0]) == {7.5}
    assert [e["kind"] for e in live.events] == ["push"] and live.events[0]["force"] == 7.5
    assert replays_exactly(run)
    assert live.frames > 0


def _reachable_off_loopback(port: int) -> bool:
    """Can the port be reached on this machine's own non-loopback address (None when it has none)?"""
    try:
        addr = socket.gethostbyname(socket.gethostname())
    except OSError:
        return None
    if addr.startswith("127."):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.connect(("10.255.255.255", 1))
                addr = s.getsockname()[0]
            except OSError:
                return None
    if addr.startswith("127."):
        return None
    with socket.socket() as s:
        s.settimeout(2)
        return s.connect_ex((addr, port)) == 0


def test_a_taken_port_is_one_sentence():
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        assert not port_free("127.0.0.1", port)
        live = WebLive(port=port, wait=False)
        with pytest.raises(WebUnavailable, match=f"Port {port} on 127.0.0.1 is in use"):
            simulate(SHIPPED_MJCF, _zero, np.zeros(4), 0.01, options=SimOptions(on_step=live))
        live.close()


def test_a_drag_from_the_page_holds_its_force_until_released_and_replays():
    live = WebLive(wait=False, realtime=False, port=_free_port())
    schedule = {"drag": 12.0}

    def on_step(m, d):
        going = live(m, d)
        k = int(round(d.time / m.opt.timestep))
        if k == 10:
            live._drag_from_page(schedule["drag"], "panel")  # the slider held at +12 N
        elif k == 40:
            live._drag_from_page(0.0, "panel")  # released
        return going

    try:
        run = simulate(SHIPPED_MJCF, _zero, np.zeros(4), 0.3, push=live.attach(None),
                       options=SimOptions(on_step=on_step))
    finally:
        live.close()
    forces = run.info["push"]
    assert [(e["kind"], e["force"], e["source"]) for e in live.events] == [("drag", 12.0, "panel"),
                                                                          ("drag", 0.0, "panel")]
    on = np.flatnonzero(forces)
    assert set(forces[on]) == {12.0} and len(on) == 30  # from the step after k = 10 to the one after k = 40
    assert run.t[on[0]] == live.events[0]["t"]
    assert {e["run"] for e in live.events} == {1}  # the first run on this page
    assert replays_exactly(run)


def test_attach_adds_the_pages_pushes_to_a_scheduled_push_and_shows_the_law():
    live = WebLive(wait=False, realtime=False, port=_free_port(),
                   describe=lambda c, t, x: [f"law {c.__name__}"])
    push = live.attach(_zero, push=lambda t: 3.0 if t < 0.05 else 0.0)
    live._push_from_page(-5.0)
    forces = [push(k * 0.002) for k in range(100)]
    assert forces[0] == -2.0 and forces[30] == -5.0 and forces[99] == 0.0  # 0.1 s of page push, 0.05 s scheduled
    live._t_now, live._x_now = 0.0, np.zeros(4)
    assert "law _zero" in live._status().lines
    live.close()


class _FakeImGui:
    """ImGui and ImPlot as the panel's drawing steps call them: every button clicked, every slider at the value
    ``slide`` gives (or unchanged), the item active while ``active``; the plots drawn are recorded."""

    def __init__(self, slide=None, active=False, released=False):
        self.slide, self.active, self.released, self.lines = slide or {}, active, released, []

    def SliderFloat(self, name, value, *a):
        return name in self.slide, self.slide.get(name, value)

    def Button(self, name):
        return True

    def IsItemActive(self):
        return self.active

    def IsItemDeactivatedAfterEdit(self):
        return self.released

    def BeginPlot(self, *a):
        return True

    def PlotLine(self, name, t, ys):
        self.lines.append((name, list(ys)))

    def __getattr__(self, name):  # SameLine, SetupAxes, SetupAxisLimits, EndPlot ...
        return lambda *a, **k: None


def _panel():
    from types import SimpleNamespace

    sent = []
    panel = SimpleNamespace(force=10.0, drag=0.0, drag_sent=0.0, values={}, widgets={},
                            viewer=SimpleNamespace(send_to_sim=sent.append))
    panel._rect = lambda name: panel.widgets.__setitem__(name, True)
    messages = SimpleNamespace(PushEvent=lambda force: ("push", force), DragEvent=lambda force: ("drag", force),
                               KnobEvent=lambda name, value: ("knob", name, value))
    return panel, messages, sent


def test_the_panels_drawing_steps_send_pushes_drags_and_knob_values_and_plot_each_series():
    from types import SimpleNamespace

    from cartpole.viz.web import _draw_knobs, _draw_plots, _draw_push

    panel, M, sent = _panel()
    _draw_push(panel, _FakeImGui(slide={"push force [N]": 12.0}), M)
    assert sent == [("push", -12.0), ("push", 12.0)] and {"push left", "push right"} <= set(panel.widgets)
    sent.clear()
    _draw_push(panel, _FakeImGui(slide={"drag to push [N]": 30.0}, active=True), M)  # held: its force sent once
    _draw_push(panel, _FakeImGui(), M)  # released: back to zero
    assert [s for s in sent if s[0] == "drag"] == [("drag", 30.0), ("drag", 0.0)] and panel.drag == 0.0
    status = SimpleNamespace(t=[0.0, 0.1], names=["hinge", "ctrl motor"], series=[[1.0, 0.5], [2.0, -0.5]],
                             ctrl_range=[(-1.0, 1.0)], knobs=[("Q hinge", 10.0, 0.1, 1000.0, True)])
    sent.clear()
    _draw_knobs(panel, _FakeImGui(slide={"Q hinge": 2.0}, released=True), status, M)  # log slider: 10 ** 2
    assert sent == [("knob", "Q hinge", 100.0)]
    im = _FakeImGui()
    _draw_plots(im, im, status)
    assert ("hinge", [1.0, 2.0]) in im.lines and ("ctrl motor", [0.5, -0.5]) in im.lines  # series: one row a time
    assert ("low", [-1.0, -1.0]) in im.lines and ("high", [1.0, 1.0]) in im.lines  # the ctrl's range drawn
