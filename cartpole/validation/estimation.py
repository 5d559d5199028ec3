"""How well an estimator saw the state: its error against MuJoCo's true state at the control instants.

A run on a rig (:mod:`cartpole.sim.rig`) logs, per control instant, the estimate ``x_hat`` the controller's
estimator produced and the time; the true state at that instant is in the same rollout (every physics step is
logged), so the error is measured exactly, with hinge-angle errors wrapped.
"""
from __future__ import annotations

import numpy as np

from cartpole.models import state_error


def estimation_errors(rollout, hinges) -> np.ndarray:
    """``x_hat - x`` (K, nx) at the control instants (hinge angles wrapped), or an empty (0, nx) array for a run
    without a rig.

    Parameters
    ----------
    rollout : Rollout
    hinges : sequence of int
        qpos indices of the hinges.
    """
    if rollout.x_hat is None:
        return np.zeros((0, rollout.x.shape[1]))
    return state_error(rollout.x_hat, rollout.x_sample, hinges)


def estimation_summary(rollouts, estimator: str, hinges, state_names=None) -> dict:
    """The JSON ``estimation`` object over one or more runs.

    Parameters
    ----------
    rollouts : Rollout or sequence of Rollout
    estimator : str
        Its name (``"none"``, ``"kf"``, ``"ekf"``, ``"mhe"``).
    hinges : sequence of int
    state_names : sequence of str, optional
        One per state, to key ``rms_error`` by name (default by index).

    Returns
    -------
    dict
        ``estimator``; ``rms_error`` (state name -> RMS of ``x_hat - x`` over every control instant of every run,
        m, rad, m/s, rad/s); ``max_error`` (state name -> largest magnitude); ``estimate_ms`` {``median``,
        ``max``} of the estimator's wall time per control step (ms); ``samples``, the number of control instants.
    """
    runs = [rollouts] if hasattr(rollouts, "x_hat") else list(rollouts)
    errs = np.vstack([estimation_errors(r, hinges) for r in runs])
    nx = runs[0].x.shape[1]
    names = list(state_names) if state_names is not None else [f"x{i}" for i in range(nx)]
    ms = np.concatenate([r.estimate_ms for r in runs if r.estimate_ms is not None] or [np.zeros(0)])
    if errs.shape[0] == 0:
        rms = mx = np.zeros(nx)
    else:
        rms = np.sqrt(np.mean(errs ** 2, axis=0))
        mx = np.abs(errs).max(axis=0)
    return {"estimator": estimator, "rms_error": dict(zip(names, rms.tolist())),
            "max_error": dict(zip(names, mx.tolist())),
            "estimate_ms": {"median": float(np.median(ms)) if ms.size else 0.0,
                            "max": float(ms.max()) if ms.size else 0.0},
            "samples": int(errs.shape[0])}
