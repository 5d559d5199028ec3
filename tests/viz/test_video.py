"""render_video: the system fills a computed frame, thick coloured poles, an overlay, browser-ready H.264 at 30 fps on
its own clock, a GIF preview, a render-only copy of the model, clean GL failures."""
import colorsys
import json
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from cartpole import replay
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.sim import Rollout, make_mujoco, replays_exactly, simulate
from cartpole.viz import (VideoInfo, VideoUnavailable, frame_indices, modes_from_switches, render_frame, render_video,
                          swingup_modes)
from cartpole.viz.video import LINK_COLOURS, MODE_COLOURS, _Overlay, _Scene

POLES = {1: SHIPPED_MJCF, 2: SHIPPED_MJCF.with_name("cartpole_two_pole.xml"),
         3: SHIPPED_MJCF.with_name("cartpole_three_pole.xml")}
W, H = 480, 270  # small frames keep the tests fast; every check is a share of the frame, not a pixel count


def _read_video(path):
    import imageio_ffmpeg

    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    first = np.frombuffer(next(gen), np.uint8)
    gen.close()
    return frames, meta, first


def _or_skip(call, *args, **kwargs):
    try:
        return call(*args, **kwargs)
    except VideoUnavailable as exc:
        if "OpenGL" in str(exc):
            pytest.skip(f"no OpenGL backend on this machine: {exc}")
        raise


def _hue_mask(frame, rgb, tol_deg=15.0, min_sat=0.45):
    """Pixels of the hue of ``rgb`` (0..1), saturated and not dark: a colour under any lighting."""
    from PIL import Image

    hsv = np.asarray(Image.fromarray(frame).convert("HSV")).astype(float)
    hue, sat, val = hsv[..., 0] * 360 / 255, hsv[..., 1] / 255, hsv[..., 2] / 255
    dh = np.abs((hue - colorsys.rgb_to_hsv(*rgb)[0] * 360 + 180) % 360 - 180)
    return (dh <= tol_deg) & (sat >= min_sat) & (val >= 0.25)


def _lqr_run(path, seconds, tilt=0.1):
    from cartpole.control import LinearFeedback

    model = build_model(path)
    x0 = np.array(model.x_eq)
    x0[model.hinges[0]] += tilt
    return model, simulate(path, LinearFeedback.for_model(model), x0, seconds)


def test_frames_follow_a_30_fps_clock_not_the_physics_step():
    t = np.arange(2001) * 0.005  # 10 s at 5 ms
    idx = frame_indices(t, 30)
    assert idx.size == 300 and idx[0] == 0
    np.testing.assert_allclose(t[idx], np.arange(300) / 30, atol=0.0025 + 1e-12)
    t2 = np.arange(5001) * 0.002
    assert frame_indices(t2, 30).size == 300


@pytest.mark.parametrize("n_poles", [1, 2, 3])
def test_upright_frame_shows_every_pole_thick_in_its_own_colour_and_the_chain_fills_the_frame(n_poles):
    path = POLES[n_poles]
    model = build_model(path)
    run = replay(path, model.x_eq, np.zeros((20, model.nu)))  # 0.1 s at upright rest
    frame = _or_skip(render_frame, model, run, 0.0, width=W, height=H, overlay=False)
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    rows = np.zeros(H, bool)
    for i in range(n_poles):
        mask = _hue_mask(frame, LINK_COLOURS[i])
        assert mask.mean() > 0.0025, f"link {i + 1} covers {100 * mask.mean():.2f} % of the frame"
        widths = mask.sum(1)[mask.any(1)]
        # thick enough to read on a phone: at least 2.5 % of the frame's height across (the MJCF's 2 cm radius
        # would be about 1.6 % for the three-pole chain)
        assert np.median(widths) >= 0.025 * H, f"link {i + 1} is {np.median(widths)} px wide"
        rows |= mask.any(1)
    r = np.flatnonzero(rows)
    assert (r.max() - r.min()) / H > 0.55  # the chain's full height fills most of the frame ...
    assert r.min() > 0 and r.max() < H - 1  # ... and stays inside it


def test_overlay_draws_time_angles_ctrl_bars_and_mode_in_bands_the_system_keeps_out_of():
    model, run = _lqr_run(POLES[2], 0.2)
    assert np.abs(run.ctrl[0]).max() > 0.05  # a ctrl bar with something in it
    plain = _or_skip(render_frame, model, run, 0.0, width=W, height=H, overlay=False, modes=[(0, "LQR")])
    drawn = render_frame(model, run, 0.0, width=W, height=H, modes=[(0, "LQR")])
    layout = _Overlay(W, H, 2, ["motor"], np.array([[-1.0, 1.0]]), 1.0, show_mode=True)
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
        assert _hue_mask(top, LINK_COLOURS[i]).sum() > 20
    fill = [np.all(np.abs(bottom.astype(int) - c) < 8, axis=2).sum() for c in (_Overlay.BAR, _Overlay.SATURATED)]
    assert max(fill) > 20  # the ctrl bar's fill (blue, or red at the ctrl limit)
    tag = np.all(np.abs(top[:, W // 2:].astype(int) - MODE_COLOURS["lqr"]) < 8, axis=2)
    assert tag.sum() > 100  # the mode tag, top right
    no_mode = render_frame(model, run, 0.0, width=W, height=H)
    assert not np.all(np.abs(no_mode[:layout.top, W // 2:].astype(int) - MODE_COLOURS["lqr"]) < 8, axis=2).any()


@pytest.mark.parametrize("n_poles", [1, 2, 3])
def test_mp4_is_browser_ready_h264_yuv420p_at_30_fps_with_a_gif_preview_beside_it(n_poles, tmp_path):
    path = POLES[n_poles]
    model, run = _lqr_run(path, 1.0)
    out = tmp_path / "videos" / "clip.mp4"
    info = _or_skip(render_video, path, run, out, width=W, height=H, preview_width=240, model=model)
    assert isinstance(info, VideoInfo) and os.fspath(info) == str(out) and info.resolve() == out.resolve()
    assert (info.frames, info.fps, info.seconds, info.size) == (30, 30.0, 1.0, (W, H))
    assert info.render_s > 0 and info.preview == out.with_suffix(".gif") and info.preview_frames >= 5
    frames, meta, first = _read_video(out)
    assert frames == 30 and meta["codec"] == "h264" and meta["pix_fmt"].startswith("yuv420p")
    assert meta["fps"] == 30 and tuple(meta["size"]) == (W, H) and first.std() > 0
    data = out.read_bytes()
    assert data.index(b"moov") < data.index(b"mdat")  # faststart: a browser can play before the download ends
    from PIL import Image

    with Image.open(info.preview) as gif:
        assert gif.format == "GIF" and gif.size == (240, 134) and gif.n_frames == info.preview_frames
        assert gif.info.get("loop") == 0
        delays = []
        for k in range(gif.n_frames):
            gif.seek(k)
            delays.append(gif.info["duration"])
    assert abs(np.mean(delays) - 1000 / 15) < 4  # real time at 15 fps
    assert sorted(p.name for p in out.parent.iterdir()) == ["clip.gif", "clip.mp4"]  # no temporary left


def test_rendering_reads_the_logged_states_and_never_touches_the_physics_model(tmp_path):
    path = POLES[3]
    params = read_params(path)
    text, xml = path.read_bytes(), params.xml
    m_before, _ = make_mujoco(params)
    model, run = _lqr_run(path, 0.3)
    _or_skip(render_video, params, run, tmp_path / "v.mp4", width=W, height=H, preview=False, model=model)
    assert path.read_bytes() == text and params.xml == xml
    m_after, _ = make_mujoco(params)
    for name in ("geom_size", "geom_rgba", "body_mass", "body_inertia", "dof_damping", "actuator_gear"):
        np.testing.assert_array_equal(getattr(m_after, name), getattr(m_before, name))
    assert replays_exactly(run)  # the log still replays bit for bit with mj_step on the MJCF
    with _Scene(params, run, fps=30, width=W, height=H, model=model) as scene:
        shown = scene.disp.m
        np.testing.assert_array_equal(shown.body_mass, m_before.body_mass)  # the copy's physics is the MJCF's ...
        np.testing.assert_array_equal(shown.body_inertia, m_before.body_inertia)
        poles = [g for gs in scene.disp.link_geoms for g in gs]
        assert np.all(shown.geom_size[poles, 0] > m_before.geom_size[poles, 0])  # ... only its drawing differs


def test_camera_follows_a_cart_that_travels_far_and_stands_still_when_the_run_fits():
    path = POLES[1]
    model = build_model(path)
    t = np.arange(801) * 0.005  # 4 s: the cart sweeps +-1.4 m with the pole upright (a log to draw, not physics)
    qpos = np.zeros((801, 2))
    qpos[:, 0] = 1.4 * np.sin(2 * np.pi * t / 4.0)
    run = Rollout(t=t, qpos=qpos, qvel=np.gradient(qpos, t, axis=0), ctrl=np.zeros((800, 1)), mjcf=str(path))
    with _or_skip(_Scene, model, run, fps=30, width=W, height=H, model=model) as scene:
        cam = scene.camera_path
        assert cam.follows
        aim = cam.lookat[:, 0]
        assert np.ptp(aim) > 1.5 and np.abs(np.diff(aim)).max() < 0.1  # follows, smoothly (m per frame)
        for i in range(0, len(scene), 12):  # the pole is in every frame, not cut by the edges
            mask = _hue_mask(scene.frame(i), LINK_COLOURS[0])
            cols = np.flatnonzero(mask.any(0))
            assert mask.mean() > 0.005 and cols.min() > 0 and cols.max() < W - 1, f"frame {i}"
    model, still = _lqr_run(path, 2.0)
    with _Scene(model, still, fps=30, width=W, height=H, model=model) as scene:
        assert not scene.camera_path.follows and np.ptp(scene.camera_path.lookat, axis=0).max() == 0


def test_modes_come_from_the_switch_log_and_label_the_overlay_at_frame_times():
    from cartpole.control.switching import Switch
    from cartpole.viz.video import _mode_labels

    energy = modes_from_switches([Switch(1.2, "catch", 0.1), Switch(3.0, "swingup", 9.0)])
    assert energy == [(0.0, "energy"), (1.2, "LQR catch"), (3.0, "energy")]
    assert _mode_labels(energy, [0.0, 1.19, 1.2, 2.9, 3.5]) == ["energy", "energy", "LQR catch", "LQR catch",
                                                                 "energy"]
    assert _mode_labels(lambda t: "MPC" if t > 1 else None, [0.5, 1.5]) == [None, "MPC"]
    trajopt = SimpleNamespace(method="trajopt", metrics={"switches": [{"t": 2.5, "mode": "catch", "cost": 0.2}]})
    assert swingup_modes(trajopt) == [(0.0, "TVLQR"), (2.5, "LQR")]
    assert swingup_modes(SimpleNamespace(method="energy", metrics={"switches": []})) == [(0.0, "energy")]
    assert swingup_modes(SimpleNamespace(method="mpc", metrics={})) == [(0.0, "MPC")]
    with pytest.raises(VideoUnavailable, match="modes must be"):
        _mode_labels([3, 4], [0.0])


def test_progress_is_a_silent_stage_without_a_reporter_and_feeds_a_callback(tmp_path, capfd):
    run = replay(None, [0.0, 0.1, 0.0, 0.0], np.zeros(100))  # 0.5 s
    seen = []
    _or_skip(render_video, None, run, tmp_path / "a.mp4", width=160, height=90, progress=seen.append)
    render_video(None, run, tmp_path / "b.mp4", width=160, height=90)
    render_video(None, run, tmp_path / "c.mp4", width=160, height=90, progress=False)
    assert seen and seen[-1] == 1.0 and seen == sorted(seen)
    captured = capfd.readouterr()
    assert captured.out == "" and captured.err == ""


def test_requested_size_is_honoured_above_the_mjcfs_offscreen_buffer(variant_dir, tmp_path):
    path = variant_dir / "cartpole_heavy_pole.xml"  # declares offwidth 320, offheight 240
    run = replay(path, [0.0, 0.1, 0.0, 0.0], np.zeros(250))  # 1 s at 4 ms, falling pole
    out = _or_skip(render_video, path, run, tmp_path / "sub" / "clip.mp4", width=640, height=360, preview=False)
    frames, meta, first = _read_video(out)
    assert frames == 30 and tuple(meta["size"]) == (640, 360) and meta["fps"] == 30
    assert first.size == 640 * 360 * 3 and first.std() > 0  # not a blank frame
    assert sorted(p.name for p in out.path.parent.iterdir()) == ["clip.mp4"]  # no temporary, no preview
    assert make_mujoco(path)[0].vis.global_.offwidth == 320  # the MJCF's own buffer is what it was


def test_unknown_camera_is_refused_without_a_file(tmp_path):
    run = replay(None, [0.0, 0.0, 0.0, 0.0], np.zeros(10))
    with pytest.raises(VideoUnavailable, match="no camera named 'nope'"):
        render_video(None, run, tmp_path / "x.mp4", camera="nope")
    assert list(tmp_path.iterdir()) == []


def test_an_mjcf_camera_is_used_when_named(tmp_path):
    run = replay(None, [0.0, 0.1, 0.0, 0.0], np.zeros(20))
    ours = _or_skip(render_frame, None, run, 0.0, width=160, height=90)
    track = render_frame(None, run, 0.0, width=160, height=90, camera="track")
    assert np.abs(ours.astype(int) - track.astype(int)).max() > 50


def test_missing_gl_backend_is_one_sentence(tmp_path):
    """A backend that cannot work headless (GLX without a display) ends in VideoUnavailable, no file."""
    code = ("import numpy as np, cartpole as cp\n"
            "from cartpole.viz import render_video, VideoUnavailable\n"
            "run = cp.replay(None, [0, 0, 0, 0], np.zeros(20))\n"
            f"try:\n    render_video(None, run, {str(tmp_path / 'v.mp4')!r})\n"
            "except VideoUnavailable as e:\n    print(str(e))\n")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MUJOCO_GL"] = "glx"
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1 and "OpenGL" in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_the_child_process_route_renders_the_same_video_and_preview(tmp_path):
    """The OSMesa fallback renders in a child process; exercised here with the backend this machine has."""
    from cartpole.viz.video import _render_frames, _render_in_child

    run = replay(None, [0.0, 0.1, 0.0, 0.0], np.zeros(100))  # 0.5 s
    opts = dict(fps=30, width=160, height=90, camera=None, progress=None, modes=[(0.0, "LQR")], preview_width=80)
    here = _or_skip(_render_frames, None, run, tmp_path / "here.mp4", preview=tmp_path / "here.gif", **opts)
    child = _render_in_child(None, run, tmp_path / "child.mp4", preview=tmp_path / "child.gif",
                             backend=os.environ.get("MUJOCO_GL", "egl"), **opts)
    assert here == child == (15, 8)
    (n_here, meta_here, first_here), (n_child, meta_child, first_child) = (_read_video(tmp_path / "here.mp4"),
                                                                           _read_video(tmp_path / "child.mp4"))
    assert n_here == n_child == 15 and meta_here["size"] == meta_child["size"] == (160, 90)
    np.testing.assert_array_equal(first_here, first_child)
    assert (tmp_path / "here.gif").read_bytes() == (tmp_path / "child.gif").read_bytes()


def test_video_draws_every_link_of_a_three_pole_chain(tmp_path):
    """Bending only the third link changes the picture: the renderer draws the whole chain from the logged qpos."""
    path = POLES[3]
    model = build_model(path)
    bent = np.array(model.x_eq)
    bent[model.hinges[-1]] = 0.8
    clips = []
    for x0 in (model.x_eq, bent):
        run = replay(path, x0, np.zeros((20, model.nu)))  # 0.1 s
        assert run.qpos.shape[1] == 4
        out = _or_skip(render_video, path, run, tmp_path / f"clip{len(clips)}.mp4", width=320, height=180,
                       preview=False, model=model)
        clips.append(_read_video(out))
    (n0, meta0, first0), (n1, _, first1) = clips
    assert n0 == n1 == 3 and tuple(meta0["size"]) == (320, 180)
    assert np.abs(first0.astype(int) - first1.astype(int)).max() > 50


def test_job_of_the_child_is_plain_json():
    """What the parent hands the OSMesa child survives json (modes from a callable become frame-time pairs)."""
    from cartpole.viz.video import _mode_labels

    times = np.arange(3) / 30
    labels = _mode_labels(lambda t: "energy" if t < 0.05 else "LQR catch", times)
    job = {"modes": [[float(t), lab] for t, lab in zip(times, labels)]}
    assert _mode_labels(json.loads(json.dumps(job))["modes"], times) == labels
