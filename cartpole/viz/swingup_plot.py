"""Figure of a swing-up: each pole's angle, the cart position, each actuator's ctrl and the energy over time, with
the catch marked.

One angle panel per pole (wrapped error from the upright equilibrium ``x*``, rad), a cart panel when the model has a
slide, one ctrl panel per actuator, and an energy panel: the pole's own energy about its hinge where the model
defines it (one pole, :attr:`~cartpole.models.CartPoleModel.pole_energy`), else the whole system's energy
(:attr:`~cartpole.models.CartPoleModel.energy`); both are zero at upright rest. For a trajectory-optimised
swing-up the plan is drawn (dashed) beside what MuJoCo did.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write
from cartpole.models import build_model
from cartpole.viz.panels import ctrl_label, mark_range, pole_panels
from cartpole.viz.traces import wrapped_angle_trace


def _energy(fun, x: np.ndarray) -> np.ndarray:
    """Energy (J) of each row of x (n, nx) by the CasADi Function ``fun``, in one vectorised call."""
    return np.asarray(fun.map(len(x))(np.asarray(x, dtype=float).T)).ravel()


def _mark_events(ax, marks: dict) -> None:
    """Knockdowns (red spans), swing-ups (green lines) and catches (blue dotted lines) on every panel of ``ax``, each
    kind labelled once with its count."""
    knocks = [tuple(map(float, k)) for k in marks.get("knockdowns") or ()]
    ups = [float(v) for v in marks.get("swingups") or ()]
    catches = [float(v) for v in marks.get("catches") or ()]
    for a in ax:
        for i, (s, e) in enumerate(knocks):
            a.axvspan(s, max(e, s + 0.02), color="r", alpha=0.25, lw=0,
                      label=f"knockdown ({len(knocks)})" if i == 0 else None)
        for i, v in enumerate(ups):
            a.axvline(v, color="g", lw=0.9, label=f"swing-up ({len(ups)})" if i == 0 else None)
        for i, v in enumerate(catches):
            a.axvline(v, color="b", ls=":", lw=0.9, label=f"catch ({len(catches)})" if i == 0 else None)


def plot_swingup(rollout, params, path, *, plan=None, caught_at: float | None = None, title: str | None = None,
                 model=None, handover_at: float | None = None, marks: dict | None = None) -> Path:
    """Draw a swing-up rollout (:func:`swingup_figure`) and save it as PNG (whole or not at all:
    :func:`~cartpole._files.atomic_write`); ``path`` is the output file (parent directories are created), the other
    arguments are :func:`swingup_figure`'s. Returns the path written."""
    fig = swingup_figure(rollout, params, plan=plan, caught_at=caught_at, title=title, model=model,
                         handover_at=handover_at, marks=marks)
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=100, format="png"))


def swingup_figure(rollout, params, *, plan=None, caught_at: float | None = None, title: str | None = None,
                   model=None, handover_at: float | None = None, marks: dict | None = None):
    """A swing-up rollout as a matplotlib ``Figure`` on an Agg canvas (no pyplot); panels as the module says.

    Parameters
    ----------
    rollout : Rollout
        What MuJoCo did: ``qpos`` (n+1, nq), ``qvel`` (n+1, nq), ``ctrl`` (n, nu).
    params : CartPoleParams
        For the joints, the cart and ctrl ranges.
    plan : Trajectory, optional
        Planned trajectory (``t`` (N+1,), ``x`` (N+1, nx), ``u`` (N or N+1, nu)) drawn dashed.
    caught_at : float, optional
        s: when the catch took over and held; marked with a vertical line on every panel.
    title : str, optional
    model : CartPoleModel, optional
        For the equilibrium and the energy (default built from ``params``).
    handover_at : float, optional
        s: when the controller handed over to the catch; without ``caught_at`` (the catch did not hold) marked with
        a dashed red line on every panel.
    marks : dict, optional
        A knocked or thrown run's events, each drawn on every panel: ``"knockdowns"`` (sequence of ``(start, end)``
        in s, shaded red), ``"swingups"`` (s, each swing-up's entry into the upright band, solid green) and
        ``"catches"`` (s, each time the catch took over, dotted blue).

    Returns
    -------
    matplotlib.figure.Figure
    """
    model = model or build_model(params)
    hinges, slide = params.hinges, params.slide
    x_eq = np.asarray(model.x_eq)
    single = model.pole_energy is not None
    energy, energy_label = ((model.pole_energy, "pole energy (J)") if single
                            else (model.energy, "total energy (J)"))
    t, x = rollout.t, rollout.x
    fig, ax, ax_th, ax_s, ax_u, (ax_e,) = pole_panels(params, extra=1, size=lambda n: (8, max(9.0, 2.0 * n)))
    px = None if plan is None else np.asarray(plan.x)
    pt = None if plan is None else np.asarray(plan.t)
    pu = None if plan is None else np.asarray(plan.u).reshape(len(np.asarray(plan.u)), -1)
    for i, (a, h) in enumerate(zip(ax_th, hinges)):
        a.plot(*wrapped_angle_trace(t, x[:, h], x_eq[h], degrees=False), label="MuJoCo")
        if px is not None:
            a.plot(*wrapped_angle_trace(pt, px[:, h], x_eq[h], degrees=False), "--", label="plan")
        a.axhline(0.0, color="k", lw=0.5)
        if len(hinges) == 1:
            a.set_ylabel("pole angle from upright\n(rad, wrapped)")
        else:
            rel = "" if i == 0 else " to parent"
            a.set_ylabel(f"pole {i + 1} ({params.joints[h].name}){rel}\nfrom x* (rad, wrapped)")
    if ax_s is not None:
        ax_s.plot(t, x[:, slide], label="MuJoCo")
        if px is not None:
            ax_s.plot(pt, px[:, slide], "--", label="plan")
        mark_range(ax_s, *params.cart_range, "joint limit", lw=1.5)
        ax_s.set_ylabel("cart position (m)")
    for k, a in enumerate(ax_u):
        a.step(t[:-1], rollout.ctrl[:, k], where="post", label="MuJoCo ctrl")
        if pu is not None:
            a.plot(pt[:len(pu)], pu[:, k], "--", label="plan ctrl")
        mark_range(a, *params.ctrl_range[k], "ctrl range", lw=1.5)
        a.set_ylabel(ctrl_label(params, k))
    ax_e.plot(t, _energy(energy, x), label="MuJoCo")
    if px is not None:
        ax_e.plot(pt, _energy(energy, px), "--", label="plan")
    ax_e.axhline(0.0, color="k", ls="--", lw=0.8, label="upright rest (0 J)")
    ax_e.set_ylabel(energy_label)
    ax[-1].set_xlabel("time (s)")
    if caught_at is not None:
        for a in ax:
            a.axvline(caught_at, color="g", lw=1.0, label=f"catch at {caught_at:.2f} s")
    elif handover_at is not None:
        for a in ax:
            a.axvline(handover_at, color="r", ls="--", lw=1.0, label=f"hand-over at {handover_at:.2f} s (did not hold)")
    _mark_events(ax, marks or {})
    for a in ax:
        a.grid(True, alpha=0.3)
        a.legend(loc="upper right", fontsize=7)
    fig.suptitle((title or "Swing-up in MuJoCo") + "\n(angles wrapped to (-pi, pi]: a gap in a trace marks a full turn)",
                 fontsize="medium")
    fig.tight_layout()
    return fig
