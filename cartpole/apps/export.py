"""``cartpole export``: a controller (and its estimator) as standalone C, and its proof in the MuJoCo loop.

:func:`run_export` designs the controller the toolkit runs in Python on the rig the options describe
(:func:`cartpole.export.design_export`), writes the folder (:func:`cartpole.export.write_export`: compiled
warning-free under ``-std=c99 -Wall -Wextra -Werror -pedantic`` before anything reaches ``--out``) and, with
``verify``, compiles it again as a shared library, loads it through ``ctypes`` and drives MuJoCo with it from the
same start as the Python controller through the same rig (:func:`cartpole.export.run_lockstep`): the double build
must give the Python ctrl to :data:`CTRL_TOLERANCE` at every control step, the float build must succeed by the
same test as the Python path (:mod:`cartpole.validation.metrics`), and both MuJoCo runs must replay exactly and
not diverge.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from cartpole.apps.lab import lab_initial_conditions
from cartpole.apps.swingup import MPC_DURATION, TRAJOPT_EXTRA, start_state
from cartpole.control.energy import EnergyShapingController, EnergyShapingModelError
from cartpole.control.linear import LinearFeedback
from cartpole.control.switching import SWINGUP_CATCH_R
from cartpole.errors import CartPoleError
from cartpole.export import (ExportError, check_target, design_export, export_files, find_compiler, load_design,
                             run_lockstep, write_export)
from cartpole.export.design import CONTROLLERS
from cartpole.export.folder import discard
from cartpole.export.mcu import cross_build, mcu_tools
from cartpole.models import build_model, planning_limits, plant_model
from cartpole.options import StageOptions
from cartpole.sim.rollout import replays_exactly
from cartpole.validation.basin import BasinCache
from cartpole.validation.metrics import diverged, summarize, swingup_success

#: Largest |C ctrl - Python ctrl| a verified double export may show at any control step.
CTRL_TOLERANCE = 1e-9
#: Seconds each verification run lasts, by task (a TVLQR swing-up: its plan and then as long as
#: :func:`cartpole.apps.swingup.run_swingup` holds the catch, ``TRAJOPT_EXTRA``).
VERIFY_DURATION = {"balance": 5.0, "swingup": 10.0}


@dataclass(frozen=True, eq=False)
class ExportOptions(StageOptions):
    """How :func:`run_export` builds and proves an export: the C's number type, the checks (MuJoCo verification, the
    Cortex-M4F build) and a swing-up's limits. Keyword-only; every field has a default.

    Attributes
    ----------
    float32 : bool
        Write the float build (``cp_real`` float) instead of double (default False).
    verify : bool
        Run the double and the float build in MuJoCo beside the Python controller (default False).
    duration : float or None
        Seconds of each verification run; None (default): :func:`verify_duration`.
    mcu : bool
        Also build the float export for a Cortex-M4F (:func:`cartpole.export.mcu.cross_build`) and report its
        flash, RAM and worst stack (default False).
    u_max : float or tuple of float or None
        A swing-up controller's (tvlqr, energy, nmpc) ``|ctrl|`` bound, one for all actuators or one each; None
        (default): each actuator's ctrlrange, or a stated default where the file has none
        (:func:`cartpole.models.planning_limits`; ``limits`` says which). A balance controller (lqr, pid) needs none
        and takes it only when given.
    cart_max : float or None
        m: likewise the cart's travel ``|s - centre| <= cart_max``; None (default): the MJCF's range.

    Raises
    ------
    ExportError
        A verification duration that is not a positive number of seconds (the limits are checked by
        :func:`cartpole.models.planning_limits`).
    """

    float32: bool = False
    verify: bool = False
    duration: float | None = None
    mcu: bool = False
    u_max: float | tuple | None = None
    cart_max: float | None = None

    error: ClassVar[type] = ExportError
    SCALARS: ClassVar[tuple] = ("duration", "cart_max")

    def __post_init__(self):
        for name in ("float32", "verify", "mcu"):
            self.set_field(name, bool(getattr(self, name)))
        self.number("duration", low=0.0, low_open=True, optional=True, unit="s",
                    hint="give the verification e.g. `duration=5`, or None for the Python path's length")
        if isinstance(self.u_max, (list, np.ndarray)):  # one per actuator: kept as a tuple (read-only)
            self.set_field("u_max", tuple(np.ravel(self.u_max).tolist()))


def verify_duration(design) -> float:
    """Seconds of the verification runs of ``design``: what the Python path runs (the lab's balance 5 s of its 6,
    the energy swing-up 10 s, a TVLQR swing-up its plan + ``TRAJOPT_EXTRA``)."""
    if design.method == "nmpc":
        return float(MPC_DURATION)
    if design.plan_end is not None:
        return float(design.plan_end) + float(TRAJOPT_EXTRA)
    return VERIFY_DURATION[design.task]


@dataclass(frozen=True)
class BuildCheck:
    """One verification run of a build.

    Attributes
    ----------
    real : str
        ``"double"`` or ``"float"``.
    max_ctrl_diff : float
        ``max |C - Python|`` over the control steps (ctrl units).
    success : bool
        The task's success test on the MuJoCo run driven by the C.
    replays : bool
        The run's logged ctrl replays it bit for bit with ``mj_step``.
    diverged : bool
        MuJoCo warned of a blown-up acceleration.
    step_us : (K,) array
        C step wall times through ctypes, microseconds.
    codes : dict
        Return code -> how many steps returned it.
    run : LockstepRun
    """

    real: str
    max_ctrl_diff: float
    success: bool
    replays: bool
    diverged: bool
    step_us: np.ndarray
    codes: dict
    run: object


def default_start(design) -> np.ndarray:
    """The verification's start: the lab's first initial condition for a balance, the hanging rest for a
    swing-up."""
    if design.task == "balance":
        return np.array(lab_initial_conditions(design.model)[0], dtype=float)
    return np.array(design.model.x_hanging, dtype=float)


def catch_level(model, loop) -> float:
    """The catch level ``rho`` of the energy swing-up's LQR catch at the loop's period: the verified basin
    :func:`cartpole.apps.swingup.run_swingup` uses (:class:`cartpole.validation.basin.BasinCache`, on disk)."""
    try:
        EnergyShapingController(model)
    except EnergyShapingModelError:
        raise ExportError(f"Energy shaping drives one pole on a cart and this model has {len(model.hinges)} "
                          "hinges; export `controller='tvlqr'` (or `controller='lqr'`) instead.") from None
    period = None if loop is None else loop.period
    catch = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R, period=period)
    return float(BasinCache.on_disk().get(model.params, catch).rho)


def task_success(design, rollout) -> bool:
    """The Python path's own success test of the task on ``rollout``: balanced as the lab's delay margin counts it
    (:func:`cartpole.apps.lab.balances`: the lab's settling time finite, the cart never at its limit) or swung
    up and held (:func:`cartpole.validation.metrics.swingup_success`); never for a run MuJoCo reset."""
    if diverged(rollout):
        return False
    if design.task == "balance":
        m = summarize(rollout, design.model)
        return bool(np.isfinite(m.settling_time_seed) and not m.hit_limit and not m.diverged)
    return bool(swingup_success(rollout, design.model.params))


def check_build(design, real: str, x0, duration: float) -> BuildCheck:
    """Compile ``design``'s export with cp_real ``real``, load it and run it in lockstep (see the module doc).

    Parameters
    ----------
    design : ExportDesign
    real : {"double", "float"}
    x0 : (nx,) array
        Start state.
    duration : float
        Seconds.

    Returns
    -------
    BuildCheck
    """
    ctl, folder = load_design(design, real)
    try:
        run = run_lockstep(design, ctl, x0, duration)
    finally:
        discard(folder)
    codes, counts = np.unique(run.codes, return_counts=True)
    return BuildCheck(real=real, max_ctrl_diff=run.max_ctrl_diff, success=task_success(design, run.rollout),
                      replays=bool(replays_exactly(run.rollout, design.model.params)),
                      diverged=diverged(run.rollout), step_us=run.step_us,
                      codes={int(c): int(n) for c, n in zip(codes, counts)}, run=run)


def run_export(plant=None, controller: str = "lqr", options: ExportOptions = ExportOptions(), *, loop=None, x0=None,
               out=".", runs: list | None = None) -> dict:
    """Export a controller as standalone C to the folder ``out``, and with ``verify`` prove it in MuJoCo.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (default the shipped asset).
    controller : str
        ``lqr``, ``pid``, ... (:data:`cartpole.export.CONTROLLERS`).
    options : ExportOptions
        The C's number type, the checks (``verify``, its ``duration``, ``mcu``) and a swing-up's limits (``u_max``,
        ``cart_max``); default :class:`ExportOptions` ``()``: a double build, unverified, the file's limits.
    loop : LoopOptions, optional
        Period, delay, sensors, estimator.
    x0 : (nx,) array, optional
        The verification's start (default :func:`default_start`), checked against the joint ranges
        (:func:`cartpole.apps.swingup.start_state`).
    out : path
        The export folder: new, empty, or an earlier export.
    runs : list, optional
        With ``verify``, the verification's MuJoCo runs driven by the C are appended to it, the double build's then
        the float's, each as ``(params, rollout)``: the CartPoleParams MuJoCo ran and its
        :class:`~cartpole.sim.Rollout` (e.g. to show them live).

    Returns
    -------
    dict
        ``limits`` (the bounds a swing-up plans within, :meth:`cartpole.models.PlanningLimits.to_dict`; None for a
        balance without ``u_max``/``cart_max``), ``start_moved`` (the default start's positions moved onto a range's
        edge, :func:`cartpole.apps.swingup.start_state`), ``mjcf``, ``controller``, ``estimator``, ``period``, ``delay``, ``real``, ``folder``, ``rig`` and
        ``export`` {``files``, ``bytes``, ``verified``, ``max_ctrl_diff``, ``step_us`` {``median``, ``max``},
        ``float32`` {``success``, ``max_ctrl_diff``}, ``double`` {``success``, ``replays``}, ``codes``, with
        ``mcu`` the Cortex-M4F build's ``flash``, ``ram``, ``stack`` (bytes) and the commands that measured them}.

    Raises
    ------
    ExportError, CartPoleError
        One sentence: ``options`` that are not an :class:`ExportOptions`, a folder that is not an earlier export, no
        C compiler, a controller or estimator the export does not reproduce, a Python design that fails.
    """
    if not isinstance(options, ExportOptions):
        raise ExportError(f"run_export's options must be an ExportOptions; got {options!r}.")
    mcu, verify, duration = options.mcu, options.verify, options.duration
    u_max, cart_max = options.u_max, options.cart_max
    check_target(out)
    find_compiler()
    if mcu:
        if mcu_tools() is None:
            cross_build({})  # its one sentence: install the ARM toolchain
    model = plant_model(plant)
    limits = None
    if CONTROLLERS.get(controller) == "swingup" or u_max is not None or cart_max is not None:
        params, limits = planning_limits(model.params, u_max=u_max, cart_max=cart_max)  # defaults where unlimited
        model = model if params is model.params else build_model(params)
    real = "float" if options.float32 else "double"
    if x0 is not None:
        x0 = np.asarray(x0, dtype=float).ravel()
        if x0.shape != (model.nx,) or not np.all(np.isfinite(x0)):
            raise CartPoleError(f"`x0` must be {model.nx} finite numbers [qpos, qvel] in MuJoCo's joint order; got "
                                f"{x0.tolist()}.")
    moves = ()
    if x0 is not None or CONTROLLERS.get(controller) == "swingup":  # a swing-up's hanging start on a range's edge
        x0, moves = start_state(x0, model.params, default=model.x_hanging)
    rho = catch_level(model, loop) if controller == "energy" else None
    design = design_export(model, controller, loop, real=real, x0=x0, rho=rho)
    start = default_start(design) if x0 is None else x0
    checks = {}
    if verify:
        T = verify_duration(design) if duration is None else float(duration)
        for r in ("double", "float"):
            checks[r] = check_build(design, r, start, T)
            if runs is not None:
                runs.append((design.model.params, checks[r].run.rollout))
    mcu_doc = None
    if mcu:
        mcu_doc = cross_build(export_files(design, "float"))
    written = write_export(design, out, real=real)
    doc = {"mjcf": model.params.mjcf, "controller": controller, "estimator": design.estimator,
           "period": design.program.period, "delay": design.program.delay, "real": real,
           "folder": str(Path(written.folder).resolve()),
           "rig": None if design.rig is None else design.rig.to_dict(), "x0": start.tolist(),
           "limits": None if limits is None else limits.to_dict(), "start_moved": [mv.to_dict() for mv in moves]}
    exp = {"files": list(written.files), "bytes": written.bytes, "verified": False, "max_ctrl_diff": None,
           "step_us": None}
    if verify:
        exp.update(_verification_doc(checks["double"], checks["float"]))
    if mcu:
        exp["mcu"] = mcu_doc
    doc["export"] = exp
    return doc


def _verification_doc(d, f) -> dict:
    """The ``export`` JSON's verification keys from the double (``d``) and float (``f``) builds' checks
    (:func:`check_build`): ``verified``, ``max_ctrl_diff``, ``step_us`` (median and max, us), ``double``, ``float32``
    and ``duration`` (s)."""
    return {
        "verified": bool(d.max_ctrl_diff <= CTRL_TOLERANCE and d.success and f.success and d.replays
                         and f.replays and not d.diverged and not f.diverged),
        "max_ctrl_diff": d.max_ctrl_diff,
        "step_us": {"median": float(np.median(d.step_us)), "max": float(np.max(d.step_us))},
        "double": {"success": d.success, "replays": d.replays, "diverged": d.diverged, "codes": d.codes},
        "float32": {"success": f.success, "replays": f.replays, "diverged": f.diverged,
                    "max_ctrl_diff": f.max_ctrl_diff, "codes": f.codes,
                    "step_us": {"median": float(np.median(f.step_us)), "max": float(np.max(f.step_us))}},
        "duration": float(d.run.rollout.t[-1]),
    }
