"""The lab's figure: each pole's angle from upright (deg), the cart position (m) and each actuator's ctrl over time,
for each initial condition.

Drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend switch), laid out as the
lab's: stacked axes sharing time (one per pole angle, then the cart, then one per actuator), one line per
start labelled ``θ₀=5°, x₀=0, ts=0.06s`` (first pole's start angle, start cart position, the lab's settling
time), a legend, units, and the mean ± population std of the lab's settling time in the title. Angles are
drawn as wrapped errors from the equilibrium ``x*``, so a pole one turn away reads as upright. Written whole or not
at all (:func:`~cartpole._files.atomic_write`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write
from cartpole.viz.panels import ctrl_label, mark_range, pole_panels
from cartpole.viz.traces import wrapped_angle_trace


def _label(result, x0, ts: float) -> str:
    ts_txt = f"{ts:.2f}s" if np.isfinite(ts) else "never"
    return ", ".join([_start_label(result, x0, cart_unit=""), f"ts={ts_txt}"])


def _start_label(result, x0, *, cart_unit: str = " m") -> str:
    """``θ₀=5°, x₀=0 m``: a start's first-pole angle from ``x*`` and its cart position."""
    p = result.params
    parts = []
    if p.hinges:
        parts.append(f"θ₀={np.rad2deg(x0[p.hinges[0]] - result.x_eq[p.hinges[0]]):.3g}°")
    if p.slide is not None:
        parts.append(f"x₀={x0[p.slide]:.3g}{cart_unit}")
    return ", ".join(parts)


def plot_lab(result, path, *, dpi: int = 120) -> Path:
    """Save the lab figure (:func:`lab_figure`) for a :class:`~cartpole.apps.lab.LabResult` as a PNG.

    Parameters
    ----------
    result : LabResult
    path : str or Path
        Output PNG (parent directories are created).
    dpi : int
        Resolution; the figure is 10 inches wide and 2 inches high per panel (at least 6, as the lab's).

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
    p = result.params
    hinges, slide = p.hinges, p.slide
    fig, axes, ax_th, ax_s, ax_u, _ = pole_panels(p)
    counted = getattr(result, "counted", (True,) * len(result.x0s))
    for run, x0, ts, c in zip(result.rollouts, result.x0s, result.settling_times_seed, counted):
        label = _label(result, x0, ts) if c else _start_label(result, x0, cart_unit="") + ", in band"
        for ax, h in zip(ax_th, hinges):
            ax.plot(*wrapped_angle_trace(run.t, run.qpos[:, h], result.x_eq[h]), label=label)
        if ax_s is not None:
            ax_s.plot(run.t, run.qpos[:, slide], label=label)
        for ax, k in zip(ax_u, range(p.nu)):
            ax.step(run.t[:-1], run.ctrl[:, k], where="post", lw=0.8, label=label)
    _dress(p, result.x_eq, result.rollouts, axes, ax_th, ax_s, ax_u)
    axes[0].legend(fontsize=8, loc="upper right")
    many = len(hinges) > 1
    kind = "discrete" if result.discrete else "continuous"
    scale = "" if getattr(result, "start_scale", 1.0) == 1.0 else f", starts x{result.start_scale:g}"
    n = sum(counted)
    mean = (f"mean settling time {result.mean_settling_time_seed:.2f}s ± {result.std_settling_time_seed:.2f}s "
            f"({n} initial conditions{scale}, every |θ| ≤ 0.05 rad)" if n else
            f"no settling time, every start{scale.replace(', starts ', ' (')}{')' if scale else ''} inside the "
            "0.05 rad band")
    fig.suptitle(f"LQR balance ({kind}, {len(hinges)} pole{'s' if many else ''}): {mean}")
    fig.tight_layout()
    return fig


def _dress(p, x_eq, rollouts, axes, ax_th, ax_s, ax_u) -> None:
    """Axis labels with units, the upright and x* lines, the rail's ends when a run came near them, the ctrl range
    dotted, the grid."""
    hinges, slide = p.hinges, p.slide
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
        ax_s.axhline(x_eq[slide], color="k", linewidth=0.5)
        # the rail's ends only when a run came within half the way to one (else they squash the traces)
        reach = max(np.abs(r.qpos[:, slide] - x_eq[slide]).max() for r in rollouts)
        mark_range(ax_s, *p.cart_range, keep=lambda v: abs(v - x_eq[slide]) < 2 * reach)
        ax_s.set_ylabel("Cart position (m)")
    for k, (ax, (ulo, uhi)) in enumerate(zip(ax_u, p.ctrl_range)):
        mark_range(ax, ulo, uhi)
        ax.set_ylabel(ctrl_label(p, k))
    axes[-1].set_xlabel("Time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)


def plot_pid_vs_lqr(lqr, pid, path, *, dpi: int = 120) -> Path:
    """Save :func:`pid_vs_lqr_figure` as a PNG at ``path`` (parent directories created, written whole or not at all).

    Returns
    -------
    Path
        The PNG written.
    """
    fig = pid_vs_lqr_figure(lqr, pid)
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=dpi, format="png"))


def pid_vs_lqr_figure(lqr, pid):
    """The PID baseline beside the LQR from the same starts, as a matplotlib ``Figure`` on an Agg canvas.

    Panels sharing time (s): one per pole angle (wrapped error from ``x*``, deg), the cart position (m), one per
    actuator's ctrl (with its ctrl range dotted). One colour per start; the LQR run solid, the PID run dashed.

    Parameters
    ----------
    lqr : LabResult
        The LQR lab (:func:`cartpole.apps.lab.run_lab`): its ``rollouts``, ``x0s``, ``x_eq``, ``params`` and settling times.
    pid : PIDLabResult
        The PID from the same starts (:func:`cartpole.apps.lab.compare_pid`).
    """
    from matplotlib.lines import Line2D

    p = lqr.params
    hinges, slide = p.hinges, p.slide
    fig, axes, ax_th, ax_s, ax_u, _ = pole_panels(p)
    colours = [f"C{i % 10}" for i in range(len(lqr.rollouts))]
    for res, ls in ((lqr, "-"), (pid, "--")):
        for run, colour in zip(res.rollouts, colours):
            for ax, h in zip(ax_th, hinges):
                ax.plot(*wrapped_angle_trace(run.t, run.qpos[:, h], res.x_eq[h]), ls=ls, color=colour, lw=1.0)
            if ax_s is not None:
                ax_s.plot(run.t, run.qpos[:, slide], ls=ls, color=colour, lw=1.0)
            for ax, k in zip(ax_u, range(p.nu)):
                ax.step(run.t[:-1], run.ctrl[:, k], where="post", ls=ls, color=colour, lw=0.8)
    _dress(p, lqr.x_eq, lqr.rollouts + pid.rollouts, axes, ax_th, ax_s, ax_u)
    starts = [Line2D([], [], color=c, lw=2, label=_start_label(lqr, x0)) for c, x0 in zip(colours, lqr.x0s)]
    styles = [Line2D([], [], color="k", ls="-", label="LQR (solid)"),
              Line2D([], [], color="k", ls="--", label="PID (dashed)")]
    axes[0].legend(handles=starts + styles, fontsize=8, loc="upper right", ncol=2)
    fig.suptitle(f"PID (dashed) beside LQR (solid) from the same {len(lqr.rollouts)} starts in MuJoCo\n"
                 f"mean settling time (every |θ| ≤ 0.05 rad): LQR {lqr.mean_settling_time_seed:.2f} s, "
                 f"PID {pid.mean_settling_time_seed:.2f} s")
    fig.tight_layout()
    return fig
