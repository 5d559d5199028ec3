"""The rig's sensors: what is measured (from the MJCF's ``<sensor>`` block, or an encoder on every joint), its noise,
quantisation and bias, and a seeded sampler that reads them from a live MuJoCo run.

A measurement ``y`` (ny,) is the sensors' entries in order (a 3-axis sensor gives three, ``name_x``, ``name_y``,
``name_z``). What the rig reports for entry ``i`` is::

    y_i = Q_i(clean_i + bias_i + noise_std_i * n_i),    n_i ~ N(0, 1) independent,
    Q_i(v) = round(v / resolution_i) * resolution_i      (mid-tread; Q_i(v) = v when resolution_i = 0)

``clean`` is what MuJoCo computes (``d.sensordata``; ``d.qpos`` for the default encoders) and what
:func:`cartpole.estimation.measurement.measurement_function` reproduces exactly from ``x`` and ``u``. The estimators
treat quantisation as uniform noise of variance ``resolution^2 / 12`` (:meth:`SensorSpec.measurement_covariance`)
and do not know the bias: it is a miscalibration to be robust to, not part of ``h``.

Supported MJCF sensors (those a function of ``x = [qpos, qvel]`` and ``u = ctrl`` reproduces exactly): ``jointpos``,
``jointvel``, ``actuatorfrc`` (MuJoCo's actuator-space force ``gain * ctrl``, before the gear),
``jointactuatorfrc`` (``gear * gain * ctrl`` summed on the joint), ``framepos``, ``framexaxis`` / ``yaxis`` /
``zaxis`` and ``framelinvel`` / ``frameangvel`` of a site, body (its inertial frame), xbody (its frame) or geom, in the
world or a reference frame, ``framelinacc`` / ``frameangacc`` (world), and on a site ``velocimeter``, ``gyro`` and
``accelerometer`` (proper acceleration in the site frame: gravity included). MuJoCo's ``cutoff`` clamps real-valued
sensors to ``[-cutoff, cutoff]``, and so does ``h``. Anything else (touch, rangefinder, user, plugin, force, a
sensor ``delay`` or ``interval``) is refused with one sentence (:class:`SensorError`). MuJoCo's ``noise`` attribute
is the default ``noise_std`` (MuJoCo itself no longer applies it).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from cartpole._arrays import readonly
from cartpole._files import short
from cartpole.estimation.base import EstimationError
from cartpole.models import CartPoleModel, CartPoleParams, load_model, mujoco_model

#: Supported kinds -> (dim, what they depend on): "position" (qpos alone), "rate" (qvel too), "input" (ctrl),
#: "acceleration" (qpos, qvel and ctrl, through the dynamics).
KINDS = {
    "jointpos": (1, "position"), "jointvel": (1, "rate"), "actuatorfrc": (1, "input"),
    "jointactuatorfrc": (1, "input"), "framepos": (3, "position"), "framexaxis": (3, "position"),
    "frameyaxis": (3, "position"), "framezaxis": (3, "position"), "framelinvel": (3, "rate"),
    "frameangvel": (3, "rate"), "velocimeter": (3, "rate"), "gyro": (3, "rate"),
    "accelerometer": (3, "acceleration"), "framelinacc": (3, "acceleration"), "frameangacc": (3, "acceleration"),
}

_MJ_KIND = {"JOINTPOS": "jointpos", "JOINTVEL": "jointvel", "ACTUATORFRC": "actuatorfrc",
            "JOINTACTFRC": "jointactuatorfrc", "FRAMEPOS": "framepos", "FRAMEXAXIS": "framexaxis",
            "FRAMEYAXIS": "frameyaxis", "FRAMEZAXIS": "framezaxis", "FRAMELINVEL": "framelinvel",
            "FRAMEANGVEL": "frameangvel", "VELOCIMETER": "velocimeter", "GYRO": "gyro",
            "ACCELEROMETER": "accelerometer", "FRAMELINACC": "framelinacc", "FRAMEANGACC": "frameangacc"}
_FRAME_KINDS = {"framepos", "framexaxis", "frameyaxis", "framezaxis", "framelinvel", "frameangvel", "framelinacc",
                "frameangacc"}
_SITE_KINDS = {"velocimeter", "gyro", "accelerometer"}
_UNITS = {"framepos": "m", "framexaxis": "1", "frameyaxis": "1", "framezaxis": "1", "framelinvel": "m/s",
          "velocimeter": "m/s", "frameangvel": "rad/s", "gyro": "rad/s", "accelerometer": "m/s^2",
          "framelinacc": "m/s^2", "frameangacc": "rad/s^2"}
_SUPPORTED = ("supported are " + ", ".join(KINDS) + " (frames of a site, body, xbody or geom; velocimeter, gyro and "
              "accelerometer on a site)")


class SensorError(EstimationError):
    """A sensor the toolkit cannot model exactly, or a noise, bias, resolution or encoder setting that is invalid."""


@dataclass(frozen=True)
class SensorFrame:
    """A frame rigidly attached to one body: where a frame sensor looks, or its reference frame.

    Attributes
    ----------
    objtype : str
        What MuJoCo names: ``"site"``, ``"body"`` (the body's inertial frame), ``"xbody"`` (the body frame) or
        ``"geom"``.
    body : int
        Index into :attr:`CartPoleParams.bodies` of the body carrying it, or -1 for one fixed in the world.
    pos : tuple of 3 floats
        Frame origin in the body frame, m (for ``body = -1``: in the world).
    quat : tuple of 4 floats
        Frame orientation in the body frame, ``(w, x, y, z)`` (for ``body = -1``: in the world).
    """

    objtype: str
    body: int
    pos: tuple
    quat: tuple


@dataclass(frozen=True)
class Sensor:
    """One sensor: ``dim`` entries of ``y`` in the units ``units``.

    Attributes
    ----------
    name : str
        The MJCF sensor's name (``"<kind>_<index>"`` when unnamed), or ``"<joint>_encoder"`` for a default encoder.
    kind : str
        One of :data:`KINDS`.
    target : int
        qpos index (joint sensors), actuator index (``actuatorfrc``), MuJoCo site/body/geom id (frame sensors).
    dim : int
        1 or 3.
    noise_std : float
        Standard deviation of the additive Gaussian noise, in ``units``.
    resolution : float
        Quantum, in ``units`` (0: not quantised).
    bias : float
        Added to every entry, in ``units``.
    units : str
        ``"m"``, ``"rad"``, ``"m/s"``, ``"rad/s"``, ``"N"``, ``"N m"``, ``"m/s^2"``, ``"rad/s^2"``, ``"1"`` (unit
        vectors); for ``actuatorfrc`` on a gear ``g`` != 1, ``"g N"`` (the joint force is ``g`` times the value).
    adr : int
        First entry in MuJoCo's ``d.sensordata``; -1 for a default encoder, which reads ``d.qpos[target]``.
    cutoff : float
        MuJoCo clamps the value to ``[-cutoff, cutoff]`` (0: no clamp).
    frame, ref : SensorFrame or None
        The frame measured (frame and site sensors) and the reference frame it is expressed in (None: the world).
    scale : float
        ``actuatorfrc``: the actuator's gain (value = ``scale * ctrl``); 1 otherwise.
    """

    name: str
    kind: str
    target: int
    dim: int
    noise_std: float = 0.0
    resolution: float = 0.0
    bias: float = 0.0
    units: str = ""
    adr: int = -1
    cutoff: float = 0.0
    frame: SensorFrame | None = None
    ref: SensorFrame | None = None
    scale: float = 1.0

    def __post_init__(self):
        if self.kind not in KINDS or KINDS[self.kind][0] != self.dim:
            raise SensorError(f"Sensor '{self.name}' of kind '{self.kind}' with {self.dim} entries is not one the "
                              f"toolkit models; {_SUPPORTED}.")
        for what, v in (("noise_std", self.noise_std), ("resolution", self.resolution)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise SensorError(f"Sensor '{self.name}' has {what} {v!r}; give a finite number >= 0 in "
                                  f"{self.units or 'its units'}.")
        if not (isinstance(self.bias, (int, float)) and math.isfinite(self.bias)):
            raise SensorError(f"Sensor '{self.name}' has bias {self.bias!r}; give a finite number in "
                              f"{self.units or 'its units'}.")

    @property
    def entry_names(self) -> tuple:
        """Name of each entry: ``name`` (dim 1) or ``name_x``, ``name_y``, ``name_z``."""
        return (self.name,) if self.dim == 1 else tuple(f"{self.name}_{c}" for c in "xyz")


@dataclass(frozen=True)
class SensorSpec:
    """The rig's sensors in measurement order: ``y`` (ny,) is their entries, one after the other.

    Attributes
    ----------
    sensors : tuple of Sensor
    """

    sensors: tuple

    def _per_entry(self, field: str) -> np.ndarray:
        return readonly([getattr(s, field) for s in self.sensors for _ in range(s.dim)])

    @property
    def ny(self) -> int:
        """Number of measured entries."""
        return sum(s.dim for s in self.sensors)

    @property
    def names(self) -> tuple:
        """(ny,) name of each entry (``"slider_encoder"``, ``"tip_x"``, ...)."""
        return tuple(n for s in self.sensors for n in s.entry_names)

    @property
    def units(self) -> tuple:
        """(ny,) unit of each entry."""
        return tuple(s.units for s in self.sensors for _ in range(s.dim))

    @property
    def noise_std(self) -> np.ndarray:
        """(ny,) noise standard deviations, in each entry's units."""
        return self._per_entry("noise_std")

    @property
    def resolution(self) -> np.ndarray:
        """(ny,) quanta, in each entry's units (0: not quantised)."""
        return self._per_entry("resolution")

    @property
    def bias(self) -> np.ndarray:
        """(ny,) biases, in each entry's units."""
        return self._per_entry("bias")

    @property
    def position_only(self) -> bool:
        """True when every entry is a function of qpos alone (encoders, frame positions and axes): ``y`` then
        carries nothing about the rates, which the estimator must infer from the motion."""
        return all(KINDS[s.kind][1] == "position" for s in self.sensors)

    @property
    def measures_rates(self) -> bool:
        """True when a sensor measures a velocity (``jointvel``, ``gyro``, ``velocimeter``, ``frame*vel``)."""
        return any(KINDS[s.kind][1] == "rate" for s in self.sensors)

    def measurement_covariance(self) -> np.ndarray:
        """``V`` (ny, ny) = ``diag(noise_std^2 + resolution^2 / 12)`` in squared sensor units: the quantisation
        error taken as uniform on ``[-res/2, res/2]``, independent of the Gaussian noise."""
        return readonly(np.diag(self.noise_std ** 2 + self.resolution ** 2 / 12.0))

    def to_dict(self) -> dict:
        """JSON-ready description: ``ny``, ``names``, ``units``, ``noise_std``, ``resolution``, ``bias`` (lists of
        ny), ``position_only``, ``measures_rates`` and ``sensors`` (one object per sensor with its fields)."""
        def frame(f):
            return None if f is None else {"objtype": f.objtype, "body": f.body, "pos": list(f.pos),
                                           "quat": list(f.quat)}
        sensors = [{"name": s.name, "kind": s.kind, "target": s.target, "dim": s.dim, "noise_std": s.noise_std,
                    "resolution": s.resolution, "bias": s.bias, "units": s.units, "adr": s.adr, "cutoff": s.cutoff,
                    "frame": frame(s.frame), "ref": frame(s.ref), "scale": s.scale} for s in self.sensors]
        return {"ny": self.ny, "names": list(self.names), "units": list(self.units),
                "noise_std": self.noise_std.tolist(), "resolution": self.resolution.tolist(),
                "bias": self.bias.tolist(), "position_only": self.position_only,
                "measures_rates": self.measures_rates, "sensors": sensors}


# ---- reading the MJCF -------------------------------------------------------------------------------------------
def _compiled(source):
    """(MjModel, where) of a CartPoleModel, CartPoleParams or MJCF path."""
    if isinstance(source, CartPoleModel):
        source = source.params
    if isinstance(source, CartPoleParams):
        m = mujoco_model(source)  # a URDF's params: their MJCF text, motors included
        return m, f"MJCF '{short(source.mjcf)}'" if source.mjcf else "The MJCF"
    m, path, _ = load_model(None if source is None else Path(source))
    return m, f"MJCF '{short(path)}'"


def _frame(m, d, objtype: int, objid: int, moving: dict) -> SensorFrame:
    ob = mujoco.mjtObj
    if objtype == ob.mjOBJ_SITE:
        kind, body, pos, quat = "site", m.site_bodyid[objid], m.site_pos[objid], m.site_quat[objid]
    elif objtype == ob.mjOBJ_GEOM:
        kind, body, pos, quat = "geom", m.geom_bodyid[objid], m.geom_pos[objid], m.geom_quat[objid]
    elif objtype == ob.mjOBJ_BODY:
        kind, body, pos, quat = "body", objid, m.body_ipos[objid], m.body_iquat[objid]
    else:  # xbody: the caller admits nothing else
        kind, body, pos, quat = "xbody", objid, np.zeros(3), np.array([1.0, 0, 0, 0])
    body = int(body)
    if body not in moving:  # fixed in the world: its world pose is a constant
        wq = np.zeros(4)
        mujoco.mju_mulQuat(wq, d.xquat[body], np.asarray(quat, float))
        pos, quat, body = d.xpos[body] + d.xmat[body].reshape(3, 3) @ pos, wq, -1
    else:
        body = moving[body]
    return SensorFrame(kind, body, tuple(float(v) for v in pos), tuple(float(v) for v in quat))


def _mjcf_sensors(m, where: str) -> list:
    """The MJCF's sensors as :class:`Sensor` objects, refusing what cannot be modelled exactly."""
    ob, jt = mujoco.mjtObj, mujoco.mjtJoint
    if int(m.opt.disableflags) & mujoco.mjtDisableBit.mjDSBL_SENSOR:
        raise SensorError(f"{where} disables sensors (<flag sensor=\"disable\"/>), so MuJoCo reports none; "
                          "remove that flag or the <sensor> block.")
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    moving = {b: i for i, b in enumerate(b for b in range(1, m.nbody) if m.body_weldid[b] != 0)}
    frames = {int(ob.mjOBJ_SITE), int(ob.mjOBJ_BODY), int(ob.mjOBJ_XBODY), int(ob.mjOBJ_GEOM)}
    out = []
    for i in range(m.nsensor):
        mjname = mujoco.mjtSensor(int(m.sensor_type[i])).name.removeprefix("mjSENS_")
        kind = _MJ_KIND.get(mjname)
        name = mujoco.mj_id2name(m, ob.mjOBJ_SENSOR, i) or f"{kind or mjname.lower()}_{i}"
        if kind is None:
            raise SensorError(f"{where} has sensor '{name}' of type {mjname.lower()}, which the toolkit cannot "
                              f"model exactly from the state and ctrl; {_SUPPORTED}.")
        if m.sensor_delay[i] != 0 or np.any(m.sensor_interval[i] != 0):
            raise SensorError(f"{where} gives sensor '{name}' a delay or interval, which changes what MuJoCo "
                              "reports; remove it and set the rig's `delay` and `period` instead.")
        objtype, objid = int(m.sensor_objtype[i]), int(m.sensor_objid[i])
        reftype, refid = int(m.sensor_reftype[i]), int(m.sensor_refid[i])
        frame = ref = None
        scale = 1.0
        if kind in ("jointpos", "jointvel", "jointactuatorfrc"):
            target = int(m.jnt_qposadr[objid])
            slide = m.jnt_type[objid] == jt.mjJNT_SLIDE
            units = {"jointpos": ("m", "rad"), "jointvel": ("m/s", "rad/s"),
                     "jointactuatorfrc": ("N", "N m")}[kind][0 if slide else 1]
        elif kind == "actuatorfrc":
            target, scale = objid, float(m.actuator_gainprm[objid, 0])
            gear = float(m.actuator_gear[objid, 0])
            base = "N" if m.jnt_type[m.actuator_trnid[objid, 0]] == jt.mjJNT_SLIDE else "N m"
            units = base if gear == 1 else f"{gear:g} {base}"
        else:
            if objtype not in frames or (kind in _SITE_KINDS and objtype != ob.mjOBJ_SITE):
                raise SensorError(f"{where} has sensor '{name}' ({kind}) on a {ob(objtype).name[6:].lower()}; "
                                  f"{_SUPPORTED}.")
            if refid >= 0 and (reftype not in frames or kind in ("framelinacc", "frameangacc")):
                raise SensorError(f"{where} gives sensor '{name}' ({kind}) a reference frame the toolkit does not "
                                  "model; use a site, body, xbody or geom reference (none for accelerations).")
            target, units = objid, _UNITS[kind]
            frame = _frame(m, d, objtype, objid, moving)
            ref = _frame(m, d, reftype, refid, moving) if refid >= 0 else None
        real = m.sensor_datatype[i] == mujoco.mjtDataType.mjDATATYPE_REAL
        out.append(Sensor(name=name, kind=kind, target=target, dim=KINDS[kind][0],
                          noise_std=float(m.sensor_noise[i]), units=units, adr=int(m.sensor_adr[i]),
                          cutoff=float(m.sensor_cutoff[i]) if real else 0.0, frame=frame, ref=ref, scale=scale))
    return out


def _default_encoders(m) -> list:
    out = []
    for j in range(m.njnt):
        slide = m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE
        jname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
        out.append(Sensor(name=f"{jname}_encoder", kind="jointpos", target=int(m.jnt_qposadr[j]), dim=1,
                          units="m" if slide else "rad"))
    return out


def _per_sensor(what: str, value, sensors: list, unit_hint: str) -> dict:
    """``name -> float`` from one number (every sensor) or a mapping ``sensor name -> number``."""
    names = [s.name for s in sensors]
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(names))
        if unknown:
            raise SensorError(f"The {what} names sensor(s) {', '.join(map(repr, unknown))}, which the rig does not "
                              f"have; its sensors are {', '.join(names)}.")
        items = dict(value)
    else:
        items = dict.fromkeys(names, value)
    out = {}
    for name, v in items.items():
        try:
            f = float(v)
        except (TypeError, ValueError):
            f = math.nan
        if isinstance(v, bool) or not math.isfinite(f) or (what == "noise" and f < 0):
            raise SensorError(f"The {what} {v!r} for sensor '{name}' is not {unit_hint}.")
        out[name] = f
    return out


def sensor_spec(plant=None, *, encoder_cpr=None, encoder_resolution=None, noise_std=None, bias=None) -> SensorSpec:
    """The rig's sensors: the MJCF's ``<sensor>`` block, or without one an encoder on every joint.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (its MJCF is compiled again to read the sensors); default the shipped asset.
    encoder_cpr : int, optional
        Counts per revolution of every hinge encoder (``jointpos`` on a hinge): resolution ``2 pi / N`` rad.
    encoder_resolution : float, optional
        Metres per count of every slide encoder (``jointpos`` on a slide), m.
    noise_std : float or dict, optional
        Noise standard deviation (sensor units) of every sensor, or ``{sensor name: std}``; default MuJoCo's
        ``noise`` attribute (0 for the default encoders).
    bias : float or dict, optional
        Bias (sensor units) of every sensor, or ``{sensor name: bias}``; default 0.

    Returns
    -------
    SensorSpec

    Raises
    ------
    SensorError
        A sensor type the toolkit cannot model exactly, a noise that is negative or not finite, a bias that is not
        finite, a cpr that is not a positive whole number, a resolution that is not positive and finite.
    MJCFError
        An MJCF that does not compile.
    """
    m, where = _compiled(plant)
    sensors = _mjcf_sensors(m, where) if m.nsensor else _default_encoders(m)
    res = {}
    if encoder_cpr is not None:
        ok = not isinstance(encoder_cpr, bool) and isinstance(encoder_cpr, (int, float, np.integer, np.floating))
        if not (ok and math.isfinite(encoder_cpr) and encoder_cpr >= 1 and float(encoder_cpr).is_integer()):
            raise SensorError(f"The encoder counts per revolution {encoder_cpr!r} is not a positive whole number; "
                              "give e.g. `encoder_cpr` 2048.")
        res["rad"] = 2 * math.pi / float(encoder_cpr)
    if encoder_resolution is not None:
        try:
            r = float(encoder_resolution)
        except (TypeError, ValueError):
            r = math.nan
        if isinstance(encoder_resolution, bool) or not (math.isfinite(r) and r > 0):
            raise SensorError(f"The encoder resolution {encoder_resolution!r} m is not a positive finite number of "
                              "metres per count; give e.g. `encoder_resolution` 1e-4.")
        res["m"] = r
    noise = _per_sensor("noise", noise_std, sensors, "a finite standard deviation >= 0 in its units") \
        if noise_std is not None else {}
    offs = _per_sensor("bias", bias, sensors, "a finite number in its units") if bias is not None else {}
    out = []
    for s in sensors:
        changes = {}
        if s.kind == "jointpos" and s.units in res:
            changes["resolution"] = res[s.units]
        if s.name in noise:
            changes["noise_std"] = noise[s.name]
        if s.name in offs:
            changes["bias"] = offs[s.name]
        out.append(replace(s, **changes) if changes else s)
    return SensorSpec(sensors=tuple(out))


# ---- sampling a live MuJoCo run ---------------------------------------------------------------------------------
class SensorSampler:
    """Reads the rig's sensors from a live ``mujoco.MjData``: MuJoCo's clean value, plus bias, plus seeded Gaussian
    noise, then quantised (mid-tread: ``round(v / res) * res``, numpy's round half to even).

    What ``d`` must hold: for MJCF sensors ``d.sensordata`` of the current ``qpos``, ``qvel`` and ``ctrl``, i.e.
    ``mujoco.mj_forward(m, d)`` called after the last change of them (``mj_step`` leaves ``sensordata`` computed at
    the state *before* its integration); the default encoders read ``d.qpos`` and need nothing.

    Parameters
    ----------
    spec : SensorSpec
    m : mujoco.MjModel
        The model ``d`` belongs to (checked against the spec's addresses).
    seed : int, optional
        Seed of the noise's ``numpy.random.Generator``: the same seed gives the same draws.
    """

    def __init__(self, spec: SensorSpec, m, seed: int = 0):
        self.spec = spec
        self.rng = np.random.default_rng(seed)
        rows = np.arange(spec.ny)
        src = np.concatenate([np.arange(s.dim) + (s.adr if s.adr >= 0 else s.target) for s in spec.sensors]
                             ).astype(int) if spec.sensors else np.zeros(0, int)
        from_data = np.concatenate([np.full(s.dim, s.adr >= 0) for s in spec.sensors]) if spec.sensors \
            else np.zeros(0, bool)
        self._data_rows, self._data_idx = rows[from_data], src[from_data]
        self._qpos_rows, self._qpos_idx = rows[~from_data], src[~from_data]
        if (self._data_idx.size and self._data_idx.max() >= m.nsensordata) or \
                (self._qpos_idx.size and self._qpos_idx.max() >= m.nq):
            raise SensorError(f"The sensors ({', '.join(spec.names)}) do not belong to this MuJoCo model "
                              f"({m.nsensordata} sensor entries, nq = {m.nq}); build the spec from the same MJCF.")
        self._std, self._res, self._bias = spec.noise_std, spec.resolution, spec.bias
        self._quantised = self._res > 0

    def clean(self, d) -> np.ndarray:
        """The noise-free, unbiased, unquantised value (ny,) in sensor units, from ``d.sensordata`` / ``d.qpos``."""
        y = np.empty(self.spec.ny)
        y[self._data_rows] = d.sensordata[self._data_idx]
        y[self._qpos_rows] = d.qpos[self._qpos_idx]
        return y

    def __call__(self, d) -> np.ndarray:
        """One measurement ``y`` (ny,) in sensor units: clean + bias + noise, quantised."""
        y = self.clean(d) + self._bias + self._std * self.rng.standard_normal(self.spec.ny)
        q = self._quantised
        y[q] = np.round(y[q] / self._res[q]) * self._res[q]
        return y
