"""Metrics, Jacobian checks and catch basins: the proof of every control claim (the runs come from
:mod:`cartpole.sim`; figures and video are in :mod:`cartpole.viz`)."""
from cartpole.validation.basin import BasinCache, BasinEstimate, estimate_basin
from cartpole.validation.metrics import (UPRIGHT_TOL, RunMetrics, held_upright, peak_ctrl, saturation_fraction,
                                         settling_time_seed, settling_time_strict, summarize, swingup_metrics,
                                         swingup_success, track_margin, upright_segments,
                                         uptime_metrics)

__all__ = ["UPRIGHT_TOL", "RunMetrics", "held_upright", "peak_ctrl", "saturation_fraction", "settling_time_seed",
           "settling_time_strict", "summarize", "swingup_metrics", "swingup_success", "track_margin", "BasinCache",
           "BasinEstimate", "estimate_basin", "upright_segments", "uptime_metrics"]
