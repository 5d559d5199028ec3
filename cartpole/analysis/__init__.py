"""The frequency domain of every linear design: loops broken at the plant input and their margins, through
python-control (:mod:`cartpole.analysis.loops`, :mod:`cartpole.analysis.margins`)."""
from cartpole.analysis.loops import (AnalysisError, Loop, channel_loop, continuous_loop, ctrl_noise_std,
                                     frozen_tvlqr_loop, pid_loop, sampled_loop, state_noise_std)
from cartpole.analysis.margins import (Margins, closed_loop_stable, frequency_grid, gain_band, loop_margins,
                                       response)

__all__ = ["AnalysisError", "Loop", "channel_loop", "continuous_loop", "ctrl_noise_std", "frozen_tvlqr_loop",
           "pid_loop", "sampled_loop", "Margins", "closed_loop_stable", "frequency_grid", "gain_band",
           "loop_margins", "response", "state_noise_std"]
