"""The ``export`` row of ``cartpole bench``: the exported C step beside the Python path it reproduces, on the
same measurements of the same MuJoCo run (the shipped cart, encoders, a 10 ms period).

Per controller: the C step timed inside C (:func:`cartpole.export.timing.time_steps`, each step's fastest of a few
replays of the run's measurements), the same step through ``ctypes`` in the MuJoCo loop, and the Python path
(estimator update + controller call) in that loop; medians and maxima in microseconds, and the ratio of the
medians. The NMPC row (not with ``quick``) is the single-pole swing-up at its own 20 ms period over 1.2 s.
"""
from __future__ import annotations

import numpy as np

from cartpole.apps.lab import lab_initial_conditions
from cartpole.export import design_export, export_files, load_design, run_lockstep
from cartpole.export.folder import discard
from cartpole.export.timing import time_steps
from cartpole.models import plant_model
from cartpole.sim.options import LoopOptions

#: The rig of the benchmark: a 10 ms period from 2048-count encoders.
PERIOD = 0.01
ENCODER_CPR = 2048


def _row(design, x0, duration: float, repeats: int) -> dict:
    ctl, folder = load_design(design, "double")
    try:
        run = run_lockstep(design, ctl, x0, duration)
    finally:
        discard(folder)
    timed = time_steps(export_files(design, "double"), run.t, run.y, repeats=repeats)
    same = bool(np.array_equal(timed["u"], run.c_ctrl))
    c, ct, py = timed["step_us"], run.step_us, run.python_us
    return {"c_step_us_median": float(np.median(c)), "c_step_us_max": float(np.max(c)),
            "ctypes_step_us_median": float(np.median(ct)), "ctypes_step_us_max": float(np.max(ct)),
            "python_step_us_median": float(np.median(py)), "python_step_us_max": float(np.max(py)),
            "speedup_median": float(np.median(py) / np.median(c)), "steps": int(c.size),
            "max_ctrl_diff": run.max_ctrl_diff, "replayed_same_ctrl": same}


def export_benchmark(plant=None, *, quick: bool = False) -> dict:
    """``{"period", "lqr_kf": {...}, "tvlqr_ekf": {...}, "nmpc": {...}}`` (see the module doc; with ``quick`` only
    ``lqr_kf``, the others None).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart (default the shipped one).
    quick : bool
        Shorter runs and fewer replays (for the test suite).

    Returns
    -------
    dict
        Per row: ``c_step_us_median``, ``c_step_us_max`` (in C), ``ctypes_step_us_median``, ``..._max``,
        ``python_step_us_median``, ``..._max``, ``speedup_median`` (Python / C), ``steps``, ``max_ctrl_diff``,
        ``replayed_same_ctrl``.
    """
    model = plant_model(plant)
    repeats = 2 if quick else 20
    lqr = design_export(model, "lqr", LoopOptions(period=PERIOD, estimator="kf", encoder_cpr=ENCODER_CPR))
    doc = {"period": PERIOD, "encoder_cpr": ENCODER_CPR,
           "lqr_kf": _row(lqr, np.asarray(lab_initial_conditions(model)[0]), 1.0 if quick else 5.0, repeats),
           "tvlqr_ekf": None, "nmpc": None}
    if not quick:
        tv = design_export(model, "tvlqr", LoopOptions(period=PERIOD, estimator="ekf", encoder_cpr=ENCODER_CPR))
        doc["tvlqr_ekf"] = _row(tv, np.asarray(model.x_hanging, float), tv.plan_end + 3.0, repeats)
        nm = design_export(model, "nmpc", None)  # its own period (20 ms), 1.2 s horizon, MuJoCo's state
        doc["nmpc"] = {**_row(nm, np.asarray(model.x_hanging, float), 8.0, 5), "period": nm.program.period}
    return doc


def print_export_table(doc: dict) -> None:
    """The export rows as lines."""
    for name, label in (("lqr_kf", "LQR + KF"), ("tvlqr_ekf", "TVLQR + EKF"), ("nmpc", "NMPC")):
        r = doc.get(name)
        if r is None:
            continue
        print(f"Exported C step, {label} at {r.get('period', doc['period']) * 1e3:g} ms: median {r['c_step_us_median']:.3f} us, max "
              f"{r['c_step_us_max']:.3f} us in C ({r['ctypes_step_us_median']:.2f} us through ctypes); the Python "
              f"path {r['python_step_us_median']:.1f} us median ({r['speedup_median']:.0f}x)")
