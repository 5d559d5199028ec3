"""A controller run live in the browser (``--view web``, :func:`watch`): watched, pushed and tuned while it runs.

The run is :func:`~cartpole.sim.rollout.simulate`'s, with :class:`cartpole.viz.web.WebLive` as its ``on_step`` and
its ``push``: every physics step logged, the page's pushes in the rollout's ``push`` column, so the log replays
exactly (:func:`~cartpole.sim.rollout.replays_exactly`). :class:`LQRTuner` puts the lab's LQR on the page: its
weights as sliders, the gain re-designed from the exact linearisation (the lab's ``A, B`` or ``Ad, Bd``, as the lab
designed it) when a slider is released, the new closed-loop eigenvalues shown and logged with the time of the change.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.riccati import dlqr, lqr
from cartpole.models import state_error
from cartpole.sim import Rollout, simulate
from cartpole.viz.web import LOCALHOST, Knob, WebLive

#: A weight slider spans its starting value times 10**-SPAN to times 10**SPAN.
SPAN = 2.0


def _eig_pairs(E) -> list[list[float]]:
    return [[float(np.real(e)), float(np.imag(e))] for e in np.asarray(E, complex).ravel()]


class LiveLQR:
    """The LQR law ``u = u* - K e`` whose gain the page may replace while the run goes on (call shape ``c(t, x)``).

    Parameters
    ----------
    feedback : LinearFeedback
        The starting law (:meth:`cartpole.apps.lab.LabResult.controller`).
    """

    def __init__(self, feedback):
        self.feedback = feedback

    def __call__(self, t: float, x):
        """``u`` (nu,) for the state ``x`` (nx,) at ``t`` (s), from the gain in force now."""
        return self.feedback(t, x)


class LQRTuner:
    """The lab's LQR on the page: ``Q`` and ``R`` diagonal weights as logarithmic sliders, re-designed on release.

    Parameters
    ----------
    lab : LabResult
        The lab (:func:`cartpole.apps.lab.run_lab`): its exact linearisation, weights, gain, period and rig.

    Attributes
    ----------
    controller : LiveLQR
        The law to run (its gain replaced by :meth:`set`).
    Q, R : (nx, nx), (nu, nu) arrays
        The weights in force.
    K : (nu, nx) array
    E : (nx,) complex array
        Closed-loop eigenvalues of the gain in force (continuous 1/s, or discrete per control period).
    """

    def __init__(self, lab):
        from dataclasses import replace

        self.lab = lab
        self.Q = np.array(lab.Q, float)
        self.R = np.array(lab.R, float)
        self.K = np.array(lab.K, float)
        self.E = np.array(lab.E, complex)
        self._feedback0 = lab.controller()
        self._replace = replace
        self.controller = LiveLQR(self._feedback0)
        self.steps = max(1, int(round(lab.period / lab.params.timestep))) if lab.period else 1
        self.kind = ("dlqr over the control period" if self.steps > 1 else
                     "dlqr on (Ad, Bd)" if lab.discrete else "lqr on the continuous (A, B)")
        names = _state_names(lab.params)
        acts = [f"u{i}" for i in range(self.R.shape[0])] if self.R.shape[0] > 1 else ["u"]
        self._q = [(f"Q {n}", i) for i, n in enumerate(names)]
        self._r = [(f"R {n}", i) for i, n in enumerate(acts)]
        self._q0 = np.diag(self.Q).copy()
        self._r0 = np.diag(self.R).copy()

    def knobs(self) -> list[Knob]:
        """One logarithmic slider per diagonal weight, spanning 10**±SPAN times its starting value."""
        out = []
        for (name, i), w0 in zip(self._q, self._q0):
            w0 = w0 if w0 > 0 else 1e-3
            out.append(Knob(name, float(self.Q[i, i]) or w0, w0 * 10 ** -SPAN, w0 * 10 ** SPAN, log=True))
        for (name, i), w0 in zip(self._r, self._r0):
            out.append(Knob(name, float(self.R[i, i]), w0 * 10 ** -SPAN, w0 * 10 ** SPAN, log=True))
        return out

    def status(self, t: float, x) -> list[str]:
        """The law, its gain and eigenvalues, the rig, and how far the state is from upright."""
        lab = self.lab
        e = state_error(np.asarray(x, float), lab.x_eq, lab.params.hinges)
        worst = max((abs(e[h]) for h in lab.params.hinges), default=0.0)
        mode = "balancing" if worst < 0.3 else "far from upright"
        with np.printoptions(precision=3, suppress=True, linewidth=60):
            k = np.array2string(self.K.ravel(), separator=", ")
        eig = ", ".join(_eig_text(c) for c in self.E)
        rig = lab.rig
        delay = 0.0 if rig is None else float(rig.delay)
        return [f"LQR ({self.kind}), {mode}: largest angle error {np.rad2deg(worst):.1f} deg",
                f"K = {k}", f"closed-loop eigenvalues: {eig}",
                f"control period {lab.period:g} s, delay {delay:g} s (set on the command line)"]

    def set(self, name: str, value: float, t: float) -> dict:
        """Set one weight to ``value`` and re-design the gain from the exact model; returns the new ``K``,
        ``eigenvalues`` ([re, im] pairs), ``Q`` and ``R`` diagonals (logged with the event).

        Raises
        ------
        CartPoleError
            An unknown knob, a weight that is not positive and finite, or a design that fails (the gain in force
            stays).
        """
        if not (np.isfinite(value) and value > 0):
            raise CartPoleError(f"The weight {name} = {value} must be positive and finite; pick another value.")
        Q, R = self.Q.copy(), self.R.copy()
        hit = [i for n, i in self._q if n == name]
        if hit:
            Q[hit[0], hit[0]] = value
        else:
            hit = [i for n, i in self._r if n == name]
            if not hit:
                raise CartPoleError(f"There is no weight named {name!r}; the page offers "
                                    f"{', '.join(n for n, _ in self._q + self._r)}.")
            R[hit[0], hit[0]] = value
        res = self.design(Q, R)
        self.Q, self.R, self.K, self.E = Q, R, np.array(res.K, float), np.array(res.E, complex)
        self.controller.feedback = type(self._feedback0)(self.K, self.lab.x_eq, self.lab.u_eq, S=res.S,
                                                         hinges=self.lab.params.hinges)
        return {"K": self.K.tolist(), "eigenvalues": _eig_pairs(self.E), "Q": np.diag(Q).tolist(),
                "R": np.diag(R).tolist()}

    def design(self, Q, R):
        """The LQR for weights ``Q``, ``R`` on the lab's exact linearisation, as the lab designs it
        (:meth:`~cartpole.control.linear.LinearFeedback.for_model`, on the lab's stored linearisation so that a
        slider does not rebuild the model): ``dlqr(Ad, Bd, Q T, R T)`` when the lab is discrete (``T`` its control
        period: the package's one cost scaling, :mod:`cartpole.riccati.algebraic`), else ``lqr(A, B, Q, R)``."""
        lab = self.lab
        if self.steps > 1 or lab.discrete:
            return dlqr(lab.Ad, lab.Bd, Q * lab.period, R * lab.period)
        return lqr(lab.A, lab.B, Q, R)


def _eig_text(c) -> str:
    c = complex(c)
    return f"{c.real:.3g}" if abs(c.imag) < 1e-9 else f"{c.real:.3g}{c.imag:+.3g}j"


def _state_names(params) -> list[str]:
    joints = [j.name for j in params.joints]
    return joints + [f"{n} rate" for n in joints]


def watch_lab(lab, *, port: int = 0, host: str = LOCALHOST, duration: float | None = None, x0=None,
              wait: bool = True) -> tuple[Rollout, dict]:
    """The lab's LQR run live in the browser, from its first start, pushed and tuned from the page.

    Parameters
    ----------
    lab : LabResult
        From :func:`cartpole.apps.lab.run_lab`.
    port : int
        TCP port of the page (0: the first free one from 8080).
    host : str
        Interface to bind (default this machine only).
    duration : float, s, optional
        Length of the live run (default the lab's); closing the page or Ctrl-C ends it sooner.
    x0 : (nx,) array, optional
        Start state (default the lab's first start).
    wait : bool
        Start the run when a browser opens the page (default True).

    Returns
    -------
    (Rollout, dict)
        The run (every physics step, pushes in ``info["push"]``) and the live part of the JSON: ``url``, ``events``
        (each push and weight change with its time), ``frames``, ``wall_time``, ``page_closed``, ``interrupted``,
        ``K`` and ``eigenvalues`` at the end.

    Raises
    ------
    WebUnavailable
        No Studio here, or the port is taken (one sentence).
    """
    tuner = LQRTuner(lab)
    live = WebLive(port=port, host=host, tuner=tuner, wait=wait, title="cartpole lqr live")
    start = lab.x0s[0] if x0 is None else x0
    try:
        run = simulate(lab.params, tuner.controller, start, lab.duration if duration is None else duration,
                       rig=lab.rig, push=live.push, on_step=live)
        live.finish()
    finally:
        live.close()
    doc = live.summary()
    doc.update({"K": tuner.K.tolist(), "eigenvalues": _eig_pairs(tuner.E)})
    return run, doc


def watch(plant: str | Path | None = None, *, Q=None, R=None, duration: float = 30.0, port: int = 0,
          host: str = LOCALHOST, x0=None, wait: bool = True) -> Rollout:
    """Balance a cart-pole with the lab's LQR live in the browser (MuJoCo Studio's web viewer) and return the run.

    The address is printed on stderr (``http://localhost:PORT/``; from a remote Jupyter server tunnel it:
    ``ssh -L 8080:localhost:PORT HOST``). The page shows the run at real time, plots each pole's angle, the cart and
    the ctrl against its range, and offers pushes and the LQR weights; closing it or interrupting the kernel ends the
    run with the steps done.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (default the shipped one).
    Q, R : arrays, optional
        Starting weights (default the lab's).
    duration : float, s
        Longest run (default 30 s).
    port : int
        TCP port (0: first free from 8080).
    host : str
        Interface to bind (default ``127.0.0.1``: only this machine; there is no authentication).
    x0 : (nx,) array, optional
        Start state (default the lab's first start).
    wait : bool
        Start when a browser opens the page (default True).

    Returns
    -------
    Rollout
        Every physics step; ``info["push"]`` the pushes (N, one per step), ``info["live"]`` the page's events with
        their times and the final gain; replays exactly (:func:`cartpole.sim.replays_exactly`).
    """
    from cartpole.apps.lab import run_lab

    lab = run_lab(plant, Q=Q, R=R)
    run, doc = watch_lab(lab, port=port, host=host, duration=duration, x0=x0, wait=wait)
    run.info["live"] = doc
    return run
