"""What an export is made of: the Python controller and rig it reproduces, and the :class:`CProgram` that does.

:func:`design_export` builds, for a model and a :class:`~cartpole.sim.options.LoopOptions`, the controller the
toolkit runs in Python (the LQR of :meth:`~cartpole.control.linear.LinearFeedback.for_model`, the
:class:`~cartpole.control.pid.CascadedPID`, ...), the rig (:func:`cartpole.sim.rig.build_rig`: period, delay,
sensors, estimator) and the C program that computes the same ctrl from the same measurements.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from cartpole.control.energy import EnergyShapingController
from cartpole.control.linear import LinearFeedback
from cartpole.control.pid import CascadedPID, tune_pid
from cartpole.control.switching import SWINGUP_CATCH_R, SwitchingController
from cartpole.export.controllers import energy_part, linear_part, pid_part, tvlqr_part
from cartpole.export.estimators import ExportError, ekf_part, kalman_part, state_part
from cartpole.export.mhe import mhe_part
from cartpole.export.nmpc import nmpc_design, nmpc_part
from cartpole.export.program import CProgram
from cartpole.mpc.options import DEFAULT_PERIOD
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim.options import LoopOptions
from cartpole.sim.rig import build_rig
from cartpole.sim.rollout import ctrl_bounds, make_mujoco

#: The controllers ``cartpole export --controller`` names, and the task each runs (its success test).
CONTROLLERS = {"lqr": "balance", "pid": "balance", "tvlqr": "swingup", "energy": "swingup", "nmpc": "swingup"}
#: The estimators each controller's export supports (``none`` is MuJoCo's exact state ``[qpos, qvel]``).
SUPPORTED_ESTIMATORS = {"lqr": ("none", "kf", "ekf", "mhe"), "pid": ("none", "kf", "ekf", "mhe"),
                        "tvlqr": ("none", "ekf", "mhe"), "energy": ("none", "ekf", "mhe"),
                        "nmpc": ("none", "kf", "ekf", "mhe")}


@dataclass(frozen=True)
class ExportDesign:
    """An export's Python side and its C program.

    Attributes
    ----------
    method : str
        One of :data:`CONTROLLERS`.
    estimator : str
        ``"none"``, ``"kf"``, ...
    model : CartPoleModel
        The design model.
    program : CProgram
        The C that reproduces ``make_controller()`` on ``rig``.
    make_controller : callable
        ``() -> controller``: a fresh Python controller (``u = c(t, x)``) for a run.
    rig : Rig or None
        The rig the Python path runs on (None: MuJoCo's exact state every physics step).
    spec : SensorSpec or None
        The sensors (None with estimator ``"none"``).
    task : str
        ``"balance"`` or ``"swingup"``.
    plan_end : float or None
        ``tvlqr``: the end of the plan in s (the catch holds from then on).
    """

    method: str
    estimator: str
    model: object
    program: CProgram
    make_controller: Callable
    rig: object
    spec: object
    task: str
    plan_end: float | None = None

    @property
    def y_names(self) -> tuple:
        """One name per entry of ``y`` (the sensors' names, or the joints' then ``<joint>_vel``)."""
        if self.spec is not None:
            return tuple(self.spec.names)
        joints = [j.name for j in self.model.params.joints]
        return tuple(joints + [f"{j}_vel" for j in joints])

    @property
    def y_units(self) -> tuple:
        """One SI unit per entry of ``y``."""
        if self.spec is not None:
            return tuple(self.spec.units)
        pos = ["rad" if j.kind == "hinge" else "m" for j in self.model.params.joints]
        return tuple(pos + [f"{p}/s" for p in pos])


def _predictor(model, lag: int) -> ca.Function:
    """``cp_predict(x (nx,), U (nu, lag)) -> x`` over the delay: the rig's prediction (``model.hold(lag)``)."""
    hm = model.hold(lag)
    x, U = ca.SX.sym("x", model.nx), ca.SX.sym("U", model.nu, lag)
    return ca.Function("cp_predict", [x, U], [hm.step_inputs(x, U)], ["x", "U"], ["x_next"])


def design_export(model, method: str, loop=None, *, real: str = "double", x0=None, rho: float | None = None,
                  plan=None) -> ExportDesign:
    """The Python controller, rig and C program of an export.

    Parameters
    ----------
    model : CartPoleModel
        The design model (the MJCF's physics step).
    method : str
        A key of :data:`CONTROLLERS`.
    loop : LoopOptions, optional
        Period, delay, sensors, estimator (default: MuJoCo's exact state every physics step).
    real : {"double", "float"}
        ``cp_real``.
    x0 : (nx,) array, optional
        ``tvlqr``: the start the swing-up is planned from (default the hanging rest).
    rho : float, optional
        ``energy``: the catch level of the LQR catch's verified basin (``BasinEstimate.rho``; required).
    plan : PlanOptions, optional
        ``tvlqr``: the planner's settings (default ``PlanOptions()``).

    Returns
    -------
    ExportDesign

    Raises
    ------
    ExportError
        A method or estimator this export does not reproduce in C.
    LQRError, PIDError, RigError, PeriodError, EstimationError
        The Python design itself fails (its own sentence).
    """
    if method not in CONTROLLERS:
        raise ExportError(f"There is no controller {method!r} to export; choose one of {', '.join(CONTROLLERS)}.")
    task = CONTROLLERS[method]
    rig = _export_rig(model, method, loop)
    estimator = "none" if rig is None else rig.estimator
    steps = 1 if rig is None else int(rig.steps)
    period = steps * float(model.dt)
    design = _CONTROLLER_DESIGNS[method](model, steps, period, x0=x0, rho=rho, plan=plan)
    spec = None if rig is None else rig.spec
    program = build_program(model, rig, design.part, real=real, title=design.title)
    return ExportDesign(method=method, estimator=estimator, model=model, program=program, make_controller=design.make,
                        rig=rig, spec=spec, task=task, plan_end=design.plan_end)


def _export_rig(model, method: str, loop):
    """The rig of ``method``'s export on ``loop`` (:func:`cartpole.sim.rig.build_rig`; None: MuJoCo's exact state
    every physics step), the NMPC's at its own period unless the loop gives one; or one sentence when the export
    does not reproduce its estimator."""
    if method == "nmpc":  # the NMPC runs at its own period (0.02 s) unless the loop gives one

        loop = LoopOptions() if loop is None else loop
        loop = loop.replace(period=DEFAULT_PERIOD if loop.period is None else loop.period)
    rig = build_rig(model, loop, task=CONTROLLERS[method])
    estimator = "none" if rig is None else rig.estimator
    allowed = SUPPORTED_ESTIMATORS[method]
    if estimator not in allowed:
        have = f"supported: `estimator` {' or '.join(allowed)}" if allowed else "it is not exported yet"
        raise ExportError(f"The {method} export with `estimator='{estimator}'` is not available ({have}); pick "
                          "another estimator or controller.")
    return rig


@dataclass(frozen=True)
class _ControllerDesign:
    """One controller's side of an export: ``make()`` a fresh Python controller (reset), its C ``part``, the
    export's one-line ``title`` and, for a planned swing-up, the plan's length ``plan_end`` (s)."""

    make: Callable
    part: object
    title: str
    plan_end: float | None = None


def _lqr_design(model, steps: int, period: float, **_) -> _ControllerDesign:
    """The upright LQR at the period (:meth:`~cartpole.control.linear.LinearFeedback.for_model`)."""
    fb = LinearFeedback.for_model(model, period=period)
    return _ControllerDesign(make=lambda: fb, part=linear_part(fb), title=f"LQR balance at a {period:g} s period")


def _pid_design(model, steps: int, period: float, **_) -> _ControllerDesign:
    """The cascaded PID tuned for the period (:func:`~cartpole.control.pid.tune_pid`)."""
    gains = tune_pid(model, period=period)

    def make():
        return CascadedPID(gains, model)
    return _ControllerDesign(make=make, part=pid_part(make()), title=f"cascaded PID balance at a {period:g} s period")


def _tvlqr_design(model, steps: int, period: float, *, x0=None, plan=None, **_) -> _ControllerDesign:
    """The trajopt swing-up from ``x0`` (default hanging) planned with ``plan`` (PlanOptions), tracked by TVLQR."""
    start = model.x_hanging if x0 is None else np.asarray(x0, dtype=float).ravel()
    kw = {} if plan is None else {"options": plan}
    sp = trajopt_swingup(model.params, x0=tuple(float(v) for v in start), plan_model=model,
                         period=None if steps == 1 else period, **kw)
    tv = sp.controller

    def make():
        tv.reset()
        return tv
    title = (f"trajopt swing-up tracked by TVLQR ({sp.trajectory.N} intervals, {tv.T:.3g} s), then the LQR "
             f"catch, at a {period:g} s period")
    return _ControllerDesign(make=make, part=tvlqr_part(tv), title=title,
                             plan_end=float(sp.trajectory.t[-1] - sp.trajectory.t[0]))


def _energy_design(model, steps: int, period: float, *, rho=None, **_) -> _ControllerDesign:
    """Energy shaping with the LQR catch below the verified basin's level ``rho`` (required)."""
    if rho is None or not rho > 0:
        raise ExportError("The energy export needs the catch level rho of the LQR catch's verified basin; "
                          "give rho (cartpole export computes it).")
    energy = EnergyShapingController(model)
    catch = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R, period=None if steps == 1 else period)

    def make():
        return SwitchingController(energy, catch, float(rho))
    title = f"energy-shaping swing-up with the LQR catch below rho = {float(rho):.4g}, at a {period:g} s period"
    return _ControllerDesign(make=make, part=energy_part(make()), title=title)


def _nmpc_design(model, steps: int, period: float, *, x0=None, **_) -> _ControllerDesign:
    """The NMPC by real-time iteration from ``x0`` (default hanging), its QP solved in C."""
    start = model.x_hanging if x0 is None else np.asarray(x0, dtype=float).ravel()
    mpc, plan_traj = nmpc_design(model, start, period)

    def make():
        mpc.reset()
        return mpc
    title = (f"nonlinear MPC by real-time iteration ({mpc.N} stages of {mpc.period:g} s, dual active-set QP in "
             "C), swing-up from the planned start")
    return _ControllerDesign(make=make, part=nmpc_part(mpc, plan_traj), title=title)


#: Each exportable controller's design, by :data:`CONTROLLERS` key.
_CONTROLLER_DESIGNS = {"lqr": _lqr_design, "pid": _pid_design, "tvlqr": _tvlqr_design, "energy": _energy_design,
                       "nmpc": _nmpc_design}


def estimator_part(rig, model):
    """The estimator part of ``rig`` (None: MuJoCo's state) for the design model ``model``: ``cp_state.c``,
    ``cp_kf.c``, ``cp_ekf.c`` or the MHE's, from a fresh estimator of the rig."""
    spec = None if rig is None else rig.spec
    name = "none" if rig is None else rig.estimator
    if name == "none":
        return state_part()
    if name == "kf":
        return kalman_part(rig.make_estimator(), model, spec)
    if name == "ekf":
        return ekf_part(rig.make_estimator(), model, spec)

    return mhe_part(rig.make_estimator(), model, spec)


def build_program(model, rig, ctrl_part, *, real: str = "double", title: str = "", params=None) -> CProgram:
    """The :class:`CProgram` of the controller part ``ctrl_part`` on ``rig`` (None: MuJoCo's exact state every
    physics step): the rig's estimator part (:func:`estimator_part`), its delay prediction when it compensates,
    the MuJoCo ctrlrange of ``model``'s MJCF.

    Parameters
    ----------
    model : CartPoleModel
        The design model (its ``params`` the MJCF MuJoCo runs).
    rig : Rig or None
    ctrl_part : CPart
    real : {"double", "float"}
    title : str
        The export's one-line description (its estimator, delay and real type are appended).
    params : CartPoleParams, optional
        The MJCF MuJoCo runs, whose ctrlrange the ctrl is clipped to (default ``model.params``).

    Returns
    -------
    CProgram
    """
    estimator = "none" if rig is None else rig.estimator
    steps = 1 if rig is None else int(rig.steps)
    lag = 0 if rig is None else int(rig.delay_steps)
    spec = None if rig is None else rig.spec
    ny = model.nx if spec is None else int(spec.ny)
    compensate = rig is not None and rig.compensate and lag > 0
    m, _ = make_mujoco(model.params if params is None else params)
    lo, hi = ctrl_bounds(m)
    return CProgram(nx=model.nx, nq=model.nq, nu=model.nu, ny=ny, steps=steps, lag=lag, dt=float(model.dt),
                    real=real, u_low=np.asarray(lo, float), u_high=np.asarray(hi, float),
                    hinges=tuple(model.hinges), estimator=estimator_part(rig, model), controller=ctrl_part,
                    predict=_predictor(model, lag) if compensate else None,
                    title=f"{title}, estimator {estimator}, delay {lag * float(model.dt):g} s, {real}")
