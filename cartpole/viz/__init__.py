"""Figures and video of MuJoCo runs. Only the applications, the commands and the notebooks import this package."""
from cartpole.viz.lab_plot import lab_figure, plot_lab
from cartpole.viz.swingup_plot import plot_swingup, swingup_figure
from cartpole.viz.video import (VideoInfo, VideoUnavailable, frame_indices, modes_from_switches, render_frame,
                                render_video, swingup_modes)

__all__ = ["lab_figure", "plot_lab", "plot_swingup", "swingup_figure", "VideoUnavailable", "frame_indices",
           "render_video", "render_frame", "VideoInfo", "modes_from_switches", "swingup_modes"]
