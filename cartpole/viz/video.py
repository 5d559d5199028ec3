"""Render a logged :class:`~cartpole.sim.rollout.Rollout` to an H.264 mp4, headless.

Frames come from ``mujoco.Renderer`` (offscreen OpenGL) on a clock of their own: frame ``i`` shows the logged
state nearest to ``i / fps`` seconds, so a 10 s run at 30 fps is 300 frames played in real time whatever the
physics step. The encoder is the ffmpeg binary shipped by ``imageio-ffmpeg``.

Headless OpenGL: ``MUJOCO_GL`` must name the backend *before* mujoco is first imported (the ``cartpole``
command sets ``egl`` by default). If the backend in use cannot make a context and it was EGL, the frames are
tried once more in a child process with ``MUJOCO_GL=osmesa`` (a process cannot switch backends once mujoco
and PyOpenGL are loaded). Every failure ends in :class:`VideoUnavailable` with one sentence; the target file
is never left half written (frames go to a temporary file that is renamed at the end,
:func:`~cartpole._files.atomic_path`).
"""
from __future__ import annotations

import ctypes.util
import json
import os
import re
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from cartpole._files import atomic_path
from cartpole.errors import CartPoleError, first_line
from cartpole.models import CartPoleParams
from cartpole.sim import Rollout, make_mujoco


class VideoUnavailable(CartPoleError):
    """No working OpenGL backend or video encoder: the video cannot be made on this machine."""


def frame_indices(t, fps: float) -> np.ndarray:
    """Indices into a rollout's ``t`` (n+1,) of the samples shown at ``0, 1/fps, 2/fps, ...`` s.

    There are ``round(t[-1] * fps)`` frames (300 for a 10 s run at 30 fps), each the sample nearest its time.
    """
    t = np.asarray(t, dtype=float)
    if fps <= 0:
        raise VideoUnavailable(f"The frame rate {fps} is not positive; give fps > 0.")
    n_frames = max(1, int(round((t[-1] - t[0]) * fps)))
    times = t[0] + np.arange(n_frames) / fps
    hi = np.clip(np.searchsorted(t, times), 1, t.size - 1)
    lo = hi - 1
    # nearest sample; ties go to the earlier one
    return np.where(times - t[lo] <= t[hi] - times, lo, hi) if t.size > 1 else np.zeros(n_frames, int)


def _render_frames(source, rollout, path: Path, *, fps, width, height, camera, progress):
    """Render and encode in this process (raises VideoUnavailable on any GL or encoder failure)."""
    import imageio_ffmpeg
    import mujoco

    m, d = make_mujoco(source if source is not None else (rollout.mjcf or None))
    # The offscreen buffer the MJCF declares bounds the frame size; even sizes keep yuv420p happy.
    width = int(min(width, m.vis.global_.offwidth)) // 2 * 2
    height = int(min(height, m.vis.global_.offheight)) // 2 * 2
    if width < 2 or height < 2:
        raise VideoUnavailable(f"The frame size {width}x{height} is too small; give width and height >= 2.")
    if camera is None:
        camera = "track" if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "track") >= 0 else -1
    elif isinstance(camera, str) and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
        raise VideoUnavailable(f"The MJCF has no camera named '{camera}'; pass camera=None for the default view.")
    # GL front ends (glfw) report through warnings as well as exceptions: keep them off stderr, use the first
    # as the reason since it usually names the cause (e.g. "The DISPLAY environment variable is missing").
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            renderer = mujoco.Renderer(m, height=height, width=width)
        except Exception as exc:  # GL failures surface as ImportError, RuntimeError, mujoco.FatalError ...
            backend = os.environ.get("MUJOCO_GL", "") or "default"
            why = first_line(caught[0].message) if caught else first_line(exc)
            why = re.split(r"[,;] ", why.replace("b'", "").replace("'", ""))[0]
            raise VideoUnavailable(f"No working OpenGL backend for offscreen rendering (MUJOCO_GL={backend}: "
                                   f"{why}); install Mesa's EGL or OSMesa, or skip the video.") from None
    idx = frame_indices(rollout.t, fps)
    writer = None
    try:
        writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264",
                                             pix_fmt_in="rgb24", pix_fmt_out="yuv420p", macro_block_size=2,
                                             quality=7, output_params=["-movflags", "+faststart"])
        writer.send(None)  # start ffmpeg
        every = max(1, len(idx) // 20)
        for i, k in enumerate(idx):
            d.qpos[:] = rollout.qpos[k]
            d.qvel[:] = rollout.qvel[k]
            d.time = float(rollout.t[k])
            mujoco.mj_forward(m, d)
            renderer.update_scene(d, camera=camera)
            writer.send(np.ascontiguousarray(renderer.render()))
            if progress is not None and ((i + 1) % every == 0 or i + 1 == len(idx)):
                progress((i + 1) / len(idx))
        writer.close()
        writer = None
    except VideoUnavailable:
        raise
    except Exception as exc:
        raise VideoUnavailable(f"Rendering or encoding the video failed ({first_line(exc)}); "
                               "check MUJOCO_GL and that imageio-ffmpeg is installed.") from None
    finally:
        if writer is not None:
            try:
                writer.close()
            except Exception:
                pass
        renderer.close()
    return len(idx)


def _osmesa_available() -> bool:
    return ctypes.util.find_library("OSMesa") is not None


def _render_in_child(source, rollout, path: Path, *, fps, width, height, camera, progress,
                     backend: str = "osmesa"):
    """Render with ``MUJOCO_GL=backend`` in a fresh Python process (the only way to switch GL backends)."""
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "rollout.json"
        rollout.save(log)
        src = source
        if isinstance(source, CartPoleParams):
            src = source.mjcf
            if not src:  # parameters built from text: hand the child the same text
                src = Path(tmp) / "model.xml"
                src.write_text(source.xml)
        elif source is None:
            src = rollout.mjcf or None
        job = {"source": str(src) if src else None, "rollout": str(log), "path": str(path), "fps": fps,
               "width": width, "height": height, "camera": camera}
        env = {**os.environ, "MUJOCO_GL": backend}
        if backend in ("osmesa", "egl"):
            env["PYOPENGL_PLATFORM"] = backend
        r = subprocess.run([sys.executable, "-m", "cartpole.viz.video", json.dumps(job)],
                           env=env, capture_output=True, text=True)
    if r.returncode != 0:
        msg = (r.stderr.strip().splitlines() or ["unknown error"])[-1]
        raise VideoUnavailable(msg)
    if progress is not None:
        progress(1.0)


def render_video(source, rollout, path, *, fps: float = 30, width: int = 640, height: int = 480,
                 camera: str | int | None = None, progress: Callable[[float], None] | None = None) -> Path:
    """Render ``rollout`` as an H.264 mp4 at ``fps`` frames per second of simulated time (real-time playback).

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
        The model to draw (None: the rollout's own ``mjcf``, else the shipped asset).
    rollout : Rollout
        Logged run; frame ``i`` shows the sample nearest ``t = i / fps`` s.
    path : str or Path
        Output ``.mp4``; parent directories are created. Written to a temporary file, then renamed.
    fps : float
        Frames per second (default 30).
    width, height : int, pixels
        Requested frame size, clamped to the MJCF's offscreen buffer (``<visual><global offwidth offheight>``)
        and rounded down to even numbers.
    camera : str or int, optional
        Camera name or id; default the MJCF's ``track`` camera if it has one, else MuJoCo's free camera.
    progress : callable, optional
        Called with the fraction of frames done (0..1), about 20 times.

    Returns
    -------
    Path
        The mp4 written.

    Raises
    ------
    VideoUnavailable
        No working OpenGL backend (EGL, then OSMesa in a child process, were tried) or the encoder failed.
    """
    path = Path(path)
    made = [p for p in (path.parent, *path.parent.parents) if not p.exists()]
    opts = dict(fps=fps, width=width, height=height, camera=camera, progress=progress)
    ok = False
    try:
        # the temporary file keeps the .mp4 ending: ffmpeg picks the container from the name
        with atomic_path(path, suffix=path.suffix or ".mp4") as tmp:
            try:
                _render_frames(source, rollout, tmp, **opts)
            except VideoUnavailable as first:
                backend = os.environ.get("MUJOCO_GL", "").lower()
                if backend != "egl" or not _osmesa_available() or "OpenGL" not in str(first):
                    raise
                try:
                    _render_in_child(source, rollout, tmp, **opts)
                except VideoUnavailable:
                    raise first from None
        ok = True
    finally:
        if not ok:  # leave no trace: remove the (empty) directories this call created
            for d in made:
                try:
                    d.rmdir()
                except OSError:
                    break
    return path


def _child_main(argv) -> int:
    """Entry of the OSMesa fallback child: ``python -m cartpole.viz.video JOB_JSON``."""
    job = json.loads(argv[0])
    try:
        _render_frames(job["source"], Rollout.load(job["rollout"]), Path(job["path"]), fps=job["fps"],
                       width=job["width"], height=job["height"], camera=job["camera"], progress=None)
    except CartPoleError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(_child_main(sys.argv[1:]))
