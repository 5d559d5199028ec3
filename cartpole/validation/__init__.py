"""Metrics, Jacobian checks and catch basins: the proof of every control claim (the runs come from
:mod:`cartpole.sim`; figures and video are in :mod:`cartpole.viz`)."""
from cartpole.validation.basin import BasinCache, BasinEstimate, estimate_basin
from cartpole.validation.metrics import (RunMetrics, peak_ctrl, saturation_fraction, settling_time_seed,
                                         settling_time_strict, summarize, track_margin)
from cartpole.validation.swingup_metrics import swingup_metrics, swingup_success, time_to_upright

__all__ = ["RunMetrics", "peak_ctrl", "saturation_fraction", "settling_time_seed", "settling_time_strict",
           "summarize", "track_margin", "BasinCache", "BasinEstimate", "estimate_basin", "swingup_metrics",
           "swingup_success", "time_to_upright"]
