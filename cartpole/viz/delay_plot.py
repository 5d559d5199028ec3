"""The delay margin as a figure: per controller, the worst start's settling time and the residual pole error against
the delay, the first delay that fails marked, the margin a dashed line."""
from __future__ import annotations

from pathlib import Path

from cartpole._files import atomic_write

#: Legend label and colour of each controller the delay margin reports.
CONTROLLERS = {"lqr": ("LQR", "tab:blue"), "pid": ("cascaded PID", "tab:orange")}


def delay_margin_figure(found: dict, *, title: str | None = None):
    """A matplotlib Figure (Agg canvas) of :func:`cartpole.apps.lab.delay_margin`'s result.

    Parameters
    ----------
    found : dict
        ``lqr_runs`` (and ``pid_runs``): per delay tried, ``delay`` (s), ``balances``, ``settling_time_seed_max``
        (s or None) and ``residual_angle_max`` (rad); ``lqr`` / ``pid`` the margins (s or None).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
        Two panels sharing the delay axis (ms): the worst start's handout settling time (s) and the largest pole
        error over the runs' last second (mrad); a failed delay is a cross, the margin a dashed vertical line.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 6))
    FigureCanvasAgg(fig)
    ax_t, ax_e = fig.subplots(2, 1, sharex=True)
    for name, (label, colour) in CONTROLLERS.items():
        runs = found.get(f"{name}_runs")
        if not runs:
            continue
        ok = [r for r in runs if r["balances"]]
        bad = [r for r in runs if not r["balances"]]
        ax_t.plot([1e3 * r["delay"] for r in ok], [r["settling_time_seed_max"] for r in ok], "o-", color=colour,
                  label=f"{label}: balances")
        ax_e.plot([1e3 * r["delay"] for r in ok], [1e3 * r["residual_angle_max"] for r in ok], "o-", color=colour,
                  label=label)
        for r in bad:  # at the top of the panel: a run that fails has no settling time to plot
            ax_t.plot([1e3 * r["delay"]], [0.95], "x", color=colour, markersize=10, markeredgewidth=2,
                      transform=ax_t.get_xaxis_transform(), label=f"{label}: fails at {1e3 * r['delay']:g} ms")
        if found.get(name) is not None:
            for ax in (ax_t, ax_e):
                ax.axvline(1e3 * found[name], color=colour, linestyle="--", linewidth=1)
    ax_t.set_ylabel("worst start's settling time (s)\n(handout: |theta| <= 0.05 rad)")
    ax_e.set_ylabel("largest pole error\nover the last 1 s (mrad)")
    ax_e.set_xlabel("delay from sampling to the ctrl taking effect (ms)")
    for ax in (ax_t, ax_e):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    fig.suptitle(title or "Delay margin: the largest delay at which every lab start still balances")
    fig.tight_layout()
    return fig


def plot_delay_margin(found: dict, path, *, title: str | None = None, dpi: int = 120) -> Path:
    """Write :func:`delay_margin_figure` as a PNG at ``path`` (whole or not at all); returns the path."""
    fig = delay_margin_figure(found, title=title)
    return atomic_write(Path(path), lambda fh: fig.savefig(fh, dpi=dpi, format="png"))
