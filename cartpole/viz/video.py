"""Render a logged :class:`~cartpole.sim.rollout.Rollout` to an H.264 mp4 a browser plays, and a GIF preview, headless:
the renderer and its process (:func:`render_video`, :func:`render_frame`).

The video is made of three parts, each a module: what a frame shows (the frame clock, the render-only copy of the
model, the camera: :mod:`cartpole.viz.scene`), what is drawn over it and the preview (:mod:`cartpole.viz.overlay`),
and, here, the GL renderer that draws each frame, the encoder and the process they run in.

Headless OpenGL: ``MUJOCO_GL`` must name the backend *before* mujoco is first imported (the ``cartpole``
command sets ``egl`` by default). If the backend in use cannot make a context and it was EGL, the frames are
tried once more in a child process with ``MUJOCO_GL=osmesa`` (a process cannot switch backends once mujoco
and PyOpenGL are loaded; the child is ``python -m cartpole.viz.video JOB_JSON``). Every failure ends in
:class:`~cartpole.viz.scene.VideoUnavailable` with one sentence; the target files are never left half written
(frames go to temporary files renamed at the end, :func:`~cartpole._files.atomic_path`). The encoder is the ffmpeg
binary shipped by ``imageio-ffmpeg`` (libx264, yuv420p, ``-movflags +faststart`` so playback starts before the
download ends).

What a render costs is reported by each call (:attr:`VideoInfo.render_s`). Shadows are off: MuJoCo's shadow pass
doubles the GL time on a software renderer and the light's shadow falls out of view.
"""
from __future__ import annotations

import ctypes.util
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import warnings
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ClassVar, Sequence

import imageio_ffmpeg
import mujoco
import numpy as np
from PIL import Image

from cartpole._files import atomic_path
from cartpole.errors import FOREIGN_WIDTH, CartPoleError, first_line
from cartpole.models import CartPoleParams, wrap_angle
from cartpole.options import StageOptions
from cartpole.progress import stage
from cartpole.sim import Rollout
from cartpole.viz.overlay import Overlay, mode_labels, preview_window, write_gif
from cartpole.viz.scene import (VideoUnavailable, build_display, camera_path, frame_indices, geom_extents,
                                thicken_poles, upright_qpos)


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`render_video` wrote and what it cost.

    It stands for its mp4 where a path is expected (``os.fspath(info)``, ``Path(info)``, ``info.resolve()``), so
    code that used :func:`render_video`'s former return value, a ``Path``, keeps working.

    Attributes
    ----------
    path : Path
        The mp4 (H.264, yuv420p, ``fps`` frames per second of simulated time).
    preview : Path or None
        The animated GIF beside it (same stem), or None when not asked for.
    frames : int
        Frames in the mp4 (``round(duration * fps)``).
    fps : float
        Frames per second.
    seconds : float
        Length of the mp4 in s (``frames / fps``), equal to the simulated time shown.
    size : (int, int)
        Frame ``(width, height)`` in pixels.
    render_s : float
        Wall-clock seconds spent rendering and encoding both files.
    preview_frames : int
        Frames in the preview (0 without one).
    backend : str
        The OpenGL backend that drew the frames (``MUJOCO_GL``: "egl", "osmesa", ...).
    """

    path: Path
    preview: Path | None
    frames: int
    fps: float
    seconds: float
    size: tuple
    render_s: float
    preview_frames: int = 0
    backend: str = ""

    def __fspath__(self) -> str:
        return os.fspath(self.path)

    def __str__(self) -> str:
        return str(self.path)

    def resolve(self) -> Path:
        """The mp4's absolute path (as ``Path.resolve``)."""
        return Path(self.path).resolve()

    def summary(self) -> str:
        """One line for a command's prose, e.g. ``videos/x.mp4: 300 frames (10.0 s at 30 fps, 960x540), rendered in
        14.1 s; preview videos/x.gif``."""
        w, h = self.size
        text = (f"{self.path}: {self.frames} frames ({self.seconds:.1f} s at {self.fps:g} fps, {w}x{h}), rendered in "
                f"{self.render_s:.1f} s")
        return text + (f"; preview {self.preview}" if self.preview is not None else "")


@dataclass(frozen=True, eq=False)
class VideoOptions(StageOptions):
    """How a run is drawn (:func:`render_video`, :func:`render_frame`): the frame clock, the frame size, the camera,
    the overlay and the GIF preview's length and width. Keyword-only; every field has a default.

    Attributes
    ----------
    fps : float
        Frames per second of simulated time (default 30); frame ``i`` shows the logged state nearest
        ``t[0] + i / fps`` s.
    width, height : int, pixels
        Frame size (default 960x540), rounded down to even numbers; the render-only copy's offscreen buffer is
        made large enough, whatever the MJCF declares.
    camera : str or int or None
        None (default): the camera computed from the model and the rollout
        (:func:`~cartpole.viz.scene.camera_path`). A name or id: that MJCF camera instead.
    overlay : bool
        Draw the time, angles, ctrl bars and mode (default True).
    preview_seconds : float
        Length of the GIF preview, s of simulated time (default 4; at 15 fps).
    preview_width : int, pixels
        Width of the preview (default 480; the height keeps the aspect).

    Raises
    ------
    VideoUnavailable
        A frame rate, size or preview length that is not a positive number.
    """

    fps: float = 30.0
    width: int = 960
    height: int = 540
    camera: str | int | None = None
    overlay: bool = True
    preview_seconds: float = 4.0
    preview_width: int = 480

    error: ClassVar[type] = VideoUnavailable
    SCALARS: ClassVar[tuple] = ("fps", "width", "height", "preview_seconds", "preview_width")

    def __post_init__(self):
        self.number("fps", low=0.0, low_open=True, unit="frames per second")
        for name in ("width", "height", "preview_width"):
            self.number(name, low=2.0, integer=True, unit="pixels")
        self.number("preview_seconds", low=0.0, low_open=True, unit="s")
        self.set_field("overlay", bool(self.overlay))


def _gl_renderer(m, height, width):
    """``mujoco.Renderer``, or VideoUnavailable naming the backend and the reason it could not make a context."""
    # GL front ends (glfw) report through warnings as well as exceptions: keep them off stderr, use the first
    # as the reason since it usually names the cause (e.g. "The DISPLAY environment variable is missing").
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            return mujoco.Renderer(m, height=height, width=width)
        except Exception as exc:  # GL failures surface as ImportError, RuntimeError, mujoco.FatalError ...
            backend = os.environ.get("MUJOCO_GL", "") or "default"
            why = first_line(caught[0].message, FOREIGN_WIDTH) if caught else first_line(exc, FOREIGN_WIDTH)
            why = re.split(r"[,;] ", why.replace("b'", "").replace("'", ""))[0]
            raise VideoUnavailable(f"No working OpenGL backend for offscreen rendering (MUJOCO_GL={backend}: "
                                   f"{why}); install Mesa's EGL or OSMesa, or skip the video.") from None


class _Scene:
    """Everything one run's frames need: the render-only copy, the camera path, the overlay and the GL renderer.

    ``frame(i)`` draws frame ``i`` (the logged state nearest ``t[0] + i / fps``) as an (height, width, 3) uint8
    array. Close it (or use it as a context manager) to free the GL context.
    """

    def __init__(self, source, rollout, options: VideoOptions, *, modes=None, model=None, x_eq=None):
        fps, camera = options.fps, options.camera
        self.width, self.height = options.width // 2 * 2, options.height // 2 * 2  # even sizes keep yuv420p happy
        if self.width < 2 or self.height < 2:
            raise VideoUnavailable(f"The frame size {self.width}x{self.height} is too small; give width and "
                                   "height >= 2.")
        self.rollout = rollout
        src = source if source is not None else (rollout.mjcf or None)
        self.idx = frame_indices(rollout.t, fps)
        self.times = np.asarray(rollout.t)[0] + np.arange(len(self.idx)) / fps
        qpos = np.asarray(rollout.qpos)[self.idx]
        # the physics model is only read: the frames come from a render-only copy and the logged qpos
        probe = build_display(src, width=self.width, height=self.height)
        if probe.m.nq != rollout.qpos.shape[1]:
            raise VideoUnavailable(f"The rollout has {rollout.qpos.shape[1]} joint positions per step and the MJCF "
                                   f"has {probe.m.nq}; render it with the MJCF it was run on.")
        if x_eq is None:
            x_eq = upright_qpos(src, model, probe.m.nq)
        self.q_up = np.asarray(x_eq, float)[:probe.m.nq] if x_eq is not None else np.asarray(probe.m.qpos0, float)
        ext = geom_extents(probe, qpos)
        ext_up = geom_extents(probe, self.q_up[None])[0]
        floor_z = min(ext[:, 2].min(), ext_up[2]) - 0.25 * max(ext_up[3] - ext_up[2], 0.3)
        self.disp = disp = build_display(src, width=self.width, height=self.height, floor_z=floor_z)
        m, d = disp.m, disp.d
        self.modes_at = mode_labels(modes, self.times)
        ctrl = np.asarray(rollout.ctrl, float).reshape(len(rollout.t) - 1, -1)
        self.ctrl = ctrl
        ctrl_scale = float(np.abs(ctrl).max()) if ctrl.size else 1.0
        layout = Overlay(self.width, self.height, len(disp.hinges), disp.ctrl_names, disp.ctrl_range,
                          max(ctrl_scale, 1e-9), show_mode=self.modes_at is not None)
        self.overlay = layout if options.overlay else None
        # the system keeps out of the overlay's bands, drawn or not, so a run frames the same either way
        reserve = (layout.top / self.height, layout.bottom / self.height)
        if camera is None:
            cart = None
            if disp.slide is not None:  # the cart's own h coordinate: its body origin
                body = int(m.jnt_bodyid[list(m.jnt_qposadr).index(disp.slide)])
                cart = []
                for q in qpos:
                    d.qpos[:] = q
                    mujoco.mj_kinematics(m, d)
                    cart.append(d.xpos[body] @ disp.h_axis)
                cart = np.array(cart)
            d.qpos[:] = qpos[0]
            mujoco.mj_kinematics(m, d)
            depth_point = d.xpos[1] if m.nbody > 1 else np.zeros(3)
            self.camera_path = camera_path(ext, ext_up[2:], aspect=self.width / self.height,
                                           axes=(disp.h_axis, disp.up), depth_point=depth_point, fps=fps,
                                           cart=cart, reserve=reserve)
            thicken_poles(disp, self.camera_path.view_height)
            self.cam = mujoco.MjvCamera()
            self.cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            self.cam.azimuth, self.cam.elevation = self.camera_path.azimuth, self.camera_path.elevation
        else:
            if isinstance(camera, str) and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
                raise VideoUnavailable(f"The MJCF has no camera named '{camera}'; pass camera=None for the "
                                       "computed view.")
            self.camera_path, self.cam = None, camera
            thicken_poles(disp, max(ext_up[3] - ext_up[2], 0.3) * 2.0)
        self.renderer = _gl_renderer(m, self.height, self.width)

    def __len__(self) -> int:
        return len(self.idx)

    def frame(self, i: int) -> np.ndarray:
        """Frame ``i`` (height, width, 3) uint8, overlay included."""
        m, d, k = self.disp.m, self.disp.d, int(self.idx[i])
        r = self.rollout
        d.qpos[:] = r.qpos[k]
        d.qvel[:] = r.qvel[k]
        d.time = float(r.t[k])
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        if self.camera_path is not None:
            self.cam.lookat[:] = self.camera_path.lookat[i]
            self.cam.distance = float(self.camera_path.distance[i])
        self.renderer.update_scene(d, camera=self.cam)
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0  # not seen from here, and half the GL time
        frame = self.renderer.render()
        if self.overlay is None:
            return np.array(frame)
        h = self.disp.hinges
        ang = np.rad2deg(np.atleast_1d(wrap_angle(np.asarray(r.qpos[k])[h] - self.q_up[h]))) if h else []
        u = self.ctrl[min(k, len(self.ctrl) - 1)] if len(self.ctrl) else []
        return self.overlay.draw(np.array(frame), float(self.times[i]), ang, u,
                                 None if self.modes_at is None else self.modes_at[i])

    def close(self) -> None:
        self.renderer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def render_frame(plant, rollout, t: float = 0.0, *, options: VideoOptions = VideoOptions(), modes=None,
                 model=None) -> np.ndarray:
    """The video frame :func:`render_video` shows at time ``t`` (s): an (height, width, 3) uint8 RGB array.

    Same render-only copy, camera path (computed over the whole rollout) and overlay as the video; handy in a
    notebook (``plt.imshow(render_frame(model, run, 2.0))``). Parameters as :func:`render_video` (of ``options``,
    the preview's fields are not used). Renders in this process only (no OSMesa child): raises
    :class:`~cartpole.viz.scene.VideoUnavailable` when the GL backend cannot start.
    """
    with _Scene(plant, rollout, _check_options(options), modes=modes, model=model) as scene:
        i = int(np.clip(np.round((float(t) - scene.times[0]) * options.fps), 0, len(scene) - 1))
        return scene.frame(i)


def _check_options(options) -> VideoOptions:
    """``options`` when it is a :class:`VideoOptions`, else one sentence."""
    if not isinstance(options, VideoOptions):
        raise VideoUnavailable(f"The video's options must be a VideoOptions; got {options!r}.")
    return options


def _encoder(path: Path, width: int, height: int, fps: float):
    """The started ffmpeg writer (``imageio_ffmpeg.write_frames``: H.264, yuv420p, faststart) of ``path``."""
    writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264", pix_fmt_in="rgb24",
                                         pix_fmt_out="yuv420p", macro_block_size=2, quality=6,
                                         output_params=["-movflags", "+faststart", "-preset", "veryfast"])
    writer.send(None)  # start ffmpeg
    return writer


def _render_frames(source, rollout, path: Path, *, options: VideoOptions, progress, modes=None, x_eq=None,
                   preview=None, model=None):
    """Render and encode in this process (raises VideoUnavailable on any GL or encoder failure).

    Returns ``(frames, preview_frames)``.
    """
    scene = _Scene(source, rollout, options, modes=modes, model=model, x_eq=x_eq)
    fps, width, height = options.fps, scene.width, scene.height
    pv = preview_window(scene.times, rollout, scene.idx, scene.modes_at, options.preview_seconds) if preview else (0, 0)
    pv_step = max(1, int(round(fps / 15.0)))
    pv_width = options.preview_width
    pv_size = (pv_width // 2 * 2, max(2, int(round(pv_width * height / width)) // 2 * 2))
    pv_frames = []
    n = len(scene)
    every = max(1, n // 50)
    # shown by the caller's progress reporter (a tqdm bar on a terminal, one line otherwise, nothing in --json)
    bar = stage("video", size=f"{n} frames at {fps:g} fps, {width}x{height}",
                callback=progress if callable(progress) else None) if progress is not False else None
    writer = None
    try:
        writer = _encoder(path, width, height, fps)
        for i in range(len(scene)):
            frame = scene.frame(i)
            writer.send(np.ascontiguousarray(frame))
            if pv[0] <= i < pv[1] and (i - pv[0]) % pv_step == 0:
                pv_frames.append(Image.fromarray(frame).resize(pv_size, Image.Resampling.BOX))
            if bar is not None and ((i + 1) % every == 0 or i + 1 == n):
                bar((i + 1) / n)
        writer.close()
        writer = None
        if preview:
            write_gif(pv_frames, Path(preview), fps / pv_step)
    except VideoUnavailable:
        raise
    except Exception as exc:
        raise VideoUnavailable(f"Rendering or encoding the video failed ({first_line(exc, FOREIGN_WIDTH)}); "
                               "check MUJOCO_GL and that imageio-ffmpeg is installed.") from None
    finally:
        if bar is not None:
            bar.close(ok=writer is None)
        if writer is not None:
            try:
                writer.close()
            except Exception:
                pass
        scene.close()
    return len(scene), len(pv_frames)


def _osmesa_available() -> bool:
    return ctypes.util.find_library("OSMesa") is not None


def _render_in_child(source, rollout, path: Path, *, options: VideoOptions, progress, modes=None, preview=None,
                     model=None, backend: str = "osmesa"):
    """Render with ``MUJOCO_GL=backend`` in a fresh Python process (the only way to switch GL backends)."""
    src = source.params if hasattr(source, "params") and isinstance(source.params, CartPoleParams) else source
    x_eq = None
    if model is not None:
        x_eq = np.asarray(model.x_eq)[:rollout.qpos.shape[1]]
    if x_eq is None and hasattr(source, "x_eq"):
        x_eq = np.asarray(source.x_eq)[:rollout.qpos.shape[1]]
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "rollout.json"
        rollout.save(log)
        if isinstance(src, CartPoleParams):
            if src.mjcf:
                src = src.mjcf
            else:  # parameters built from text: hand the child the same text
                (Path(tmp) / "model.xml").write_text(src.xml)
                src = Path(tmp) / "model.xml"
        elif src is None:
            src = rollout.mjcf or None
        fps = options.fps
        times = np.asarray(rollout.t)[0] + np.arange(len(frame_indices(rollout.t, fps))) / fps
        labels = mode_labels(modes, times)
        job = {"source": str(src) if src else None, "rollout": str(log), "path": str(path),
               "options": options.as_dict(),
               "modes": None if labels is None else [[float(t), lab] for t, lab in zip(times, labels)
                                                      if lab is not None],
               "x_eq": None if x_eq is None else np.asarray(x_eq, float).tolist(),
               "preview": None if preview is None else str(preview)}
        env = {**os.environ, "MUJOCO_GL": backend}
        if backend in ("osmesa", "egl"):
            env["PYOPENGL_PLATFORM"] = backend
        r = subprocess.run([sys.executable, "-m", "cartpole.viz.video", json.dumps(job)],
                           env=env, capture_output=True, text=True)
    if r.returncode != 0:
        msg = (r.stderr.strip().splitlines() or ["unknown error"])[-1]
        raise VideoUnavailable(msg)
    if callable(progress):
        progress(1.0)
    out = (r.stdout.strip().splitlines() or ["0 0"])[-1].split()
    return int(out[0]), int(out[1])


def render_video(plant, rollout, path, *, options: VideoOptions = VideoOptions(), preview: bool | str | Path = True,
                 progress: Callable[[float], None] | bool | None = None,
                 modes: Sequence | Callable[[float], str] | None = None, model=None) -> VideoInfo:
    """Render ``rollout`` as an H.264 mp4 (yuv420p, faststart) at ``options.fps`` frames per second of simulated
    time, and a GIF preview beside it.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The model to draw (None: the rollout's own ``mjcf``, else the shipped asset). Only read: the frames come
        from a render-only copy (:func:`~cartpole.viz.scene.build_display`).
    rollout : Rollout
        Logged run; frame ``i`` shows the logged state nearest ``t = t[0] + i / fps`` s.
    path : str or Path
        Output ``.mp4``; parent directories are created. Written to a temporary file, then renamed.
    options : VideoOptions
        Frame rate, frame size, camera, overlay and the preview's length and width (default
        :class:`VideoOptions` ``()``: 30 fps, 960x540, the computed camera, the overlay, a 4 s preview 480 wide).
    preview : bool or path
        True (default): an animated GIF beside the mp4 (same stem, ``.gif``); a path: there; False: none.
    progress : callable, None or False
        The render is a :func:`cartpole.progress.stage` ("video"): shown by the current progress reporter if there
        is one (a tqdm bar on a terminal, one line otherwise, nothing with ``--json``), silent without one. A
        callable also gets the fraction of frames done (0..1, about 50 times, increasing, ending at 1); False
        opens no stage at all.
    modes : sequence of (t_start, label), or callable t -> label, optional
        The controller's mode shown in the overlay's top right (e.g. ``[(0, "energy"), (4.1, "LQR catch")]``;
        :func:`~cartpole.viz.overlay.modes_from_switches`, :func:`~cartpole.viz.overlay.swingup_modes`); None: no
        mode shown.
    model : CartPoleModel, optional
        Its ``x_eq`` is upright for the overlay's angles; built from ``source`` when not given (and the MJCF's
        ``qpos0`` used if the toolkit cannot build one).

    Returns
    -------
    VideoInfo
        Paths, frame count, length, size and the wall-clock render time; it also stands for the mp4's path.

    Raises
    ------
    VideoUnavailable
        No working OpenGL backend (EGL, then OSMesa in a child process, were tried), the encoder failed, an unknown
        camera name, a rollout that does not match the MJCF, bad ``modes`` or ``options`` that are not a
        :class:`VideoOptions`.
    """
    start = time.perf_counter()
    options = _check_options(options)
    path = Path(path)
    gif = None if preview is False or preview is None else (path.with_suffix(".gif") if preview is True
                                                            else Path(preview))
    made = [p for p in (path.parent, *path.parent.parents) if not p.exists()]
    if gif is not None:
        made += [p for p in (gif.parent, *gif.parent.parents) if not p.exists() and p not in made]
    job = dict(options=options, progress=progress, modes=modes, model=model)
    ok = False
    backend = os.environ.get("MUJOCO_GL", "").lower() or "default"
    try:
        # the temporary files keep their endings: ffmpeg and Pillow pick the format from the name
        with ExitStack() as files:
            tmp = files.enter_context(atomic_path(path, suffix=path.suffix or ".mp4"))
            tmp_gif = files.enter_context(atomic_path(gif, suffix=".gif")) if gif is not None else None
            try:
                frames, pv_frames = _render_frames(plant, rollout, tmp, preview=tmp_gif, **job)
            except VideoUnavailable as first:
                if backend != "egl" or not _osmesa_available() or "OpenGL" not in str(first):
                    raise
                try:
                    frames, pv_frames = _render_in_child(plant, rollout, tmp, preview=tmp_gif, **job)
                    backend = "osmesa"
                except VideoUnavailable:
                    raise first from None
        ok = True
    finally:
        if not ok:  # leave no trace: remove the (empty) directories this call created
            for d in sorted(made, key=lambda p: len(p.parts), reverse=True):
                try:
                    d.rmdir()
                except OSError:
                    pass
    return VideoInfo(path=path, preview=gif, frames=frames, fps=float(options.fps), seconds=frames / options.fps,
                     size=(options.width // 2 * 2, options.height // 2 * 2), render_s=time.perf_counter() - start,
                     preview_frames=pv_frames, backend=backend)


def _child_main(argv) -> int:
    """Entry of the OSMesa fallback child: ``python -m cartpole.viz.video JOB_JSON``; prints ``frames preview``."""
    job = json.loads(argv[0])
    try:
        n, k = _render_frames(job["source"], Rollout.load(job["rollout"]), Path(job["path"]),
                              options=VideoOptions(**job["options"]), progress=False, modes=job.get("modes"),
                              x_eq=job.get("x_eq"), preview=job.get("preview"))
    except CartPoleError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    print(n, k)
    return 0


if __name__ == "__main__":
    sys.exit(_child_main(sys.argv[1:]))
