"""A controller run live in the browser (``--view web``, :func:`watch`): watched, pushed and tuned while it runs.

The run is :func:`~cartpole.sim.rollout.simulate`'s, with :class:`cartpole.viz.web.WebLive` as its ``on_step`` and
its ``push``: every physics step logged, the page's pushes in the rollout's ``push`` column, so the log replays
exactly (:func:`~cartpole.sim.rollout.replays_exactly`). :class:`LQRTuner` puts the lab's LQR on the page: its
weights as sliders, the gain re-designed from the exact linearisation (the lab's ``A, B`` or ``Ad, Bd``, as the lab
designed it) when a slider is released, the new closed-loop eigenvalues shown and logged with the time of the change.
:class:`PIDTuner` does the same for the cascaded PID's gains (``lqr --compare-pid``: the PID runs live after the LQR),
:class:`LoopTuner` for the rig's control period and delay (:class:`LiveLoop` holds and delays the ctrl as
:class:`cartpole.sim.rig.Rig` does, with a period and a delay the page may change), and :func:`controller_status`
says which law of a swing-up is in charge (swing-up, tracking, catch, the supervisor's fallbacks).
:func:`paced_supervisor` makes the supervisor fit for a run paced in real time: its plans are made in a worker process
while the loop steps on (the brake acting), so the page's frame rate never waits for a plan.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from cartpole.apps.lab import compare_pid, run_lab
from cartpole.control.pid import CascadedPID, closed_loop_matrix
from cartpole.errors import CartPoleError
from cartpole.models import state_error
from cartpole.riccati import dlqr, lqr
from cartpole.sim import Rollout, SimOptions, simulate
from cartpole.sim.rig import MAX_DELAY
from cartpole.supervise.worker import fork_available
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
        self.loop_live = False  # a LoopTuner beside it shows the period and the delay

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
        lines = [f"LQR ({self.kind}), {mode}: largest angle error {np.rad2deg(worst):.1f} deg",
                 f"K = {k}", f"closed-loop eigenvalues: {eig}"]
        if not self.loop_live:
            lines.append(f"control period {lab.period:g} s, delay {delay:g} s (set on the command line)")
        return lines

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


#: Names of the cascaded PID's gains the page offers, with their units.
PID_KNOBS = (("kp", "ctrl/rad"), ("ki", "ctrl/(rad s)"), ("kd", "ctrl/(rad/s)"), ("kp_cart", "rad/m"),
             ("kd_cart", "rad/(m/s)"))
#: A PID gain's slider spans 0 to this many times its tuned value.
PID_SPAN = 3.0


class PIDTuner:
    """The cascaded PID on the page: its five gains as sliders (0 to :data:`PID_SPAN` times the tuned value, sign
    kept), applied from the next control instant with the integrator and filter kept; the linear closed loop's
    eigenvalues shown and logged.

    Parameters
    ----------
    pid : CascadedPID
        The law that runs (its gains replaced by :meth:`set`).
    A, B : (4, 4), (4, 1) arrays
        The continuous linearisation at upright the PID was tuned on (its eigenvalues: :func:`closed_loop_matrix`).
    """

    def __init__(self, pid, A, B):
        self.pid = pid
        self.A, self.B = np.asarray(A, float), np.asarray(B, float)
        self._matrix = closed_loop_matrix
        self.gains0 = pid.gains
        self.E = self._eig(pid.gains)
        self.loop_live = False

    def _eig(self, gains) -> np.ndarray:
        M = self._matrix(self.A, self.B, gains, slide=self.pid.slide, hinge=self.pid.hinge)
        return np.linalg.eigvals(M)

    def _name(self, gain: str) -> str:
        return f"PID {gain} [{dict(PID_KNOBS)[gain]}]"

    def knobs(self) -> list[Knob]:
        """One linear slider per gain, from 0 to :data:`PID_SPAN` times the tuned value (negative gains mirrored)."""
        out = []
        for gain, _ in PID_KNOBS:
            g0 = float(getattr(self.gains0, gain)) or 1.0
            lo, hi = sorted((0.0, PID_SPAN * g0))
            out.append(Knob(self._name(gain), float(getattr(self.pid.gains, gain)), lo, hi))
        return out

    def status(self, t: float, x) -> list[str]:
        """The law, its gains and the eigenvalues of its linear closed loop."""
        g = self.pid.gains
        stable = bool(np.all(np.real(self.E) < 0))
        return [f"PID (cascade: cart PD outside, pole PID inside), tilt setpoint {np.rad2deg(self.pid.theta_ref):+.1f} "
                f"deg", "  ".join(f"{n} {getattr(g, n):.3g}" for n, _ in PID_KNOBS),
                f"linear closed loop {'stable' if stable else 'UNSTABLE'}: "
                + ", ".join(_eig_text(c) for c in self.E)]

    def set(self, name: str, value: float, t: float) -> dict:
        """Set one gain; returns the new ``gains`` and ``eigenvalues`` ([re, im] pairs of the linear closed loop).

        Raises
        ------
        CartPoleError
            An unknown knob or a gain that is not finite (the gains in force stay).
        """
        gain = next((g for g, _ in PID_KNOBS if self._name(g) == name), None)
        if gain is None:
            raise CartPoleError(f"There is no PID gain named {name!r}; the page offers "
                                f"{', '.join(self._name(g) for g, _ in PID_KNOBS)}.")
        if not np.isfinite(value):
            raise CartPoleError(f"The gain {name} = {value} must be finite; pick another value.")
        gains = replace(self.pid.gains, **{gain: float(value)})
        self.pid.set_gains(gains)
        self.E = self._eig(gains)
        return {"gains": {g: float(getattr(gains, g)) for g, _ in PID_KNOBS}, "eigenvalues": _eig_pairs(self.E)}


class LiveLoop:
    """The rig's period and delay around a controller, changeable while it runs (call shape ``c(t, x)``).

    Run it in :func:`~cartpole.sim.simulate` at every physics step (no ``control_period``, no ``rig``): every
    ``steps`` physics steps it samples the state and calls ``controller((k + lag) h, x)``, whose ctrl acts from ``lag``
    steps later for ``steps`` steps; until the first ctrl arrives the ctrl is 0 (simulate clips it to the ctrl range),
    as :class:`cartpole.sim.rig.Rig` without sensors and without delay compensation does, so the ctrl logged is the
    same step for step. A new period or delay (:meth:`change`) takes effect at the next sample. The log replays
    exactly, like every run of simulate.

    Parameters
    ----------
    controller : callable
        ``controller(t [s], x (nx,)) -> ctrl (nu,)``.
    timestep : float
        MuJoCo's physics step, s.
    steps, delay_steps : int
        Physics steps per control period (>= 1) and of delay (>= 0) at the start.
    """

    def __init__(self, controller, timestep: float, *, steps: int = 1, delay_steps: int = 0):
        self.controller = controller
        self.h = float(timestep)
        self.steps, self.delay_steps = int(steps), int(delay_steps)
        self._next = 0
        self._planned: dict[int, np.ndarray] = {}
        self._zero = None

    def change(self, *, steps: int | None = None, delay_steps: int | None = None) -> None:
        """Use ``steps`` physics steps per period and/or ``delay_steps`` of delay from the next sample on."""
        if steps is not None:
            self.steps = max(1, int(steps))
        if delay_steps is not None:
            self.delay_steps = max(0, int(delay_steps))

    def __call__(self, t: float, x):
        """The ctrl (nu,) MuJoCo applies during the physics step from ``t`` (s)."""
        k = int(round(float(t) / self.h))
        if k >= self._next:
            lag = self.delay_steps
            u = np.asarray(self.controller((k + lag) * self.h, x), dtype=float).ravel()
            for j in range(k + lag, k + lag + self.steps):
                self._planned[j] = u
            self._next = k + self.steps
            if self._zero is None:
                self._zero = np.zeros_like(u)
        for old in [j for j in self._planned if j < k]:
            del self._planned[old]
        return self._planned.get(k, self._zero)


class LoopTuner:
    """The rig's control period and delay as sliders (whole physics steps), applied by a :class:`LiveLoop` from its
    next sample; the gain in force is kept (designed for the starting period: the page shows what a slower or later
    loop does to it).

    Parameters
    ----------
    loop : LiveLoop
    max_period, max_delay : float, s
        Slider ends.
    """

    PERIOD, DELAY = "control period [s]", "delay [s]"

    def __init__(self, loop: LiveLoop, *, max_period: float = 0.1, max_delay: float = 0.1):
        self.loop = loop
        self.period0 = loop.steps * loop.h
        self.max_period = max(float(max_period), 2.0 * self.period0)
        self.max_delay = min(max(float(max_delay), 2.0 * loop.delay_steps * loop.h), MAX_DELAY)

    def knobs(self) -> list[Knob]:
        """The period (one physics step up) and the delay (0 up)."""
        h = self.loop.h
        return [Knob(self.PERIOD, self.loop.steps * h, h, self.max_period),
                Knob(self.DELAY, self.loop.delay_steps * h, 0.0, self.max_delay)]

    def status(self, t: float, x) -> list[str]:
        """The period and delay in force."""
        h = self.loop.h
        return [f"period {self.loop.steps * h:g} s, delay {self.loop.delay_steps * h:g} s (uncompensated; "
                f"gain for {self.period0:g} s)"]

    def set(self, name: str, value: float, t: float) -> dict:
        """Set the period or the delay to ``value`` s, rounded to whole physics steps; returns ``period``, ``delay``
        (s, as applied) and ``from`` (s: the next sample, where it takes effect).

        Raises
        ------
        CartPoleError
            An unknown knob, or a value outside the slider's range.
        """
        h = self.loop.h
        if name == self.PERIOD:
            if not (np.isfinite(value) and 0 < value <= self.max_period * (1 + 1e-9)):
                raise CartPoleError(f"The control period {value} s must be above 0 and at most {self.max_period:g} "
                                    "s; pick another value.")
            self.loop.change(steps=max(1, int(round(value / h))))
        elif name == self.DELAY:
            if not (np.isfinite(value) and 0 <= value <= self.max_delay * (1 + 1e-9)):
                raise CartPoleError(f"The delay {value} s must be from 0 to {self.max_delay:g} s; pick another "
                                    "value.")
            self.loop.change(delay_steps=int(round(value / h)))
        else:
            raise CartPoleError(f"There is no loop setting named {name!r}; the page offers {self.PERIOD} and "
                                f"{self.DELAY}.")
        return {"period": self.loop.steps * h, "delay": self.loop.delay_steps * h, "from": self.loop._next * h}


class Tuners:
    """Several tuners on one page (e.g. the LQR's weights and the loop's period and delay): knobs and status lines
    in order, a knob set on the tuner that offers it."""

    def __init__(self, *tuners):
        self.tuners = [t for t in tuners if t is not None]

    def knobs(self) -> list[Knob]:
        """Every tuner's knobs."""
        return [k for t in self.tuners for k in t.knobs()]

    def status(self, t: float, x) -> list[str]:
        """Every tuner's lines."""
        return [line for tu in self.tuners for line in tu.status(t, x)]

    def set(self, name: str, value: float, t: float) -> dict:
        """Set ``name`` on the tuner that has it.

        Raises
        ------
        CartPoleError
            No tuner has it, or that tuner refuses the value.
        """
        for tu in self.tuners:
            if any(k.name == name for k in tu.knobs()):
                return tu.set(name, value, t)
        raise CartPoleError(f"There is no knob named {name!r}; the page offers "
                            f"{', '.join(k.name for k in self.knobs())}.")


#: What the supervisor's modes mean, as the page says them.
SUPERVISOR_MODES = {
    "start": "starting",
    "catch": "catch: the LQR, inside its verified basin",
    "swingup": "swing-up: the energy law",
    "wait": "fallback: braking while the plan is solved",
    "track": "tracking the plan (TVLQR)",
    "brake": "fallback: passive brake (re-plans once calm)",
}


def paced_supervisor(supervisor):
    """The supervisor (:class:`cartpole.supervise.Supervisor`) set for a run paced in real time (a live view, where
    simulated time is wall time): each plan made in its worker process while the loop steps on, the brake acting
    (``plan_while_running``; charged the time it took to come in, killed at ``plan_budget``), and the planner warmed
    in this process first (:meth:`~cartpole.supervise.Supervisor.prepare`: a plan made and discarded before the run,
    so that neither the first plan nor one after a kill waits for its solvers to be built). A swing-up MPC (the
    acrobot's) without a step budget gets its control period as one (``mpc_step_budget``: a step whose solve comes
    later than the period applies the previous solution's shifted input). Where the platform cannot
    fork, or the supervisor plans in the caller's thread by request (``plan_in_worker=False``), or never plans (the
    energy law, the hinge pump), it is returned as it is: the loop then waits for each plan, as in a simulated run.

    Parameters
    ----------
    supervisor : Supervisor

    Returns
    -------
    Supervisor
        The same object, its options replaced.
    """
    mpc = getattr(supervisor, "mpc", None)
    if mpc is not None and supervisor.options.mpc_step_budget is None:
        # paced, an MPC step later than its period would stall the loop: its answer is then too late for that step
        supervisor.options = supervisor.options.replace(mpc_step_budget=mpc.period)
        mpc.step_budget = mpc.period
    options = supervisor.options
    if supervisor.planner is None or not fork_available() or options.plan_in_worker is False:
        return supervisor
    supervisor.options = options.replace(plan_in_worker=True, plan_while_running=True)
    if supervisor.swingup is None:  # a swing-up law acts first; it plans only once the law runs out (law_budget)
        supervisor.prepare()
    return supervisor


def controller_status(controller, t: float, x) -> list[str]:
    """Lines naming the law in charge of a run and its state, for the page (:meth:`WebLive.attach`'s ``describe``).

    Knows the swing-up's laws by what they expose: the supervisor (``decisions``; its mode: catch, swing-up,
    tracking, or a fallback: brake, wait), the switching energy/catch law (``switches``; swing-up or catch) and the
    TVLQR tracker (``handover_time``; tracking, then the catch); anything else by its class name.

    Parameters
    ----------
    controller : callable
        The law running.
    t : float, s
    x : (nx,) array

    Returns
    -------
    list of str
    """
    name = type(controller).__name__
    mode = getattr(controller, "mode", None)
    if hasattr(controller, "decisions"):
        lines = [f"supervisor: {SUPERVISOR_MODES.get(mode, mode)}"]
        server = getattr(controller, "server", None)
        if mode == "wait" and getattr(controller, "asked", None) is not None and server is not None:
            lines[0] += f" (in a worker process, {server.elapsed:.1f} s so far; the run goes on)"
        last = controller.decisions[-1] if controller.decisions else None
        if last is not None:
            lines.append(f"last decision: {last.kind} at {last.t:.2f} s; plans {getattr(controller, 'plans', 0)}, "
                         f"failed {getattr(controller, 'failures', 0)}")
        return lines
    if hasattr(controller, "switches") and mode is not None:
        text = "catch: the LQR, inside its basin" if mode == "catch" else "swing-up: the energy law"
        lines = [f"energy shaping + LQR catch: {text}"]
        if controller.switches:
            s = controller.switches[-1]
            lines.append(f"{len(controller.switches)} switch(es), last to {s.mode} at {s.t:.2f} s")
        return lines
    if hasattr(controller, "handover_time"):
        ht = controller.handover_time
        return ["TVLQR along the plan: " + ("tracking" if ht is None else f"catch (the LQR) since {ht:.2f} s")]
    return [f"controller: {name}" + (f" ({mode})" if mode else "")]


def _eig_text(c) -> str:
    c = complex(c)
    return f"{c.real:.3g}" if abs(c.imag) < 1e-9 else f"{c.real:.3g}{c.imag:+.3g}j"


def _state_names(params) -> list[str]:
    joints = [j.name for j in params.joints]
    return joints + [f"{n} rate" for n in joints]


def live_loop(lab, controller):
    """``(controller to run, rig for simulate, LoopTuner or None)``: the lab's loop with its period and delay live
    (:class:`LiveLoop`) when that loop gives the controller MuJoCo's state (no rig, or one without an estimator whose
    delay is not compensated); else the lab's own rig, fixed (its estimator is built for its period and delay)."""
    rig, h = lab.rig, float(lab.params.timestep)
    if rig is None:
        loop = LiveLoop(controller, h, steps=max(1, int(round(lab.period / h))) if lab.period else 1)
    elif rig.spec is None and (rig.delay_steps == 0 or not rig.compensate):
        loop = LiveLoop(controller, h, steps=rig.steps, delay_steps=rig.delay_steps)
    else:
        return controller, rig.for_run(0), None
    return loop, None, LoopTuner(loop)


def _live_run(live, params, controller, x0, duration, rig):
    """One run on the page ``live``: simulate with its push and step hooks; ``(rollout, the run's events)``."""
    first = len(live.events)
    run = simulate(params, controller, x0, duration, rig=rig, push=live.attach(None), options=SimOptions(on_step=live))
    return run, list(live.events[first:])


def watch_lab(lab, *, port: int = 0, host: str = LOCALHOST, duration: float | None = None, x0=None,
              wait: bool = True, pid=None) -> tuple[Rollout, dict]:
    """The lab's LQR run live in the browser, from its first start, pushed and tuned from the page; with ``pid``
    the PID then runs live on the same page, its gains tuned there.

    Parameters
    ----------
    lab : LabResult
        From :func:`cartpole.apps.lab.run_lab`.
    port : int
        TCP port of the page (0: the first free one from 8080).
    host : str
        Interface to bind (default this machine only).
    duration : float, s, optional
        Length of each live run (default the lab's); closing the page or Ctrl-C ends it sooner.
    x0 : (nx,) array, optional
        Start state (default the lab's first start).
    wait : bool
        Start the run when a browser opens the page (default True).
    pid : PIDLabResult, optional
        The PID beside the lab (:func:`cartpole.apps.lab.compare_pid`): run live after the LQR (unless the page was
        closed or Ctrl-C pressed), its gains as sliders.

    Returns
    -------
    (Rollout, dict)
        The LQR run (every physics step, pushes in ``info["push"]``) and the live part of the JSON: ``url``,
        ``events`` (each push, drag, weight, period and delay change with its time), ``frames``, ``wall_time``,
        ``page_closed``, ``interrupted``, ``K`` and ``eigenvalues`` at the end, ``loop`` (``period``, ``delay`` at
        the end, or None when the lab's rig is fixed); with ``pid`` also ``pid``: ``None`` (not run) or
        ``{"rollout": Rollout, "events", "gains", "eigenvalues", "loop"}``.

    Raises
    ------
    WebUnavailable
        No Studio here, or the port is taken (one sentence).
    """
    tuner = LQRTuner(lab)
    controller, rig, loop = live_loop(lab, tuner.controller)
    tuner.loop_live = loop is not None
    live = WebLive(port=port, host=host, tuner=Tuners(tuner, loop), wait=wait, title="cartpole lqr live",
                   describe=None)
    start = lab.x0s[0] if x0 is None else x0
    T = lab.duration if duration is None else duration
    pid_doc = None
    try:
        run, events = _live_run(live, lab.params, controller, start, T, rig)
        if pid is not None and not (live.page_closed or live.interrupted):
            pid_doc = _pid_run(live, lab, pid, start, T)
        live.finish()
    finally:
        live.close()
    doc = live.summary()
    doc.update({"events": events, "K": tuner.K.tolist(), "eigenvalues": _eig_pairs(tuner.E),
                "loop": None if loop is None else _loop_doc(loop.loop)})
    if pid is not None:
        doc["pid"] = pid_doc
    return run, doc


def _loop_doc(loop: LiveLoop) -> dict:
    return {"period": loop.steps * loop.h, "delay": loop.delay_steps * loop.h}


def _pid_run(live, lab, pid, start, T) -> dict:
    """The PID of ``pid`` (a PIDLabResult) run live on ``live``'s page after the LQR, its gains and loop tunable."""
    law = CascadedPID(pid.gains, pid.params)
    shift = np.asarray(pid.x_eq, float) - np.asarray(law.model.x_eq, float)

    def measured(t, x):  # the lab's x* (as run_pid_lab measures it)
        return law(t, np.asarray(x, dtype=float) - shift)

    ptuner = PIDTuner(law, lab.A, lab.B)
    controller, rig, loop = live_loop(lab, measured)
    live.tuner = Tuners(ptuner, loop)
    run, events = _live_run(live, lab.params, controller, start, T, rig)
    return {"rollout": run, "events": events, "gains": pid.gains.to_dict() | {
        g: float(getattr(law.gains, g)) for g, _ in PID_KNOBS}, "eigenvalues": _eig_pairs(ptuner.E),
        "loop": None if loop is None else _loop_doc(loop.loop)}


def watch(plant: str | Path | None = None, *, Q=None, R=None, duration: float = 30.0, port: int = 0,
          host: str = LOCALHOST, x0=None, wait: bool = True, pid: bool = False) -> Rollout:
    """Balance a cart-pole with the lab's LQR live in the browser (MuJoCo Studio's web viewer) and return the run.

    The address is printed on stderr (``http://localhost:PORT/``; from a remote Jupyter server tunnel it:
    ``ssh -L 8080:localhost:PORT HOST``). The page shows the run at real time, plots each pole's angle, the cart and
    the ctrl against its range, and offers pushes, drags, the LQR weights, the control period and the delay; closing it
    or interrupting the kernel ends the run with the steps done.

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
    pid : bool
        Then run the lab's cascaded PID live on the same page, its gains as sliders (default False).

    Returns
    -------
    Rollout
        Every physics step; ``info["push"]`` the pushes (N, one per step), ``info["live"]`` the page's events with
        their times, the final gain and loop, and with ``pid`` the PID's run (``info["live"]["pid"]["rollout"]``,
        None when the page was closed first); each replays exactly (:func:`cartpole.sim.replays_exactly`).
    """
    lab = run_lab(plant, Q=Q, R=R)
    baseline = compare_pid(lab) if pid else None
    run, doc = watch_lab(lab, port=port, host=host, duration=duration, x0=x0, wait=wait, pid=baseline)
    run.info["live"] = doc
    return run
