"""Figure of feedforward beside feedback: several MuJoCo runs against the plans they follow, on one set of axes.

One angle panel per pole (wrapped angle error from the upright equilibrium ``x*``, degrees; each plan dashed, each
run solid, lines broken where the wrapped angle jumps by a turn), the cart position (with its joint limits) when the
model has a slide, and one ctrl panel per actuator (each run's applied ctrl as steps, each plan's knot input dashed,
the ctrl range dotted). Vertical lines mark each plan's end (where TVLQR hands over to the LQR catch).
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from cartpole._files import atomic_write
from cartpole.models import build_model
from cartpole.viz.panels import ctrl_label, mark_range, pole_panels
from cartpole.viz.traces import wrapped_angle_trace

#: Line colours of the runs, in order; plans are drawn in shades of grey.
RUN_COLOURS = ("C3", "C0", "C2", "C1", "C4", "C5")
PLAN_COLOURS = ("k", "0.45", "0.7")


def plot_feedforward(runs: Mapping, plans: Mapping, params, path, *, model=None, title: str | None = None) -> Path:
    """Draw :func:`feedforward_figure` and save it as PNG (whole or not at all:
    :func:`~cartpole._files.atomic_write`; parent directories are created). Returns the path written."""
    fig = feedforward_figure(runs, plans, params, model=model, title=title)
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=100, format="png"))


def feedforward_figure(runs: Mapping, plans: Mapping, params, *, model=None, title: str | None = None):
    """Runs beside plans as a matplotlib ``Figure`` on an Agg canvas (no pyplot); panels as the module says.

    Parameters
    ----------
    runs : mapping of str -> Rollout
        Legend label -> what MuJoCo did (``t`` (n+1,), ``qpos`` (n+1, nq), ``ctrl`` (n, nu)), drawn solid.
    plans : mapping of str -> Trajectory
        Legend label -> planned trajectory (knots ``t`` (N+1,), ``state(t)``, ``u`` (N+1, nu)), drawn dashed; its
        end is marked on every panel.
    params : CartPoleParams
        Joints, cart and ctrl ranges, actuator names and gears.
    model : CartPoleModel, optional
        For the upright equilibrium ``x_eq`` (default built from ``params``).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    model = model or build_model(params)
    hinges, slide = params.hinges, params.slide
    x_eq = np.asarray(model.x_eq)
    fig, ax, ax_th, ax_s, ax_u, _ = pole_panels(params, size=lambda n: (10, 2.6 * n + 1.0))

    plan_lines = {}
    for j, (label, plan) in enumerate(plans.items()):
        c = PLAN_COLOURS[j % len(PLAN_COLOURS)]
        tp = np.linspace(plan.t[0], plan.t[-1], 600)
        xp = plan.state(tp)
        plan_lines[label] = (tp, xp, c)
        for a, h in zip(ax_th, hinges):
            a.plot(*wrapped_angle_trace(tp, xp[:, h], x_eq[h]), "--", color=c, lw=1.6, label=label)
        if ax_s is not None:
            ax_s.plot(tp, xp[:, slide], "--", color=c, lw=1.6, label=label)
        u = np.asarray(plan.u).reshape(len(plan.t), -1)
        for k, a in enumerate(ax_u):
            a.plot(plan.t, u[:, k], "--", color=c, lw=1.6, label=label)
        for a in ax:
            a.axvline(plan.t[-1], color=c, lw=0.8, ls=":")

    for i, (label, run) in enumerate(runs.items()):
        c = RUN_COLOURS[i % len(RUN_COLOURS)]
        for a, h in zip(ax_th, hinges):
            a.plot(*wrapped_angle_trace(run.t, run.qpos[:, h], x_eq[h]), color=c, lw=1.0, label=label)
        if ax_s is not None:
            ax_s.plot(run.t, run.qpos[:, slide], color=c, lw=1.0, label=label)
        for k, a in enumerate(ax_u):
            a.step(run.t[:-1], run.ctrl[:, k], where="post", color=c, lw=0.8, label=label)

    for i, (a, h) in enumerate(zip(ax_th, hinges)):
        a.axhline(0.0, color="k", lw=0.5)
        a.set_ylim(-190, 190)
        a.set_yticks([-180, -90, 0, 90, 180])
        name = params.joints[h].name
        rel = "" if i == 0 else ", to its parent"
        a.set_ylabel(f"pole {i + 1} ({name})\nangle from upright{rel}\n(deg, wrapped: gaps mark a turn)")
    if ax_s is not None:
        mark_range(ax_s, *params.cart_range, "joint limit", lw=1.0)
        ax_s.set_ylabel(f"cart ({params.joints[slide].name})\nposition (m)")
    for k, a in enumerate(ax_u):
        mark_range(a, *params.ctrl_range[k], "ctrl range", lw=1.0)
        a.set_ylabel(ctrl_label(params, k))
    ax[-1].set_xlabel("time (s); dotted vertical: end of each plan (hand-over to the LQR catch)")
    for a in ax:
        a.grid(True, alpha=0.3)
    # one legend per panel kind, outside the busy curves
    ax[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="plans (dashed), runs (solid)",
                 title_fontsize=8)
    for a in ax[1:]:
        handles, labels = a.get_legend_handles_labels()
        keep = [(h_, l_) for h_, l_ in zip(handles, labels) if l_ in ("joint limit", "ctrl range")]
        if keep:
            a.legend(*zip(*keep), loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.suptitle(title or "Feedforward beside feedback, in MuJoCo")
    fig.tight_layout()
    return fig
