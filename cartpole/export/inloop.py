"""The exported program as the MuJoCo loop's controller: one implementation, the C the rig runs.

:func:`compile_program` builds the C files of an export (``cartpole/csrc`` plus the rendered and CasADi-generated
parts: :func:`~cartpole.export.make.export_files`) into a shared library cached by their content
(:func:`~cartpole.export.build.program_library`, the one compile path the verification's folder shares, with the
flags the export is verified under) and loads it through ``ctypes``. :func:`run_compiled` runs it in MuJoCo: at
every control instant the rig's sensors are sampled in Python (the same
:class:`~cartpole.estimation.SensorSampler` and noise stream as the Python rig) and the whole rig step (estimate,
delay prediction, law, clip) is one call of the compiled ``cp_step``; the rollout logs the measurements and the
C's own estimate. The Python classes (:mod:`cartpole.control`, :mod:`cartpole.estimation`,
:class:`cartpole.sim.rig.RigRun`) remain the path without a C compiler and the tests' reference
(:func:`cartpole.export.loop.run_lockstep` compares them step by step).

A compiled program keeps its state in the library's static memory: each :class:`InLoopController` loads its own
private copy of the cached library (:func:`cartpole.codegen.load_private_copy`, the one way a compiled library is
loaded with state of its own), so two controllers of one design, in one thread or in several, never share a run's
state. The loop's
controller (:class:`CompiledLaw`) exposes the state the Python class does (the switch log of the energy law and its
catch, the TVLQR's hand-over time), read from the C.
"""
from __future__ import annotations

import ctypes
import os
import time
from dataclasses import replace
from types import SimpleNamespace

import mujoco
import numpy as np

from cartpole.codegen import compiler, load_private_copy
from cartpole.control.energy import EnergyShapingController
from cartpole.control.linear import LinearFeedback
from cartpole.control.pid import CascadedPID
from cartpole.control.switching import Switch, SwitchingController
from cartpole.control.tvlqr import TVLQRController
from cartpole.estimation import SensorSampler
from cartpole.export.build import CController, program_library
from cartpole.export.controllers import energy_part, linear_part, pid_part, tvlqr_part
from cartpole.export.design import build_program
from cartpole.export.estimators import ExportError
from cartpole.export.make import c_sources
from cartpole.export.nmpc import nmpc_part
from cartpole.mpc.nmpc import NMPCController
from cartpole.mpc.nmpc_c import NMPC_STATE_ARGTYPES, SolveRecord, read_state
from cartpole.sim.rollout import simulate

class InLoopController(CController):
    """The compiled program of an export, for the MuJoCo loop: :class:`~cartpole.export.build.CController`'s
    ``reset()`` and ``step(t, y)``, plus ``estimate()`` (the C's ``x_hat``, nx).

    Parameters
    ----------
    lib : path
        The shared library (:func:`compile_program`), built once and cached; this controller loads a private copy
        of it (its own static state).
    ny, nu, nx : int
        Sizes of ``y``, ``u`` and the state.
    real : {"double", "float"}
        ``cp_real``.

    Attributes
    ----------
    library : str
        The cached library (``lib``); ``lib_path`` is this controller's copy.
    """

    def __init__(self, lib, ny: int, nu: int, nx: int, real: str = "double"):
        super().__init__(load_private_copy(lib, "cp_program_"), ny, nu, real)
        self.library = str(lib)
        self.nx = int(nx)
        ctype = ctypes.c_float if real == "float" else ctypes.c_double
        self._ctype = ctype
        self._accessors = SimpleNamespace()
        self._x = np.zeros(self.nx, dtype=self.dtype)
        self._est = self._lib.cp_estimate
        self._est.argtypes = [ctypes.POINTER(ctype)]
        self._est.restype = None
        self._xp = self._x.ctypes.data_as(ctypes.POINTER(ctype))

    def estimate(self) -> np.ndarray:
        """The rig's current estimate ``x_hat`` (nx,) as float64 (before the delay prediction)."""
        self._est(self._xp)
        return self._x.astype(float)

    def switch_state(self) -> tuple[bool, float, float]:
        """The energy part's ``cp_switch_state``: ``(caught, t, cost)``, whether the catch is in charge, and the
        time (s) and the catch's ``e' S e`` of the last evaluation.

        Raises
        ------
        ExportError
            The program's controller is not the energy law with its catch.
        """
        fn = self._accessor("cp_switch_state", [ctypes.POINTER(ctypes.c_double), ctypes.POINTER(self._ctype)])
        t, cost = ctypes.c_double(), self._ctype()
        caught = fn(ctypes.byref(t), ctypes.byref(cost))
        return bool(caught), float(t.value), float(cost.value)

    def handover_state(self) -> float | None:
        """The TVLQR part's ``cp_handover_state``: the time (s) of the first evaluation that used the catch since the
        reset, or None.

        Raises
        ------
        ExportError
            The program's controller is not the TVLQR with its catch.
        """
        fn = self._accessor("cp_handover_state", [ctypes.POINTER(ctypes.c_double)])
        t = ctypes.c_double()
        return float(t.value) if fn(ctypes.byref(t)) else None

    def nmpc_state(self) -> SolveRecord:
        """The NMPC part's ``cp_nmpc_state``: its last solve (count since the reset, time, wall time timed in the C,
        status, safe action).

        Raises
        ------
        ExportError
            The program's controller is not the NMPC.
        """
        return read_state(self._accessor("cp_nmpc_state", NMPC_STATE_ARGTYPES))

    def has(self, name: str) -> bool:
        """Whether the program defines the C function ``name`` (a part's state accessor, ``cp_nmpc_state``...)."""
        return hasattr(self._lib, name)

    def _accessor(self, name: str, argtypes):
        fn = getattr(self._accessors, name, None)
        if fn is None:
            try:
                fn = getattr(self._lib, name)
            except AttributeError:
                raise ExportError(f"This compiled program has no {name}(): its controller does not keep that state "
                                  "(cp_switch_state is the energy law's, cp_handover_state the TVLQR's, "
                                  "cp_nmpc_state the NMPC's).") from None
            fn.argtypes, fn.restype = argtypes, ctypes.c_int
            setattr(self._accessors, name, fn)
        return fn


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
    prog = design.program if real == design.program.real else replace(design.program, real=real)
    return load_program(c_sources(prog), prog, real)


class _CRun:
    """One run of the compiled rig step: samples the sensors as :class:`cartpole.sim.rig.RigRun` does (same
    sampler, same noise stream), then one ``cp_step`` does estimate, prediction, law and clip."""

    def __init__(self, rig, ctl: InLoopController, m):
        self.ctl, self.h = ctl, float(m.opt.timestep)
        self.sampler, self.forward = None, False
        if rig.spec is not None:
            self.sampler = SensorSampler(rig.spec, m, seed=rig.seed)
            self.forward = any(s.adr >= 0 for s in rig.spec.sensors)
        self.u = None

    def sample(self, m, d, k, since, ahead, log):
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
    :func:`cartpole.sim.rollout.simulate`'s ``rig=``; its controller returns the ctrl the sample computed). Any
    other attribute is the rig's (``estimator``, ``spec``, ``to_dict()``...).

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

    def __getattr__(self, name: str):
        # Only reached for names this class does not define: the rig's own (estimator, spec, to_dict(), ...).
        rig = self.__dict__.get("rig")
        if rig is None or name.startswith("__"):
            raise AttributeError(name)
        return getattr(rig, name)


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
        time of each ``cp_step`` call through ``ctypes``). The controller's state read from the C: for the energy
        law with its catch ``info["switches"]`` (list of :class:`~cartpole.control.switching.Switch`), for the TVLQR
        ``info["handover_time"]`` (s or None).
    """
    ctl = compile_program(design) if ctl is None else ctl
    params = design.model.params
    law = _law(design.program.controller, ctl, design.rig is not None)
    if design.rig is None:
        rollout = simulate(params, law, x0, duration, push=push)
    else:
        rollout = simulate(params, law, x0, duration, rig=CompiledRig(design.rig, ctl), push=push)
    if isinstance(law, CompiledSwitching):
        rollout.info["switches"] = list(law.switches)
    elif isinstance(law, CompiledTracker):
        rollout.info["handover_time"] = law.handover_time
    return rollout


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
    kind = type(controller)
    if kind is NMPCController:  # its part from the first iterate: the program resets it every run
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


class CompiledLaw:
    """The loop's controller ``u = c(t, x)`` when the compiled program runs: without a rig it calls ``cp_step`` on
    MuJoCo's exact state every physics step (``cp_reset`` at ``t = 0``, the start of every run); with a rig
    (:class:`CompiledRig`) the sample already called it and ``x`` is that ctrl, returned as it is.

    Parameters
    ----------
    program : InLoopController
    rig : bool
        Whether a :class:`CompiledRig` calls ``cp_step`` (then ``c(t, u)`` returns ``u``).

    Attributes
    ----------
    program : InLoopController
        The compiled program (its state is the run's).
    """

    def __init__(self, program: InLoopController, rig: bool = False):
        self.program = program
        self._rig = bool(rig)
        self._last_t = -np.inf

    def reset(self) -> None:
        """Start a new run now (as a call at ``t = 0`` does): ``cp_reset`` and the state read from it forgotten."""
        self.program.reset()
        self._restart()
        self._last_t = -np.inf

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s): ``cp_step``'s on ``x`` (nx,), or ``x`` itself (the ctrl) with a rig."""
        t = float(t)
        if t < self._last_t or (t == 0.0 and not self._rig):  # a new run
            if not self._rig:
                self.program.reset()
            self._restart()
        self._last_t = t
        u = np.asarray(x, dtype=float) if self._rig else self.program.step(t, x)[1]
        self._observe(t)
        return u

    def _restart(self) -> None:
        """Forget the state read from the program (a new run started)."""

    def _observe(self, t: float) -> None:
        """Read the program's state after its ``cp_step`` of time ``t``."""


class CompiledSwitching(CompiledLaw):
    """:class:`CompiledLaw` of the energy law with its LQR catch (``cp_energy.c``), exposing what
    :class:`~cartpole.control.switching.SwitchingController` does, read from the C after every ``cp_step``
    (``cp_switch_state``): the time and the cost ``e' S e`` of each switch are the C's.

    Attributes
    ----------
    mode : str
        "swingup" or "catch", the law in charge after the last ``cp_step``.
    switches : list of Switch
        Every mode change of this run.
    """

    def __init__(self, program: InLoopController, rig: bool = False):
        super().__init__(program, rig)
        self._restart()

    def _restart(self) -> None:
        self.mode = "swingup"
        self.switches = []

    def _observe(self, t: float) -> None:
        caught, t_c, cost = self.program.switch_state()
        mode = "catch" if caught else "swingup"
        if mode != self.mode:
            self.mode = mode
            self.switches.append(Switch(t_c, mode, cost))

    @property
    def caught_at(self) -> float | None:
        """Time (s) of the last switch to the catch if the catch is still in charge, else None."""
        if self.mode == "catch" and self.switches:
            return self.switches[-1].t
        return None


class CompiledTracker(CompiledLaw):
    """:class:`CompiledLaw` of the TVLQR along a plan with its LQR catch (``cp_tvlqr.c``), exposing what
    :class:`~cartpole.control.tvlqr.TVLQRController` does: ``handover_time``, read from the C
    (``cp_handover_state``)."""

    @property
    def handover_time(self) -> float | None:
        """Time (s) of the first evaluation that used the catch in this run, or None."""
        return self.program.handover_state()


class CompiledNMPCLaw(CompiledLaw):
    """:class:`CompiledLaw` of the NMPC (``nmpc.c.jinja``), exposing what :class:`~cartpole.mpc.nmpc.NMPCController`
    records, read from the C after every ``cp_step`` (``cp_nmpc_state``): one entry per solve (a held ctrl is not
    one), its time measured inside the C around the step (``cp_clock.c``).

    Parameters
    ----------
    program : InLoopController
    rig : bool
    nmpc : NMPCController, optional
        The controller the program was made from (its ``period``, ``horizon``, ``N`` and ``objective``; None
        when only the program is at hand: those read None).

    Attributes
    ----------
    solve_ms : list of float
        ms of each solve, timed inside the C (``cp_clock_seconds``; without the ``ctypes`` call around it).
    failures : list of dict
        ``{"t", "reason", "action"}`` of each solve that took the safe action, as the Python class's.
    qp_iterations : list of int
        The QP's active-set changes in each solve.
    period, horizon : float or None
        s.
    """

    #: Where each solve runs (as :attr:`NMPCController.step_implementation`).
    step_implementation = "c"
    #: The QP solver (as :attr:`NMPCController.qp_solver`): the C dual active set of ``qp_dual.c``.
    qp_solver = "c"

    def __init__(self, program: InLoopController, rig: bool = False, nmpc=None):
        super().__init__(program, rig)
        self.period = None if nmpc is None else float(nmpc.period)
        self.horizon = None if nmpc is None else float(nmpc.horizon)
        self.N = None if nmpc is None else int(nmpc.N)
        self.objective = "tracking" if nmpc is None else getattr(nmpc, "objective", "tracking")
        self._restart()

    def _restart(self) -> None:
        self.solve_ms: list[float] = []
        self.failures: list[dict] = []
        self.qp_iterations: list[int] = []
        self._solves = 0

    def _observe(self, t: float) -> None:
        solve = self.program.nmpc_state()
        if solve.solves == self._solves:
            return
        self._solves = solve.solves
        self.solve_ms.append(1e3 * solve.seconds)
        self.qp_iterations.append(solve.qp_iterations)
        failure = solve.failure()
        if failure is not None:
            self.failures.append(failure)

    @property
    def step_c_ms(self) -> list:
        """ms of each solve timed inside the C: :attr:`solve_ms` (the loop pays the ``ctypes`` call on top)."""
        return self.solve_ms


def _law(part, ctl: InLoopController, rig: bool, controller=None) -> CompiledLaw:
    """The :class:`CompiledLaw` of the controller part ``part`` (made from the Python ``controller``, when given)
    that keeps the state its Python class exposes."""
    if isinstance(controller, NMPCController) or ctl.has("cp_nmpc_state"):
        return CompiledNMPCLaw(ctl, rig, controller if isinstance(controller, NMPCController) else None)
    if "cp_energy.c" in part.sources:
        return CompiledSwitching(ctl, rig)
    if "cp_tvlqr.c" in part.sources:
        return CompiledTracker(ctl, rig)
    return CompiledLaw(ctl, rig)


def in_loop(model, controller, rig=None):
    """``(controller, rig)`` for :func:`cartpole.sim.rollout.simulate` running ``controller`` on ``rig`` as the one
    compiled implementation: the export's C (the controller's part, the rig's estimator, delay prediction and
    clip) built through :mod:`cartpole.codegen` (cached on disk by its content) and called every period, when a C
    compiler exists and the controller and estimator have C parts (LQR, PID, TVLQR, energy with its catch, the NMPC;
    none, KF, EKF, MHE). Otherwise, or with ``CARTPOLE_NO_COMPILE`` set, ``(controller, rig)`` unchanged: the Python
    classes. C that does not compile raises (:class:`~cartpole.export.estimators.ExportError`): it is a bug, never
    hidden behind a Python run.

    The compiled controller is a :class:`CompiledLaw`; for the energy law with its catch a
    :class:`CompiledSwitching` (``mode``, ``switches``, ``caught_at``), for the TVLQR a :class:`CompiledTracker`
    (``handover_time``): the state the Python classes expose, read from the C. Nothing is kept between calls
    here: each call generates the program's files (the library is found by their content) and loads it.

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
    if os.environ.get("CARTPOLE_NO_COMPILE") or compiler() is None:
        return controller, rig
    if rig is not None and rig.estimator not in ("none", "kf", "ekf", "mhe"):
        return controller, rig
    part = controller_part(controller)
    if part is None:
        return controller, rig
    design_model = model if rig is None else rig.model
    prog = build_program(design_model, rig, part, params=model.params, title="in-loop program")
    ctl = load_program(c_sources(prog), prog)  # a compile error is a bug, said (never a silent Python run)
    if rig is None:
        return _law(part, ctl, False, controller), None
    return _law(part, ctl, True, controller), CompiledRig(rig, ctl)


def load_program(files: dict, prog, real: str = "double") -> InLoopController:
    """The C files ``files`` (relative path -> text) of the program ``prog`` compiled with the export's flags
    (:func:`~cartpole.export.build.program_library`, cached by their content) and loaded: a private copy of the
    library, so runs in concurrent threads (a threaded Dask worker, a live view) or one after another never share a
    program's static memory.

    Parameters
    ----------
    files : dict
        Relative path -> C text (:func:`~cartpole.export.make.c_sources`).
    prog : CProgram
        Its sizes.
    real : {"double", "float"}

    Returns
    -------
    InLoopController

    Raises
    ------
    ExportError
        No C compiler, or the C does not compile.
    """
    return InLoopController(program_library(files), prog.ny, prog.nu, prog.nx, real)
