"""A rig margin as a figure (:func:`cartpole.apps.lab.rig_margin`: the delay margin, the noise tolerance): per
controller, the worst start's settling time and the residual pole error against the setting, the first value that
fails marked, the margin a dashed line."""
from __future__ import annotations

from pathlib import Path

from cartpole._files import atomic_write

#: Legend label and colour of each controller the delay margin reports.
CONTROLLERS = {"lqr": ("LQR", "tab:blue"), "pid": ("cascaded PID", "tab:orange")}
#: Per setting: the x-axis label, the factor from SI to its unit, the unit, the title.
SETTINGS = {
    "delay": ("delay from sampling to the ctrl taking effect (ms)", 1e3, "ms",
              "Delay margin: the largest delay at which every lab start still balances"),
    "sensor_noise": ("sensor noise standard deviation (mm on slides, mrad on hinges)", 1e3, "mm or mrad",
                     "Noise tolerance: the largest sensor noise at which every lab start still balances"),
}


def margin_figure(found: dict, *, title: str | None = None):
    """A matplotlib Figure (Agg canvas) of :func:`cartpole.apps.lab.rig_margin`'s result.

    Parameters
    ----------
    found : dict
        ``setting`` (a key of :data:`SETTINGS`), ``lqr_runs`` (and ``pid_runs``): per value tried, the value (SI),
        ``balances``, ``settling_time_seed_max`` (s or None) and ``residual_angle_max`` (rad); ``lqr`` / ``pid`` the
        margins (or None).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
        Two panels sharing the setting's axis: the worst start's settling time (s) and the largest pole
        error over the runs' last second (mrad); a failed value is a cross, the margin a dashed vertical line.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    setting = found.get("setting", "delay")
    xlabel, scale, unit, default_title = SETTINGS[setting]
    fig = Figure(figsize=(8, 6))
    FigureCanvasAgg(fig)
    ax_t, ax_e = fig.subplots(2, 1, sharex=True)
    for name, (label, colour) in CONTROLLERS.items():
        runs = found.get(f"{name}_runs")
        if not runs:
            continue
        ok = [r for r in runs if r["balances"]]
        bad = [r for r in runs if not r["balances"]]
        ax_t.plot([scale * r[setting] for r in ok], [r["settling_time_seed_max"] for r in ok], "o-", color=colour,
                  label=f"{label}: balances")
        ax_e.plot([scale * r[setting] for r in ok], [1e3 * r["residual_angle_max"] for r in ok], "o-", color=colour,
                  label=label)
        for r in bad:  # at the top of the panel: a run that fails has no settling time to plot
            ax_t.plot([scale * r[setting]], [0.95], "x", color=colour, markersize=10, markeredgewidth=2,
                      transform=ax_t.get_xaxis_transform(), label=f"{label}: fails at {scale * r[setting]:g} {unit}")
        if found.get(name) is not None:
            for ax in (ax_t, ax_e):
                ax.axvline(scale * found[name], color=colour, linestyle="--", linewidth=1)
    ax_t.set_ylabel("worst start's settling time (s)\n(|theta| <= 0.05 rad)")
    ax_e.set_ylabel("largest pole error\nover the last 1 s (mrad)")
    ax_e.set_xlabel(xlabel)
    values = sorted({scale * r[setting] for name in CONTROLLERS for r in found.get(f"{name}_runs") or ()} - {0.0})
    if setting == "sensor_noise" and len(values) > 1:  # halvings: even spacing on a log axis, 0 in its linear part
        ax_e.set_xscale("symlog", linthresh=values[0], linscale=0.5)
    for ax in (ax_t, ax_e):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    fig.suptitle(title or default_title)
    fig.tight_layout()
    return fig


def plot_margin(found: dict, path, *, title: str | None = None, dpi: int = 120) -> Path:
    """Write :func:`margin_figure` as a PNG at ``path`` (whole or not at all); returns the path."""
    fig = margin_figure(found, title=title)
    return atomic_write(Path(path), lambda fh: fig.savefig(fh, dpi=dpi, format="png"))
