"""Success maps of robustness sweeps, read at a glance.

* A sweep over two or more axes (:class:`cartpole.apps.sweep.Axis`): success over the first two swept axes (e.g. push
  force x model error). Two grid axes make a map of cells, green where the run succeeded (annotated with its time to
  upright), red where it failed (a cross), shaded by the success fraction when a cell holds several runs; a sampled
  axis makes a scatter, successes coloured by their time to upright, failures as red crosses.
* A sweep of starts without axes (the classic start box, or a basin-style sweep): each run a marker at its start,
  over the first pole's start angle (from hanging) and start rate; the start box dotted.
* :func:`comparison_figure`: several methods' sweeps of the same description side by side, same axes and colours
  (e.g. TVLQR against NMPC over push size x model error).

The title gives the count of successes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write


def preload() -> None:
    """Import what drawing a success map needs (matplotlib's figure, Agg canvas and patches) and draw one tiny
    figure in memory (fonts and the text renderer loaded), so that a sweep can do it ahead, in a thread while its
    runs go on other processes, instead of after the last run (about half a second of a fresh process)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch, Rectangle  # noqa: F401  (imported for the map's legend and cells)

    fig = Figure(figsize=(1, 1))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.set_title("success")
    ax.plot([0.0, 1.0], [0.0, 1.0])
    fig.canvas.draw()


def plot_success_map(result, params, path, *, title: str | None = None) -> Path:
    """Draw :func:`success_map_figure` and save it as PNG (whole or not at all:
    :func:`~cartpole._files.atomic_write`; parent directories are created). Returns the path written."""
    fig = success_map_figure(result, params, title=title)
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=100, format="png"))


def plot_comparison(results, params, path, *, title: str | None = None) -> Path:
    """Draw :func:`comparison_figure` and save it as PNG (whole or not at all). Returns the path written."""
    fig = comparison_figure(results, params, title=title)
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=100, format="png"))


def swept_axes(result) -> list:
    """The axes of ``result`` that vary (a grid of two or more points, or a sampled axis), in description order."""
    return [a for a in getattr(result, "axes", ()) if a.random or (a.count or 1) > 1]


_METHOD_NAMES = {"energy": "energy shaping + LQR catch", "trajopt": "trajopt + TVLQR", "mpc": "NMPC"}


def comparison_figure(results, params, *, title: str | None = None):
    """Several sweeps of one description (one per method) side by side as a matplotlib ``Figure`` (Agg canvas).

    Parameters
    ----------
    results : sequence of SweepResult
        The same axes (checked), e.g. ``trajopt`` and ``mpc`` over push force x model error.
    params : CartPoleParams
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        Fewer than two results, or results over different axes.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    results = list(results)
    if len(results) < 2:
        raise ValueError("A comparison needs two or more sweeps.")
    if len({tuple(a.describe()["name"] for a in r.axes) for r in results}) != 1:
        raise ValueError("The sweeps compared must sweep the same axes.")
    k = len(results)
    fig = Figure(figsize=(5.6 * k + 1.2, 5.8), layout="constrained")
    FigureCanvasAgg(fig)
    axs = [fig.add_subplot(1, k, i + 1) for i in range(k)]
    mappable = None
    for ax, r in zip(axs, results):
        ok = int(np.sum(r.success))
        mappable = _draw(ax, r, params) or mappable
        ax.set_title(f"{_METHOD_NAMES.get(r.method, r.method)}: {ok} of {r.n} succeed", fontsize=10)
    for ax in axs[1:]:
        ax.set_ylabel("")
    if mappable is not None:
        fig.colorbar(mappable, ax=axs, label=_cbar_label(results[0]), shrink=0.9)
    fig.suptitle(title or f"Which scenarios each controller survives ({Path(str(params.mjcf)).name}; MuJoCo runs "
                          "that replay exactly)", fontsize=11)
    return fig


def success_map_figure(result, params, *, title: str | None = None):
    """The success map as a matplotlib ``Figure`` on an Agg canvas (no pyplot).

    Parameters
    ----------
    result : SweepResult
        ``starts`` (n, 2 nq) [m, rad, m/s, rad/s], ``success``, ``time_to_upright`` (s), ``half_widths``,
        ``method``, ``n``, ``axes`` (the description: over two swept axes the map is over the first two).
    params : CartPoleParams
        Joint names and kinds; without swept axes the map is over the first hinge's angle (minus pi: 0 is
        hanging) and rate.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ok = np.asarray(result.success, bool)
    fig = Figure(figsize=(7.5, 5.8))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    mappable = _draw(ax, result, params)
    if mappable is not None:
        fig.colorbar(mappable, ax=ax, label=_cbar_label(result))
    n = len(ok)
    swept = swept_axes(result)
    what = (f"{int(ok.sum())} of {n} runs succeed ({Path(str(params.mjcf)).name})" if swept else
            f"{int(ok.sum())} of {n} starts succeed ({Path(str(params.mjcf)).name}, other start components random)")
    ax.set_title(title or f"{result.method} swing-up: {what}")
    ax.title.set_fontsize(10)
    fig.tight_layout()
    return fig


def _cbar_label(result) -> str:
    return "success fraction of the cell's runs" if _is_cell_map(result) else "time to upright [s]"


def _is_cell_map(result) -> bool:
    swept = swept_axes(result)
    return len(swept) >= 2 and not swept[0].random and not swept[1].random


def _runs_per_cell(result) -> int:
    swept = swept_axes(result)
    return max(1, len(result.success) // (swept[0].count * swept[1].count))


def _draw(ax, result, params):
    """Draw ``result`` on ``ax`` (see the module notes); returns the colour mappable, or None."""
    swept = swept_axes(result)
    ok = np.asarray(result.success, bool)
    t_up = np.asarray(result.time_to_upright, float)
    if len(swept) >= 2:
        ax_x, ax_y = swept[0], swept[1]
        x, y = result.axis_values(ax_x, params), result.axis_values(ax_y, params)
        ax.set_xlabel(ax_x.label)
        ax.set_ylabel(ax_y.label)
        if _is_cell_map(result):  # a colour bar only when cells hold several runs (a fraction, not a yes/no)
            mesh = _cells(ax, ax_x.values(), ax_y.values(), x, y, ok, t_up)
            return mesh if _runs_per_cell(result) > 1 else None
        return _scatter(ax, x, y, ok, t_up)
    if len(swept) == 1:
        a = swept[0]
        x = result.axis_values(a, params)
        ax.set_xlabel(a.label)
        ax.set_ylabel("time to upright [s] (failures at 0)")
        return _scatter(ax, x, np.where(ok, t_up, 0.0), ok, t_up)
    starts = np.asarray(result.starts, float)
    nq = params.nq
    h = params.hinges[0]
    name = params.joints[h].name
    ix, iy, off = h, nq + h, np.pi
    ax.set_xlabel(f"start angle of '{name}' from hanging, theta0 - pi [rad]")
    ax.set_ylabel(f"start rate of '{name}' [rad/s]")
    hw = np.asarray(result.half_widths, float)
    if not getattr(result, "axes", ()):
        ax.add_patch(_box(ax, hw[ix], hw[iy]))
    ax.axhline(0, color="0.8", lw=0.8, zorder=0)
    ax.axvline(0, color="0.8", lw=0.8, zorder=0)
    return _scatter(ax, starts[:, ix] - off, starts[:, iy], ok, t_up)


def _scatter(ax, x, y, ok, t_up):
    sc = None
    if ok.any():
        sc = ax.scatter(x[ok], y[ok], c=t_up[ok], cmap="viridis", s=36, edgecolors="k", linewidths=0.4,
                        label=f"success ({int(ok.sum())})", zorder=3)
    if (~ok).any():
        ax.scatter(x[~ok], y[~ok], marker="x", c="C3", s=50, linewidths=1.6, label=f"failure ({int((~ok).sum())})",
                   zorder=4)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, fontsize=9, frameon=False)
    ax.grid(alpha=0.3)
    return sc


def _edges(v):
    v = np.asarray(v, float)
    if v.size == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = (v[1:] + v[:-1]) / 2
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


def _cells(ax, gx, gy, x, y, ok, t_up):
    """A map of grid cells: success fraction of each (x, y) cell's runs (red 0 to green 1), annotated with the
    time to upright of a single successful run, a cross for a single failure, or k/m for several runs."""
    from matplotlib.patches import Patch

    frac = np.full((gy.size, gx.size), np.nan)
    text = {}
    for j, yv in enumerate(gy):
        for i, xv in enumerate(gx):
            sel = np.isclose(x, xv, rtol=0, atol=1e-12 * max(1.0, abs(xv))) & \
                np.isclose(y, yv, rtol=0, atol=1e-12 * max(1.0, abs(yv)))
            m = int(sel.sum())
            if not m:
                continue
            k = int(ok[sel].sum())
            frac[j, i] = k / m
            if m == 1:
                text[(i, j)] = f"{t_up[sel][0]:.1f} s" if k else "\u2717"
            else:
                text[(i, j)] = f"{k}/{m}"
    mesh = ax.pcolormesh(_edges(gx), _edges(gy), frac, cmap="RdYlGn", vmin=0.0, vmax=1.0, edgecolors="w",
                         linewidth=1.5)
    small = gx.size * gy.size > 80
    for (i, j), t in text.items():
        ax.text(gx[i], gy[j], t, ha="center", va="center", fontsize=6 if small else 8, color="k")
    ax.set_xticks(gx if gx.size <= 12 else gx[::max(1, gx.size // 8)])
    ax.set_yticks(gy if gy.size <= 12 else gy[::max(1, gy.size // 8)])
    ax.legend(handles=[Patch(color=mesh.cmap(1.0), label=f"success ({int(ok.sum())})"),
                       Patch(color=mesh.cmap(0.0), label=f"failure ({int((~ok).sum())})")],
              loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=2, fontsize=9, frameon=False)
    return mesh


def _box(ax, hx, hy):
    from matplotlib.patches import Rectangle

    return Rectangle((-hx, -hy), 2 * hx, 2 * hy, fill=False, ls=":", ec="0.4", lw=1.0, label="start box")
