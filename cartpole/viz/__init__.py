"""Figures and video of MuJoCo runs. Only the applications, the commands and the notebooks import this package.

The video is three modules: :mod:`~cartpole.viz.scene` (the frame clock, the render-only copy of the model, the
camera), :mod:`~cartpole.viz.overlay` (the overlay drawn on each frame, the modes it shows, the GIF preview) and
:mod:`~cartpole.viz.video` (the renderer and its process: :func:`render_video`, :func:`render_frame`, and how they
draw as one value, :class:`~cartpole.viz.video.VideoOptions`).
"""
from cartpole.viz.lab_plot import lab_figure, plot_lab
from cartpole.viz.overlay import modes_from_switches, swingup_modes
from cartpole.viz.scene import VideoUnavailable, frame_indices
from cartpole.viz.swingup_plot import plot_swingup, swingup_figure
from cartpole.viz.video import VideoInfo, VideoOptions, render_frame, render_video

__all__ = ["lab_figure", "plot_lab", "plot_swingup", "swingup_figure", "VideoUnavailable", "frame_indices",
           "render_video", "render_frame", "VideoInfo", "VideoOptions", "modes_from_switches", "swingup_modes"]
