"""``cartpole identify``: fit MJCF parameters to logged runs, check them on held-out runs, write the fitted MJCF.

Flow: read the nominal MJCF and the logs (:mod:`cartpole.identify.logs`), choose the parameters by name
(:mod:`cartpole.identify.parameters`), fit them (:func:`cartpole.identify.fit.fit`), write the fitted MJCF
(:mod:`cartpole.identify.mjcf`, checked by compiling it), and simulate the nominal and fitted models open loop
on every held-out run (or, without one, on the first fitted run) for the figure and ``holdout_rms``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cartpole.identify.fit import DEFAULT_REGULARIZATION, DEFAULT_SEGMENT_S, FitResult, fit, simulate_log
from cartpole.identify.logs import read_log
from cartpole.identify.mjcf import write_fitted_mjcf
from cartpole.identify.parameters import parse_parameters
from cartpole.models import plant_params
from cartpole.viz.identify_plot import plot_identify


@dataclass(frozen=True)
class IdentifyResult:
    """What ``identify`` found and wrote.

    Attributes
    ----------
    fit : FitResult
    mjcf : Path
        The fitted MJCF written.
    figure : Path or None
    fit_rms : dict
        ``{"fitted": {joint: rms}, "nominal": {joint: rms}}`` on the fitted runs, open loop from each run's
        estimated start (m or rad).
    holdout_rms : dict or None
        The same on the held-out runs (None without any).
    nominal_mjcf : str
    joints : tuple of str
        Joint names in qpos order.
    """

    fit: FitResult
    mjcf: Path
    figure: Path | None
    fit_rms: dict
    holdout_rms: dict | None
    nominal_mjcf: str
    joints: tuple = ()

    def to_dict(self) -> dict:
        """The JSON ``identify`` object."""
        f = self.fit
        return {"parameters": f.as_dict(), "names": list(f.names), "correlation": f.correlation,
                "warnings": list(f.warnings), "fit_rms": self.fit_rms, "holdout_rms": self.holdout_rms,
                "shooting_rms": dict(zip(self.joints, f.fit_rms.tolist())), "mjcf": str(self.mjcf),
                "nominal_mjcf": self.nominal_mjcf, "figure": None if self.figure is None else str(self.figure),
                "solve_s": f.solve_s, "iterations": f.iterations}



def _rms(p, params, theta, logs) -> dict:
    """Per joint RMS over all samples of the open-loop simulations of ``logs``."""
    sq = np.zeros(p.nq)
    n = 0
    sims = []
    for log in logs:
        s = simulate_log(p, params, theta, log)
        sims.append(s)
        sq += s.rms ** 2 * log.n
        n += log.n
    return dict(zip(p.joint_names, np.sqrt(sq / n).tolist())), sims


def run_identify(plant, logs, out: str | Path, *, fit_names=("all",), holdout=(), regularization: float =
                 DEFAULT_REGULARIZATION, segment_s: float = DEFAULT_SEGMENT_S, figure: bool = True,
                 name: str = "fitted") -> IdentifyResult:
    """Fit, check and write (module docstring).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The nominal MJCF.
    logs : sequence of path
        Runs to fit (CSV or rollout JSON).
    out : path
        Directory for ``<name>.xml`` and ``figures/identify_holdout.png``.
    fit_names : sequence of str
        Parameter names (:func:`~cartpole.identify.parameters.parse_parameters`).
    holdout : sequence of path
        Runs not used for the fit.
    regularization : float
        Weight toward the nominal (:func:`~cartpole.identify.fit.fit`).
    segment_s : float
        Shooting segment, s.
    figure : bool
        Write the figure.
    name : str
        Stem of the fitted MJCF's file name.

    Returns
    -------
    IdentifyResult
    """
    p = plant_params(plant)
    params = parse_parameters(p, list(fit_names))
    fit_logs = [read_log(f, p) for f in logs]
    hold_logs = [read_log(f, p) for f in holdout]
    result = fit(p, params, fit_logs, regularization=regularization, segment_s=segment_s)
    out = Path(out)
    path = write_fitted_mjcf(out / f"{name}.xml", p, params, result.fitted)
    nominal = np.array([q.nominal for q in params])
    fit_rms = {"fitted": _rms(p, params, result.fitted, fit_logs)[0], "nominal": _rms(p, params, nominal,
                                                                                          fit_logs)[0]}
    holdout_rms = None
    shown = hold_logs[0] if hold_logs else fit_logs[0]
    if hold_logs:
        fitted_h, sims_f = _rms(p, params, result.fitted, hold_logs)
        nominal_h, sims_n = _rms(p, params, nominal, hold_logs)
        holdout_rms = {"fitted": fitted_h, "nominal": nominal_h}
        sims = {"nominal": sims_n[0], "fitted": sims_f[0]}
    else:
        sims = {"nominal": simulate_log(p, params, nominal, shown), "fitted": simulate_log(p, params, result.fitted,
                                                                                          shown)}
    fig_path = None
    if figure:
        what = "Held-out" if hold_logs else "Fitted (no held-out run given)"
        fig_path = plot_identify(shown, sims, p, out / "figures" / "identify_holdout.png",
                                 title=f"{what} run {Path(shown.name).name}: measured vs nominal vs fitted model")
    return IdentifyResult(fit=result, mjcf=path, figure=fig_path, fit_rms=fit_rms, holdout_rms=holdout_rms,
                          nominal_mjcf=p.mjcf, joints=p.joint_names)
