"""Run controllers inside MuJoCo on the MJCF and log every physics step so the run replays exactly.

A :class:`Rollout` holds ``t`` (n+1,), ``qpos`` (n+1, nq), ``qvel`` (n+1, nq) and ``ctrl`` (n, nu): row 0 is
the start state and ``ctrl[k]`` is what MuJoCo applied (after clipping to ``ctrlrange``) during the step
from ``t[k]`` to ``t[k+1]``. :func:`replay` re-runs a logged ``ctrl`` open loop with ``mj_step`` and gives
back the same states bit for bit, which is how every control claim in the toolkit is checked. Any model the
reader accepts (``nq`` one-DOF joints, so ``nv = nq``, and ``nu`` motors); states are ``x = [qpos, qvel]``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, ClassVar

import mujoco
import numpy as np

from cartpole._arrays import readonly
from cartpole._files import atomic_write
from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF, CartPoleModel, CartPoleParams, Plant, load_model, mujoco_model, plant_params
from cartpole.options import OptionsError, StageOptions

#: The rig's per-control-instant log (None without a rig): times, measurements, estimates, estimator wall time.
SAMPLE_FIELDS = ("t_sample", "y", "x_hat", "estimate_ms")

Controller = Callable[[float, np.ndarray], "float | np.ndarray"]  # (t, x (nx,)) -> ctrl (nu,), or a float for nu = 1


@dataclass(frozen=True)
class Rollout:
    """What MuJoCo did: one row per simulator step.

    Attributes
    ----------
    t : (n+1,) array, s
    qpos : (n+1, nq) array, m (slides) and rad (hinges), MuJoCo's qpos order
    qvel : (n+1, nq) array, m/s and rad/s
    ctrl : (n, nu) array, MuJoCo ctrl actually applied during step k (already clipped); a flat (n,) is one
        actuator
    mjcf : str
        Path of the MJCF MuJoCo ran ("" when built from text).
    info : dict
        Free-form annotations (e.g. controller mode switches, ``push``, ``diverged``); not used for replay.
    t_sample : (K,) array or None
        With a rig (sensors, estimator, delay): the control instants in s, one per period.
    y : (K, ny) array or None
        The measurement the controller's estimator received at each control instant (sensor units).
    x_hat : (K, nx) array or None
        The estimate of the state at each control instant (before any prediction over the delay).
    estimate_ms : (K,) array or None
        Wall time of each estimator update, ms.
    """

    t: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    ctrl: np.ndarray
    mjcf: str = ""
    info: dict = field(default_factory=dict, compare=False)
    t_sample: np.ndarray | None = field(default=None, compare=False)
    y: np.ndarray | None = field(default=None, compare=False)
    x_hat: np.ndarray | None = field(default=None, compare=False)
    estimate_ms: np.ndarray | None = field(default=None, compare=False)

    def __post_init__(self):
        for name in ("t", "qpos", "qvel", "ctrl"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        for name in SAMPLE_FIELDS:
            if getattr(self, name) is not None:
                object.__setattr__(self, name, readonly(getattr(self, name)))
        if self.ctrl.ndim == 1:  # one actuator given as a flat list
            object.__setattr__(self, "ctrl", readonly(self.ctrl.reshape(-1, 1)))
        n = self.ctrl.shape[0]
        if (self.t.shape != (n + 1,) or self.ctrl.ndim != 2 or self.qpos.ndim != 2 or self.qpos.shape[0] != n + 1
                or self.qvel.shape != self.qpos.shape):
            raise ValueError(f"Rollout arrays disagree: t {self.t.shape}, qpos {self.qpos.shape}, "
                             f"qvel {self.qvel.shape}, ctrl {self.ctrl.shape}; need n+1 rows of states for n ctrl.")

    @property
    def x(self) -> np.ndarray:
        """States (n+1, nx) = [qpos, qvel]."""
        return np.hstack([self.qpos, self.qvel])

    @property
    def nq(self) -> int:
        """Number of joint positions."""
        return int(self.qpos.shape[1])

    @property
    def nu(self) -> int:
        """Number of ctrl entries."""
        return int(self.ctrl.shape[1])

    @property
    def dt(self) -> float:
        """Physics step in s."""
        return float(self.t[1] - self.t[0]) if len(self.t) > 1 else 0.0

    @property
    def x_sample(self) -> np.ndarray | None:
        """The true states (K, nx) at the control instants :attr:`t_sample` (None without a rig)."""
        if self.t_sample is None:
            return None
        idx = np.rint(np.asarray(self.t_sample) / self.dt).astype(int) if self.dt else np.zeros(0, int)
        return self.x[idx]

    def to_dict(self) -> dict:
        """JSON-ready dict with lists (the CLI's ``rollout`` contract); with a rig also ``t_sample``, ``y``,
        ``x_hat`` and ``estimate_ms``."""
        doc = {"t": self.t.tolist(), "qpos": self.qpos.tolist(), "qvel": self.qvel.tolist(),
               "ctrl": self.ctrl.tolist()}
        for name in SAMPLE_FIELDS:
            if getattr(self, name) is not None:
                doc[name] = getattr(self, name).tolist()
        return doc

    def save(self, path: str | Path) -> None:
        """Write the rollout as JSON (whole or not at all: :func:`~cartpole._files.atomic_write`), with its push log
        (``info["push"]``) and generalized-force log (``info["qfrc_applied"]``) when it has them and, for a run that diverged, ``diverged_at`` (s) and
        ``diverged_warning``."""
        doc = {"mjcf": self.mjcf, **self.to_dict()}
        if isinstance(self.info, dict) and self.info.get("push") is not None:
            doc["push"] = np.asarray(self.info["push"], dtype=float).tolist()
        if isinstance(self.info, dict) and self.info.get("qfrc_applied") is not None:
            doc["qfrc_applied"] = np.asarray(self.info["qfrc_applied"], dtype=float).tolist()
        if isinstance(self.info, dict) and self.info.get("diverged") is not None:
            doc["diverged_at"] = float(self.info["diverged"])
            doc["diverged_warning"] = self.info.get("diverged_warning")
        text = json.dumps(doc)
        atomic_write(path, lambda fh: fh.write(text.encode()))

    @classmethod
    def load(cls, path: str | Path) -> "Rollout":
        """Read a rollout written by :meth:`save`."""
        d = json.loads(Path(path).read_text())
        info = {k: np.asarray(d[k], dtype=float) for k in ("push", "qfrc_applied") if d.get(k) is not None}
        if d.get("diverged_at") is not None:
            info.update(diverged=float(d["diverged_at"]), diverged_warning=d.get("diverged_warning"))
        extra = {k: np.asarray(d[k], dtype=float) for k in SAMPLE_FIELDS if d.get(k) is not None}
        return cls(t=d["t"], qpos=d["qpos"], qvel=d["qvel"], ctrl=d["ctrl"], mjcf=d.get("mjcf", ""), info=info,
                   **extra)


def make_mujoco(plant: Plant = None):
    """Compile a fresh ``(MjModel, MjData)`` for a plant: params or a model (from their MJCF path, else their XML
    text) or an MJCF path (None = shipped asset); any number of joints and actuators."""
    if isinstance(plant, (CartPoleParams, CartPoleModel)):
        m = mujoco_model(plant_params(plant))  # a URDF's params: their MJCF text, with the motors added
    else:
        m, _, _ = load_model(plant)
    return m, mujoco.MjData(m)


def source_path(plant: Plant) -> str:
    """Absolute path of the MJCF a plant names ("" for parameters read from XML text)."""
    if isinstance(plant, (CartPoleParams, CartPoleModel)):
        return plant_params(plant).mjcf
    if plant is None:
        return str(SHIPPED_MJCF)
    return str(Path(plant).expanduser().resolve())


def _check_state(x0, m) -> np.ndarray:
    """The start state as a float (nq + nv,) array for MuJoCo model ``m``, or one sentence saying what is wrong."""
    nx = m.nq + m.nv
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.shape != (nx,):
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint {j}" for j in range(m.njnt)]
        raise CartPoleError(f"The start state has {x0.size} entries; give {nx}: the positions of "
                            f"{', '.join(names)}, then their velocities.")
    if not np.all(np.isfinite(x0)):
        raise CartPoleError(f"The start state {x0.tolist()} is not finite; give {nx} finite numbers.")
    return x0


def ctrl_bounds(m) -> tuple[np.ndarray, np.ndarray]:
    """(nu,) lower and upper ctrl bounds MuJoCo clamps to (``-inf``/``inf`` for an actuator without ctrlrange)."""
    lim = np.asarray(m.actuator_ctrllimited, dtype=bool)
    rng = np.asarray(m.actuator_ctrlrange, dtype=float).reshape(m.nu, 2)
    return np.where(lim, rng[:, 0], -np.inf), np.where(lim, rng[:, 1], np.inf)


def cart_body(m) -> int:
    """Index of the cart's body in the MjModel ``m``: the body of the first slide joint."""
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            return int(m.jnt_bodyid[j])
    raise CartPoleError("The MJCF has no slide joint, so there is no cart to push; drop the push.")


#: MuJoCo's warnings of an unstable simulation (``mujoco.mjtWarning`` names): a NaN, inf or huge position, velocity,
#: acceleration or ctrl. On the first three MuJoCo resets the state to ``qpos0`` at rest (on a file whose ``qpos0`` is
#: upright a blown-up run then looks caught); on a bad ctrl it zeroes the ctrl. Any of them ends a run as diverged.
INSTABILITY_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")


class WarningWatch:
    """Watches one ``MjData`` for MuJoCo's instability warnings (:data:`INSTABILITY_WARNINGS`).

    Made on the data before a run (its counts then are the baseline); :meth:`fired` after each ``mj_step`` names the
    first warning whose count grew since, e.g. ``"BADQACC"``, or gives None.

    Parameters
    ----------
    d : mujoco.MjData
        The data the run steps.
    """

    def __init__(self, d):
        self.indices = tuple(int(getattr(mujoco.mjtWarning, name)) for name in INSTABILITY_WARNINGS)
        self.names = tuple(name.removeprefix("mjWARN_") for name in INSTABILITY_WARNINGS)
        self.base = self.counts(d)

    def counts(self, d) -> tuple:
        """The warning counts (one per :data:`INSTABILITY_WARNINGS` entry) of ``d`` now."""
        return tuple(int(d.warning[i].number) for i in self.indices)

    def fired(self, d) -> str | None:
        """The name (``BADQPOS``, ``BADQVEL``, ``BADQACC`` or ``BADCTRL``) of the first instability warning ``d``
        raised since this watch was made (or last :meth:`reset`), else None."""
        for name, i, n0 in zip(self.names, self.indices, self.base):
            if int(d.warning[i].number) > n0:
                return name
        return None

    def reset(self, d) -> None:
        """Take ``d``'s counts now as the new baseline."""
        self.base = self.counts(d)


@dataclass(frozen=True, eq=False)
class SimOptions(StageOptions):
    """How :func:`simulate` holds the ctrl and who watches the run: the control period and the hooks called as it
    goes (each may end it early). Keyword-only; the defaults run every physics step unwatched.

    Attributes
    ----------
    control_period : float or None
        Hold each ctrl for this long, s (rounded to whole physics steps, at least one); None (default): every physics
        step. Ignored when :func:`simulate` is given a ``rig`` (it has its own period).
    progress : callable or None
        ``progress(fraction)`` with the fraction done (0..1), about 20 times a run; None (default): silent.
    stop : callable or None
        ``stop(t [s], x (nx,)) -> bool`` after each logged step: True ends the run there (that state logged);
        None (default): run to the end.
    on_step : callable or None
        ``on_step(m, d)`` (MuJoCo's model and data) on the start state and after each logged step, e.g.
        :class:`cartpole.viz.viewer.LiveViewer`; returning False ends the run there. None (default): no hook.

    Raises
    ------
    OptionsError
        A control period that is not a positive number of seconds, or a hook that is not callable.
    """

    control_period: float | None = None
    progress: Callable[[float], None] | None = None
    stop: Callable[[float, np.ndarray], bool] | None = None
    on_step: Callable[[object, object], bool | None] | None = None

    error: ClassVar[type] = OptionsError
    SCALARS: ClassVar[tuple] = ("control_period",)

    def __post_init__(self):
        self.number("control_period", low=0.0, low_open=True, optional=True, unit="s")
        for name in ("progress", "stop", "on_step"):
            if getattr(self, name) is not None and not callable(getattr(self, name)):
                raise OptionsError(f"SimOptions.{name} must be a callable or None; got {getattr(self, name)!r}.")


def simulate(plant: Plant, controller: Controller, x0, duration: float, *, rig=None,
             push: Callable[[float], float] | None = None,
             disturbance: Callable[[float, np.ndarray], np.ndarray] | None = None,
             options: SimOptions = SimOptions()) -> Rollout:
    """Run ``u = controller(t, x)`` in MuJoCo from ``x0`` for ``duration`` seconds.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole MuJoCo runs: an MJCF path (None = shipped asset), its parameters or its model.
    controller : callable
        ``controller(t [s], x (nx,)) -> ctrl`` (nu,) (a scalar for one actuator); MuJoCo clips it to
        ``ctrlrange``. Without a ``rig``, ``x`` is MuJoCo's exact state; with one, the rig's estimate.
    x0 : (nx,) array
        Start state ``[qpos, qvel]`` in MuJoCo's order (one pole: ``[s, theta, s_dot, theta_dot]``).
    duration : float
        Seconds to simulate; rounded to whole physics steps.
    rig : Rig, optional
        What stands between MuJoCo and the controller on a real rig (:class:`cartpole.sim.rig.Rig`): the control
        period, the delay from sampling to the ctrl taking effect, the sensors and the estimator. Every period the
        loop samples the sensors, updates the estimate ``x_hat`` with the ctrl applied since the last sample,
        predicts it over the delay (when the rig compensates it) and calls ``controller(t + delay, x)``; that ctrl
        acts from ``delay`` later for one period. Until the first ctrl arrives MuJoCo applies zero ctrl (clipped to
        ``ctrlrange``). The rollout then logs ``t_sample``, ``y`` and ``x_hat`` (one row per control instant).
    push : callable, optional
        ``push(t [s]) -> force [N]``: world-x force on the cart body during the step from ``t`` (MuJoCo's
        ``xfrc_applied``), logged as ``rollout.info["push"]`` (n,).
    disturbance : callable, optional
        ``disturbance(t [s], x (nx,)) -> (nv,)``: generalized forces (N on slides, N m on hinges) on the joints
        during the step from ``t``, given MuJoCo's true state at the start of that step (MuJoCo's
        ``qfrc_applied``; e.g. :class:`cartpole.sim.disturbance.Knockdown`), logged as
        ``rollout.info["qfrc_applied"]`` (n, nv) so the run replays exactly.
    options : SimOptions, optional
        The control period without a rig and the hooks (``progress``, ``stop``, ``on_step``) watching the run;
        default :class:`SimOptions` ``()``: every physics step, unwatched.

    Returns
    -------
    Rollout
        Every physics step is logged even when the control is held: ``qpos`` (n+1, nq), ``qvel`` (n+1, nq),
        ``ctrl`` (n, nu); with a rig also the samples. ``info["diverged"]`` is the time (s) at the end of the step in
        which MuJoCo first warned that the simulation is unstable (:data:`INSTABILITY_WARNINGS`: a bad position,
        velocity, acceleration or ctrl; it then resets the state), else None, and ``info["diverged_warning"]`` names
        that warning (``"BADQACC"`` ...). The run stops there: that step (MuJoCo's reset state) is the last logged,
        so the log still replays exactly, and no success test may count the run
        (:func:`cartpole.validation.metrics.diverged`). The file's contacts stay on as written: ``info["contact"]`` is
        None when MuJoCo found no contact in any step, else the first one (:func:`first_contact`: ``t``, ``geom1``,
        ``geom2``, ``dist``) and ``steps``, the number of steps that ended in contact.
    """
    if not isinstance(options, SimOptions):
        raise OptionsError(f"simulate's options must be a SimOptions; got {options!r}.")
    m, d = make_mujoco(plant)
    loop = _Loop(m, d, _check_state(x0, m), duration, rig, options, push=push, disturbance=disturbance)
    if options.on_step is not None and options.on_step(m, d) is False:  # the start state too (a viewer opens on it)
        loop.n = loop.last = 0
    for k in range(loop.n):
        loop.command(k, controller)
        loop.apply_forces(k)
        if loop.step(k):
            break
    return loop.rollout(source_path(plant))


class _Loop:
    """One :func:`simulate` run in steps: MuJoCo's model ``m`` and data ``d`` set to ``x0``, the log, the ctrl plan
    (a command issued at step ``k`` acts on steps ``k + lag .. k + lag + hold - 1``; zero, clipped, until the first
    one arrives), the push and disturbance with their logs, and the run's end so far (``last``, in steps)."""

    def __init__(self, m, d, x0: np.ndarray, duration: float, rig, options: SimOptions, *, push, disturbance):
        self.m, self.d, self.options = m, d, options
        nq, nv, nu = m.nq, m.nv, m.nu
        self.h = h = float(m.opt.timestep)
        self.n = n = int(round(duration / h))
        if n < 1:
            raise CartPoleError(f"Duration {duration} s is shorter than one physics step ({h} s); give a longer one.")
        if rig is not None:
            self.hold, self.lag = int(rig.steps), int(rig.delay_steps)
        else:
            period = options.control_period
            self.hold, self.lag = (1 if period is None else max(1, int(round(period / h)))), 0
        self.lo, self.hi = ctrl_bounds(m)
        d.qpos[:] = x0[:nq]
        d.qvel[:] = x0[nq:]
        d.time = 0.0
        mujoco.mj_forward(m, d)
        self.t, self.qpos, self.qvel = np.empty(n + 1), np.empty((n + 1, nq)), np.empty((n + 1, nv))
        self.ctrl = np.empty((n, nu))
        self.t[0], self.qpos[0], self.qvel[0] = 0.0, d.qpos, d.qvel
        self.planned = np.tile(np.clip(np.zeros(nu), self.lo, self.hi), (n + self.lag + self.hold, 1))
        self.run = rig.start(m) if rig is not None else None
        self.samples = _Samples() if self.run is not None else None
        self.every = max(1, n // 20)
        self.last = n
        self.push, self.disturbance = push, disturbance
        self.cart = cart_body(m) if push is not None else -1
        self.forces = np.zeros(n) if push is not None else None
        self.qfrc = np.zeros((n, nv)) if disturbance is not None else None
        self.watch = WarningWatch(d)
        self.diverged, self.warning = None, None
        self.contact, self.touching = None, 0

    def state(self) -> np.ndarray:
        """MuJoCo's exact state ``[qpos, qvel]`` now, (nx,)."""
        return np.concatenate([self.d.qpos, self.d.qvel])

    def command(self, k: int, controller: Controller) -> None:
        """At a control instant (every ``hold`` steps) ask the controller, through the rig if any, and plan its
        clipped ctrl from ``lag`` steps on for ``hold`` steps."""
        hold, lag, h = self.hold, self.lag, self.h
        if k % hold:
            return
        if self.run is None:
            x_used = self.state()
        else:
            x_used = self.run.sample(self.m, self.d, k, self.planned[max(0, k - hold):k], self.planned[k:k + lag],
                                     self.samples)
        u_raw = np.asarray(controller((k + lag) * h, x_used), dtype=float).ravel()
        nu = self.m.nu
        if u_raw.size != nu or not np.all(np.isfinite(u_raw)):
            raise CartPoleError(f"The controller returned {u_raw.tolist()} at t = {(k + lag) * h:.3f} s; "
                                f"it must return {nu} finite ctrl value{'s' if nu != 1 else ''}.")
        self.planned[k + lag:k + lag + hold] = np.clip(u_raw, self.lo, self.hi)

    def apply_forces(self, k: int) -> None:
        """Set the push on the cart and the generalized-force disturbance for step ``k``, and log them."""
        if self.push is not None:
            self.forces[k] = float(self.push(k * self.h))
            self.d.xfrc_applied[self.cart, 0] = self.forces[k]
        if self.disturbance is not None:
            self.qfrc[k] = _generalized_force(self.disturbance(k * self.h, self.state()), self.m.nv, k * self.h)
            self.d.qfrc_applied[:] = self.qfrc[k]

    def step(self, k: int) -> bool:
        """One ``mj_step`` with the planned ctrl, logged; True when the run ends here (MuJoCo warned of an unstable
        simulation, or a hook ended it)."""
        m, d, h, opts = self.m, self.d, self.h, self.options
        u = self.planned[k]
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        self.ctrl[k] = u
        self.t[k + 1] = (k + 1) * h
        self.qpos[k + 1] = d.qpos
        self.qvel[k + 1] = d.qvel
        if d.ncon:  # the file's contacts are kept as written: a run that touches says so
            self.touching += 1
            if self.contact is None:
                self.contact = first_contact(m, d, (k + 1) * h)
        self.warning = self.watch.fired(d)
        if self.warning is not None:  # MuJoCo reset a blown-up state: the run ends here, diverged
            self.diverged, self.last = (k + 1) * h, k + 1
            return True
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            raise CartPoleError(f"MuJoCo's state became NaN/inf at t = {(k + 1) * h:.3f} s; "
                                "the controller or the model is unstable, reduce gains or the time step.")
        if opts.progress is not None and (k + 1) % self.every == 0:
            opts.progress((k + 1) / self.n)
        if (opts.on_step is not None and opts.on_step(m, d) is False) or (
                opts.stop is not None and opts.stop((k + 1) * h, self.state())):
            self.last = k + 1
            return True
        return False

    def rollout(self, mjcf: str) -> Rollout:
        """The log up to the run's end as a :class:`Rollout` (MJCF path ``mjcf``)."""
        last = self.last
        info = {} if self.forces is None else {"push": self.forces[:last].copy()}
        if self.qfrc is not None:
            info["qfrc_applied"] = self.qfrc[:last].copy()
        info["diverged"] = self.diverged
        info["diverged_warning"] = self.warning
        info["contact"] = None if self.contact is None else {**self.contact, "steps": self.touching}
        kw = {} if self.samples is None else self.samples.arrays(last * self.h)
        return Rollout(t=self.t[:last + 1], qpos=self.qpos[:last + 1], qvel=self.qvel[:last + 1],
                       ctrl=self.ctrl[:last], mjcf=mjcf, info=info, **kw)


def _generalized_force(f, nv: int, t: float) -> np.ndarray:
    """A disturbance's value as a finite (nv,) array, or one sentence saying what is wrong."""
    f = np.asarray(f, dtype=float).ravel()
    if f.shape != (nv,) or not np.all(np.isfinite(f)):
        raise CartPoleError(f"The disturbance returned {f.tolist()} at t = {t:.3f} s; it must return {nv} finite "
                            "generalized forces (N on slides, N m on hinges).")
    return f


def first_contact(m, d, t: float) -> dict:
    """The first of MuJoCo's active contacts in ``d`` as a JSON-ready dict: ``t`` (s), ``geom1``, ``geom2`` (names, or
    ``"geom N"``) and ``dist`` (m, negative when penetrating)."""
    c = d.contact[0]
    name = lambda g: mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or f"geom {int(g)}"  # noqa: E731
    return {"t": float(t), "geom1": name(c.geom1), "geom2": name(c.geom2), "dist": float(c.dist)}


class _Samples:
    """The rig's log, one row per control instant: sample time (s), measurement ``y`` (ny,), estimate ``x_hat``
    (nx,) at that instant, and the estimator's wall time (ms)."""

    def __init__(self):
        self.t, self.y, self.x_hat, self.ms = [], [], [], []

    def add(self, t: float, y, x_hat, ms: float) -> None:
        self.t.append(t)
        self.y.append(np.asarray(y, dtype=float).ravel())
        self.x_hat.append(np.asarray(x_hat, dtype=float).ravel())
        self.ms.append(float(ms))

    def arrays(self, t_end: float) -> dict:
        keep = [i for i, ti in enumerate(self.t) if ti < t_end or i == 0]
        return {"t_sample": np.asarray([self.t[i] for i in keep]), "y": np.asarray([self.y[i] for i in keep]),
                "x_hat": np.asarray([self.x_hat[i] for i in keep]),
                "estimate_ms": np.asarray([self.ms[i] for i in keep])}


def replay(plant: Plant, x0, ctrl, *, push=None, qfrc_applied=None) -> Rollout:
    """Re-run a logged ctrl sequence open loop with ``mj_step``.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole: an MJCF path (None = shipped asset), its parameters or its model.
    x0 : (nx,) start state ``[qpos, qvel]``
    ctrl : (n, nu) ctrl applied during each step ((n,) accepted for one actuator)
    push : (n,) array, optional
        World-x force in N on the cart body during each step (``xfrc_applied``), as :func:`simulate` logs it in
        ``rollout.info["push"]``; default none.
    qfrc_applied : (n, nv) array, optional
        Generalized forces on the joints during each step (MuJoCo's ``qfrc_applied``), as :func:`simulate` logs a
        disturbance in ``rollout.info["qfrc_applied"]``; default none.

    Returns
    -------
    Rollout with n+1 states; equal to the logged one when the log is honest. Its ``info["diverged"]`` is the time
    (s) of the step in which MuJoCo first warned of an unstable simulation (:data:`INSTABILITY_WARNINGS`), else
    None: a replay does not stop there (a log that :func:`simulate` ended at its divergence ends at that step).
    """
    m, d = make_mujoco(plant)
    x0 = _check_state(x0, m)
    nq, nv, nu = m.nq, m.nv, m.nu
    ctrl = np.asarray(ctrl, dtype=float)
    if ctrl.ndim == 1 and nu == 1:
        ctrl = ctrl.reshape(-1, 1)
    if ctrl.ndim != 2 or ctrl.shape[1] != nu:
        raise CartPoleError(f"The ctrl log has shape {ctrl.shape}; give (n, {nu}), one row of {nu} ctrl per step.")
    h = float(m.opt.timestep)
    n = ctrl.shape[0]
    forces = None if push is None else np.asarray(push, dtype=float).ravel()
    if forces is not None and forces.shape != (n,):
        raise CartPoleError(f"The push log has {forces.size} entries for {n} ctrl rows; give one force per step.")
    cart = cart_body(m) if forces is not None else -1
    qfrc = None if qfrc_applied is None else np.asarray(qfrc_applied, dtype=float)
    if qfrc is not None and qfrc.shape != (n, nv):
        raise CartPoleError(f"The qfrc_applied log has shape {qfrc.shape} for {n} ctrl rows; give ({n}, {nv}), one "
                            "row of generalized forces per step.")
    d.qpos[:] = x0[:nq]
    d.qvel[:] = x0[nq:]
    mujoco.mj_forward(m, d)
    qpos = np.empty((n + 1, nq))
    qvel = np.empty((n + 1, nv))
    qpos[0], qvel[0] = d.qpos, d.qvel
    watch = WarningWatch(d)
    diverged, warning = None, None
    for k in range(n):
        if forces is not None:
            d.xfrc_applied[cart, 0] = forces[k]
        if qfrc is not None:
            d.qfrc_applied[:] = qfrc[k]
        d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        qpos[k + 1], qvel[k + 1] = d.qpos, d.qvel
        if diverged is None and (warning := watch.fired(d)) is not None:
            diverged = (k + 1) * h
    info = {} if forces is None else {"push": forces.copy()}
    if qfrc is not None:
        info["qfrc_applied"] = qfrc.copy()
    info.update(diverged=diverged, diverged_warning=warning)
    return Rollout(t=np.arange(n + 1) * h, qpos=qpos, qvel=qvel, ctrl=ctrl, mjcf=source_path(plant), info=info)


def replays_exactly(rollout: Rollout, source: CartPoleParams | str | Path | None = None, *, atol: float = 0.0) -> bool:
    """True when replaying ``rollout.ctrl`` (n, nu) from its first state, with the logged pushes
    (``rollout.info["push"]``, if any) and generalized forces (``rollout.info["qfrc_applied"]``, if any), reproduces
    every logged state within ``atol`` (default 0: bit for bit).
    ``source`` defaults to the rollout's own MJCF file (required for a rollout run on MJCF text)."""
    if source is None and not rollout.mjcf:
        raise CartPoleError("This rollout was run on MJCF text, not a file, so it cannot name its model; pass the "
                            "CartPoleParams it ran on as source.")
    src = source if source is not None else rollout.mjcf
    info = rollout.info if isinstance(rollout.info, dict) else {}
    again = replay(src, rollout.x[0], rollout.ctrl, push=info.get("push"), qfrc_applied=info.get("qfrc_applied"))
    return bool(np.allclose(again.x, rollout.x, rtol=0.0, atol=atol))
