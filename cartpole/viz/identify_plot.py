"""The held-out check's figure: measured vs nominal vs fitted model, one panel per joint."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_path


def identify_figure(log, simulations: dict, params, *, title: str | None = None):
    """Measured positions of ``log`` and each model's open-loop simulation, one panel per joint.

    Parameters
    ----------
    log : RunLog
    simulations : dict
        label -> :class:`cartpole.identify.fit.Simulation` (e.g. ``{"nominal": ..., "fitted": ...}``).
    params : CartPoleParams
        Joint names and kinds (units).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 2.6 * params.nq + 0.6))
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(params.nq, 1, sharex=True))
    styles = {"nominal": {"color": "tab:red", "ls": "--"}, "fitted": {"color": "tab:green"}}
    for j, ax in enumerate(axes):
        unit = "m" if params.joints[j].kind == "slide" else "rad"
        ax.plot(log.t, log.qpos[:, j], ".", ms=2, color="k", label="measured")
        for label, sim in simulations.items():
            ax.plot(sim.t, sim.x[:, j], lw=1.2, label=f"{label} (rms {sim.rms[j]:.3g} {unit})",
                    **styles.get(label, {}))
        ax.set_ylabel(f"{params.joint_names[j]} [{unit}]")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(title or f"Held-out run {Path(log.name).name}: measured vs simulated (open loop)")
    fig.tight_layout()
    return fig


def plot_identify(log, simulations: dict, params, path, *, title: str | None = None, dpi: int = 120) -> Path:
    """Write :func:`identify_figure` to ``path`` (PNG) whole or not at all; returns the path."""
    fig = identify_figure(log, simulations, params, title=title)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    return Path(path)
