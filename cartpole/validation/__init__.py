"""Metrics, Jacobian checks, basins, plots and video: the proof of every control claim (runs come from
:mod:`cartpole.sim`)."""
from cartpole.validation.lab_plot import plot_lab
from cartpole.validation.metrics import (RunMetrics, peak_ctrl, saturation_fraction, settling_time_seed,
                                         settling_time_strict, summarize, track_margin)
from cartpole.validation.video import VideoUnavailable, render_video

__all__ = ["RunMetrics", "peak_ctrl", "saturation_fraction", "settling_time_seed", "settling_time_strict",
           "summarize", "track_margin", "render_video", "VideoUnavailable", "plot_lab"]
from cartpole.validation.basin import BasinCache, BasinEstimate, estimate_basin  # noqa: E402
from cartpole.validation.swingup_metrics import swingup_metrics, swingup_success, time_to_upright  # noqa: E402
from cartpole.validation.swingup_plot import plot_swingup  # noqa: E402

__all__ += ["BasinCache", "BasinEstimate", "estimate_basin", "swingup_metrics", "swingup_success",
            "time_to_upright", "plot_swingup"]
