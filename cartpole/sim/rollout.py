"""Run controllers inside MuJoCo on the MJCF and log every physics step so the run replays exactly.

A :class:`Rollout` holds ``t`` (n+1,), ``qpos`` (n+1, 2), ``qvel`` (n+1, 2) and ``ctrl`` (n, 1): row 0 is
the start state and ``ctrl[k]`` is what MuJoCo applied (after clipping to ``ctrlrange``) during the step
from ``t[k]`` to ``t[k+1]``. :func:`replay` re-runs a logged ``ctrl`` open loop with ``mj_step`` and gives
back the same states bit for bit, which is how every control claim in the toolkit is checked.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from cartpole._arrays import readonly
from cartpole._files import atomic_write
from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF, CartPoleParams, load_model

Controller = Callable[[float, np.ndarray], "float | np.ndarray"]


@dataclass(frozen=True)
class Rollout:
    """What MuJoCo did: one row per simulator step.

    Attributes
    ----------
    t : (n+1,) array, s
    qpos : (n+1, 2) array, [m, rad]
    qvel : (n+1, 2) array, [m/s, rad/s]
    ctrl : (n, 1) array, MuJoCo ctrl actually applied during step k (already clipped)
    mjcf : str
        Path of the MJCF MuJoCo ran ("" when built from text).
    info : dict
        Free-form annotations (e.g. controller mode switches); not used for replay.
    """

    t: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    ctrl: np.ndarray
    mjcf: str = ""
    info: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        for name in ("t", "qpos", "qvel", "ctrl"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        n = self.ctrl.shape[0]
        if self.t.shape != (n + 1,) or self.qpos.shape[0] != n + 1 or self.qvel.shape[0] != n + 1:
            raise ValueError(f"Rollout arrays disagree: t {self.t.shape}, qpos {self.qpos.shape}, "
                             f"qvel {self.qvel.shape}, ctrl {self.ctrl.shape}; need n+1 rows of states for n ctrl.")

    @property
    def x(self) -> np.ndarray:
        """States (n+1, 4) = [qpos, qvel]."""
        return np.hstack([self.qpos, self.qvel])

    @property
    def dt(self) -> float:
        """Physics step in s."""
        return float(self.t[1] - self.t[0]) if len(self.t) > 1 else 0.0

    def to_dict(self) -> dict:
        """JSON-ready dict with lists (the CLI's ``rollout`` contract)."""
        return {"t": self.t.tolist(), "qpos": self.qpos.tolist(), "qvel": self.qvel.tolist(),
                "ctrl": self.ctrl.tolist()}

    def save(self, path: str | Path) -> None:
        """Write the rollout as JSON (whole or not at all: :func:`~cartpole._files.atomic_write`)."""
        text = json.dumps({"mjcf": self.mjcf, **self.to_dict()})
        atomic_write(path, lambda fh: fh.write(text.encode()))

    @classmethod
    def load(cls, path: str | Path) -> "Rollout":
        """Read a rollout written by :meth:`save`."""
        d = json.loads(Path(path).read_text())
        ctrl = np.asarray(d["ctrl"], float).reshape(-1, 1)
        return cls(t=d["t"], qpos=d["qpos"], qvel=d["qvel"], ctrl=ctrl, mjcf=d.get("mjcf", ""))


def make_mujoco(source: CartPoleParams | str | Path | None = None):
    """Compile a fresh ``(MjModel, MjData)`` for params (from their XML text) or an MJCF path."""
    import mujoco

    if isinstance(source, CartPoleParams):
        if source.mjcf:
            m, _, _ = load_model(source.mjcf)
        else:
            m, _, _ = load_model(xml=source.xml)
    else:
        m, _, _ = load_model(source)
    return m, mujoco.MjData(m)


def source_path(source: CartPoleParams | str | Path | None) -> str:
    """Absolute path of the MJCF a source names ("" for parameters read from XML text)."""
    if isinstance(source, CartPoleParams):
        return source.mjcf
    if source is None:
        return str(SHIPPED_MJCF)
    return str(Path(source).expanduser().resolve())


def _check_state(x0) -> np.ndarray:
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.shape != (4,):
        raise CartPoleError(f"The start state has {x0.size} entries; give 4: [cart position, pole angle, "
                            "cart velocity, pole angular velocity].")
    if not np.all(np.isfinite(x0)):
        raise CartPoleError(f"The start state {x0.tolist()} is not finite; give four finite numbers.")
    return x0


def simulate(source: CartPoleParams | str | Path | None, controller: Controller, x0, duration: float, *,
             control_period: float | None = None, progress: Callable[[float], None] | None = None,
             stop: Callable[[float, np.ndarray], bool] | None = None) -> Rollout:
    """Run ``u = controller(t, x)`` in MuJoCo from ``x0`` for ``duration`` seconds.

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
        The cart-pole MuJoCo runs (None = shipped asset).
    controller : callable
        ``controller(t [s], x (4,)) -> ctrl`` (scalar or (1,)); MuJoCo clips it to ``ctrlrange``.
    x0 : (4,) array
        Start state ``[s, theta, s_dot, theta_dot]``.
    duration : float
        Seconds to simulate; rounded to whole physics steps.
    control_period : float, optional
        Hold each ctrl for this long (rounded to whole physics steps); default every physics step.
    progress : callable, optional
        Called with the fraction done (0..1) about 20 times.
    stop : callable, optional
        ``stop(t, x) -> bool`` ends the run early (after logging that state).

    Returns
    -------
    Rollout
        Every physics step is logged even when the control is held.
    """
    import mujoco

    x0 = _check_state(x0)
    m, d = make_mujoco(source)
    h = float(m.opt.timestep)
    n = int(round(duration / h))
    if n < 1:
        raise CartPoleError(f"Duration {duration} s is shorter than one physics step ({h} s); give a longer one.")
    hold = 1 if control_period is None else max(1, int(round(control_period / h)))
    lo, hi = (m.actuator_ctrlrange[0] if m.actuator_ctrllimited[0] else (-np.inf, np.inf))
    d.qpos[:] = x0[:2]
    d.qvel[:] = x0[2:]
    d.time = 0.0
    mujoco.mj_forward(m, d)
    t = np.empty(n + 1)
    qpos = np.empty((n + 1, 2))
    qvel = np.empty((n + 1, 2))
    ctrl = np.empty((n, 1))
    t[0], qpos[0], qvel[0] = 0.0, d.qpos, d.qvel
    u = 0.0
    every = max(1, n // 20)
    last = n
    for k in range(n):
        if k % hold == 0:
            xk = np.concatenate([d.qpos, d.qvel])
            u_raw = np.asarray(controller(k * h, xk), dtype=float).ravel()
            if u_raw.size != 1 or not np.isfinite(u_raw[0]):
                raise CartPoleError(f"The controller returned {u_raw.tolist()} at t = {k * h:.3f} s; "
                                    "it must return one finite ctrl value.")
            u = float(np.clip(u_raw[0], lo, hi))
        d.ctrl[0] = u
        mujoco.mj_step(m, d)
        ctrl[k, 0] = u
        t[k + 1] = (k + 1) * h
        qpos[k + 1] = d.qpos
        qvel[k + 1] = d.qvel
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            raise CartPoleError(f"MuJoCo's state became NaN/inf at t = {(k + 1) * h:.3f} s; "
                                "the controller or the model is unstable, reduce gains or the time step.")
        if progress is not None and (k + 1) % every == 0:
            progress((k + 1) / n)
        if stop is not None and stop((k + 1) * h, np.concatenate([d.qpos, d.qvel])):
            last = k + 1
            break
    return Rollout(t=t[:last + 1], qpos=qpos[:last + 1], qvel=qvel[:last + 1], ctrl=ctrl[:last],
                   mjcf=source_path(source))


def replay(source: CartPoleParams | str | Path | None, x0, ctrl) -> Rollout:
    """Re-run a logged ctrl sequence open loop with ``mj_step``.

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
    x0 : (4,) start state
    ctrl : (n,) or (n, 1) ctrl applied during each step

    Returns
    -------
    Rollout with n+1 states; equal to the logged one when the log is honest.
    """
    import mujoco

    x0 = _check_state(x0)
    ctrl = np.asarray(ctrl, dtype=float).reshape(-1)
    m, d = make_mujoco(source)
    h = float(m.opt.timestep)
    n = ctrl.size
    d.qpos[:] = x0[:2]
    d.qvel[:] = x0[2:]
    mujoco.mj_forward(m, d)
    qpos = np.empty((n + 1, 2))
    qvel = np.empty((n + 1, 2))
    qpos[0], qvel[0] = d.qpos, d.qvel
    for k in range(n):
        d.ctrl[0] = ctrl[k]
        mujoco.mj_step(m, d)
        qpos[k + 1], qvel[k + 1] = d.qpos, d.qvel
    return Rollout(t=np.arange(n + 1) * h, qpos=qpos, qvel=qvel, ctrl=ctrl.reshape(-1, 1),
                   mjcf=source_path(source))


def replays_exactly(rollout: Rollout, source: CartPoleParams | str | Path | None = None, *, atol: float = 0.0) -> bool:
    """True when replaying ``rollout.ctrl`` from its first state reproduces every logged state within ``atol``."""
    src = source if source is not None else (rollout.mjcf or None)
    again = replay(src, rollout.x[0], rollout.ctrl)
    return bool(np.allclose(again.x, rollout.x, rtol=0.0, atol=atol))
