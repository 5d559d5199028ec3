"""The exported program as the MuJoCo loop's controller: one implementation, the C the rig runs.

:func:`compile_program` builds the C files of an export (``cartpole/csrc`` plus the rendered and CasADi-generated
parts: :func:`~cartpole.export.make.export_files`) once per model and design into a cached shared library through
:func:`cartpole.codegen.build_sources`, with the flags the export is verified under (:data:`STRICT_CFLAGS` and
:data:`OPT_CFLAGS`), and loads it through ``ctypes``. :func:`run_compiled` runs it in MuJoCo: at every control
instant the rig's sensors are sampled in Python (the same :class:`~cartpole.estimation.SensorSampler` and noise
stream as the Python rig) and the whole rig step (estimate, delay prediction, law, clip) is one call of the
compiled ``cp_step``; the rollout logs the measurements and the C's own estimate. The Python classes
(:mod:`cartpole.control`, :mod:`cartpole.estimation`, :class:`cartpole.sim.rig.RigRun`) remain the path without a
C compiler and the tests' reference (:func:`cartpole.export.loop.run_lockstep` compares them step by step).

A compiled program keeps its state in the library's static memory: one run at a time per design in a process
(:class:`InLoopController` refuses a step after another controller of the same library was reset).
"""
from __future__ import annotations

import ctypes
import time

import numpy as np

from cartpole.export.build import OPT_CFLAGS, STRICT_CFLAGS, CController
from cartpole.export.estimators import ExportError

#: Which :class:`InLoopController` last reset each library (path -> id): its static state is that run's.
_OWNER: dict = {}


class InLoopController(CController):
    """The compiled program of an export, for the MuJoCo loop: :class:`~cartpole.export.build.CController`'s
    ``reset()`` and ``step(t, y)``, plus ``estimate()`` (the C's ``x_hat``, nx).

    Parameters
    ----------
    lib : path
        The shared library (:func:`compile_program`).
    ny, nu, nx : int
        Sizes of ``y``, ``u`` and the state.
    real : {"double", "float"}
        ``cp_real``.
    """

    def __init__(self, lib, ny: int, nu: int, nx: int, real: str = "double"):
        super().__init__(lib, ny, nu, real)
        self.nx = int(nx)
        ctype = ctypes.c_float if real == "float" else ctypes.c_double
        self._x = np.zeros(self.nx, dtype=self.dtype)
        self._est = self._lib.cp_estimate
        self._est.argtypes = [ctypes.POINTER(ctype)]
        self._est.restype = None
        self._xp = self._x.ctypes.data_as(ctypes.POINTER(ctype))

    def reset(self) -> None:
        """``cp_reset()``; this controller now owns the library's static state."""
        _OWNER[self.lib_path] = id(self)
        super().reset()

    def step(self, t: float, y) -> tuple[int, np.ndarray]:
        """``cp_step(t, y, u)``: the return code and ``u`` (nu,) as float64.

        Raises
        ------
        ExportError
            Another controller of the same library was reset since this one (their runs would share state).
        """
        if _OWNER.get(self.lib_path) != id(self):
            raise ExportError("Another run reset this compiled controller since this run started (a compiled "
                              "program holds one run's state); call reset() before stepping it again.")
        return super().step(t, y)

    def estimate(self) -> np.ndarray:
        """The rig's current estimate ``x_hat`` (nx,) as float64 (before the delay prediction)."""
        self._est(self._xp)
        return self._x.astype(float)


def compile_program(design, real: str = "double") -> InLoopController:
    """The C files of ``design``'s export compiled once (cached by their content, the compiler and the flags) and
    loaded.

    Parameters
    ----------
    design : ExportDesign
    real : {"double", "float"}

    Returns
    -------
    InLoopController

    Raises
    ------
    ExportError
        No C compiler, or the C does not compile.
    """
    from dataclasses import replace

    from cartpole.export.make import c_sources

    prog = design.program if real == design.program.real else replace(design.program, real=real)
    return load_program(c_sources(prog), prog, real)


class _CRun:
    """One run of the compiled rig step: samples the sensors as :class:`cartpole.sim.rig.RigRun` does (same
    sampler, same noise stream), then one ``cp_step`` does estimate, prediction, law and clip."""

    def __init__(self, rig, ctl: InLoopController, m):
        self.ctl, self.h = ctl, float(m.opt.timestep)
        self.sampler, self.forward = None, False
        if rig.spec is not None:
            from cartpole.estimation import SensorSampler

            self.sampler = SensorSampler(rig.spec, m, seed=rig.seed)
            self.forward = any(s.adr >= 0 for s in rig.spec.sensors)
        self.u = None

    def sample(self, m, d, k, since, ahead, log):
        import mujoco

        t = k * self.h
        if self.sampler is None:
            y = np.concatenate([d.qpos, d.qvel])
        else:
            if self.forward:
                mujoco.mj_forward(m, d)
            y = self.sampler(d)
        t0 = time.perf_counter()
        _, self.u = self.ctl.step(t, y)
        ms = 1e3 * (time.perf_counter() - t0)
        log.add(t, y, self.ctl.estimate(), ms)
        return self.u


class CompiledRig:
    """A :class:`~cartpole.sim.rig.Rig` whose control instants are one call of the compiled ``cp_step`` (for
    :func:`cartpole.sim.rollout.simulate`'s ``rig=``; its controller returns the ctrl the sample computed).

    Parameters
    ----------
    rig : Rig
    ctl : InLoopController
    """

    def __init__(self, rig, ctl: InLoopController):
        self.rig, self.ctl = rig, ctl
        self.steps, self.delay_steps = int(rig.steps), int(rig.delay_steps)

    def start(self, m):
        """A run on ``m``: the compiled program reset, the sensors' noise stream started from the rig's seed."""
        self.ctl.reset()
        return _CRun(self.rig, self.ctl, m)


def run_compiled(design, x0, duration: float, *, ctl: InLoopController | None = None, push=None):
    """Run ``design``'s compiled program in MuJoCo from ``x0`` (the one implementation in the loop).

    Parameters
    ----------
    design : ExportDesign
        Its rig and ``model.params`` (the MJCF MuJoCo runs).
    x0 : (nx,) array
        Start state ``[qpos, qvel]``.
    duration : float
        Seconds.
    ctl : InLoopController, optional
        The loaded program (default :func:`compile_program` of ``design``).
    push : optional
        As :func:`cartpole.sim.rollout.simulate`'s ``push``.

    Returns
    -------
    Rollout
        With a rig, ``y`` (what ``cp_step`` received), ``x_hat`` (the C's estimate) and ``estimate_ms`` (the wall
        time of each ``cp_step`` call through ``ctypes``).
    """
    from cartpole.sim.rollout import simulate

    ctl = compile_program(design) if ctl is None else ctl
    params = design.model.params
    if design.rig is None:
        ctl.reset()
        return simulate(params, lambda t, x: ctl.step(t, x)[1], x0, duration, push=push)
    return simulate(params, lambda t, u: u, x0, duration, rig=CompiledRig(design.rig, ctl), push=push)


def controller_part(controller):
    """The C part (:mod:`cartpole.export.controllers`, :mod:`cartpole.export.nmpc`) of a Python controller of the
    loop, or None when the controller has no C implementation here (a wrapper, a supervisor: they stay Python in the
    loop).

    Parameters
    ----------
    controller : callable
        ``u = controller(t, x)``.

    Returns
    -------
    CPart or None
    """
    from cartpole.control.energy import EnergyShapingController
    from cartpole.control.linear import LinearFeedback
    from cartpole.control.pid import CascadedPID
    from cartpole.control.switching import SwitchingController
    from cartpole.control.tvlqr import TVLQRController
    from cartpole.export.controllers import energy_part, linear_part, pid_part, tvlqr_part
    from cartpole.mpc.nmpc import NMPCController

    kind = type(controller)
    if kind is NMPCController:  # its part from the first iterate: the program resets it every run
        from cartpole.export.nmpc import nmpc_part

        controller.reset()
        return nmpc_part(controller, controller.offline_plan)
    if kind is LinearFeedback:
        return linear_part(controller)
    if kind is CascadedPID:
        return pid_part(controller)
    if kind is TVLQRController and type(controller.catch) is LinearFeedback:
        return tvlqr_part(controller)
    if (kind is SwitchingController and type(controller.swingup) is EnergyShapingController
            and type(controller.catch) is LinearFeedback):
        return energy_part(controller)
    return None


class _Stepper:
    """The compiled program as ``u = c(t, x)`` for a loop without a rig (MuJoCo's exact state every physics step):
    reset at ``t = 0``, the start of every run."""

    def __init__(self, ctl: InLoopController):
        self.ctl = ctl

    def __call__(self, t, x):
        if t == 0.0:
            self.ctl.reset()
        return self.ctl.step(t, x)[1]


#: Compiled programs by the Python objects they reproduce (kept alive beside them): (controller, estimator
#: factory, steps, lag, compensation, run MJCF) -> InLoopController.
_PROGRAMS: dict = {}


def in_loop(model, controller, rig=None):
    """``(controller, rig)`` for :func:`cartpole.sim.rollout.simulate` running ``controller`` on ``rig`` as the one
    compiled implementation: the export's C (the controller's part, the rig's estimator, delay prediction and
    clip) built once through :mod:`cartpole.codegen` and called every period, when a C compiler exists and the
    controller and estimator have C parts (LQR, PID, TVLQR, energy with its catch, the NMPC; none, KF, EKF, MHE). Otherwise, or
    with ``CARTPOLE_NO_COMPILE`` set, ``(controller, rig)`` unchanged: the Python classes. C that does not compile
    raises (:class:`~cartpole.export.estimators.ExportError`): it is a bug, never hidden behind a Python run.

    Parameters
    ----------
    model : CartPoleModel
        The model whose MJCF MuJoCo runs (its ctrlrange clips the ctrl).
    controller : callable
        ``u = controller(t, x)``, reset by the caller between runs as usual (the compiled program resets itself at
        the start of each run).
    rig : Rig, optional
        The rig (its sensors and noise stream stay Python: MuJoCo's sensors sampled, then ``cp_step``).

    Returns
    -------
    (callable, object)
        The loop's controller and rig.
    """
    import os

    from cartpole.codegen import compiler

    if os.environ.get("CARTPOLE_NO_COMPILE") or compiler() is None:
        return controller, rig
    if rig is not None and rig.estimator not in ("none", "kf", "ekf", "mhe"):
        return controller, rig
    key = (id(controller), None if rig is None else id(rig.make_estimator), None if rig is None else rig.steps,
           None if rig is None else rig.delay_steps, None if rig is None else rig.compensate, id(model.params))
    entry = _PROGRAMS.get(key)
    if entry is None:
        part = controller_part(controller)
        if part is None:
            return controller, rig
        from cartpole.export.design import build_program
        from cartpole.export.make import c_sources

        design_model = model if rig is None else rig.model
        prog = build_program(design_model, rig, part, params=model.params, title="in-loop program")
        ctl = load_program(c_sources(prog), prog)  # a compile error is a bug, said (never a silent Python run)
        entry = _PROGRAMS[key] = (controller, rig, model.params, ctl)
    ctl = entry[3]
    if rig is None:
        return _Stepper(ctl), None
    return (lambda t, u: u), CompiledRig(rig, ctl)


def load_program(files: dict, prog, real: str = "double") -> InLoopController:
    """The C files ``files`` (relative path -> text) of the program ``prog`` compiled through
    :func:`cartpole.codegen.build_sources` with the export's flags and loaded.

    Raises
    ------
    ExportError
        No C compiler, or the C does not compile.
    """
    from cartpole.codegen import build_sources
    from cartpole.export.build import find_compiler

    find_compiler()
    try:
        lib = build_sources(files, "cp_program", cflags=(*STRICT_CFLAGS, *OPT_CFLAGS))
    except RuntimeError as exc:
        raise ExportError(f"The exported C does not compile ({exc}); report this as a bug.") from None
    return InLoopController(lib, prog.ny, prog.nu, prog.nx, real)
