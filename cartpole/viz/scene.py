"""What a video frame shows, before any pixel is drawn: the frame clock, the render-only copy of the model and the
camera (used by :mod:`cartpole.viz.video`, which draws the frames, and :mod:`cartpole.viz.overlay`).

* **Only the log, on a clock of its own.** Frame ``i`` shows the logged ``qpos`` nearest ``t = t[0] + i / fps``
  (:func:`frame_indices`; 30 fps in the video whatever the physics step: a 10 s run is 300 frames played in real
  time). Nothing is re-simulated: the frames come from ``mj_kinematics`` of the logged positions.
* **A render-only copy of the model** (:func:`build_display`). The MJCF is compiled a second time, for drawing only,
  and that copy is dressed for reading on a small screen: a gradient sky, a floor with a 0.5 m checker and a line
  every metre (it gives the scale; the MJCF's own plane is reused when it has one), poles drawn thicker
  (:func:`thicken_poles`: capsule radius about 1.6 % of the view's height, at most 12 % of the link's length, never
  thinner than the MJCF's) in one colour per link (:data:`LINK_COLOURS`, first link red). Before compiling only
  textures, materials and (when the MJCF has no plane) a floor are added; the thicker radii and the colours are set
  on the compiled copy (``geom_size``, ``geom_rgba``), so its bodies, joints, masses and inertias stay the physics
  model's. The physics model itself is never touched.
* **A camera computed from the model and the rollout** (:func:`camera_path`, a free ``mujoco.MjvCamera``, not the
  MJCF's camera): it looks across the plane of motion (perpendicular to the slide and to gravity), 12 degrees from
  above, and frames every moving geom in every frame (:func:`geom_extents`) plus the chain's full upright height
  (the geoms at ``x_eq``). When the cart's travel fits in the frame (or in a frame up to 1.6 times wider) the
  camera stands still; otherwise it follows the cart, its aim the cart's position smoothed over 0.3 s (zero-phase
  Gaussian, the whole log is known) and nudged only where a link would leave the frame.

Two costs are chosen here, for a software renderer (Mesa's llvmpipe): 2x multisampling (:data:`OFFSAMPLES`; 4x
costs about 1.6 times more) and a floor drawn with 1 m quads (its ``size[2]``; 0.1 m quads on the 80 m floor took
most of the GL time). Every failure is a :class:`VideoUnavailable` with one sentence.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from cartpole.errors import FOREIGN_WIDTH, CartPoleError, first_line
from cartpole.models import CartPoleParams, is_urdf, load_model, plant_model
from cartpole.sim import ctrl_bounds, make_mujoco, source_path

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


class VideoUnavailable(CartPoleError):
    """No working OpenGL backend or video encoder: the video cannot be made on this machine."""


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


# ---------------------------------------------------------------------------------------------------------------
# the render-only model


def upright_qpos(plant, model, nq: int) -> np.ndarray | None:
    """The upright qpos (nq,) (m, rad) the overlay measures angles from and the camera frames the full height at.

    ``model.x_eq`` when a model is given, else ``source.x_eq`` when the source has one, else the ``x_eq`` of the
    model built from ``source`` (an MJCF path or parameters); None when the toolkit cannot build a model of it (the
    caller then uses MuJoCo's ``qpos0``).
    """
    if model is not None:
        return np.asarray(model.x_eq, float)[:nq]
    if hasattr(plant, "x_eq"):
        return np.asarray(plant.x_eq, float)[:nq]

    try:
        return np.asarray(plant_model(plant).x_eq, float)[:nq]
    except CartPoleError:  # not a model the toolkit builds: angles from MuJoCo's qpos0
        return None


def _spec(source):
    """A fresh ``mujoco.MjSpec`` of the source (its MJCF file, else its XML text)."""
    params = source.params if hasattr(source, "params") and isinstance(source.params, CartPoleParams) else source
    make_mujoco(params)  # validates the source with the toolkit's one-sentence errors
    if isinstance(params, CartPoleParams):
        if params.mjcf and params.urdf is None:
            return mujoco.MjSpec.from_file(params.mjcf)
        return mujoco.MjSpec.from_string(params.xml)  # MJCF text, or a URDF's with its motors

    path = source_path(params)
    _, _, text = load_model(path)
    return mujoco.MjSpec.from_string(text) if is_urdf(Path(path).read_text()) else mujoco.MjSpec.from_file(path)


@dataclass
class Display:
    """The render-only copy of a model (:func:`build_display`) and what the frames need to know about it.

    Not frozen: it holds MuJoCo's own mutable objects, and :func:`thicken_poles` widens the poles of ``m`` once the
    camera is known.

    Attributes
    ----------
    m : mujoco.MjModel
        The render-only copy (same bodies, joints and inertias as the physics model; its own look).
    d : mujoco.MjData
        Data of ``m``, set from the logged qpos frame by frame.
    hinges : list of int
        qpos addresses of the hinges, tree order.
    link_geoms : list of list of int
        Per hinge, the geom ids of its body.
    moving : (n_moving,) int array
        Visible geom ids on moving bodies.
    slide : int or None
        qpos address of the first slide joint (the cart), None without one.
    h_axis : (3,) array
        Unit horizontal direction across the screen (the slide's axis, made level).
    up : (3,) array
        Unit screen up (against gravity).
    ctrl_range : (nu, 2) array
        ``[low, high]`` ctrl of each actuator (MuJoCo ctrl units).
    ctrl_names : list of str
        Each actuator's name (``u<k>`` when it has none).
    """

    m: object
    d: object
    hinges: list
    link_geoms: list
    moving: np.ndarray
    slide: int | None
    h_axis: np.ndarray
    up: np.ndarray
    ctrl_range: np.ndarray
    ctrl_names: list


def build_display(plant, *, width: int, height: int, floor_z: float | None = None) -> Display:
    """Compile the render-only copy of ``source`` (a model, parameters or an MJCF path): sky, grid floor, an
    offscreen buffer of at least ``width`` x ``height`` pixels, lighting, one colour per link.

    ``floor_z`` (m): the height of the floor added when the MJCF has no plane of its own (None: none added). The
    physics model is only read. Raises :class:`VideoUnavailable` when the copy does not compile.
    """
    spec = _spec(plant)
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
        raise VideoUnavailable(f"The render-only copy of the MJCF does not compile ({first_line(exc, FOREIGN_WIDTH)}); "
                               "skip the video (`video=False`).") from None
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
    return Display(m=m, d=d, hinges=hinges, link_geoms=link_geoms, moving=moving, slide=slide,
                    h_axis=h_axis, up=up, ctrl_range=np.stack([lo, hi], 1) if m.nu else np.zeros((0, 2)),
                    ctrl_names=ctrl_names)


def geom_extents(disp: Display, qpos) -> np.ndarray:
    """Extents of the moving geoms at each row of ``qpos`` (n, nq): (n, 4) ``[h_min, h_max, v_min, v_max]`` in m,
    along ``disp.h_axis`` and ``disp.up``, over every geom in ``disp.moving`` (``disp.d`` is left at the last row)."""
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


def camera_path(ext: np.ndarray, upright: np.ndarray, *, aspect: float, axes, depth_point, fps: float,
                fovy: float = FOVY, elevation: float = ELEVATION, cart=None, reserve=(0.0, 0.0)) -> CameraPath:
    """Frame a run: per-frame extents ``ext`` (n, 4) ``[h_min, h_max, v_min, v_max]`` of the moving geoms, plus the
    vertical extent ``upright`` (2,) of the chain at ``x_eq`` (its full height, always in the frame).

    The frame's height covers ``v`` over the whole run (and ``upright``) with :data:`MARGIN` on each side; its width
    is that times ``aspect``. If every frame's ``h`` range fits (or fits in a frame up to :data:`FOLLOW_FACTOR` times
    wider, the camera backing off) the camera stands still, centred on the run; otherwise it follows ``cart`` (n,)
    (h coordinate, m) smoothed over :data:`FOLLOW_SMOOTHING` s, clamped so each frame's system stays inside.
    ``reserve`` = (top, bottom): fractions of the frame's height kept free of the system (the overlay's bands).
    ``axes`` = (h_axis, up): the world directions (3,) of the frame's horizontal and vertical (a :class:`Display`'s
    ``h_axis`` and ``up``); ``depth_point`` (3,) sets the camera's distance along the third.
    """
    h_axis, up = (np.asarray(a, float) for a in axes)
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


def thicken_poles(disp: Display, view_height: float) -> None:
    """Draw the pole capsules (and cylinders) of the render-only copy ``disp.m`` with radius :data:`RADIUS_FRACTION`
    times ``view_height`` (m, the height of the system's plane the frame spans), at most
    :data:`MAX_RADIUS_FRACTION` of the link's length and never thinner than the MJCF's (changes ``geom_size``)."""
    m = disp.m
    for gs in disp.link_geoms:
        for g in gs:
            if int(m.geom_type[g]) in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
                length = 2 * m.geom_size[g, 1]
                m.geom_size[g, 0] = max(m.geom_size[g, 0], min(RADIUS_FRACTION * view_height,
                                                               MAX_RADIUS_FRACTION * length))
