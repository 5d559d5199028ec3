"""The stacked time panels every control figure shares: one per pole angle, the cart, one per actuator (and extras)."""
from __future__ import annotations

from typing import Callable

import numpy as np


def pole_panels(params, *, extra: int = 0, size: Callable[[int], tuple] = lambda n: (10, max(6.0, 2.0 * n))):
    """Panels sharing time on an Agg canvas (no pyplot: a notebook's inline backend is left alone).

    Parameters
    ----------
    params : CartPoleParams
        Gives the layout: ``hinges`` (one angle panel each), ``slide`` (a cart panel when not None), ``nu``.
    extra : int
        Panels added below the ctrl panels (e.g. energy).
    size : callable
        ``size(number of panels) -> (width, height)`` in inches.

    Returns
    -------
    (fig, axes (all), angle axes, cart axis or None, ctrl axes (nu), extra axes (extra))
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n_th, has_cart, nu = len(params.hinges), params.slide is not None, params.nu
    n_panels = n_th + has_cart + nu + extra
    fig = Figure(figsize=size(n_panels))
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(n_panels, 1, sharex=True))
    first_u = n_th + has_cart
    return (fig, axes, list(axes[:n_th]), axes[n_th] if has_cart else None, list(axes[first_u:first_u + nu]),
            list(axes[first_u + nu:]))


def mark_range(ax, lo: float, hi: float, label: str | None = None, *, lw: float = 0.8, keep=None) -> None:
    """Dotted red horizontal lines at the finite ends of a range ``[lo, hi]`` (a joint's range in m or rad, a
    ctrlrange in ctrl units) on ``ax``, the first one drawn carrying ``label`` for the legend. ``keep(v)``, when
    given, says which ends to draw (e.g. only those near the traces)."""
    for v in (lo, hi):
        if np.isfinite(v) and (keep is None or keep(v)):
            ax.axhline(v, color="r", ls=":", lw=lw, label=label)
            label = None


def ctrl_label(params, k: int) -> str:
    """The y label of actuator ``k``'s ctrl panel: its name and what one unit of ctrl is (``force = gear N x ctrl``
    on a slide, ``N m`` on a hinge)."""
    act = params.actuators[k]
    unit = "N" if params.joints[act.joint].kind == "slide" else "N m"
    return f"ctrl {act.name}\n(force = {act.gear:g} {unit} x ctrl)"
