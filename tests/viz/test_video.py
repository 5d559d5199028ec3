"""render_video: 30 fps on its own clock, the MJCF's offscreen size, temp-then-rename, clean GL failures."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from cartpole import replay
from cartpole.viz import VideoUnavailable, frame_indices, render_video


def _read_video(path):
    import imageio_ffmpeg

    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    first = np.frombuffer(next(gen), np.uint8)
    gen.close()
    return frames, meta, first


def test_frames_follow_a_30_fps_clock_not_the_physics_step():
    t = np.arange(2001) * 0.005  # 10 s at 5 ms
    idx = frame_indices(t, 30)
    assert idx.size == 300 and idx[0] == 0
    np.testing.assert_allclose(t[idx], np.arange(300) / 30, atol=0.0025 + 1e-12)
    t2 = np.arange(5001) * 0.002
    assert frame_indices(t2, 30).size == 300


def test_video_is_clamped_to_the_offscreen_buffer_and_written_whole(variant_dir, tmp_path):
    path = variant_dir / "cartpole_heavy_pole.xml"  # declares offwidth 320, offheight 240
    run = replay(path, [0.0, 0.1, 0.0, 0.0], np.zeros(250))  # 1 s at 4 ms, falling pole
    seen = []
    try:
        out = render_video(path, run, tmp_path / "sub" / "clip.mp4", progress=seen.append)
    except VideoUnavailable as exc:
        pytest.skip(f"no OpenGL backend on this machine: {exc}")
    frames, meta, first = _read_video(out)
    assert frames == 30 and tuple(meta["size"]) == (320, 240) and meta["fps"] == 30
    assert first.size == 320 * 240 * 3 and first.std() > 0  # not a blank frame
    assert seen and seen[-1] == 1.0 and seen == sorted(seen)
    assert sorted(p.name for p in out.parent.iterdir()) == ["clip.mp4"]  # no temporary left behind


def test_unknown_camera_is_refused_without_a_file(tmp_path):
    run = replay(None, [0.0, 0.0, 0.0, 0.0], np.zeros(10))
    with pytest.raises(VideoUnavailable, match="no camera named 'nope'"):
        render_video(None, run, tmp_path / "x.mp4", camera="nope")
    assert list(tmp_path.iterdir()) == []


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


def test_the_child_process_route_renders_the_same_video(tmp_path):
    """The OSMesa fallback renders in a child process; exercised here with the backend this machine has."""
    from cartpole.viz.video import _render_frames, _render_in_child

    run = replay(None, [0.0, 0.1, 0.0, 0.0], np.zeros(100))  # 0.5 s
    opts = dict(fps=30, width=160, height=120, camera=None, progress=None)
    try:
        _render_frames(None, run, tmp_path / "here.mp4", **opts)
    except VideoUnavailable as exc:
        pytest.skip(f"no OpenGL backend on this machine: {exc}")
    _render_in_child(None, run, tmp_path / "child.mp4", backend=os.environ.get("MUJOCO_GL", "egl"), **opts)
    here, meta_here, first_here = _read_video(tmp_path / "here.mp4")
    child, meta_child, first_child = _read_video(tmp_path / "child.mp4")
    assert here == child == 15 and meta_here["size"] == meta_child["size"] == (160, 120)
    np.testing.assert_array_equal(first_here, first_child)


def test_video_draws_every_link_of_a_three_pole_chain(tmp_path):
    """Bending only the third link changes the picture: the renderer draws the whole chain from the logged qpos."""
    from cartpole.models import SHIPPED_MJCF, build_model

    path = SHIPPED_MJCF.with_name("cartpole_three_pole.xml")
    model = build_model(path)
    bent = np.array(model.x_eq)
    bent[model.hinges[-1]] = 0.8
    clips = []
    for x0 in (model.x_eq, bent):
        run = replay(path, x0, np.zeros((20, model.nu)))  # 0.1 s
        assert run.qpos.shape[1] == 4
        try:
            out = render_video(path, run, tmp_path / f"clip{len(clips)}.mp4", width=320, height=240)
        except VideoUnavailable as exc:
            pytest.skip(f"no OpenGL backend on this machine: {exc}")
        clips.append(_read_video(out))
    (n0, meta0, first0), (n1, _, first1) = clips
    assert n0 == n1 == 3 and tuple(meta0["size"]) == (320, 240)
    assert np.abs(first0.astype(int) - first1.astype(int)).max() > 50
