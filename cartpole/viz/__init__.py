"""Figures and video of MuJoCo runs. Only the applications, the commands and the notebooks import this package."""
from cartpole.viz.lab_plot import plot_lab
from cartpole.viz.swingup_plot import plot_swingup
from cartpole.viz.video import VideoUnavailable, frame_indices, render_video

__all__ = ["plot_lab", "plot_swingup", "VideoUnavailable", "frame_indices", "render_video"]
