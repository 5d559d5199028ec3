"""The exported C in the MuJoCo loop, in lockstep with the Python controller it reproduces.

:func:`run_lockstep` drives MuJoCo (:func:`cartpole.sim.rollout.simulate`, the same rig: period, delay, sensors
with the same noise stream) with the C controller's ctrl. At every control instant the Python path gets the same
inputs (its estimator updated with the same measurement and the same ctrl history, its prediction over the delay)
and its ctrl is recorded beside the C's, so the two are compared on identical inputs, step for step.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from cartpole._arrays import readonly
from cartpole.sim.rollout import ctrl_bounds, make_mujoco, simulate


class Observation(NamedTuple):
    """What the loop hands the lockstep controller at a control instant: the sample time ``t`` (s), the
    measurement ``y`` (ny,) and the state the Python controller acts on ``x`` (nx,: its estimate, predicted over
    the delay)."""

    t: float
    y: np.ndarray
    x: np.ndarray


class _TapLog:
    def __init__(self, log):
        self.log, self.y = log, None

    def add(self, t, y, x_hat, ms):
        self.y = np.array(y, dtype=float)
        self.log.add(t, y, x_hat, ms)


class _TapRun:
    def __init__(self, run, timestep: float):
        self.run, self.h = run, float(timestep)

    def sample(self, m, d, k, since, ahead, log):
        tap = _TapLog(log)
        x = self.run.sample(m, d, k, since, ahead, tap)
        return Observation(k * self.h, tap.y, np.asarray(x, dtype=float))


class TapRig:
    """A :class:`~cartpole.sim.rig.Rig` whose samples reach the controller as :class:`Observation` (measurement and
    the Python path's state), for :func:`cartpole.sim.rollout.simulate`'s ``rig=``.

    Parameters
    ----------
    rig : Rig
    """

    def __init__(self, rig):
        self.rig = rig
        self.steps, self.delay_steps = int(rig.steps), int(rig.delay_steps)

    def start(self, m):
        """A run of the wrapped rig on ``m`` whose samples are :class:`Observation`."""
        return _TapRun(self.rig.start(m), float(m.opt.timestep))


@dataclass(frozen=True)
class LockstepRun:
    """A MuJoCo run driven by the exported C, with the Python controller's ctrl beside it at every control instant.

    Attributes
    ----------
    rollout : Rollout
        What MuJoCo did under the C's ctrl (replays with ``mj_step``).
    t : (K,) array
        Control instants, s (sample times).
    c_ctrl : (K, nu) array
        The C's ctrl (clipped to ctrlrange).
    py_ctrl : (K, nu) array
        The Python controller's ctrl on the same inputs, clipped to ctrlrange as MuJoCo does.
    codes : (K,) int array
        ``cp_step``'s return codes.
    step_us : (K,) array
        Wall time of each C step through ``ctypes``, microseconds.
    y : (K, ny) array
        The measurements the C received.
    python_us : (K,) array
        Wall time of the Python path at each instant, microseconds: its estimator's update (the rig's
        ``estimate_ms``; 0 without an estimator) plus the controller call.
    """

    rollout: object
    t: np.ndarray
    c_ctrl: np.ndarray
    py_ctrl: np.ndarray
    codes: np.ndarray
    step_us: np.ndarray
    y: np.ndarray | None = None
    python_us: np.ndarray | None = None

    @property
    def max_ctrl_diff(self) -> float:
        """``max |C ctrl - Python ctrl|`` over every control instant and input."""
        return float(np.max(np.abs(self.c_ctrl - self.py_ctrl))) if self.t.size else 0.0


def run_lockstep(design, cctl, x0, duration: float) -> LockstepRun:
    """Run the C controller ``cctl`` in MuJoCo on ``design``'s rig from ``x0``, the Python controller in lockstep.

    Parameters
    ----------
    design : ExportDesign
        Its ``make_controller``, ``rig`` and ``model.params`` (the MJCF MuJoCo runs).
    cctl : CController
        The loaded export of ``design``.
    x0 : (nx,) array
        Start state ``[qpos, qvel]``.
    duration : float
        Seconds.

    Returns
    -------
    LockstepRun
    """
    params = design.model.params
    m, _ = make_mujoco(params)
    lo, hi = ctrl_bounds(m)
    py = design.make_controller()
    if hasattr(py, "reset"):
        py.reset()
    cctl.reset()
    rec_t, rec_c, rec_p, rec_code, rec_us, rec_y, rec_py = [], [], [], [], [], [], []

    def lockstep(t_sample, y, t_ctrl, x):
        t0 = time.perf_counter_ns()
        code, u = cctl.step(t_sample, y)
        rec_us.append(1e-3 * (time.perf_counter_ns() - t0))
        t1 = time.perf_counter_ns()
        up = np.clip(np.asarray(py(t_ctrl, x), dtype=float).ravel(), lo, hi)
        rec_py.append(1e-3 * (time.perf_counter_ns() - t1))
        rec_y.append(np.array(y, dtype=float))
        rec_t.append(t_sample)
        rec_c.append(u)
        rec_p.append(up)
        rec_code.append(code)
        return u

    if design.rig is None:
        rollout = simulate(params, lambda t, x: lockstep(t, x, t, x), x0, duration)
    else:
        def controller(t_ctrl, obs):
            return lockstep(obs.t, obs.y, t_ctrl, obs.x)
        rollout = simulate(params, controller, x0, duration, rig=TapRig(design.rig))
    nu = design.program.nu
    py_us = np.asarray(rec_py, float)
    if rollout.estimate_ms is not None:
        py_us = py_us + 1e3 * np.asarray(rollout.estimate_ms, float)[:py_us.size]
    return LockstepRun(rollout=rollout, t=readonly(np.asarray(rec_t, float)),
                       c_ctrl=readonly(np.asarray(rec_c, float).reshape(-1, nu)),
                       py_ctrl=readonly(np.asarray(rec_p, float).reshape(-1, nu)),
                       codes=readonly(np.asarray(rec_code, int)), step_us=readonly(np.asarray(rec_us, float)),
                       y=readonly(np.asarray(rec_y, float).reshape(len(rec_y), -1)), python_us=readonly(py_us))
