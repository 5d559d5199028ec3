"""The lab's figure: pole angle (deg) and cart position (m) over time for each initial condition.

Drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend switch), laid out as the
handout's: two stacked axes sharing time, one line per start labelled ``θ₀=5°, x₀=0, ts=0.06s`` (start angle,
start cart position, the handout's settling time), a legend, units, and the mean ± population std of the
handout's settling time in the title. Written whole or not at all (:func:`~cartpole._files.atomic_write`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write


def _label(x0, ts: float) -> str:
    ts_txt = f"{ts:.2f}s" if np.isfinite(ts) else "never"
    return f"θ₀={np.rad2deg(x0[1]):.3g}°, x₀={x0[0]:.3g}, ts={ts_txt}"


def plot_lab(result, path, *, dpi: int = 120) -> Path:
    """Save the lab figure for a :class:`~cartpole.lab.LabResult` as a PNG.

    Parameters
    ----------
    result : LabResult
        Its ``rollouts``, ``x0s``, ``settling_times_seed`` and mean/std are drawn.
    path : str or Path
        Output PNG (parent directories are created).
    dpi : int
        Resolution; the figure is 10 x 6 inches as in the handout.

    Returns
    -------
    Path
        The PNG written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 6))
    FigureCanvasAgg(fig)
    ax_th, ax_s = fig.subplots(2, 1, sharex=True)
    for run, x0, ts in zip(result.rollouts, result.x0s, result.settling_times_seed):
        label = _label(x0, ts)
        ax_th.plot(run.t, np.rad2deg(run.qpos[:, 1]), label=label)
        ax_s.plot(run.t, run.qpos[:, 0], label=label)
    ax_th.axhline(np.rad2deg(result.x_eq[1]), color="k", linewidth=0.5)
    ax_s.axhline(result.x_eq[0], color="k", linewidth=0.5)
    ax_th.set_ylabel("Pole angle (deg)")
    ax_s.set_ylabel("Cart position (m)")
    ax_s.set_xlabel("Time (s)")
    ax_th.legend(fontsize=8, loc="upper right")
    for ax in (ax_th, ax_s):
        ax.grid(alpha=0.3)
    kind = "discrete" if result.discrete else "continuous"
    fig.suptitle(f"Cart-pole LQR ({kind}): mean settling time {result.mean_settling_time_seed:.2f}s "
                 f"± {result.std_settling_time_seed:.2f}s ({len(result.rollouts)} initial conditions, "
                 "|θ| ≤ 0.05 rad)")
    fig.tight_layout()
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=dpi, format="png"))
