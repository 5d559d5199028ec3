"""Success map of a robustness sweep: each run a marker at its start, over the first pole's start angle (from
hanging) and start rate; successes coloured by their time to upright, failures as red crosses.

Read at a glance: the green-to-yellow cloud is the region the swing-up handles, the crosses where it does not; the
title gives the count. The start box of the sweep is drawn dotted.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write


def plot_success_map(result, params, path, *, title: str | None = None) -> Path:
    """Draw :func:`success_map_figure` and save it as PNG (whole or not at all:
    :func:`~cartpole._files.atomic_write`; parent directories are created). Returns the path written."""
    fig = success_map_figure(result, params, title=title)
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=100, format="png"))


def success_map_figure(result, params, *, title: str | None = None):
    """The success map as a matplotlib ``Figure`` on an Agg canvas (no pyplot).

    Parameters
    ----------
    result : SweepResult
        ``starts`` (n, 2 nq) [m, rad, m/s, rad/s], ``success``, ``time_to_upright`` (s), ``half_widths``,
        ``method``, ``n``.
    params : CartPoleParams
        Joint names and kinds; the axes are the first hinge's angle (minus pi: 0 is hanging) and rate, or the
        first two state components for a model without a hinge.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    starts = np.asarray(result.starts, float)
    nq = params.nq
    if params.hinges:
        h = params.hinges[0]
        name = params.joints[h].name
        ix, iy, off = h, nq + h, np.pi
        xlabel = f"start angle of '{name}' from hanging, theta0 - pi [rad]"
        ylabel = f"start rate of '{name}' [rad/s]"
    else:  # pragma: no cover - the reader demands a hinge
        ix, iy, off = 0, nq, 0.0
        xlabel, ylabel = "start position [m]", "start velocity [m/s]"
    x, y = starts[:, ix] - off, starts[:, iy]
    ok = np.asarray(result.success, bool)
    fig = Figure(figsize=(7.5, 5.8))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    hw = np.asarray(result.half_widths, float)
    ax.add_patch(_box(ax, hw[ix], hw[iy]))
    if ok.any():
        sc = ax.scatter(x[ok], y[ok], c=np.asarray(result.time_to_upright)[ok], cmap="viridis", s=36,
                        edgecolors="k", linewidths=0.4, label=f"success ({int(ok.sum())})", zorder=3)
        fig.colorbar(sc, ax=ax, label="time to upright [s]")
    if (~ok).any():
        ax.scatter(x[~ok], y[~ok], marker="x", c="C3", s=50, linewidths=1.6, label=f"failure ({int((~ok).sum())})",
                   zorder=4)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.axhline(0, color="0.8", lw=0.8, zorder=0)
    ax.axvline(0, color="0.8", lw=0.8, zorder=0)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, fontsize=9, frameon=False)
    n = len(ok)
    ax.set_title(title or f"{result.method} swing-up: {int(ok.sum())} of {n} starts succeed "
                          f"({Path(str(params.mjcf)).name}, other start components random)")
    ax.title.set_fontsize(10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _box(ax, hx, hy):
    from matplotlib.patches import Rectangle

    return Rectangle((-hx, -hy), 2 * hx, 2 * hy, fill=False, ls=":", ec="0.4", lw=1.0, label="start box")
