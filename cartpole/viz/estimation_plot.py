"""The estimate against the truth: one panel per joint position and rate, MuJoCo's true state as a line, the
estimator's ``x_hat`` at the control instants as a line with markers, the measured positions as dots."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write


def estimation_figure(rollout, params, *, title: str | None = None):
    """A matplotlib Figure (Agg canvas) of a rig run's estimate against the truth.

    Parameters
    ----------
    rollout : Rollout
        A run on a rig (``t_sample``, ``x_hat``, ``y`` logged): ``x`` (n+1, 2 nq) m, rad, m/s, rad/s.
    params : CartPoleParams
        Names and units of the joints.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
        2 nq panels sharing time (s); a joint position measured directly (the ``y`` entry closest to it, within half
        its range) also shows the measurements as dots.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    nq = params.nq
    fig = Figure(figsize=(10, 1.8 * 2 * nq + 1))
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(2 * nq, 1, sharex=True))
    x, t = rollout.x, rollout.t
    ts, xh = rollout.t_sample, rollout.x_hat
    y = rollout.y
    xs = rollout.x_sample
    for i, ax in enumerate(axes):
        j = params.joints[i % nq]
        unit = ("m" if j.kind == "slide" else "rad") + ("/s" if i >= nq else "")
        ax.plot(t, x[:, i], color="0.3", lw=1.2, label="MuJoCo (true)")
        ax.plot(ts, xh[:, i], color="C1", lw=0.9, marker=".", ms=2, label="estimate x_hat")
        if i < nq and y is not None and y.size:
            err = np.abs(y - xs[:, [i]]).max(axis=0)  # a y column that reads this position directly
            k = int(np.argmin(err))
            # a quantised reading is off by up to half its count, which may be a good part of a small motion
            if err[k] < 0.5 * np.ptp(xs[:, i]) + 0.02:
                ax.plot(ts, y[:, k], ".", color="C0", ms=2.5, label="measured")
        ax.set_ylabel(f"{j.name}{' rate' if i >= nq else ''} ({unit})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_estimation(rollout, params, path, *, title: str | None = None, dpi: int = 120) -> Path:
    """Write :func:`estimation_figure` as a PNG at ``path`` (whole or not at all); returns the path."""
    fig = estimation_figure(rollout, params, title=title)
    return atomic_write(Path(path), lambda fh: fig.savefig(fh, dpi=dpi, format="png"))
