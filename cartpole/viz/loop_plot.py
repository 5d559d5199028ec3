"""Frequency-domain figures of the loops broken at the plant input (:mod:`cartpole.analysis`): Bode, Nyquist and
sensitivity, one panel (column) per loop, the margins marked. The responses come from python-control's
``frequency_response`` on the same frequencies the margins are read on."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from cartpole._files import atomic_write
from cartpole.analysis import frequency_grid, response

#: The figures :func:`plot_loops` writes, by kind.
KINDS = ("bode", "nyquist", "sensitivity")


def _figure(n_rows: int, n_cols: int):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.0 * n_cols, 3.6 * n_rows))
    FigureCanvasAgg(fig)
    return fig, fig.subplots(n_rows, n_cols, squeeze=False)


def _title(loop, mg) -> str:
    gm = mg.to_dict()["gain_margin"]
    hi = "inf" if gm[1] is None else f"{gm[1]:.3g}"
    lo = "0" if gm[0] is None else f"{gm[0]:.3g}"
    dm = "inf" if not math.isfinite(mg.delay_margin_s) else f"{1e3 * mg.delay_margin_s:.3g} ms"
    what = textwrap.fill(f"{loop.name}: {loop.description}", 48)
    return (f"{what}\nGM [{lo}, {hi}], PM {mg.phase_margin_deg:.3g} deg, DM {dm}, "
            f"Ms {mg.ms:.3g}")


def loop_figure(pairs, kind: str):
    """One figure of ``kind`` (``bode``, ``nyquist`` or ``sensitivity``) with a column per ``(Loop, Margins)``.

    Parameters
    ----------
    pairs : sequence of (Loop, Margins)
    kind : str
        ``bode``: magnitude (dB) and phase (deg) of ``L`` against frequency (rad/s), the gain crossovers dashed;
        ``nyquist``: ``L`` in the complex plane with -1 and the circle of radius ``1 / Ms`` about it;
        ``sensitivity``: ``|S|`` and ``|T|`` (dB) against frequency, their peaks marked.

    Returns
    -------
    matplotlib.figure.Figure
    """
    pairs = list(pairs)
    rows = 2 if kind == "bode" else 1
    fig, axes = _figure(rows, len(pairs))
    for j, (loop, mg) in enumerate(pairs):
        w = frequency_grid(loop.L)
        H = response(loop.L, w)
        if kind == "bode":
            ax_m, ax_p = axes[0, j], axes[1, j]
            ax_m.semilogx(w, 20 * np.log10(np.abs(H)))
            ax_m.axhline(0.0, color="k", linewidth=0.8)
            ax_p.semilogx(w, np.degrees(np.unwrap(np.angle(H))))
            for wc in mg.gain_crossovers:
                for ax in (ax_m, ax_p):
                    ax.axvline(wc, color="tab:red", linestyle="--", linewidth=0.8)
            ax_m.set_ylabel("|L| (dB)")
            ax_p.set_ylabel("phase of L (deg)")
            ax_p.set_xlabel("frequency (rad/s)")
            ax_m.set_title(_title(loop, mg), fontsize=8)
        elif kind == "nyquist":
            ax = axes[0, j]
            ax.plot(H.real, H.imag, label="L(jw), w > 0")
            ax.plot(H.real, -H.imag, linestyle=":", label="w < 0")
            ax.plot([-1.0], [0.0], "r+", markersize=12, markeredgewidth=2, label="-1")
            t = np.linspace(0, 2 * np.pi, 200)
            ax.plot(-1 + np.cos(t) / mg.ms, np.sin(t) / mg.ms, color="tab:red", linewidth=0.8,
                    label=f"radius 1/Ms = {1 / mg.ms:.3g}")
            ax.set_xlim(-4, 2)
            ax.set_ylim(-3, 3)
            ax.set_aspect("equal")
            ax.set_xlabel("Re L")
            ax.set_ylabel("Im L")
            ax.legend(fontsize=7, loc="lower left")
            ax.set_title(_title(loop, mg), fontsize=8)
        elif kind == "sensitivity":
            ax = axes[0, j]
            ax.semilogx(w, 20 * np.log10(np.abs(1 / (1 + H))), label="|S| = |1 / (1 + L)|")
            ax.semilogx(w, 20 * np.log10(np.abs(H / (1 + H))), label="|T| = |L / (1 + L)|")
            ax.axhline(20 * np.log10(mg.ms), color="tab:blue", linestyle="--", linewidth=0.8,
                       label=f"Ms = {mg.ms:.3g}")
            ax.axhline(20 * np.log10(mg.mt), color="tab:orange", linestyle="--", linewidth=0.8,
                       label=f"Mt = {mg.mt:.3g}")
            ax.set_xlabel("frequency (rad/s)")
            ax.set_ylabel("magnitude (dB)")
            ax.legend(fontsize=7)
            ax.set_title(_title(loop, mg), fontsize=8)
        else:
            raise ValueError(f"No loop figure of kind {kind!r}; pick one of {', '.join(KINDS)}.")
        for ax in axes[:, j]:
            ax.grid(True, which="both", alpha=0.3)
    fig.suptitle({"bode": "Bode plot of the loop broken at the plant input",
                  "nyquist": "Nyquist plot of the loop broken at the plant input",
                  "sensitivity": "Sensitivity S and complementary sensitivity T"}[kind])
    fig.tight_layout()
    return fig


def plot_loops(pairs, out_dir, *, dpi: int = 110) -> dict:
    """Write the Bode, Nyquist and sensitivity figures of ``pairs`` ((Loop, Margins)) as
    ``out_dir/margins_<kind>.png`` (each whole or not at all).

    Parameters
    ----------
    pairs : sequence of (Loop, Margins)
    out_dir : path
        Directory (created if missing).
    dpi : int

    Returns
    -------
    dict
        Kind -> path written.
    """
    pairs = list(pairs)
    out = {}
    for kind in KINDS:
        fig = loop_figure(pairs, kind)
        out[kind] = atomic_write(Path(out_dir) / f"margins_{kind}.png",
                                 lambda fh, fig=fig: fig.savefig(fh, dpi=dpi, format="png"))
    return out
