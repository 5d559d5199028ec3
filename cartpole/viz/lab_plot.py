"""The lab's figure: each pole's angle from upright (deg), the cart position (m) and each actuator's ctrl over time,
for each initial condition.

Drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend switch), laid out as the
handout's: stacked axes sharing time (one per pole angle, then the cart, then one per actuator), one line per
start labelled ``θ₀=5°, x₀=0, ts=0.06s`` (first pole's start angle, start cart position, the handout's settling
time), a legend, units, and the mean ± population std of the handout's settling time in the title. Angles are
drawn as wrapped errors from the equilibrium ``x*``, so a pole one turn away reads as upright. Written whole or not
at all (:func:`~cartpole._files.atomic_write`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write
from cartpole.models import wrap_angle


def _label(result, x0, ts: float) -> str:
    p = result.params
    ts_txt = f"{ts:.2f}s" if np.isfinite(ts) else "never"
    parts = []
    if p.hinges:
        parts.append(f"θ₀={np.rad2deg(x0[p.hinges[0]] - result.x_eq[p.hinges[0]]):.3g}°")
    if p.slide is not None:
        parts.append(f"x₀={x0[p.slide]:.3g}")
    return ", ".join(parts + [f"ts={ts_txt}"])


def plot_lab(result, path, *, dpi: int = 120) -> Path:
    """Save the lab figure (:func:`lab_figure`) for a :class:`~cartpole.lab.LabResult` as a PNG.

    Parameters
    ----------
    result : LabResult
    path : str or Path
        Output PNG (parent directories are created).
    dpi : int
        Resolution; the figure is 10 inches wide and 2 inches high per panel (at least 6, as the handout's).

    Returns
    -------
    Path
        The PNG written.
    """
    fig = lab_figure(result)
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=dpi, format="png"))


def lab_figure(result):
    """The lab figure as a matplotlib ``Figure`` on an Agg canvas (no pyplot).

    Panels, sharing time (s): one per pole angle (wrapped error from ``x*``, deg), the cart position (m) when the
    model has a slide, one per actuator's ctrl (with its ctrl range dotted); one line per start.

    Parameters
    ----------
    result : LabResult
        Its ``rollouts``, ``x0s``, ``x_eq``, ``params``, ``settling_times_seed`` and mean/std are drawn.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    p = result.params
    hinges, slide = p.hinges, p.slide
    n_panels = len(hinges) + (slide is not None) + p.nu
    fig = Figure(figsize=(10, max(6.0, 2.0 * n_panels)))
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(n_panels, 1, sharex=True))
    ax_th = axes[:len(hinges)]
    ax_s = axes[len(hinges)] if slide is not None else None
    ax_u = axes[n_panels - p.nu:]
    for run, x0, ts in zip(result.rollouts, result.x0s, result.settling_times_seed):
        label = _label(result, x0, ts)
        for ax, h in zip(ax_th, hinges):
            ax.plot(run.t, np.rad2deg(wrap_angle(run.qpos[:, h] - result.x_eq[h])), label=label)
        if ax_s is not None:
            ax_s.plot(run.t, run.qpos[:, slide], label=label)
        for ax, k in zip(ax_u, range(p.nu)):
            ax.step(run.t[:-1], run.ctrl[:, k], where="post", lw=0.8, label=label)
    many = len(hinges) > 1
    for i, (ax, h) in enumerate(zip(ax_th, hinges)):
        ax.axhline(0.0, color="k", linewidth=0.5)
        if not many:
            ax.set_ylabel("Pole angle\nfrom upright (deg)")
        elif i == 0:
            ax.set_ylabel(f"Pole 1 ({p.joints[h].name}) angle\nfrom upright (deg)")
        else:  # MuJoCo measures each hinge relative to its parent link
            ax.set_ylabel(f"Pole {i + 1} ({p.joints[h].name}) angle\nto its parent, from x* (deg)")
    if ax_s is not None:
        ax_s.axhline(result.x_eq[slide], color="k", linewidth=0.5)
        # the rail's ends only when a run came within half the way to one (else they squash the traces)
        reach = max(np.abs(r.qpos[:, slide] - result.x_eq[slide]).max() for r in result.rollouts)
        for v in p.cart_range:
            if np.isfinite(v) and abs(v - result.x_eq[slide]) < 2 * reach:
                ax_s.axhline(v, color="r", ls=":", lw=0.8)
        ax_s.set_ylabel("Cart position (m)")
    for ax, act, (ulo, uhi) in zip(ax_u, p.actuators, p.ctrl_range):
        for v in (ulo, uhi):
            if np.isfinite(v):
                ax.axhline(v, color="r", ls=":", lw=0.8)
        unit = "N" if p.joints[act.joint].kind == "slide" else "N m"
        ax.set_ylabel(f"ctrl {act.name}\n(force = {act.gear:g} {unit} x ctrl)")
    axes[-1].set_xlabel("Time (s)")
    axes[0].legend(fontsize=8, loc="upper right")
    for ax in axes:
        ax.grid(alpha=0.3)
    kind = "discrete" if result.discrete else "continuous"
    scale = "" if getattr(result, "start_scale", 1.0) == 1.0 else f", starts x{result.start_scale:g}"
    fig.suptitle(f"LQR balance ({kind}, {len(hinges)} pole{'s' if many else ''}): mean settling time "
                 f"{result.mean_settling_time_seed:.2f}s ± {result.std_settling_time_seed:.2f}s "
                 f"({len(result.rollouts)} initial conditions{scale}, every |θ| ≤ 0.05 rad)")
    fig.tight_layout()
    return fig
