"""``cartpole excite``: design an informative experiment and log it in the ``--log`` CSV format.

``hanging``, open loop: the multisine of :mod:`cartpole.identify.excite` from hanging rest, run in MuJoCo on the
MJCF (the "rig"). ``balance``: the lab's LQR (designed on the MJCF, for the sample period) holds the pole upright
while the same multisine, at :data:`BALANCE_AMPLITUDE` of the ctrl half-range unless told, is added to its ctrl;
the ctrl MuJoCo applied is logged. Each sample's joint positions are read through the rig's sensors (encoder
quantisation and noise of :func:`cartpole.estimation.sensor_spec`), the ctrl held over each sample. With
``dry_run`` (hanging only: a balancing ctrl depends on the state) only the ctrl is written (the positions left
empty), to play the same signal on a real rig.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np

from cartpole._arrays import readonly
from cartpole._files import write_csv
from cartpole.control.linear import LinearFeedback
from cartpole.errors import CartPoleError
from cartpole.estimation import SensorSampler, sensor_spec
from cartpole.identify.excite import Excitation, ExciteError, multisine
from cartpole.identify.logs import RunLog
from cartpole.models import plant_model, state_error
from cartpole.options import StageOptions
from cartpole.sim.rollout import SimOptions, make_mujoco, replay, simulate
from cartpole.validation.metrics import diverged

#: Modes of the experiment.
MODES = ("hanging", "balance")
#: Default multisine envelope while balancing, as a fraction of the ctrl half-range.
BALANCE_AMPLITUDE = 0.15
#: Largest pole-angle error from upright (rad) a balancing run may reach and still count as balanced.
BALANCE_LIMIT = 0.6


@dataclass(frozen=True, eq=False)
class ExciteOptions(StageOptions):
    """The experiment :func:`run_excite` designs and runs: its length, sample time, amplitude and mode, and the rig's
    sensors that read it. Keyword-only; every field has a default.

    Attributes
    ----------
    duration : float
        Length of the experiment, s (default 20).
    sample_time : float or None
        Log and ctrl-hold step, s, a whole number of physics steps; None (default): the MJCF's step.
    amplitude : float or None
        Envelope of the multisine as a fraction of the ctrl half-range; None (default): the largest that keeps the
        cart within its rail when hanging, :data:`BALANCE_AMPLITUDE` when balancing.
    mode : str
        ``"hanging"`` (default: open loop from hanging rest) or ``"balance"`` (the LQR plus the multisine, from
        upright).
    seed : int
        Seed of the sensor noise and of the frequencies' small shift (default 0).
    encoder_cpr, encoder_resolution, sensor_noise : optional
        The rig's sensors (:func:`cartpole.estimation.sensor_spec`): counts per revolution of every hinge's encoder,
        metres per count of every slide's, the noise's standard deviation in each sensor's units; None (default):
        not quantised, the MJCF's own noise.

    Raises
    ------
    ExciteError
        An unknown mode (the others are checked where the experiment is designed,
        :func:`cartpole.identify.excite.multisine`, and the sensors built, :func:`cartpole.estimation.sensor_spec`).
    """

    duration: float = 20.0
    sample_time: float | None = None
    amplitude: float | None = None
    mode: str = "hanging"
    seed: int = 0
    encoder_cpr: int | None = None
    encoder_resolution: float | None = None
    sensor_noise: float | None = None

    error: ClassVar[type] = ExciteError
    SCALARS: ClassVar[tuple] = ("duration", "sample_time", "amplitude", "seed", "encoder_cpr", "encoder_resolution",
                                "sensor_noise")

    def __post_init__(self):
        if self.mode not in MODES:
            raise ExciteError(f"Unknown excitation mode '{self.mode}'; choose one of {', '.join(MODES)}.")


@dataclass(frozen=True)
class ExciteResult:
    """What ``excite`` did.

    Attributes
    ----------
    excitation : Excitation
    log : RunLog or None
        The logged run (None for a dry run).
    rollout : Rollout or None
        MuJoCo's run at every physics step (replays exactly).
    csv : Path
    """

    excitation: Excitation
    log: RunLog | None
    rollout: object
    csv: Path


def _position_rows(spec, params) -> list:
    """Row of the measurement vector holding each joint's position."""
    rows, k = {}, 0
    for s in spec.sensors:
        if s.kind == "jointpos":
            rows[s.target] = k
        k += s.dim
    missing = [params.joint_names[j] for j in range(params.nq) if j not in rows]
    if missing:
        raise CartPoleError(f"The MJCF's sensors measure no position of joint(s) {', '.join(missing)}, which the log "
                            "needs; add a jointpos sensor for each or remove the <sensor> block (encoders then).")
    return [rows[j] for j in range(params.nq)]


def _balance(model, exc: Excitation, ts: float, steps: int):
    """MuJoCo run of the LQR plus the excitation from upright, the ctrl held over each sample: ``(rollout,
    excitation with the ctrl MuJoCo applied)``."""
    p = model.params
    lqr = LinearFeedback.for_model(model, period=ts if steps > 1 else None)
    extra = exc.ctrl - exc.ctrl[0]  # the multisine about its middle

    def controller(t, x):
        k = min(round(t / ts), len(extra) - 1)
        return np.clip(lqr(t, x) + extra[k], model.u_low, model.u_high)

    roll = simulate(p.mjcf or p, controller, model.x_eq, float(exc.t[-1]),
                    options=SimOptions(control_period=ts if steps > 1 else None))
    err = state_error(roll.x, model.x_eq, model.hinges)[:, list(model.hinges)]
    if diverged(roll) or np.max(np.abs(err)) > BALANCE_LIMIT or len(roll.ctrl) != steps * (len(exc.t) - 1):
        raise CartPoleError("The balancing experiment lost the pole (its angle left upright by more than "
                            f"{BALANCE_LIMIT} rad); give a smaller `amplitude`.")
    ctrl = np.vstack([roll.ctrl[::steps], roll.ctrl[-1:]])
    return roll, dataclasses.replace(exc, ctrl=readonly(ctrl))


def run_excite(plant, out: str | Path, options: ExciteOptions = ExciteOptions(), *, dry_run: bool = False,
               csv_name: str = "excite.csv") -> ExciteResult:
    """Design the excitation and (unless ``dry_run``) run and log it.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The model to run (the "rig"); default the shipped cart.
    out : path
        Directory for the CSV (and ``excite_rollout.json``).
    options : ExciteOptions
        The experiment (length, sample time, amplitude, mode, seed) and the rig's sensors; default
        :class:`ExciteOptions` ``()``: 20 s hanging at the MJCF's step, amplitude sized to the rail, exact sensors.
    dry_run : bool
        Write only the ctrl (hanging mode only).
    csv_name : str
        File name of the CSV under ``out``.

    Returns
    -------
    ExciteResult

    Raises
    ------
    CartPoleError
        ``options`` that are not an :class:`ExciteOptions`, a balancing dry run, a bad excitation or sensor, a
        balancing run that lost the pole, or a cart driven to the end of its rail.
    """
    if not isinstance(options, ExciteOptions):
        raise ExciteError(f"run_excite's options must be an ExciteOptions; got {options!r}.")
    o = options
    mode, seed = o.mode, o.seed
    if mode == "balance" and dry_run:
        raise CartPoleError("A balancing experiment's ctrl depends on the measured state, so it cannot be written "
                            "ahead; use `dry_run` with `mode='hanging'`.")
    model = plant_model(plant)
    p = model.params
    ts = p.timestep if o.sample_time is None else float(o.sample_time)
    balance = mode == "balance"
    exc = multisine(model, o.duration, ts, amplitude=(o.amplitude or BALANCE_AMPLITUDE) if balance else o.amplitude,
                    seed=seed)
    out = Path(out)
    act = [a.name for a in p.actuators]
    path = out / csv_name
    if dry_run:
        write_csv(path, ["t", *p.joint_names, *act],
                  [[t, *([""] * p.nq), *u] for t, u in zip(exc.t, exc.ctrl)])
        return ExciteResult(excitation=exc, log=None, rollout=None, csv=path)
    spec = sensor_spec(p.mjcf or None, encoder_cpr=o.encoder_cpr, encoder_resolution=o.encoder_resolution,
                       noise_std=o.sensor_noise)
    rows = _position_rows(spec, p)
    steps = round(ts / p.timestep)
    if balance:
        roll, exc = _balance(model, exc, ts, steps)
    else:
        per_step = np.repeat(exc.ctrl[:-1], steps, axis=0)
        roll = replay(p.mjcf or p, model.x_hanging, per_step)
    rail = p.cart_range
    if model.slide is not None and np.any(np.abs(roll.qpos[:, model.slide] - rail.mean()) >= 0.98 * 0.5 * np.ptp(rail)):
        raise CartPoleError("The excitation drove the cart to the end of its rail on this MJCF; give a smaller "
                            "`amplitude`.")
    m, d = make_mujoco(p.mjcf or p)
    sampler = SensorSampler(spec, m, seed=seed)
    y = np.empty((len(exc.t), p.nq))
    for k in range(len(exc.t)):
        d.qpos[:], d.qvel[:] = roll.qpos[k * steps], roll.qvel[k * steps]
        d.ctrl[:] = exc.ctrl[k]  # what MuJoCo applied from this sample on
        mujoco.mj_forward(m, d)
        y[k] = sampler(d)[rows]
    log = RunLog(name=str(path), t=exc.t, qpos=y, qvel=None, ctrl=exc.ctrl)
    header, data = log.to_csv_rows(p.joint_names, act)
    write_csv(path, header, data)
    roll.save(out / (Path(csv_name).stem + "_rollout.json"))
    return ExciteResult(excitation=exc, log=log, rollout=roll, csv=path)
