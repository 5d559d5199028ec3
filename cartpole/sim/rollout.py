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
from typing import Callable

import numpy as np

from cartpole._arrays import readonly
from cartpole._files import atomic_write
from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF, CartPoleParams, load_model

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

    def to_dict(self) -> dict:
        """JSON-ready dict with lists (the CLI's ``rollout`` contract)."""
        return {"t": self.t.tolist(), "qpos": self.qpos.tolist(), "qvel": self.qvel.tolist(),
                "ctrl": self.ctrl.tolist()}

    def save(self, path: str | Path) -> None:
        """Write the rollout as JSON (whole or not at all: :func:`~cartpole._files.atomic_write`), with its push log
        (``info["push"]``) when it has one."""
        doc = {"mjcf": self.mjcf, **self.to_dict()}
        if isinstance(self.info, dict) and self.info.get("push") is not None:
            doc["push"] = np.asarray(self.info["push"], dtype=float).tolist()
        text = json.dumps(doc)
        atomic_write(path, lambda fh: fh.write(text.encode()))

    @classmethod
    def load(cls, path: str | Path) -> "Rollout":
        """Read a rollout written by :meth:`save`."""
        d = json.loads(Path(path).read_text())
        info = {"push": np.asarray(d["push"], dtype=float)} if d.get("push") is not None else {}
        return cls(t=d["t"], qpos=d["qpos"], qvel=d["qvel"], ctrl=d["ctrl"], mjcf=d.get("mjcf", ""), info=info)


def make_mujoco(source: CartPoleParams | str | Path | None = None):
    """Compile a fresh ``(MjModel, MjData)`` for params (from their MJCF path, else their XML text) or an MJCF path
    (None = shipped asset); any number of joints and actuators."""
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


def _check_state(x0, m) -> np.ndarray:
    """The start state as a float (nq + nv,) array for MuJoCo model ``m``, or one sentence saying what is wrong."""
    import mujoco

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
    import mujoco

    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            return int(m.jnt_bodyid[j])
    raise CartPoleError("The MJCF has no slide joint, so there is no cart to push; drop the push.")


def simulate(source: CartPoleParams | str | Path | None, controller: Controller, x0, duration: float, *,
             control_period: float | None = None, progress: Callable[[float], None] | None = None,
             stop: Callable[[float, np.ndarray], bool] | None = None,
             push: Callable[[float], float] | None = None,
             on_step: Callable[[object, object], bool | None] | None = None) -> Rollout:
    """Run ``u = controller(t, x)`` in MuJoCo from ``x0`` for ``duration`` seconds.

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
        The cart-pole MuJoCo runs (None = shipped asset).
    controller : callable
        ``controller(t [s], x (nx,)) -> ctrl`` (nu,) (a scalar for one actuator); MuJoCo clips it to
        ``ctrlrange``.
    x0 : (nx,) array
        Start state ``[qpos, qvel]`` in MuJoCo's order (one pole: ``[s, theta, s_dot, theta_dot]``).
    duration : float
        Seconds to simulate; rounded to whole physics steps.
    control_period : float, optional
        Hold each ctrl for this long (rounded to whole physics steps); default every physics step.
    progress : callable, optional
        Called with the fraction done (0..1) about 20 times.
    stop : callable, optional
        ``stop(t, x) -> bool`` ends the run early (after logging that state).
    push : callable, optional
        ``push(t [s]) -> force [N]``: world-x force on the cart body during the step from ``t`` (MuJoCo's
        ``xfrc_applied``), logged as ``rollout.info["push"]`` (n,).
    on_step : callable, optional
        ``on_step(m, d)`` on the start state and after each logged step (e.g. :class:`cartpole.viz.viewer.LiveViewer`);
        returning False ends the run there.

    Returns
    -------
    Rollout
        Every physics step is logged even when the control is held: ``qpos`` (n+1, nq), ``qvel`` (n+1, nq),
        ``ctrl`` (n, nu).
    """
    import mujoco

    m, d = make_mujoco(source)
    x0 = _check_state(x0, m)
    nq, nv, nu = m.nq, m.nv, m.nu
    h = float(m.opt.timestep)
    n = int(round(duration / h))
    if n < 1:
        raise CartPoleError(f"Duration {duration} s is shorter than one physics step ({h} s); give a longer one.")
    hold = 1 if control_period is None else max(1, int(round(control_period / h)))
    lo, hi = ctrl_bounds(m)
    d.qpos[:] = x0[:nq]
    d.qvel[:] = x0[nq:]
    d.time = 0.0
    mujoco.mj_forward(m, d)
    t = np.empty(n + 1)
    qpos = np.empty((n + 1, nq))
    qvel = np.empty((n + 1, nv))
    ctrl = np.empty((n, nu))
    t[0], qpos[0], qvel[0] = 0.0, d.qpos, d.qvel
    u = np.zeros(nu)
    every = max(1, n // 20)
    last = n
    cart = cart_body(m) if push is not None else -1
    forces = np.zeros(n) if push is not None else None
    if on_step is not None and on_step(m, d) is False:  # the start state too (a viewer opens on it)
        n = last = 0
    for k in range(n):
        if k % hold == 0:
            xk = np.concatenate([d.qpos, d.qvel])
            u_raw = np.asarray(controller(k * h, xk), dtype=float).ravel()
            if u_raw.size != nu or not np.all(np.isfinite(u_raw)):
                raise CartPoleError(f"The controller returned {u_raw.tolist()} at t = {k * h:.3f} s; "
                                    f"it must return {nu} finite ctrl value{'s' if nu != 1 else ''}.")
            u = np.clip(u_raw, lo, hi)
        if push is not None:
            forces[k] = float(push(k * h))
            d.xfrc_applied[cart, 0] = forces[k]
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        ctrl[k] = u
        t[k + 1] = (k + 1) * h
        qpos[k + 1] = d.qpos
        qvel[k + 1] = d.qvel
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            raise CartPoleError(f"MuJoCo's state became NaN/inf at t = {(k + 1) * h:.3f} s; "
                                "the controller or the model is unstable, reduce gains or the time step.")
        if progress is not None and (k + 1) % every == 0:
            progress((k + 1) / n)
        if on_step is not None and on_step(m, d) is False:
            last = k + 1
            break
        if stop is not None and stop((k + 1) * h, np.concatenate([d.qpos, d.qvel])):
            last = k + 1
            break
    info = {} if forces is None else {"push": forces[:last].copy()}
    return Rollout(t=t[:last + 1], qpos=qpos[:last + 1], qvel=qvel[:last + 1], ctrl=ctrl[:last],
                   mjcf=source_path(source), info=info)


def replay(source: CartPoleParams | str | Path | None, x0, ctrl, *, push=None) -> Rollout:
    """Re-run a logged ctrl sequence open loop with ``mj_step``.

    Parameters
    ----------
    source : CartPoleParams or MJCF path or None
    x0 : (nx,) start state ``[qpos, qvel]``
    ctrl : (n, nu) ctrl applied during each step ((n,) accepted for one actuator)
    push : (n,) array, optional
        World-x force in N on the cart body during each step (``xfrc_applied``), as :func:`simulate` logs it in
        ``rollout.info["push"]``; default none.

    Returns
    -------
    Rollout with n+1 states; equal to the logged one when the log is honest.
    """
    import mujoco

    m, d = make_mujoco(source)
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
    d.qpos[:] = x0[:nq]
    d.qvel[:] = x0[nq:]
    mujoco.mj_forward(m, d)
    qpos = np.empty((n + 1, nq))
    qvel = np.empty((n + 1, nv))
    qpos[0], qvel[0] = d.qpos, d.qvel
    for k in range(n):
        if forces is not None:
            d.xfrc_applied[cart, 0] = forces[k]
        d.ctrl[:] = ctrl[k]
        mujoco.mj_step(m, d)
        qpos[k + 1], qvel[k + 1] = d.qpos, d.qvel
    info = {} if forces is None else {"push": forces.copy()}
    return Rollout(t=np.arange(n + 1) * h, qpos=qpos, qvel=qvel, ctrl=ctrl, mjcf=source_path(source), info=info)


def replays_exactly(rollout: Rollout, source: CartPoleParams | str | Path | None = None, *, atol: float = 0.0) -> bool:
    """True when replaying ``rollout.ctrl`` (n, nu) from its first state, with the logged pushes
    (``rollout.info["push"]``, if any), reproduces every logged state within ``atol`` (default 0: bit for bit).
    ``source`` defaults to the rollout's own MJCF file (required for a rollout run on MJCF text)."""
    if source is None and not rollout.mjcf:
        raise CartPoleError("This rollout was run on MJCF text, not a file, so it cannot name its model; pass the "
                            "CartPoleParams it ran on as source.")
    src = source if source is not None else rollout.mjcf
    push = rollout.info.get("push") if isinstance(rollout.info, dict) else None
    again = replay(src, rollout.x[0], rollout.ctrl, push=push)
    return bool(np.allclose(again.x, rollout.x, rtol=0.0, atol=atol))
