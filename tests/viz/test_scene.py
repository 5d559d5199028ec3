"""The scene of a video frame: frames on a 30 fps clock of their own, a render-only copy of the model (thick poles in
one colour per link, the physics model untouched) and a camera that frames the whole chain, following the cart
only when it must."""
import numpy as np
import pytest

from cartpole import replay
from cartpole.models import build_model, read_params
from cartpole.sim import Rollout, make_mujoco, replays_exactly
from cartpole.viz import VideoOptions, frame_indices, render_frame, render_video
from cartpole.viz.scene import LINK_COLOURS
from cartpole.viz.video import _Scene
from video_helpers import POLES, H, W, hue_mask, lqr_run, or_skip


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
    frame = or_skip(render_frame, model, run, 0.0, options=VideoOptions(width=W, height=H, overlay=False))
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    rows = np.zeros(H, bool)
    for i in range(n_poles):
        mask = hue_mask(frame, LINK_COLOURS[i])
        assert mask.mean() > 0.0025, f"link {i + 1} covers {100 * mask.mean():.2f} % of the frame"
        widths = mask.sum(1)[mask.any(1)]
        # thick enough to read on a phone: at least 2.5 % of the frame's height across (the MJCF's 2 cm radius
        # would be about 1.6 % for the three-pole chain)
        assert np.median(widths) >= 0.025 * H, f"link {i + 1} is {np.median(widths)} px wide"
        rows |= mask.any(1)
    r = np.flatnonzero(rows)
    assert (r.max() - r.min()) / H > 0.55  # the chain's full height fills most of the frame ...
    assert r.min() > 0 and r.max() < H - 1  # ... and stays inside it


def test_rendering_reads_the_logged_states_and_never_touches_the_physics_model(tmp_path):
    path = POLES[3]
    params = read_params(path)
    text, xml = path.read_bytes(), params.xml
    m_before, _ = make_mujoco(params)
    model, run = lqr_run(path, 0.3)
    or_skip(render_video, params, run, tmp_path / "v.mp4", options=VideoOptions(width=W, height=H), preview=False,
            model=model)
    assert path.read_bytes() == text and params.xml == xml
    m_after, _ = make_mujoco(params)
    for name in ("geom_size", "geom_rgba", "body_mass", "body_inertia", "dof_damping", "actuator_gear"):
        np.testing.assert_array_equal(getattr(m_after, name), getattr(m_before, name))
    assert replays_exactly(run)  # the log still replays bit for bit with mj_step on the MJCF
    with _Scene(params, run, VideoOptions(fps=30, width=W, height=H), model=model) as scene:
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
    with or_skip(_Scene, model, run, VideoOptions(fps=30, width=W, height=H), model=model) as scene:
        cam = scene.camera_path
        assert cam.follows
        aim = cam.lookat[:, 0]
        assert np.ptp(aim) > 1.5 and np.abs(np.diff(aim)).max() < 0.1  # follows, smoothly (m per frame)
        for i in range(0, len(scene), 12):  # the pole is in every frame, not cut by the edges
            mask = hue_mask(scene.frame(i), LINK_COLOURS[0])
            cols = np.flatnonzero(mask.any(0))
            assert mask.mean() > 0.005 and cols.min() > 0 and cols.max() < W - 1, f"frame {i}"
    model, still = lqr_run(path, 2.0)
    with _Scene(model, still, VideoOptions(fps=30, width=W, height=H), model=model) as scene:
        assert not scene.camera_path.follows and np.ptp(scene.camera_path.lookat, axis=0).max() == 0
