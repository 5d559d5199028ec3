"""What the video tests share: the shipped carts, a small frame size, reading an mp4 back, a colour mask, an LQR run,
and skipping where the machine has no OpenGL."""
import colorsys

import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.sim import simulate
from cartpole.viz import VideoUnavailable

POLES = {1: SHIPPED_MJCF, 2: SHIPPED_MJCF.with_name("cartpole_two_pole.xml"),
         3: SHIPPED_MJCF.with_name("cartpole_three_pole.xml")}
W, H = 480, 270  # small frames keep the tests fast; every check is a share of the frame, not a pixel count


def read_video(path):
    """``(frame count, ffmpeg metadata, first frame as flat uint8)`` of an mp4."""
    import imageio_ffmpeg

    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    first = np.frombuffer(next(gen), np.uint8)
    gen.close()
    return frames, meta, first


def or_skip(call, *args, **kwargs):
    """``call(...)``, or skip the test when the machine has no OpenGL backend."""
    try:
        return call(*args, **kwargs)
    except VideoUnavailable as exc:
        if "OpenGL" in str(exc):
            pytest.skip(f"no OpenGL backend on this machine: {exc}")
        raise


def hue_mask(frame, rgb, tol_deg=15.0, min_sat=0.45):
    """Pixels of the hue of ``rgb`` (0..1), saturated and not dark: a colour under any lighting."""
    from PIL import Image

    hsv = np.asarray(Image.fromarray(frame).convert("HSV")).astype(float)
    hue, sat, val = hsv[..., 0] * 360 / 255, hsv[..., 1] / 255, hsv[..., 2] / 255
    dh = np.abs((hue - colorsys.rgb_to_hsv(*rgb)[0] * 360 + 180) % 360 - 180)
    return (dh <= tol_deg) & (sat >= min_sat) & (val >= 0.25)


def lqr_run(path, seconds, tilt=0.1):
    """``(model, rollout)``: the LQR balancing ``path``'s chain for ``seconds`` s from the first hinge ``tilt`` rad off."""
    from cartpole.control import LinearFeedback

    model = build_model(path)
    x0 = np.array(model.x_eq)
    x0[model.hinges[0]] += tilt
    return model, simulate(path, LinearFeedback.for_model(model), x0, seconds)
