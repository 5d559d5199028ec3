"""Render a logged :class:`~cartpole.sim.rollout.Rollout` to an H.264 mp4 a browser plays, and a GIF preview, headless.

What the video shows
    * **Only the log.** Frame ``i`` shows the logged ``qpos`` nearest ``t = i / fps`` (30 fps on a clock of its own,
      whatever the physics step: a 10 s run is 300 frames played in real time). Nothing is re-simulated: the frames
      come from ``mj_kinematics`` of the logged positions.
    * **A render-only copy of the model.** The MJCF is compiled a second time, for drawing only, and that copy is
      dressed for reading on a small screen: a gradient sky, a floor with a 0.5 m checker and a line every metre
      (it gives the scale; the MJCF's own plane is reused when it has one), poles drawn thicker (capsule radius
      about 1.6 % of the view's height, at most 12 % of the link's length, never thinner than the MJCF's) in one
      colour per link (:data:`LINK_COLOURS`, first link red). Before compiling only textures, materials and (when
      the MJCF has no plane) a floor are added; the thicker radii and the colours are set on the compiled copy
      (``geom_size``, ``geom_rgba``), so its bodies, joints, masses and inertias stay the physics model's. The
      physics model itself is never touched.
    * **A camera computed from the model and the rollout** (a free ``mujoco.MjvCamera``, not the MJCF's camera):
      it looks across the plane of motion (perpendicular to the slide and to gravity), 12 degrees from above, and
      frames every moving geom in every frame plus the chain's full upright height (the geoms at ``x_eq``).
      When the cart's travel fits in the frame (or in a frame up to 1.6 times wider) the camera stands still;
      otherwise it follows the cart, its aim the cart's position smoothed over 0.3 s (zero-phase Gaussian, the
      whole log is known) and nudged only where a link would leave the frame.
    * **An overlay** (Pillow on each frame): the time, each pole's angle from upright (the error from ``x_eq``
      wrapped to (-180, 180] degrees, in the link's colour), each actuator's ctrl as a bar against its range (red
      when at the limit), and the controller's mode when ``modes`` says (:func:`modes_from_switches`,
      :func:`swingup_modes`).
    * **A preview** beside the mp4 (same stem, ``.gif``): about 4 s at 15 fps, 480 px wide, from the window with
      the last mode switch near its end (else the most motion), made from the same frames.

Headless OpenGL: ``MUJOCO_GL`` must name the backend *before* mujoco is first imported (the ``cartpole``
command sets ``egl`` by default). If the backend in use cannot make a context and it was EGL, the frames are
tried once more in a child process with ``MUJOCO_GL=osmesa`` (a process cannot switch backends once mujoco
and PyOpenGL are loaded). Every failure ends in :class:`VideoUnavailable` with one sentence; the target files
are never left half written (frames go to temporary files renamed at the end,
:func:`~cartpole._files.atomic_path`). The encoder is the ffmpeg binary shipped by ``imageio-ffmpeg``
(libx264, yuv420p, ``-movflags +faststart`` so playback starts before the download ends).

Cost, measured on a 2-core machine with Mesa's llvmpipe through EGL (:attr:`VideoInfo.render_s` reports each
render): a 10 s LQR run of the three-pole asset at 960x540, 300 frames, renders and encodes in about 8.5 s of wall
time (12.4 s of CPU over both cores), 15 to 21 s while other jobs load the machine. What it costs: 2x
multisampling (:data:`OFFSAMPLES`, 4x costs about 1.6 times more on a software renderer), no shadows (MuJoCo's
shadow pass doubles the GL time and the light's shadow falls out of view), and a floor drawn with 1 m quads (its
``size[2]``; with 0.1 m quads the 80 m floor took most of the GL time).
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
from typing import Callable, Sequence

import numpy as np

from cartpole._files import atomic_path
from cartpole.errors import CartPoleError, first_line
from cartpole.models import CartPoleParams, wrap_angle
from cartpole.progress import stage
from cartpole.sim import Rollout, ctrl_bounds, make_mujoco

#: Display colours (RGB, 0..1) of the links, first pole first; more links than colours cycle.
LINK_COLOURS = ((0.86, 0.15, 0.15), (0.97, 0.60, 0.05), (0.15, 0.62, 0.20), (0.55, 0.30, 0.78),
                (0.05, 0.65, 0.80))
#: Display colour of the cart (every moving geom that is not on a hinged body).
CART_COLOUR = (0.16, 0.26, 0.62)
#: Camera elevation in degrees (negative: looking down a little, so the floor's grid shows perspective).
ELEVATION = -12.0
#: Vertical field of view of the render-only copy, degrees.
FOVY = 40.0
#: Empty border kept around the system, as a fraction of the frame on each side.
MARGIN = 0.04
#: Pole capsule radius drawn, as a fraction of the view's height (and at most :data:`MAX_RADIUS_FRACTION` of
#: the link's length; never thinner than the MJCF's).
RADIUS_FRACTION = 0.016
MAX_RADIUS_FRACTION = 0.12
#: Multisampling of the render-only copy's offscreen buffer: 2 smooths the edges at about 60 % of the GL time of
#: MuJoCo's default 4 on a software renderer (llvmpipe), 0 shows jagged pole edges.
OFFSAMPLES = 2
#: The camera stands still when the whole run fits in a frame up to this many times wider than the system needs.
FOLLOW_FACTOR = 1.6
#: s: how smoothly a following camera tracks the cart (Gaussian standard deviation).
FOLLOW_SMOOTHING = 0.3
#: Colours of the mode tag (RGB 0..255) by the label's first word, lower case; others get grey.
MODE_COLOURS = {"energy": (214, 120, 20), "swing-up": (214, 120, 20), "swingup": (214, 120, 20),
                "catch": (30, 140, 60), "lqr": (30, 140, 60), "tvlqr": (120, 70, 180), "mpc": (30, 100, 190),
                "pid": (150, 90, 40)}


class VideoUnavailable(CartPoleError):
    """No working OpenGL backend or video encoder: the video cannot be made on this machine."""


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


# ---------------------------------------------------------------------------------------------------------------
# clocks and modes


def frame_indices(t, fps: float) -> np.ndarray:
    """Indices into a rollout's ``t`` (n+1,) of the samples shown at ``0, 1/fps, 2/fps, ...`` s.

    There are ``round(t[-1] * fps)`` frames (300 for a 10 s run at 30 fps), each the sample nearest its time.
    """
    t = np.asarray(t, dtype=float)
    if not (np.isfinite(fps) and fps > 0):
        raise VideoUnavailable(f"The frame rate {fps} is not positive; give fps > 0.")
    n_frames = max(1, int(round((t[-1] - t[0]) * fps)))
    times = t[0] + np.arange(n_frames) / fps
    hi = np.clip(np.searchsorted(t, times), 1, t.size - 1)
    lo = hi - 1
    # nearest sample; ties go to the earlier one
    return np.where(times - t[lo] <= t[hi] - times, lo, hi) if t.size > 1 else np.zeros(n_frames, int)


#: How :func:`modes_from_switches` names the switching controller's modes.
MODE_LABELS = {"swingup": "energy", "catch": "LQR catch"}


def modes_from_switches(switches, *, initial: str = "energy", labels: dict | None = None) -> list:
    """The ``modes`` argument of :func:`render_video` from a switching controller's log.

    Parameters
    ----------
    switches : iterable
        :class:`~cartpole.control.switching.Switch` objects or dicts with ``t`` (s) and ``mode`` (as
        ``SwingupResult.metrics["switches"]`` holds them), in time order.
    initial : str
        Label shown from t = 0 until the first switch.
    labels : dict, optional
        Display label of each logged mode name (default :data:`MODE_LABELS`: "swingup" -> "energy",
        "catch" -> "LQR catch"); names not in it are shown as they are.

    Returns
    -------
    list of (float, str)
        ``[(0.0, initial), (t_1, label_1), ...]``: each label holds from its time to the next.
    """
    names = MODE_LABELS if labels is None else labels
    out = [(0.0, str(initial))]
    for s in switches:
        t, mode = (s["t"], s["mode"]) if isinstance(s, dict) else (s.t, s.mode)
        out.append((float(t), str(names.get(mode, mode))))
    return out


def swingup_modes(result) -> list:
    """The ``modes`` of a :class:`~cartpole.apps.swingup.SwingupResult` (read by duck typing: ``method``, ``metrics``).

    ``energy``: "energy" then "LQR catch" at each switch the controller logged (and back); ``trajopt``: "TVLQR"
    along the plan, "LQR" from the handover; ``mpc``: "MPC"; any other method: its name.
    """
    method = str(getattr(result, "method", "") or "")
    switches = (getattr(result, "metrics", None) or {}).get("switches") or []
    if method == "energy":
        return modes_from_switches(switches, initial="energy")
    if method == "trajopt":
        return modes_from_switches(switches, initial="TVLQR", labels={"catch": "LQR", "swingup": "TVLQR"})
    if method == "mpc":
        return modes_from_switches(switches, initial="MPC", labels={"catch": "LQR"})
    return [(0.0, method or "controller")]


def _mode_labels(modes, times) -> list | None:
    """The label at each frame time (None: no mode shown)."""
    if modes is None:
        return None
    if callable(modes):
        return [None if (lab := modes(float(t))) is None else str(lab) for t in times]
    try:
        pairs = sorted(((float(t0), str(lab)) for t0, lab in modes), key=lambda p: p[0])
    except (TypeError, ValueError):
        raise VideoUnavailable("modes must be a sequence of (t_start, label) pairs or a callable t -> label; "
                               f"got {modes!r}.") from None
    starts = np.array([p[0] for p in pairs])
    out = []
    for t in times:
        k = int(np.searchsorted(starts, t + 1e-9, side="right")) - 1
        out.append(pairs[k][1] if k >= 0 else None)
    return out


# ---------------------------------------------------------------------------------------------------------------
# the render-only model


def _x_eq(source, model, nq):
    """The upright qpos (nq,) the overlay measures angles from: the model's ``x_eq`` (built when not given)."""
    if model is not None:
        return np.asarray(model.x_eq, float)[:nq]
    if hasattr(source, "x_eq"):
        return np.asarray(source.x_eq, float)[:nq]
    from cartpole.models import build_model

    try:
        return np.asarray(build_model(source).x_eq, float)[:nq]
    except CartPoleError:  # not a model the toolkit builds: angles from MuJoCo's qpos0
        return None


def _spec(source):
    """A fresh ``mujoco.MjSpec`` of the source (its MJCF file, else its XML text)."""
    import mujoco

    params = source.params if hasattr(source, "params") and isinstance(source.params, CartPoleParams) else source
    make_mujoco(params)  # validates the source with the toolkit's one-sentence errors
    if isinstance(params, CartPoleParams):
        return mujoco.MjSpec.from_file(params.mjcf) if params.mjcf else mujoco.MjSpec.from_string(params.xml)
    from cartpole.sim import source_path

    return mujoco.MjSpec.from_file(source_path(params))


@dataclass
class _Display:
    """The render-only copy and what the frames need to know about it."""

    m: object            # mujoco.MjModel, render-only
    d: object            # mujoco.MjData of it
    hinges: list         # qpos addresses of the hinges, tree order
    link_geoms: list     # per hinge: geom ids of its body
    moving: np.ndarray   # geom ids on moving bodies
    slide: int | None    # qpos address of the first slide
    h_axis: np.ndarray   # (3,) horizontal direction across the screen (the slide's axis, level)
    up: np.ndarray       # (3,) screen up (against gravity)
    ctrl_range: np.ndarray  # (nu, 2)
    ctrl_names: list


def _build_display(source, *, width, height, floor_z=None):
    """Compile the render-only copy: sky, grid floor, offscreen buffer of the frame size, lighting."""
    import mujoco

    spec = _spec(source)
    spec.visual.global_.offwidth = max(int(width), int(spec.visual.global_.offwidth))
    spec.visual.global_.offheight = max(int(height), int(spec.visual.global_.offheight))
    spec.visual.global_.fovy = FOVY
    spec.visual.headlight.ambient = [0.45, 0.45, 0.45]
    spec.visual.headlight.diffuse = [0.55, 0.55, 0.55]
    spec.visual.headlight.specular = [0.1, 0.1, 0.1]
    spec.visual.quality.offsamples = OFFSAMPLES
    spec.visual.map.zfar = 60.0
    pre = "_cartpole_viz_"
    spec.add_texture(name=pre + "sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.62, 0.76, 0.92], rgb2=[0.97, 0.98, 1.0],
                     width=256, height=256)
    spec.add_texture(name=pre + "grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.93, 0.93, 0.91], rgb2=[0.80, 0.81, 0.80],
                     mark=mujoco.mjtMark.mjMARK_EDGE, markrgb=[0.40, 0.40, 0.45], width=512, height=512)
    grid = spec.add_material(name=pre + "grid", texrepeat=[1, 1], texuniform=True, reflectance=0.0,
                             specular=0.0, shininess=0.0, emission=0.08)
    grid.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = pre + "grid"
    spec.add_material(name=pre + "link", specular=0.25, shininess=0.4, emission=0.15)  # used by name below
    planes = [g for g in spec.worldbody.geoms if g.type == mujoco.mjtGeom.mjGEOM_PLANE]
    if not planes and floor_z is not None:
        planes = [spec.worldbody.add_geom(name=pre + "floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                                          pos=[0, 0, float(floor_z)], contype=0, conaffinity=0)]
    for g in planes:
        g.material = pre + "grid"
        g.rgba = [1, 1, 1, 1]
        g.size = [40.0, 40.0, 1.0]  # size[2]: the spacing of the quads the plane is drawn with
    for b in spec.bodies:
        if b is not spec.worldbody:
            for g in b.geoms:
                if not g.material:  # a geom's own material (a texture, say) is kept
                    g.material = pre + "link"
    try:
        m = spec.compile()
    except Exception as exc:
        raise VideoUnavailable(f"The render-only copy of the MJCF does not compile ({first_line(exc)}); "
                               "skip the video (--no-video).") from None
    d = mujoco.MjData(m)
    hinges, link_geoms = [], []
    slide = None
    slide_axis = np.array([1.0, 0.0, 0.0])
    mujoco.mj_kinematics(m, d)
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            hinges.append(int(m.jnt_qposadr[j]))
            link_geoms.append([g for g in range(m.ngeom) if m.geom_bodyid[g] == m.jnt_bodyid[j]])
        elif m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE and slide is None:
            slide = int(m.jnt_qposadr[j])
            slide_axis = d.xaxis[j].copy()
    grav = np.asarray(m.opt.gravity, float)
    up = -grav / np.linalg.norm(grav) if np.linalg.norm(grav) > 0 else np.array([0.0, 0.0, 1.0])
    h_axis = slide_axis - (slide_axis @ up) * up
    if np.linalg.norm(h_axis) < 1e-9:  # a vertical slide: look along y
        h_axis = np.array([1.0, 0.0, 0.0]) - up[0] * up
    h_axis /= np.linalg.norm(h_axis)
    moving = np.array([g for g in range(m.ngeom) if m.geom_bodyid[g] > 0 and m.geom_rgba[g, 3] > 0], int)
    # colours: one per link, the cart's for every other moving geom
    on_link = {g for gs in link_geoms for g in gs}
    for g in moving:
        if g not in on_link:
            m.geom_rgba[g, :3] = CART_COLOUR
    for i, gs in enumerate(link_geoms):
        for g in gs:
            m.geom_rgba[g] = (*LINK_COLOURS[i % len(LINK_COLOURS)], 1.0)
    lo, hi = ctrl_bounds(m)
    ctrl_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"u{a}" for a in range(m.nu)]
    return _Display(m=m, d=d, hinges=hinges, link_geoms=link_geoms, moving=moving, slide=slide,
                    h_axis=h_axis, up=up, ctrl_range=np.stack([lo, hi], 1) if m.nu else np.zeros((0, 2)),
                    ctrl_names=ctrl_names)


def _extents(disp: _Display, qpos) -> np.ndarray:
    """(n, 4) ``[h_min, h_max, v_min, v_max]`` (m, along ``h_axis`` and ``up``) of every moving geom, per qpos row."""
    import mujoco

    m, d = disp.m, disp.d
    g = disp.moving
    types, size = m.geom_type[g], m.geom_size[g]
    out = np.empty((len(qpos), 4))
    for i, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        c = d.geom_xpos[g]
        R = d.geom_xmat[g].reshape(-1, 3, 3)
        for k, v in enumerate((disp.h_axis, disp.up)):
            proj = np.abs(np.einsum("gij,i->gj", R, v))  # |axis_j . v| per geom
            half = np.where(np.isin(types, (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER)),
                            proj[:, 2] * size[:, 1] + size[:, 0],
                            np.where(types == mujoco.mjtGeom.mjGEOM_SPHERE, size[:, 0],
                                     np.where(np.isin(types, (mujoco.mjtGeom.mjGEOM_BOX,
                                                              mujoco.mjtGeom.mjGEOM_ELLIPSOID)),
                                              (proj * size).sum(1), m.geom_rbound[g])))
            cv = c @ v
            out[i, 2 * k] = (cv - half).min() if g.size else 0.0
            out[i, 2 * k + 1] = (cv + half).max() if g.size else 0.0
    return out


def _smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    """Zero-phase Gaussian smoothing of a 1-D series, ``sigma`` in samples."""
    if sigma <= 0 or x.size < 3:
        return x.copy()
    r = int(3 * sigma) + 1
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    # odd reflection about the end values keeps a ramp a ramp at both ends (no pull towards the mean)
    padded = np.pad(x, r, mode="reflect", reflect_type="odd") if x.size > r else np.pad(x, r, mode="edge")
    return np.convolve(padded, k, mode="valid")


@dataclass(frozen=True)
class CameraPath:
    """A free camera per frame: ``lookat`` (n, 3) m, ``distance`` (n,) m, ``azimuth`` and ``elevation`` in degrees,
    ``view_height`` (m, the height of the system's plane the frame spans), ``follows`` (whether it tracks the
    cart)."""

    lookat: np.ndarray
    distance: np.ndarray
    azimuth: float
    elevation: float
    view_height: float
    follows: bool


def camera_path(ext: np.ndarray, upright: np.ndarray, *, aspect: float, h_axis, up, depth_point, fps: float,
                fovy: float = FOVY, elevation: float = ELEVATION, cart=None, reserve=(0.0, 0.0)) -> CameraPath:
    """Frame a run: per-frame extents ``ext`` (n, 4) ``[h_min, h_max, v_min, v_max]`` of the moving geoms, plus the
    vertical extent ``upright`` (2,) of the chain at ``x_eq`` (its full height, always in the frame).

    The frame's height covers ``v`` over the whole run (and ``upright``) with :data:`MARGIN` on each side; its width
    is that times ``aspect``. If every frame's ``h`` range fits (or fits in a frame up to :data:`FOLLOW_FACTOR` times
    wider, the camera backing off) the camera stands still, centred on the run; otherwise it follows ``cart`` (n,)
    (h coordinate, m) smoothed over :data:`FOLLOW_SMOOTHING` s, clamped so each frame's system stays inside.
    ``reserve`` = (top, bottom): fractions of the frame's height kept free of the system (the overlay's bands).
    """
    h_axis, up = np.asarray(h_axis, float), np.asarray(up, float)
    n = len(ext)
    v_lo = min(ext[:, 2].min(), upright[0])
    v_hi = max(ext[:, 3].max(), upright[1])
    inner = 1.0 - 2 * MARGIN
    top, bottom = (float(r) for r in reserve)
    height = (v_hi - v_lo) / max(inner - top - bottom, 0.2)
    width = height * aspect
    span = (ext[:, 1].max() - ext[:, 0].min()) / inner
    follows = False
    if span <= width:
        centre = np.full(n, 0.5 * (ext[:, 1].max() + ext[:, 0].min()))
    elif span <= FOLLOW_FACTOR * width:
        width, height = span, span / aspect
        centre = np.full(n, 0.5 * (ext[:, 1].max() + ext[:, 0].min()))
    else:
        follows = True
        own = (ext[:, 1] - ext[:, 0]).max() / inner
        width = max(width, 2.0 * own)
        height = width / aspect
        c = 0.5 * (ext[:, 0] + ext[:, 1]) if cart is None else np.asarray(cart, float)
        centre = _smooth(c, FOLLOW_SMOOTHING * fps)
        half = 0.5 * width * inner
        centre = np.clip(centre, ext[:, 1] - half, ext[:, 0] + half)
    v_centre = 0.5 * (v_lo + v_hi) + 0.5 * (top - bottom) * height
    # the depth of the plane of motion (along the viewing direction) is that of the system's own points
    view = np.cross(up, h_axis)
    depth = float(np.asarray(depth_point, float) @ view)
    lookat = centre[:, None] * h_axis + v_centre * up + depth * view
    distance = np.full(n, 0.5 * height / np.tan(np.deg2rad(fovy) / 2) / np.cos(np.deg2rad(elevation)))
    azimuth = float(np.rad2deg(np.arctan2(view[1], view[0])))
    return CameraPath(lookat=lookat, distance=distance, azimuth=azimuth, elevation=elevation, view_height=height,
                      follows=follows)


def _thicken(disp: _Display, view_height: float) -> None:
    """Pole capsules (and cylinders) drawn with radius ``RADIUS_FRACTION * view_height`` (render-only copy)."""
    import mujoco

    m = disp.m
    for gs in disp.link_geoms:
        for g in gs:
            if int(m.geom_type[g]) in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
                length = 2 * m.geom_size[g, 1]
                m.geom_size[g, 0] = max(m.geom_size[g, 0], min(RADIUS_FRACTION * view_height,
                                                               MAX_RADIUS_FRACTION * length))


# ---------------------------------------------------------------------------------------------------------------
# overlay


def _font(size: int, mono: bool = False):
    from PIL import ImageFont

    try:
        import matplotlib

        name = "DejaVuSansMono.ttf" if mono else "DejaVuSans.ttf"
        return ImageFont.truetype(str(Path(matplotlib.get_data_path()) / "fonts" / "ttf" / name), size)
    except Exception:  # no matplotlib fonts: Pillow's own
        return ImageFont.load_default(size)


class _Overlay:
    """Draws the overlay on an (h, w, 3) uint8 frame: a top band (time, each pole's angle from upright in its link's
    colour, the mode tag on the right) and a bottom band (one ctrl bar per actuator against its range).

    ``top`` and ``bottom`` are the bands' heights in pixels: the camera keeps the system out of them.
    """

    BAR = (40, 70, 160)
    SATURATED = (200, 30, 30)
    INK = (15, 15, 15)

    def __init__(self, width: int, height: int, n_poles: int, ctrl_names, ctrl_range, ctrl_scale, show_mode: bool):
        from PIL import Image, ImageDraw

        self.w, self.h = width, height
        self.fs = max(9, int(round(height / 24)))
        self.font = _font(self.fs, mono=True)
        self.bold = _font(self.fs)
        self.pad = max(3, self.fs // 3)
        self.line = int(round(self.fs * 1.35))
        measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
        self.char = measure.textlength("0", font=self.font)
        self.theta = ["θ"] if n_poles == 1 else [f"θ{i + 1}" for i in range(n_poles)]
        self.colours = [tuple(int(255 * c) for c in LINK_COLOURS[i % len(LINK_COLOURS)]) for i in range(n_poles)]
        self.show_mode = show_mode
        self.mode_w = int(measure.textlength("LQR catch", font=self.bold)) + 3 * self.pad if show_mode else 0
        # top band: "t  3.47 s" then one "[] th1  +10.3°" item per pole, wrapped to the width left by the mode tag
        self.t_w = int(self.char * 10)
        self.item_w = int(self.fs + self.pad + self.char * (len(self.theta[-1]) + 8)) + 2 * self.pad
        room = max(1, int((width - self.mode_w - self.t_w - 2 * self.pad) // self.item_w))
        self.per_row = room
        rows = max(1, -(-n_poles // room))
        self.top = 2 * self.pad + self.line * rows
        # bottom band: one bar per actuator
        self.ctrl_names = list(ctrl_names)
        nu = len(self.ctrl_names)
        cr = np.asarray(ctrl_range, float).reshape(nu, 2)
        self.lo = np.where(np.isfinite(cr[:, 0]), cr[:, 0], -ctrl_scale)
        self.hi = np.where(np.isfinite(cr[:, 1]), cr[:, 1], ctrl_scale)
        self.name_w = int(max([measure.textlength(s, font=self.font) for s in self.ctrl_names] + [0])) + self.pad
        self.bar_w = int(width * 0.32)
        self.bottom = (2 * self.pad + self.line * nu) if nu else 0

    @staticmethod
    def _shade(frame, x0, y0, x1, y1):
        region = frame[y0:y1, x0:x1]
        region[:] = (region.astype(np.uint16) * 2 // 7 + 182).astype(np.uint8)  # ~70 % white

    def draw(self, frame: np.ndarray, t: float, angles_deg, ctrl, mode: str | None) -> np.ndarray:
        """The frame (h, w, 3) uint8 with the overlay: time ``t`` (s), ``angles_deg`` (n_poles,), ``ctrl`` (nu,)."""
        from PIL import Image, ImageDraw

        p, L, fs = self.pad, self.line, self.fs
        n = len(angles_deg)
        top_w = min(self.w, self.t_w + min(n, self.per_row) * self.item_w + 2 * p)
        self._shade(frame, 0, 0, top_w, self.top)
        nu = len(self.ctrl_names)
        y_bars = self.h - self.bottom
        bars_w = min(self.w, self.name_w + self.bar_w + int(self.char * 6) + 3 * p)
        if nu:
            self._shade(frame, 0, y_bars, bars_w, self.h)
        img = Image.fromarray(frame)
        dr = ImageDraw.Draw(img)
        dr.text((p, p), f"t {t:5.2f} s", font=self.font, fill=self.INK)
        for i, a in enumerate(angles_deg):
            row, col = divmod(i, self.per_row)
            x = p + self.t_w + col * self.item_w
            y = p + row * L
            dr.rectangle([x, y + 2, x + fs - 2, y + fs], fill=self.colours[i])
            dr.text((x + fs + p, y), f"{self.theta[i]} {a:+6.1f}°", font=self.font, fill=self.INK)
        for k, name in enumerate(self.ctrl_names):
            y = y_bars + p + L * k
            u = float(ctrl[k])
            lo, hi = float(self.lo[k]), float(self.hi[k])
            dr.text((p, y), name, font=self.font, fill=self.INK)
            x0 = p + self.name_w
            x1 = x0 + self.bar_w
            yb0, yb1 = y + 2, y + fs
            dr.rectangle([x0, yb0, x1, yb1], fill=(240, 240, 240), outline=(80, 80, 80))
            span = max(hi - lo, 1e-12)
            pos = lambda v: x0 + (min(max(v, lo), hi) - lo) / span * (x1 - x0)  # noqa: E731
            zero = pos(0.0 if lo <= 0.0 <= hi else lo)
            at_limit = u <= lo + 1e-9 * span or u >= hi - 1e-9 * span
            xa, xb = sorted((zero, pos(u)))
            dr.rectangle([xa, yb0 + 1, max(xb, xa + 1), yb1 - 1], fill=self.SATURATED if at_limit else self.BAR)
            dr.line([zero, yb0 - 2, zero, yb1 + 2], fill=self.INK, width=max(1, fs // 12))
            dr.text((x1 + p, y), f"{u:+.2f}", font=self.font, fill=self.INK)
        if self.show_mode and mode:
            colour = MODE_COLOURS.get(mode.split()[0].lower(), (90, 90, 90))
            tw = int(dr.textlength(mode, font=self.bold))
            x1 = self.w - p
            x0 = x1 - tw - 2 * p
            dr.rounded_rectangle([x0, p - 1, x1, p + fs + 3], radius=max(2, fs // 3), fill=colour)
            dr.text((x0 + p, p), mode, font=self.bold, fill=(255, 255, 255))
        return np.asarray(img)


# ---------------------------------------------------------------------------------------------------------------
# rendering


def _preview_window(times, rollout, idx, modes_at, seconds: float) -> tuple[int, int]:
    """Frame range [j0, j1) of the preview: ending 1.5 s after the last mode switch if there is one, else the
    earliest ``seconds`` with at least 95 % of the most joint motion (sum of |qvel| over the frames)."""
    n = len(times)
    fps = 1.0 / (times[1] - times[0]) if n > 1 else 30.0
    k = max(1, min(n, int(round(seconds * fps))))
    if modes_at is not None:
        changes = [j for j in range(1, n) if modes_at[j] != modes_at[j - 1]]
        if changes:
            j1 = min(n, changes[-1] + int(round(1.5 * fps)))
            j0 = max(0, j1 - k)
            return j0, min(n, j0 + k)
    speed = np.abs(np.asarray(rollout.qvel)[idx]).sum(1)
    if n <= k:
        return 0, n
    window = np.convolve(speed, np.ones(k), mode="valid")
    j0 = int(np.argmax(window >= 0.95 * window.max()))  # the earliest window with nearly the most motion
    return j0, j0 + k


def _write_gif(frames, path: Path, fps: float) -> None:
    """Animated GIF with one palette for every frame (no flicker, small), looping, real-time frame delays."""
    from PIL import Image

    if not frames:
        return
    sample = frames[:: max(1, len(frames) // 6)][:6]
    strip = Image.new("RGB", (sample[0].width, sample[0].height * len(sample)))
    for i, f in enumerate(sample):
        strip.paste(f, (0, i * f.height))
    palette = strip.quantize(colors=128, method=Image.Quantize.MEDIANCUT)
    pal = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    # GIF delays are in 10 ms units: alternate them so the average is exactly 1/fps
    ideal = 1000.0 / fps
    durations = [int(round((i + 1) * ideal / 10.0)) * 10 - int(round(i * ideal / 10.0)) * 10 for i in range(len(pal))]
    pal[0].save(path, format="GIF", save_all=True, append_images=pal[1:], duration=durations, loop=0,
                optimize=False, disposal=1)


def _gl_renderer(m, height, width):
    """``mujoco.Renderer``, or VideoUnavailable naming the backend and the reason it could not make a context."""
    import mujoco

    # GL front ends (glfw) report through warnings as well as exceptions: keep them off stderr, use the first
    # as the reason since it usually names the cause (e.g. "The DISPLAY environment variable is missing").
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            return mujoco.Renderer(m, height=height, width=width)
        except Exception as exc:  # GL failures surface as ImportError, RuntimeError, mujoco.FatalError ...
            backend = os.environ.get("MUJOCO_GL", "") or "default"
            why = first_line(caught[0].message) if caught else first_line(exc)
            why = re.split(r"[,;] ", why.replace("b'", "").replace("'", ""))[0]
            raise VideoUnavailable(f"No working OpenGL backend for offscreen rendering (MUJOCO_GL={backend}: "
                                   f"{why}); install Mesa's EGL or OSMesa, or skip the video.") from None


class _Scene:
    """Everything one run's frames need: the render-only copy, the camera path, the overlay and the GL renderer.

    ``frame(i)`` draws frame ``i`` (the logged state nearest ``t[0] + i / fps``) as an (height, width, 3) uint8
    array. Close it (or use it as a context manager) to free the GL context.
    """

    def __init__(self, source, rollout, *, fps, width, height, camera=None, modes=None, model=None, x_eq=None,
                 overlay=True):
        import mujoco

        self.width, self.height = int(width) // 2 * 2, int(height) // 2 * 2  # even sizes keep yuv420p happy
        if self.width < 2 or self.height < 2:
            raise VideoUnavailable(f"The frame size {self.width}x{self.height} is too small; give width and "
                                   "height >= 2.")
        self.rollout = rollout
        src = source if source is not None else (rollout.mjcf or None)
        self.idx = frame_indices(rollout.t, fps)
        self.times = np.asarray(rollout.t)[0] + np.arange(len(self.idx)) / fps
        qpos = np.asarray(rollout.qpos)[self.idx]
        # the physics model is only read: the frames come from a render-only copy and the logged qpos
        probe = _build_display(src, width=self.width, height=self.height)
        if probe.m.nq != rollout.qpos.shape[1]:
            raise VideoUnavailable(f"The rollout has {rollout.qpos.shape[1]} joint positions per step and the MJCF "
                                   f"has {probe.m.nq}; render it with the MJCF it was run on.")
        if x_eq is None:
            x_eq = _x_eq(src, model, probe.m.nq)
        self.q_up = np.asarray(x_eq, float)[:probe.m.nq] if x_eq is not None else np.asarray(probe.m.qpos0, float)
        ext = _extents(probe, qpos)
        ext_up = _extents(probe, self.q_up[None])[0]
        floor_z = min(ext[:, 2].min(), ext_up[2]) - 0.25 * max(ext_up[3] - ext_up[2], 0.3)
        self.disp = disp = _build_display(src, width=self.width, height=self.height, floor_z=floor_z)
        m, d = disp.m, disp.d
        self.modes_at = _mode_labels(modes, self.times)
        ctrl = np.asarray(rollout.ctrl, float).reshape(len(rollout.t) - 1, -1)
        self.ctrl = ctrl
        ctrl_scale = float(np.abs(ctrl).max()) if ctrl.size else 1.0
        layout = _Overlay(self.width, self.height, len(disp.hinges), disp.ctrl_names, disp.ctrl_range,
                          max(ctrl_scale, 1e-9), show_mode=self.modes_at is not None)
        self.overlay = layout if overlay else None
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
            self.camera_path = camera_path(ext, ext_up[2:], aspect=self.width / self.height, h_axis=disp.h_axis,
                                           up=disp.up, depth_point=depth_point, fps=fps, cart=cart, reserve=reserve)
            _thicken(disp, self.camera_path.view_height)
            self.cam = mujoco.MjvCamera()
            self.cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            self.cam.azimuth, self.cam.elevation = self.camera_path.azimuth, self.camera_path.elevation
        else:
            if isinstance(camera, str) and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
                raise VideoUnavailable(f"The MJCF has no camera named '{camera}'; pass camera=None for the "
                                       "computed view.")
            self.camera_path, self.cam = None, camera
            _thicken(disp, max(ext_up[3] - ext_up[2], 0.3) * 2.0)
        self.renderer = _gl_renderer(m, self.height, self.width)

    def __len__(self) -> int:
        return len(self.idx)

    def frame(self, i: int) -> np.ndarray:
        """Frame ``i`` (height, width, 3) uint8, overlay included."""
        import mujoco

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


def render_frame(source, rollout, t: float = 0.0, *, fps: float = 30, width: int = 960, height: int = 540,
                 camera: str | int | None = None, modes=None, model=None, overlay: bool = True) -> np.ndarray:
    """The video frame :func:`render_video` shows at time ``t`` (s): an (height, width, 3) uint8 RGB array.

    Same render-only copy, camera path (computed over the whole rollout) and overlay as the video; handy in a
    notebook (``plt.imshow(render_frame(model, run, 2.0))``). Parameters as :func:`render_video`. Renders in this
    process only (no OSMesa child): raises :class:`VideoUnavailable` when the GL backend cannot start.
    """
    with _Scene(source, rollout, fps=fps, width=width, height=height, camera=camera, modes=modes, model=model,
                overlay=overlay) as scene:
        i = int(np.clip(np.round((float(t) - scene.times[0]) * fps), 0, len(scene) - 1))
        return scene.frame(i)


def _render_frames(source, rollout, path: Path, *, fps, width, height, camera, progress, modes=None, x_eq=None,
                   overlay=True, preview=None, preview_seconds=4.0, preview_width=480, model=None):
    """Render and encode in this process (raises VideoUnavailable on any GL or encoder failure).

    Returns ``(frames, preview_frames)``.
    """
    import imageio_ffmpeg
    from PIL import Image

    scene = _Scene(source, rollout, fps=fps, width=width, height=height, camera=camera, modes=modes, model=model,
                   x_eq=x_eq, overlay=overlay)
    width, height = scene.width, scene.height
    pv = _preview_window(scene.times, rollout, scene.idx, scene.modes_at, preview_seconds) if preview else (0, 0)
    pv_step = max(1, int(round(fps / 15.0)))
    pv_size = (int(preview_width) // 2 * 2, max(2, int(round(preview_width * height / width)) // 2 * 2))
    pv_frames = []
    n = len(scene)
    every = max(1, n // 50)
    # shown by the caller's progress reporter (a tqdm bar on a terminal, one line otherwise, nothing in --json)
    bar = stage("video", size=f"{n} frames at {fps:g} fps, {width}x{height}",
                callback=progress if callable(progress) else None) if progress is not False else None
    writer = None
    try:
        writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264",
                                             pix_fmt_in="rgb24", pix_fmt_out="yuv420p", macro_block_size=2,
                                             quality=6, output_params=["-movflags", "+faststart", "-preset",
                                                                       "veryfast"])
        writer.send(None)  # start ffmpeg
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
            _write_gif(pv_frames, Path(preview), fps / pv_step)
    except VideoUnavailable:
        raise
    except Exception as exc:
        raise VideoUnavailable(f"Rendering or encoding the video failed ({first_line(exc)}); "
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


def _render_in_child(source, rollout, path: Path, *, fps, width, height, camera, progress, modes=None, x_eq=None,
                     overlay=True, preview=None, preview_seconds=4.0, preview_width=480, model=None,
                     backend: str = "osmesa"):
    """Render with ``MUJOCO_GL=backend`` in a fresh Python process (the only way to switch GL backends)."""
    src = source.params if hasattr(source, "params") and isinstance(source.params, CartPoleParams) else source
    if x_eq is None and model is not None:
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
        times = np.asarray(rollout.t)[0] + np.arange(len(frame_indices(rollout.t, fps))) / fps
        labels = _mode_labels(modes, times)
        job = {"source": str(src) if src else None, "rollout": str(log), "path": str(path), "fps": fps,
               "width": width, "height": height, "camera": camera, "overlay": overlay,
               "modes": None if labels is None else [[float(t), lab] for t, lab in zip(times, labels)
                                                      if lab is not None],
               "x_eq": None if x_eq is None else np.asarray(x_eq, float).tolist(),
               "preview": None if preview is None else str(preview), "preview_seconds": preview_seconds,
               "preview_width": preview_width}
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


def render_video(source, rollout, path, *, fps: float = 30, width: int = 960, height: int = 540,
                 camera: str | int | None = None, progress: Callable[[float], None] | bool | None = None,
                 modes: Sequence | Callable[[float], str] | None = None, model=None, overlay: bool = True,
                 preview: bool | str | Path = True, preview_seconds: float = 4.0,
                 preview_width: int = 480) -> VideoInfo:
    """Render ``rollout`` as an H.264 mp4 (yuv420p, faststart) at ``fps`` frames per second of simulated time, and a
    GIF preview beside it.

    Parameters
    ----------
    source : CartPoleModel, CartPoleParams, MJCF path or None
        The model to draw (None: the rollout's own ``mjcf``, else the shipped asset). Only read: the frames come
        from a render-only copy (see the module's docstring).
    rollout : Rollout
        Logged run; frame ``i`` shows the logged state nearest ``t = t[0] + i / fps`` s.
    path : str or Path
        Output ``.mp4``; parent directories are created. Written to a temporary file, then renamed.
    fps : float
        Frames per second (default 30).
    width, height : int, pixels
        Frame size (default 960x540), rounded down to even numbers; the render-only copy's offscreen buffer is
        made large enough, whatever the MJCF declares.
    camera : str or int, optional
        None (default): the camera computed from the model and the rollout (:func:`camera_path`). A name or id:
        that MJCF camera instead.
    progress : callable, None or False
        The render is a :func:`cartpole.progress.stage` ("video"): shown by the current progress reporter if there
        is one (a tqdm bar on a terminal, one line otherwise, nothing with ``--json``), silent without one. A
        callable also gets the fraction of frames done (0..1, about 50 times, increasing, ending at 1); False
        opens no stage at all.
    modes : sequence of (t_start, label), or callable t -> label, optional
        The controller's mode shown in the overlay's top right (e.g. ``[(0, "energy"), (4.1, "LQR catch")]``;
        :func:`modes_from_switches`, :func:`swingup_modes`); None: no mode shown.
    model : CartPoleModel, optional
        Its ``x_eq`` is upright for the overlay's angles; built from ``source`` when not given (and the MJCF's
        ``qpos0`` used if the toolkit cannot build one).
    overlay : bool
        Draw the time, angles, ctrl bars and mode (default True).
    preview : bool or path
        True (default): an animated GIF beside the mp4 (same stem, ``.gif``); a path: there; False: none.
    preview_seconds : float
        Length of the preview, s of simulated time (default 4; at 15 fps).
    preview_width : int, pixels
        Width of the preview (default 480; the height keeps the aspect).

    Returns
    -------
    VideoInfo
        Paths, frame count, length, size and the wall-clock render time; it also stands for the mp4's path.

    Raises
    ------
    VideoUnavailable
        No working OpenGL backend (EGL, then OSMesa in a child process, were tried), the encoder failed, an unknown
        camera name, a rollout that does not match the MJCF, or bad ``modes``.
    """
    start = time.perf_counter()
    path = Path(path)
    gif = None if preview is False or preview is None else (path.with_suffix(".gif") if preview is True
                                                            else Path(preview))
    made = [p for p in (path.parent, *path.parent.parents) if not p.exists()]
    if gif is not None:
        made += [p for p in (gif.parent, *gif.parent.parents) if not p.exists() and p not in made]
    opts = dict(fps=fps, width=width, height=height, camera=camera, progress=progress, modes=modes, model=model,
                overlay=overlay, preview_seconds=preview_seconds, preview_width=preview_width)
    if not (np.isfinite(fps) and fps > 0):
        raise VideoUnavailable(f"The frame rate {fps} is not positive; give fps > 0.")
    ok = False
    backend = os.environ.get("MUJOCO_GL", "").lower() or "default"
    try:
        # the temporary files keep their endings: ffmpeg and Pillow pick the format from the name
        with ExitStack() as files:
            tmp = files.enter_context(atomic_path(path, suffix=path.suffix or ".mp4"))
            tmp_gif = files.enter_context(atomic_path(gif, suffix=".gif")) if gif is not None else None
            try:
                frames, pv_frames = _render_frames(source, rollout, tmp, preview=tmp_gif, **opts)
            except VideoUnavailable as first:
                if backend != "egl" or not _osmesa_available() or "OpenGL" not in str(first):
                    raise
                try:
                    frames, pv_frames = _render_in_child(source, rollout, tmp, preview=tmp_gif, **opts)
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
    return VideoInfo(path=path, preview=gif, frames=frames, fps=float(fps), seconds=frames / float(fps),
                     size=(int(width) // 2 * 2, int(height) // 2 * 2), render_s=time.perf_counter() - start,
                     preview_frames=pv_frames, backend=backend)


def _child_main(argv) -> int:
    """Entry of the OSMesa fallback child: ``python -m cartpole.viz.video JOB_JSON``; prints ``frames preview``."""
    job = json.loads(argv[0])
    try:
        n, k = _render_frames(job["source"], Rollout.load(job["rollout"]), Path(job["path"]), fps=job["fps"],
                              width=job["width"], height=job["height"], camera=job["camera"], progress=False,
                              modes=job.get("modes"), x_eq=job.get("x_eq"), overlay=job.get("overlay", True),
                              preview=job.get("preview"), preview_seconds=job.get("preview_seconds", 4.0),
                              preview_width=job.get("preview_width", 480))
    except CartPoleError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    print(n, k)
    return 0


if __name__ == "__main__":
    sys.exit(_child_main(sys.argv[1:]))
