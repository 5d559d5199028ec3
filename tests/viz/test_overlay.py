"""The overlay drawn on each frame (time, angles, ctrl bars, the controller's mode, in bands the system keeps out of),
the modes read from a controller's log, and the GIF preview's window and timing."""
from types import SimpleNamespace

import numpy as np
import pytest

from cartpole.viz import VideoOptions, VideoUnavailable, modes_from_switches, render_frame, swingup_modes
from cartpole.viz.overlay import MODE_COLOURS, Overlay, mode_labels, preview_window, write_gif
from cartpole.viz.scene import LINK_COLOURS
from video_helpers import POLES, H, W, hue_mask, lqr_run, or_skip


def test_overlay_draws_time_angles_ctrl_bars_and_mode_in_bands_the_system_keeps_out_of():
    model, run = lqr_run(POLES[2], 0.2)
    assert np.abs(run.ctrl[0]).max() > 0.05  # a ctrl bar with something in it
    plain = or_skip(render_frame, model, run, 0.0, options=VideoOptions(width=W, height=H, overlay=False),
                    modes=[(0, "LQR")])
    drawn = render_frame(model, run, 0.0, options=VideoOptions(width=W, height=H), modes=[(0, "LQR")])
    layout = Overlay(W, H, 2, ["motor"], np.array([[-1.0, 1.0]]), 1.0, show_mode=True)
    changed = np.any(drawn != plain, axis=2)
    assert changed.any()
    inside = np.zeros((H, W), bool)
    inside[:layout.top] = True
    inside[H - layout.bottom:] = True
    assert not changed[~inside].any()  # the overlay only draws in its bands; the framing is the same either way
    top, bottom = drawn[:layout.top], drawn[H - layout.bottom:]
    ink = lambda a: np.all(a < 70, axis=2).sum()  # noqa: E731  (dark text pixels)
    assert ink(top[:, : W // 2]) > 150 and ink(bottom) > 50  # time, angles; actuator name and value
    for i in range(2):  # each angle has its link's swatch
        assert hue_mask(top, LINK_COLOURS[i]).sum() > 20
    fill = [np.all(np.abs(bottom.astype(int) - c) < 8, axis=2).sum() for c in (Overlay.BAR, Overlay.SATURATED)]
    assert max(fill) > 20  # the ctrl bar's fill (blue, or red at the ctrl limit)
    tag = np.all(np.abs(top[:, W // 2:].astype(int) - MODE_COLOURS["lqr"]) < 8, axis=2)
    assert tag.sum() > 100  # the mode tag, top right
    no_mode = render_frame(model, run, 0.0, options=VideoOptions(width=W, height=H))
    assert not np.all(np.abs(no_mode[:layout.top, W // 2:].astype(int) - MODE_COLOURS["lqr"]) < 8, axis=2).any()


def test_modes_come_from_the_switch_log_and_label_the_overlay_at_frame_times():
    from cartpole.control.switching import Switch

    energy = modes_from_switches([Switch(1.2, "catch", 0.1), Switch(3.0, "swingup", 9.0)])
    assert energy == [(0.0, "energy"), (1.2, "LQR catch"), (3.0, "energy")]
    assert mode_labels(energy, [0.0, 1.19, 1.2, 2.9, 3.5]) == ["energy", "energy", "LQR catch", "LQR catch",
                                                                 "energy"]
    assert mode_labels(lambda t: "MPC" if t > 1 else None, [0.5, 1.5]) == [None, "MPC"]
    trajopt = SimpleNamespace(method="trajopt", metrics={"switches": [{"t": 2.5, "mode": "catch", "cost": 0.2}]})
    assert swingup_modes(trajopt) == [(0.0, "TVLQR"), (2.5, "LQR")]
    assert swingup_modes(SimpleNamespace(method="energy", metrics={"switches": []})) == [(0.0, "energy")]
    assert swingup_modes(SimpleNamespace(method="mpc", metrics={})) == [(0.0, "MPC")]
    with pytest.raises(VideoUnavailable, match="modes must be"):
        mode_labels([3, 4], [0.0])


def test_preview_window_ends_after_the_last_mode_switch_else_holds_the_most_motion():
    fps, seconds = 30.0, 4.0
    times = np.arange(300) / fps  # a 10 s run
    k = int(round(seconds * fps))
    calm = SimpleNamespace(qvel=np.zeros((300, 2)))
    modes_at = ["energy"] * 100 + ["LQR catch"] * 200  # one switch, at frame 100
    j0, j1 = preview_window(times, calm, np.arange(300), modes_at, seconds)
    assert j1 - j0 == k and times[j1] - times[100] == pytest.approx(1.5)
    burst = np.zeros((300, 2))
    burst[200:230, 1] = 5.0  # the pole only moves from 6.67 s to 7.67 s
    j0, j1 = preview_window(times, SimpleNamespace(qvel=burst), np.arange(300), None, seconds)
    assert j1 - j0 == k and np.count_nonzero(burst[j0:j1, 1]) >= 0.95 * 30
    assert preview_window(times[:90], calm, np.arange(90), None, seconds) == (0, 90)  # shorter than the preview


def test_gif_preview_loops_with_one_palette_and_delays_that_add_up_to_real_time(tmp_path):
    from PIL import Image

    fps = 15.0
    frames = []
    for i in range(9):  # a dark square moving across a light frame: every frame differs from the one before
        f = Image.new("RGB", (48, 18), (230, 230, 220))
        f.paste((30, 40, 120), (4 * i, 4, 4 * i + 8, 12))
        frames.append(f)
    write_gif(frames, tmp_path / "p.gif", fps)
    with Image.open(tmp_path / "p.gif") as gif:
        assert gif.n_frames == 9 and gif.info.get("loop") == 0
        delays = []
        for k in range(gif.n_frames):
            gif.seek(k)
            delays.append(gif.info["duration"])
    # GIF delays are whole 10 ms: each differs from 1/fps by less than one unit and their sum is the real time
    assert all(abs(d - 1000 / fps) < 10 for d in delays)
    assert sum(delays) == round(len(frames) * 1000 / fps, -1)
    write_gif([], tmp_path / "none.gif", fps)
    assert not (tmp_path / "none.gif").exists()
