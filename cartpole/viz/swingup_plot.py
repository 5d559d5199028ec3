"""Figure of a swing-up: pole angle, cart position, ctrl and pole energy over time, with the catch marked.

For a trajectory-optimised swing-up the plan is drawn (dashed) beside what MuJoCo did.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole._files import atomic_write
from cartpole.models import build_model, wrap_angle


def _energy(model, x: np.ndarray) -> np.ndarray:
    """Pole energy (J) of each row of x (n, 4), in one vectorised CasADi call."""
    return np.asarray(model.pole_energy.map(len(x))(x.T)).ravel()


def plot_swingup(rollout, params, path, *, plan=None, caught_at: float | None = None, title: str | None = None,
                 model=None) -> Path:
    """Draw a swing-up rollout and save it as PNG (whole or not at all: :func:`~cartpole._files.atomic_write`).

    Parameters
    ----------
    rollout : Rollout
        What MuJoCo did.
    params : CartPoleParams
        For the cart and ctrl ranges.
    path : str or Path
        Output file; parent directories are created.
    plan : Trajectory, optional
        Planned trajectory (``t`` (N+1,), ``x`` (N+1, 4), ``u`` (N or N+1, 1)) drawn dashed.
    caught_at : float, optional
        s; marked with a vertical line on every panel.
    title : str, optional
    model : CartPoleModel, optional
        For the pole energy (default built from ``params``).

    Returns
    -------
    Path
    """
    # object API on an Agg canvas: no pyplot, so a notebook's inline backend is left alone
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    model = model or build_model(params)
    t, x = rollout.t, rollout.x
    fig = Figure(figsize=(8, 9))
    FigureCanvasAgg(fig)
    ax = fig.subplots(4, 1, sharex=True)
    ax[0].plot(t, wrap_angle(x[:, 1]), label="MuJoCo")
    ax[0].axhline(0.0, color="k", lw=0.5)
    ax[0].set_ylabel("pole angle from upright\n(rad, wrapped)")
    ax[1].plot(t, x[:, 0], label="MuJoCo")
    lo, hi = params.cart_range
    if np.isfinite(lo):
        ax[1].axhline(lo, color="r", ls=":", label="joint limit")
        ax[1].axhline(hi, color="r", ls=":")
    ax[1].set_ylabel("cart position (m)")
    ax[2].step(t[:-1], rollout.ctrl[:, 0], where="post", label="MuJoCo ctrl")
    ulo, uhi = params.ctrl_range
    if np.isfinite(ulo):
        ax[2].axhline(ulo, color="r", ls=":", label="ctrl range")
        ax[2].axhline(uhi, color="r", ls=":")
    ax[2].set_ylabel(f"ctrl (force = {params.gear:g} N x ctrl)")
    ax[3].plot(t, _energy(model, x), label="MuJoCo")
    ax[3].axhline(0.0, color="k", ls="--", lw=0.8, label="upright rest (0 J)")
    ax[3].set_ylabel("pole energy (J)")
    ax[3].set_xlabel("time (s)")
    if plan is not None:
        px = np.asarray(plan.x)
        pt = np.asarray(plan.t)
        ax[0].plot(pt, wrap_angle(px[:, 1]), "--", label="plan")
        ax[1].plot(pt, px[:, 0], "--", label="plan")
        pu = np.asarray(plan.u).reshape(len(np.asarray(plan.u)), -1)[:, 0]
        ax[2].plot(pt[:len(pu)], pu, "--", label="plan ctrl")
        ax[3].plot(pt, _energy(model, px), "--", label="plan")
    if caught_at is not None:
        for a in ax:
            a.axvline(caught_at, color="g", lw=1.0, label=f"catch at {caught_at:.2f} s")
    for a in ax:
        a.grid(True, alpha=0.3)
        a.legend(loc="upper right", fontsize=7)
    fig.suptitle(title or "Swing-up in MuJoCo")
    fig.tight_layout()
    return atomic_write(path, lambda fh: fig.savefig(fh, dpi=100, format="png"))
