"""The day-5 LQR balance lab as one function call: design K, run five initial conditions in MuJoCo, measure.

``run_lab()`` reproduces the lab handout's experiment on any MJCF the toolkit reads and the LQR stabilises: a
cart with one pole (the lab's), a chain of two or three, a pendulum with no cart, more than one motor. The exact
linearisation at upright rest (continuous ``A, B`` from the symbolic model, or ``Ad, Bd`` of one step of the
MJCF's integrator with ``discrete=True``), LQR with the default weights (:func:`~cartpole.riccati.default_weights`:
for one pole the handout's ``Q = diag(1, 10, 0.1, 0.1)``, ``R = 0.1``, :data:`Q_LAB`, :data:`R_LAB`), and five 6 s MuJoCo runs of
``u = u* - K (x - x*)`` (hinge errors wrapped, ctrl clipped to ``ctrlrange`` by MuJoCo) from the lab's five
starts, each logged every physics step so it replays exactly. The settling statistics are those of
:mod:`cartpole.validation.metrics` (the handout's definition over every pole angle, and a strict one).

The starts (:func:`lab_initial_conditions`) are the handout's cart offsets on the slide and its angles on the
*first* pole, every other joint at its upright equilibrium angle and everything at rest. When the model cannot
catch them at full size for the ctrl limit (dm_control's triple pole on its cart from 8 degrees), all five are
scaled down by one factor, :func:`lab_start_scale`: the largest of 1, 1/2, 1/4, ... (:data:`START_SCALES`) at which
the ctrl limit keeps no start from settling under the lab's own LQR (:func:`~cartpole.riccati.default_weights`, continuous)
in the lab's 6 s. Only the ctrl limit shrinks them: a start the closed loop is merely too slow to settle in the run
stays full size and is reported unsettled with the reason (:func:`why_not_settled`: the final error, the slowest
closed-loop time constant, the run its linear loop would need). The factor depends on the model only, not on the
weights or duration a run asks for, so a sweep over Q or R runs the same starts throughout; it is 1 on every
shipped asset, and :func:`run_lab` reports it as ``start_scale`` with ``start_scale_reason``.

A start whose pole angles all begin inside the handout's 0.05 rad band has the handout's settling time 0 whatever
the controller does: it is run and shown, but never counted in the mean (:attr:`LabResult.counted`).

The classical baseline beside it (``cartpole lqr --compare-pid``): :func:`compare_pid` runs the cascaded PID of
:mod:`cartpole.control.pid` (gains by :func:`~cartpole.control.pid.tune_pid`, reset before each start) from the lab's
own starts for its duration on its MJCF, measured the same way from the same ``x*`` (:class:`PIDLabResult`, with the
same statistics as :class:`LabResult`, plus ``peak_ctrl`` and ``cart_excursion`` on both). A cascade needs one pole on
an actuated cart, so on a chain it raises :class:`~cartpole.control.pid.PIDError` before anything runs.
:func:`view_first_run` shows the first start live (``--view``) and logs the run shown.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from cartpole._arrays import readonly
from cartpole.control.friction import friction_design
from cartpole.control.linear import LinearFeedback
from cartpole.control.pid import CascadedPID, tune_pid
from cartpole.errors import CartPoleError
from cartpole.export.inloop import in_loop
from cartpole.models import (CartPoleModel, CartPoleParams, Plant, friction_treatment, linearize, plant_model,
                             state_error, steps_per_period, wrap_angle)
from cartpole.progress import stage
from cartpole.riccati import ONE_POLE, default_weights
from cartpole.sim import SimOptions, simulate
from cartpole.sim.options import LoopOptions
from cartpole.sim.rig import build_rig
from cartpole.validation.estimation import estimation_summary
from cartpole.validation.metrics import (STRICT_TOLERANCE, UPRIGHT_TOL, cart_range_used, residual_error,
                                         saturation_fraction, summarize)

#: The handout's state weight ``diag(1, 10, 0.1, 0.1)`` on ``[s, theta, s_dot, theta_dot]`` (read-only): the
#: default weights of one pole (:func:`~cartpole.riccati.default_weights`).
Q_LAB = readonly(default_weights(ONE_POLE)[0])
#: The handout's input weight ``[[0.1]]`` on MuJoCo ctrl (read-only).
R_LAB = readonly(default_weights(ONE_POLE)[1])

#: The lab's deliverables, relative to the output folder (the course's file names, which the command line keeps:
#: ``cartpole lqr`` writes them under ``--out``): the figure of the five runs, the PID comparison, the estimator's
#: figure, the 10 s video and the metrics table with the row's run id and course day.
FIGURE = Path("figures") / "day5_cartpole_lqr.png"
PID_FIGURE = Path("figures") / "day5_cartpole_pid_vs_lqr.png"
ESTIMATION_FIGURE = Path("figures") / "day5_cartpole_estimation.png"
VIDEO = Path("videos") / "day5_cartpole.mp4"
METRICS = Path("metrics") / "metrics.csv"
METRICS_RUN_ID = "day5_cartpole_lqr"
METRICS_DAY = 5

#: The handout's five starts as offsets ``[cart (m), first pole angle (rad)]``: 5, -5 and 8 degrees at the centre,
#: 3 degrees with the cart at 0.2 m, -4 degrees with the cart at -0.3 m (velocities zero).
LAB_OFFSETS = np.array([
    [0.0, np.deg2rad(5.0)],
    [0.0, -np.deg2rad(5.0)],
    [0.0, np.deg2rad(8.0)],
    [0.2, np.deg2rad(3.0)],
    [-0.3, np.deg2rad(-4.0)],
])
LAB_OFFSETS.setflags(write=False)

#: The handout's five starts on its single-pole cart, ``[s (m), theta (rad), s_dot, theta_dot]`` (5, 4).
LAB_INITIAL_CONDITIONS = readonly(np.hstack([LAB_OFFSETS, np.zeros((5, 2))]))

#: Seconds each lab run lasts (the handout's ``SIM_TIME_S``).
LAB_DURATION = 6.0

#: Factors :func:`lab_start_scale` tries in turn on the five starts: the first from which all five settle under the
#: lab's own LQR is used (1 when they settle at full size, as on every shipped asset); when none does, 1.
START_SCALES = tuple(0.5 ** k for k in range(7))

#: Fraction of the room to a joint limit that a start may use (the rest is left for the transient).
_ROOM = 0.5

#: A state derivative below this (SI units) counts as rest when the cart is moved to the middle of its rail.
_REST_TOL = 1e-9


class LabError(CartPoleError):
    """The lab cannot be run on this model (e.g. its joint ranges exclude upright rest)."""


def lab_equilibrium(plant) -> np.ndarray:
    """The lab's upright rest ``x*`` (2 nq,): the model's computed equilibrium with the cart in the middle of its rail.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The model (its ``x_eq``: every pole's centre of mass above its hinge, at rest).

    Returns
    -------
    (2 nq,) read-only array
        ``model.x_eq`` with the slide at the middle of a finite rail (1 m clear of the only end of a rail limited on
        one side, 0 on an unlimited one), provided the model rests there too (a slide without a spring); for one
        pole on the shipped asset ``[0, 0, 0, 0]``.

    Raises
    ------
    LabError
        When a hinge's range excludes its upright angle.
    """
    model = plant_model(plant)
    p = model.params
    x_eq = np.array(model.x_eq, dtype=float)
    for h in model.hinges:
        lo, hi = (float(v) for v in p.joints[h].range)
        if not lo < x_eq[h] < hi:
            raise LabError(f"The range [{lo:g}, {hi:g}] rad of hinge '{p.joints[h].name}' does not contain the "
                           f"upright angle {x_eq[h]:g} rad; the lab balances the poles upright, so widen the "
                           "hinge range.")
    if model.slide is not None:
        lo, hi = (float(v) for v in p.cart_range)
        if np.isfinite(lo) and np.isfinite(hi):
            s_eq = 0.5 * (lo + hi)
        elif np.isfinite(lo):  # a rail limited on one side only: start 1 m clear of that end
            s_eq = max(0.0, lo + 1.0)
        elif np.isfinite(hi):
            s_eq = min(0.0, hi - 1.0)
        else:
            s_eq = 0.0
        moved = x_eq.copy()
        moved[model.slide] = s_eq
        if np.abs(model.dynamics(moved, model.u_eq)).max() <= _REST_TOL:
            x_eq = moved
    return readonly(x_eq)


def lab_initial_conditions(plant, *, scale: float = 1.0) -> np.ndarray:
    """The lab's five starts (5, 2 nq), placed at the model's equilibrium and scaled into its joint ranges.

    The handout's offsets (:data:`LAB_OFFSETS`) go on the cart's slide and on the *first* pole's hinge
    (``model.hinges[0]``), from ``x*`` (:func:`lab_equilibrium`); every other joint stays at its ``x*`` value, every
    rate at zero. When a cart offset uses more than half of the room to a slide limit, every cart offset is scaled
    by one factor so the largest uses exactly half; the same for the angles and the first hinge's range. So on the
    shipped MJCF (track +-1.5 m, free hinge) they are the handout's starts unchanged. A model with no cart gets
    the angles only.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    scale : float
        Factor on both offsets after the range scaling (:func:`run_lab`'s ``start_scale``; 1 = the handout's).

    Returns
    -------
    (5, 2 nq) read-only array
        One state ``[qpos, qvel]`` per row; for one pole ``[s (m), theta (rad), s_dot (m/s), theta_dot (rad/s)]``.
    """
    model = plant_model(plant)
    x_eq = lab_equilibrium(model)
    x0s = np.tile(x_eq, (len(LAB_OFFSETS), 1))
    joints = ((model.slide, LAB_OFFSETS[:, 0]), (model.hinges[0] if model.hinges else None, LAB_OFFSETS[:, 1]))
    for col, offsets in joints:
        if col is None:
            continue
        lo, hi = (float(v) for v in model.params.joints[col].range)
        room = _ROOM * min(x_eq[col] - lo, hi - x_eq[col])
        need = np.abs(offsets).max()
        x0s[:, col] += float(scale) * (offsets * (room / need) if need > room else offsets)
    return readonly(x0s)


class _LabRuns:
    """The statistics of a lab's five MuJoCo runs, shared by :class:`LabResult` (LQR) and :class:`PIDLabResult`.

    Needs the attributes ``params``, ``x_eq`` (nx,), ``rollouts`` and ``metrics`` (one RunMetrics per run).
    """

    @property
    def settling_times_seed(self) -> np.ndarray:
        """(5,) s, the handout's definition per start (every pole angle within 0.05 rad)."""
        return np.array([m.settling_time_seed for m in self.metrics])

    @property
    def settling_times(self) -> np.ndarray:
        """(5,) s, the strict whole-state definition per start (``inf`` if never)."""
        return np.array([m.settling_time_strict for m in self.metrics])

    @property
    def in_band(self) -> tuple:
        """Per start: every pole angle already within the handout's settling band (0.05 rad,
        :data:`~cartpole.validation.metrics.UPRIGHT_TOL`) of upright at t = 0 (:func:`starts_in_band`)."""
        return starts_in_band(self.x0s, self.x_eq, self.params.hinges)

    @property
    def counted(self) -> tuple:
        """Per start: whether its handout settling time counts in the mean: not :attr:`in_band` (a start inside the
        band has the settling time 0 by definition, which says nothing about the controller)."""
        return tuple(not b for b in self.in_band)

    @property
    def mean_settling_time_seed(self) -> float:
        """Mean over the :attr:`counted` starts of the handout's settling time, s (NaN when no start counts, ``inf``
        when a counted start never settled)."""
        ts = self.settling_times_seed[list(self.counted)]
        return float(np.mean(ts)) if ts.size else float("nan")

    @property
    def std_settling_time_seed(self) -> float:
        """Population standard deviation (``np.std``, as the handout) of the handout's settling time over the
        :attr:`counted` starts, s (``inf`` when one of them never settled, NaN when none counts)."""
        ts = self.settling_times_seed[list(self.counted)]
        if not ts.size:
            return float("nan")
        return float(np.std(ts)) if np.all(np.isfinite(ts)) else float("inf")

    @property
    def settled(self) -> tuple:
        """Per start: strict settling time finite and the cart never reached its limit."""
        return tuple(m.settled for m in self.metrics)

    @property
    def peak_ctrl(self) -> np.ndarray:
        """(5,) largest ``|ctrl|`` of each run over every actuator, MuJoCo ctrl units (force = gear x ctrl)."""
        return np.array([m.peak_ctrl for m in self.metrics])

    @property
    def cart_excursion(self) -> np.ndarray:
        """(5,) m, each run's largest ``|cart - x*_cart|`` (:func:`cart_excursion`); NaN without a cart."""
        return np.array([cart_excursion(r, self.x_eq, self.params.slide) for r in self.rollouts])

    @property
    def residual_error(self) -> np.ndarray:
        """(5, nx) each run's largest ``|x - x*|`` per state over its last second
        (:func:`~cartpole.validation.metrics.residual_error`): the limit cycle or offset left (m, rad, m/s, rad/s)."""
        return np.array([residual_error(r.t, r.x, self.x_eq, hinges=self.params.hinges) for r in self.rollouts])

    @property
    def steps(self) -> int:
        """Physics steps per run."""
        return int(self.rollouts[0].ctrl.shape[0])


@dataclass(frozen=True)
class LabResult(_LabRuns):
    """Everything the lab computed; arrays are read-only. ``nx = 2 nq`` states, ``nu`` inputs.

    Attributes
    ----------
    mjcf : str
        Absolute path of the MJCF run.
    params : CartPoleParams
    discrete : bool
        True when K came from ``dlqr(Ad, Bd, Q T, R T)`` over the control period ``T`` (the package's one cost
        scaling, :mod:`cartpole.riccati.algebraic`: ``S`` is then the continuous design's to first order in ``T``),
        else ``lqr(A, B, Q, R)``.
    A, B : (nx, nx), (nx, nu) arrays
        Continuous linearisation at upright rest (1/s; state derivative per unit ctrl).
    Ad, Bd : (nx, nx), (nx, nu) arrays
        One step of the MJCF's integrator there.
    Q, R : (nx, nx), (nu, nu) arrays
        LQR weights used.
    K : (nu, nx) array
        Gain, ctrl per state unit (m, rad, m/s, rad/s); the law is ``u = u* - K (x - x*)`` (python-control's sign).
    S : (nx, nx) array
        Riccati solution (cost-to-go ``e' S e``).
    E : (nx,) complex array
        Closed-loop eigenvalues of ``A - B K`` (or ``Ad - Bd K``).
    x_eq : (nx,) array
        Equilibrium ``x*`` (:func:`lab_equilibrium`).
    u_eq : (nu,) array
        Equilibrium ctrl ``u*`` (zero unless gravity has a horizontal part or a pole is built off vertical).
    x0s : (5, nx) array
        Initial conditions run.
    start_scale : float
        Factor the lab's offsets were scaled by (1 = the handout's starts; see :data:`START_SCALES`).
    duration : float, s
    rollouts : tuple of Rollout
        One MuJoCo run per start, every physics step logged.
    metrics : tuple of RunMetrics
        Per run (see :mod:`cartpole.validation.metrics`).
    period : float
        Control period in s (the ctrl held in between); K is designed on the exact discrete model over it when it
        is more than one physics step.
    rig : Rig or None
        The period, delay, sensors and estimator the runs had (:mod:`cartpole.sim.rig`); None: MuJoCo's exact
        state every physics step.
    friction_compensation : bool
        True when the MJCF's driven joints have frictionloss and the runs cancelled it
        (:func:`~cartpole.control.friction.friction_design`): A, B, K are then those of the model without it.
    start_scale_reason : str or None
        Why the starts were scaled (``start_scale < 1``): which full-size starts the ctrl limit kept from settling;
        None at full size.
    """

    mjcf: str
    params: CartPoleParams
    discrete: bool
    A: np.ndarray
    B: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    K: np.ndarray
    S: np.ndarray
    E: np.ndarray
    x_eq: np.ndarray
    u_eq: np.ndarray
    x0s: np.ndarray
    start_scale: float
    duration: float
    rollouts: tuple
    metrics: tuple
    period: float = 0.0
    rig: object = None
    friction_compensation: bool = False
    start_scale_reason: str | None = None

    @property
    def slowest_time_constant(self) -> float:
        """s: the slowest closed-loop time constant, ``1 / min |Re s|`` over the eigenvalues ``E``
        (:func:`slowest_time_constant`)."""
        return slowest_time_constant(self.E, discrete=self.discrete, period=self.period or self.params.timestep)

    @property
    def not_settled(self) -> tuple:
        """Per start: None when it settled (:attr:`settled`), else a :class:`NotSettled` saying why and by how much
        (:func:`why_not_settled`)."""
        return why_not_settled(self)

    @property
    def estimation(self) -> dict | None:
        """The JSON ``estimation`` object of the five runs (:func:`~cartpole.validation.estimation.estimation_summary`),
        None without an estimator."""
        if self.rig is None or self.rig.estimator == "none":
            return None

        return estimation_summary(self.rollouts, self.rig.estimator, self.params.hinges, state_names(self.params))

    def controller(self):
        """The lab's feedback law as a :class:`~cartpole.control.linear.LinearFeedback` (hinge errors wrapped)."""
        return LinearFeedback(self.K, self.x_eq, self.u_eq, S=self.S, hinges=self.params.hinges)


def starts_in_band(x0s, x_eq, hinges, *, band: float = UPRIGHT_TOL) -> tuple:
    """Per start: every pole angle within ``band`` of upright already at t = 0.

    Such a start's handout settling time is 0 by definition (no sample ever leaves the band), whatever the
    controller does, so the lab never counts it in its mean (:attr:`LabResult.counted`).

    Parameters
    ----------
    x0s : (k, 2 nq) array
        Starts ``[qpos, qvel]``.
    x_eq : (2 nq,) array
        Upright equilibrium.
    hinges : sequence of int
        qpos indices of the pole angles (a model without hinges has no start in the band).
    band : float, rad
        The handout's band (default 0.05 rad).

    Returns
    -------
    tuple of bool, one per start
    """
    x0s = np.atleast_2d(np.asarray(x0s, dtype=float))
    idx = list(hinges)
    if not idx:
        return tuple(False for _ in x0s)
    err = wrap_angle(x0s[:, idx] - np.asarray(x_eq, dtype=float)[idx])
    return tuple(bool(np.all(np.abs(e) <= band)) for e in err)


def slowest_time_constant(E, *, discrete: bool = False, period: float | None = None) -> float:
    """The slowest time constant in s of a closed loop with eigenvalues ``E``.

    Parameters
    ----------
    E : (nx,) complex array
        Closed-loop eigenvalues: of ``A - B K`` (1/s), or with ``discrete`` of ``Ad - Bd K`` over ``period``.
    discrete : bool
        ``E`` are discrete-time eigenvalues ``z``; each is mapped to ``s = ln(z) / period``.
    period : float, s
        The discrete step (needed with ``discrete``).

    Returns
    -------
    float, s
        ``1 / min(-Re s)``: the e-folding time of the slowest mode (``inf`` for a mode on or beyond the stability
        boundary).
    """
    E = np.asarray(E, dtype=complex).ravel()
    if discrete:
        mag = np.abs(E)
        with np.errstate(divide="ignore"):
            rates = -np.log(np.where(mag > 0, mag, np.finfo(float).tiny)) / float(period)
    else:
        rates = -E.real
    slowest = float(np.min(rates)) if rates.size else float("inf")
    return 1.0 / slowest if slowest > 0 else float("inf")


def linear_settling_time(M, e0, h: float, horizon: float, *, tol: float = STRICT_TOLERANCE,
                         samples: int = 4000) -> float:
    """When the linear closed loop ``e[k+1] = M e[k]`` enters the strict settling box for good, in s.

    The LQR's own prediction without the ctrl limit, the friction or the nonlinearity: the time the lab's strict
    settling (:func:`~cartpole.validation.metrics.settling_time_strict`) would take if MuJoCo were the linear model.

    Parameters
    ----------
    M : (nx, nx) array
        Closed-loop transition over one step ``h``: ``Ad - Bd K``.
    e0 : (nx,) array
        Start error ``x0 - x*`` (angles wrapped).
    h : float, s
        The step of ``M``.
    horizon : float, s
        How far to look.
    tol : float
        Half-width of the box on every error entry (m, rad, m/s, rad/s).
    samples : int
        At most this many instants are tested (every ``ceil(horizon / h / samples)`` steps), so the answer is
        rounded up to that stride.

    Returns
    -------
    float, s
        The first tested instant from which every later one is inside the box; ``inf`` when the last is not.
    """
    M = np.asarray(M, dtype=float)
    n = max(1, int(np.ceil(float(horizon) / float(h))))
    stride = max(1, int(np.ceil(n / samples)))
    Ms = np.linalg.matrix_power(M, stride)
    e = np.asarray(e0, dtype=float).copy()
    inside = [bool(np.all(np.abs(e) <= tol))]
    for _ in range(int(np.ceil(n / stride))):
        e = Ms @ e
        if not np.all(np.isfinite(e)):
            return float("inf")
        inside.append(bool(np.all(np.abs(e) <= tol)))
    inside = np.array(inside)
    if not inside[-1]:
        return float("inf")
    outside = np.flatnonzero(~inside)
    return float((outside[-1] + 1) * stride * h) if outside.size else 0.0


#: Why a lab start did not settle (:attr:`NotSettled.reason`): the words the prose uses for each.
NOT_SETTLED_REASONS = {
    "ctrl_limit": "the ctrl limit: the LQR asked for more than the ctrl range gives",
    "slow": "the run is too short for the closed loop's slowest mode",
    "cart_limit": "the cart reached the end of its rail",
    "diverged": "MuJoCo's simulation blew up",
    "residual": "an error that does not decay (friction, a model error, the rig's sensors or delay)",
}


@dataclass(frozen=True)
class NotSettled:
    """Why one lab start did not settle, and by how much.

    Attributes
    ----------
    reason : str
        A key of :data:`NOT_SETTLED_REASONS`: ``ctrl_limit`` (a pole fell or the cart hit its rail's end in a run
        whose ctrl sat at its limit for more than 1 % of it, or the ctrl is still at its limit in the last second),
        ``slow`` (else, when the LQR's linear closed loop itself needs longer than the run), ``cart_limit``,
        ``diverged`` or ``residual`` (an error that does not decay: friction, a model error, the rig).
    final_angle_error : float, rad
        Largest wrapped ``|theta_i - theta_i*|`` over the poles at the end of the run (0 without poles).
    final_error : float
        Largest ``|x - x*|`` entry at the end (angles wrapped; m, rad, m/s or rad/s).
    final_error_state : int
        Index into the state of that entry.
    linear_settling_time : float, s
        :func:`linear_settling_time` of this start (``inf`` beyond the horizon looked at).
    saturation_fraction : float
        Fraction of the run's steps with some ctrl at its limit.
    """

    reason: str
    final_angle_error: float
    final_error: float
    final_error_state: int
    linear_settling_time: float
    saturation_fraction: float

    def to_dict(self) -> dict:
        """The JSON object (``linear_settling_time`` null when infinite)."""
        t = self.linear_settling_time
        return {"reason": self.reason, "final_angle_error": self.final_angle_error, "final_error": self.final_error,
                "final_error_state": self.final_error_state,
                "linear_settling_time": t if np.isfinite(t) else None,
                "saturation_fraction": self.saturation_fraction}


#: Fraction of a run's steps with the ctrl at its limit above which a pole that fell is blamed on the ctrl limit (a
#: few saturated steps at the start, as every lab start on the shipped cart has, are not).
_SATURATED = 0.01

#: The last seconds of a run in which a ctrl still at its limit makes the ctrl limit the reason it has not settled.
_LATE = 1.0


def _classify(M, h: float, tau: float, x0s, x_eq, hinges, runs, mets, duration: float, ctrl_range) -> tuple:
    """:class:`NotSettled` or None per run (see :func:`why_not_settled`)."""
    x_eq = np.asarray(x_eq, dtype=float)
    hinges = tuple(hinges)
    horizon = min(max(2.0 * duration, 30.0 * tau if np.isfinite(tau) else 0.0), 1e5)
    out = []
    for x0, run, m in zip(x0s, runs, mets):
        if m.settled:
            out.append(None)
            continue
        e_end = state_error(run.x[-1], x_eq, hinges)
        angle = float(np.abs(e_end[list(hinges)]).max()) if hinges else 0.0
        k = int(np.argmax(np.abs(e_end)))
        t_lin = linear_settling_time(M, state_error(x0, x_eq, hinges), h, horizon)
        late = np.asarray(run.t[:-1]) >= float(run.t[-1]) - _LATE
        still = saturation_fraction(np.asarray(run.ctrl)[late], ctrl_range) > 0
        fell = angle > UPRIGHT_TOL or m.hit_limit
        if m.diverged:
            reason = "diverged"
        elif fell and m.saturation_fraction > _SATURATED:
            reason = "ctrl_limit"
        elif t_lin > duration:
            reason = "slow"
        elif still:
            reason = "ctrl_limit"
        elif m.hit_limit:
            reason = "cart_limit"
        else:
            reason = "residual"
        out.append(NotSettled(reason=reason, final_angle_error=angle, final_error=float(np.abs(e_end[k])),
                              final_error_state=k, linear_settling_time=t_lin,
                              saturation_fraction=float(m.saturation_fraction)))
    return tuple(out)


def why_not_settled(lab: "LabResult") -> tuple:
    """Per start of a lab run: None when it settled, else why not (:class:`NotSettled`).

    The LQR's own prediction decides between the ctrl limit and a short run: the closed loop ``Ad - Bd K`` (one
    MJCF step, or the control period's hold) run from the start without any ctrl limit
    (:func:`linear_settling_time`). A start whose pole fell (or whose cart hit the rail) while the ctrl saturated,
    or whose ctrl is still at its limit in the run's last second, failed for the ctrl limit; otherwise one the
    linear loop does not settle within the run failed because the run is too short for the slowest closed-loop
    mode (:attr:`LabResult.slowest_time_constant`): a longer run settles it (see :class:`NotSettled`).

    Parameters
    ----------
    lab : LabResult

    Returns
    -------
    tuple of NotSettled or None, one per start
    """
    h = lab.period or lab.params.timestep
    M = np.asarray(lab.Ad, dtype=float) - np.asarray(lab.Bd, dtype=float) @ np.asarray(lab.K, dtype=float)
    return _classify(M, h, lab.slowest_time_constant, lab.x0s, lab.x_eq, lab.params.hinges, lab.rollouts,
                     lab.metrics, lab.duration, lab.params.ctrl_range)


def lab_friction(model, compensated: bool) -> list:
    """What the lab's LQR design did with the MJCF's dry friction (JSON ``smoothed_friction``).

    :meth:`~cartpole.control.linear.LinearFeedback.for_model` linearises at rest without any ``frictionloss``
    (there the smooth model's slope would be a viscous damping the sticking joint does not have): every joint with friction is ``omitted``, the driven ones
    ``cancelled`` when the runs compensate them (:func:`~cartpole.control.friction.friction_design`).

    Parameters
    ----------
    model : CartPoleModel
        The model MuJoCo runs.
    compensated : bool
        :attr:`LabResult.friction_compensation`.

    Returns
    -------
    list of dict
        :func:`~cartpole.models.friction_treatment`'s entries (empty without friction).
    """
    p = model.params
    cancelled = p.driven_joints if compensated else ()
    return friction_treatment(p, width=model.friction_width, omitted=range(p.nq), cancelled=cancelled)


def state_names(params) -> list[str]:
    """One name per state entry (2 nq), MuJoCo's order: each joint's name, then ``<joint>_vel`` for each rate (the
    names of the ``--log`` CSV columns and of the JSON ``estimation`` errors)."""
    return [j.name for j in params.joints] + [f"{j.name}_vel" for j in params.joints]


def _five_runs(model, ctrl, x_eq, scale: float, duration: float, progress=None, rig=None):
    """The five lab starts at ``scale`` run in MuJoCo under ``ctrl``: ``(x0s, rollouts, metrics)``."""
    x0s = lab_initial_conditions(model, scale=scale)
    return (x0s, *_runs(model, ctrl, x0s, x_eq, duration, progress, rig=rig))


def _runs(model, ctrl, x0s, x_eq, duration: float, progress=None, reset=None, rig=None):
    """``ctrl`` run in MuJoCo from each row of ``x0s`` for ``duration`` s (``reset()`` called before each run), on
    ``rig`` (each run its own noise stream) when given: ``(rollouts, metrics)``, the metrics measured from
    ``x_eq``. ``progress`` receives the fraction of all the runs' steps done, about 20 times a run."""
    runs, mets = [], []
    n = len(x0s)
    for i, x0 in enumerate(x0s):
        if reset is not None:
            reset()
        tick = None if progress is None else (lambda f, i=i: progress((i + f) / n))
        # the one implementation: the compiled C of the export when there is a compiler (cartpole.export.inloop)
        loop_ctrl, loop_rig = in_loop(model, ctrl, None if rig is None else rig.for_run(i))
        run = simulate(model.params, loop_ctrl, x0, duration, rig=loop_rig, options=SimOptions(progress=tick))
        runs.append(run)
        mets.append(summarize(run, model, x_eq=x_eq))
        if progress is not None:
            progress((i + 1) / n)
    return runs, mets


def _lab_controller(model, Q, R, *, discrete: bool = False, steps: int = 1):
    """``(LinearFeedback, (A, B, Ad, Bd), x_eq)`` of the lab's design about :func:`lab_equilibrium`
    (:meth:`~cartpole.control.linear.LinearFeedback.for_model`: the law carries ``K``, ``S``, ``E``), with the
    linearisation it was designed on: ``Ad``, ``Bd`` over the control period of
    ``steps`` physics steps, the model without dry friction (it has no slope at rest)."""
    x_eq = lab_equilibrium(model)
    period = None if steps == 1 else steps * model.dt
    ctrl = LinearFeedback.for_model(model, Q, R, discrete=discrete, period=period, x_eq=x_eq, u_limits=None)
    smooth = model.without_friction()
    A, B = linearize(smooth, x_eq, smooth.u_eq)
    Ad, Bd = linearize(smooth, x_eq, smooth.u_eq, period=steps * model.dt)
    return ctrl, (A, B, Ad, Bd), x_eq


def _runs_label(model, duration: float, runs: int = 5) -> str:
    """The size of a set of lab runs, for its progress stage: ``"5 runs of 6 s (6000 MuJoCo steps)"``."""
    steps = runs * int(round(float(duration) / float(model.dt)))
    return f"{runs} runs of {float(duration):g} s ({steps} MuJoCo steps)"


def _search_scale(model, ctrl, res, mats, x_eq, progress=None):
    """``(scale, (x0s, runs, metrics), reason)``: the first factor of :data:`START_SCALES` at which no start fails
    for the ctrl limit under ``ctrl`` (the lab's own LQR, ``res``, with its linearisation ``mats``) in
    :data:`LAB_DURATION` s, with its runs and, below 1, the sentence saying which full-size starts the ctrl limit
    stopped; ``(1.0, full-size runs, None)`` when no factor clears the ctrl limit, or when the full-size starts fail
    for another reason only (a slow closed loop is no reason to shrink them)."""
    _, _, Ad, Bd = mats
    h = float(model.dt)
    M = np.asarray(Ad, dtype=float) - np.asarray(Bd, dtype=float) @ np.asarray(res.K, dtype=float)
    tau = slowest_time_constant(res.E)
    first = None
    for scale in START_SCALES:
        label = "lab runs" if scale == 1.0 else f"lab runs, starts x{scale:g}"
        with stage(label, size=_runs_label(model, LAB_DURATION), callback=progress) as tick:
            attempt = _five_runs(model, ctrl, x_eq, scale, LAB_DURATION, tick)
        why = _classify(M, h, tau, attempt[0], x_eq, model.hinges, attempt[1], attempt[2], LAB_DURATION,
                        model.params.ctrl_range)
        limited = [i for i, w in enumerate(why) if w is not None and w.reason == "ctrl_limit"]
        if first is None:
            first, first_why = attempt, why
        if not limited:
            if scale == START_SCALES[0]:
                return scale, attempt, None
            full = [i for i, w in enumerate(first_why) if w is not None and w.reason == "ctrl_limit"]
            sat = ", ".join(f"IC {i + 1} {100 * first_why[i].saturation_fraction:.0f} %" for i in full)
            return scale, attempt, (f"at full size the ctrl limit kept {len(full)} of the 5 starts from settling, the "
                                    f"ctrl at its limit for {sat} of the run")
    return 1.0, first, None


def lab_start_scale(plant=None) -> float:
    """The factor on the lab's five starts for this model: the largest of :data:`START_SCALES` (1, 1/2, ... 1/64)
    at which the ctrl limit keeps no start from settling under the lab's own LQR in :data:`LAB_DURATION` s.

    The lab's own LQR is ``lqr(A, B, *default_weights(model))`` at :func:`lab_equilibrium`, whatever weights a run asks
    for, so the factor is a property of the model (its masses, lengths and ctrl range). A start that does not settle
    fails for the ctrl limit when the ctrl saturated and the LQR's own linear closed loop would have settled it
    (:func:`why_not_settled`); a start the closed loop is too slow to settle in the run is no reason to shrink the
    starts (a longer run is).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None

    Returns
    -------
    float
        1.0 on every shipped asset; 1.0 too when no factor clears the ctrl limit (the lab then reports its runs
        unsettled, saying why).
    """
    return _start_scale(plant)[0]


def _start_scale(mjcf=None) -> tuple:
    """``(scale, reason)`` of :func:`lab_start_scale` (``reason`` None at full size)."""
    model = plant_model(mjcf)
    ctrl, mats, x_eq = _lab_controller(model, *default_weights(model))
    scale, _, reason = _search_scale(model, ctrl, ctrl, mats, x_eq)
    return scale, reason


def run_lab(plant: Plant = None, *, Q=None, R=None,
            discrete: bool = False, duration: float = LAB_DURATION, start_scale: float | None = None,
            progress: Callable[[float], None] | None = None, loop=None,
            plan_model: CartPoleModel | None = None) -> LabResult:
    """Run the LQR balance lab on an MJCF: a cart with any chain of poles, or anything else the LQR stabilises.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        Model to balance (default the shipped single-pole asset).
    Q : (nx, nx) array, optional
        State weights (default :func:`~cartpole.riccati.default_weights`: 1 per slide, 10 per hinge angle, 0.1 per rate;
        for one pole the lab's ``diag(1, 10, 0.1, 0.1)``, :data:`Q_LAB`).
    R : (nu, nu) array or float, optional
        ctrl weights (default 0.1 per input; the lab's :data:`R_LAB` for one).
    discrete : bool
        Design on the exact discrete model ``(Ad, Bd)`` at the MJCF's time step (``dlqr``) instead of ``(A, B)``.
    duration : float, s
        Length of each MuJoCo run (default 6 s, the handout's).
    start_scale : float, optional
        Factor on the lab's starts; default :func:`lab_start_scale` of the model (1 on every shipped asset; below 1
        only when the ctrl limit keeps full-size starts from settling).
    progress : callable, optional
        Called with the fraction of the current set of five runs done (0..1), about 20 times a run; the runs are
        also a :func:`cartpole.progress.stage` of the current reporter.
    loop : LoopOptions, optional
        The rig the runs have (:class:`~cartpole.sim.options.LoopOptions`: control period, delay, sensors,
        estimator, noise seed; its duration, when given, replaces ``duration``). K is designed for the period
        (:meth:`~cartpole.control.linear.LinearFeedback.for_model`); the starts are still :func:`lab_start_scale`'s,
        found on the perfect loop.
    plan_model : CartPoleModel, optional
        Design K (and its equilibrium) on this model while MuJoCo runs ``mjcf`` (``--plan-mjcf``: e.g. a fitted
        MJCF); the settling metrics are measured from ``mjcf``'s own upright. Default: design on ``mjcf``.

    Returns
    -------
    LabResult

    Raises
    ------
    MJCFError, LQRError, LabError
        Bad MJCF, weights, or a model the lab cannot balance.
    """
    plant = plant_model(plant)
    params = plant.params
    if loop is not None and loop.duration is not None:
        duration = loop.duration
    # the controller's knowledge: the planning model (the MJCF's own unless given), and from it the model the LQR
    # is designed on, without the friction a compensation cancels; MuJoCo always runs the MJCF
    known = plant if plan_model is None else plan_model
    friction = friction_design(known, loop)
    rig = build_rig(known, loop, task="balance")
    model = plant
    steps = steps_per_period(None if loop is None else loop.period, model.dt)
    Q0, R0 = default_weights(model)
    # the design and loop lab_start_scale uses
    own = (Q is None and R is None and not discrete and duration == LAB_DURATION and rig is None
           and plan_model is None and not friction.compensated)
    Q = Q0 if Q is None else Q
    R = R0 if R is None else R
    ctrl, (A, B, Ad, Bd), x_eq = _lab_controller(friction.model, Q, R, discrete=discrete, steps=steps)
    res = ctrl  # K, S, E of the design
    ctrl = friction.wrap(ctrl)
    reason = None
    if start_scale is None and own:  # the scale search's runs are this lab's runs
        scale, (x0s, runs, mets), reason = _search_scale(model, ctrl, res, (A, B, Ad, Bd), x_eq, progress)
    else:
        scale, reason = _start_scale(model) if start_scale is None else (float(start_scale), None)
        x_true = x_eq if plan_model is None else readonly(lab_equilibrium(model))
        with stage("lab runs", size=_runs_label(model, duration), callback=progress) as tick:
            x0s, runs, mets = _five_runs(model, ctrl, x_true, scale, duration, tick, rig=rig)
    return LabResult(mjcf=params.mjcf, params=params, discrete=bool(discrete) or steps > 1, A=readonly(A), B=readonly(B),
                     Ad=readonly(Ad), Bd=readonly(Bd), Q=readonly(np.atleast_2d(Q)), R=readonly(np.atleast_2d(R)),
                     K=readonly(res.K), S=readonly(res.S), E=readonly(res.E, complex), x_eq=x_eq,
                     u_eq=readonly(model.u_eq), x0s=x0s, start_scale=float(scale), duration=float(duration),
                     rollouts=tuple(runs), metrics=tuple(mets), period=float(steps * model.dt), rig=rig,
                     friction_compensation=friction.compensated, start_scale_reason=reason)


def cart_excursion(run, x_eq, slide: int | None) -> float:
    """Largest distance in m of the cart from its equilibrium position over a run: ``max_k |s_k - x*_slide|``.

    Parameters
    ----------
    run : Rollout
        ``qpos`` (n+1, nq) is read.
    x_eq : (2 nq,) array
        Equilibrium ``x*`` (:func:`lab_equilibrium`).
    slide : int or None
        qpos index of the cart's slide; None (no cart) gives NaN.
    """
    if slide is None:
        return float("nan")
    lo, hi = cart_range_used(run, slide=slide)
    s_eq = float(np.asarray(x_eq, dtype=float)[slide])
    return max(abs(lo - s_eq), abs(hi - s_eq))


@dataclass(frozen=True)
class PIDLabResult(_LabRuns):
    """The cascaded PID baseline (:mod:`cartpole.control.pid`) run from the lab's starts; arrays are read-only.

    The same statistics as :class:`LabResult` (``settling_times_seed``, ``settling_times``,
    ``mean_settling_time_seed``, ``std_settling_time_seed``, ``settled``, ``peak_ctrl``, ``cart_excursion``), measured
    the same way from ``x_eq``.

    Attributes
    ----------
    mjcf : str
        Absolute path of the MJCF run.
    params : CartPoleParams
    gains : PIDGains
        From :func:`~cartpole.control.pid.tune_pid` (pole placement on the exact linearisation).
    x_eq : (4,) array
        The lab's equilibrium (:func:`lab_equilibrium`) the PID regulates to and the metrics measure from.
    x0s : (5, 4) array
        Starts run (the LQR lab's, for :func:`compare_pid`).
    duration : float, s
        Length of each run.
    rollouts : tuple of Rollout
        One MuJoCo run per start, every physics step logged (replays exactly); the PID is reset before each.
    metrics : tuple of RunMetrics
        Per run (:func:`cartpole.validation.metrics.summarize` from ``x_eq``).
    """

    mjcf: str
    params: CartPoleParams
    gains: object
    x_eq: np.ndarray
    x0s: np.ndarray
    duration: float
    rollouts: tuple
    metrics: tuple


def run_pid_lab(plant: Plant = None, *, x0s=None,
                duration: float = LAB_DURATION, start_scale: float | None = None,
                progress: Callable[[float], None] | None = None, rig=None, **tuning) -> PIDLabResult:
    """The lab's experiment with the cascaded PID instead of the LQR: one MuJoCo run per start.

    The PID is :class:`~cartpole.control.pid.CascadedPID` with gains from
    :func:`~cartpole.control.pid.tune_pid` (``tuning`` = its keyword settings), reset before each start. It
    regulates to the lab's equilibrium :func:`lab_equilibrium` (the model's ``x_eq`` with the cart in the middle of
    its rail: the state it sees is shifted along the rail by the difference, which changes nothing else since the
    cart has no spring).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        One pole on a cart driven by one motor on the slide (default the shipped asset).
    x0s : (k, 4) array, optional
        Starts ``[s, theta, s_dot, theta_dot]`` (default :func:`lab_initial_conditions` at ``start_scale``).
    duration : float, s
        Length of each run (default the lab's 6 s).
    start_scale : float, optional
        Factor on the lab's starts when ``x0s`` is not given; default :func:`lab_start_scale`.
    progress : callable, optional
        Called with the fraction of the runs done (0..1).
    rig : Rig, optional
        The period, delay, sensors and estimator of the runs (:mod:`cartpole.sim.rig`; the PID acts on the
        estimate and is tuned for the period); default MuJoCo's exact state every physics step.

    Returns
    -------
    PIDLabResult

    Raises
    ------
    PIDError
        A model where a cascade does not apply (not exactly one pole on an actuated cart: one sentence, before
        anything runs), bad tuning settings, or a tuned loop that is not stable.
    """
    model = plant_model(plant)
    if rig is not None:  # designed for the rig's period (the PID reads the rig's estimate, as the LQR does)
        tuning = {"period": rig.period, **tuning}
    gains = tune_pid(model, **tuning)
    x_eq = lab_equilibrium(model)
    if x0s is None:
        scale = lab_start_scale(model) if start_scale is None else float(start_scale)
        x0s = lab_initial_conditions(model, scale=scale)
    x0s = readonly(np.atleast_2d(np.asarray(x0s, dtype=float)))
    pid = CascadedPID(gains, model)
    shift = x_eq - np.asarray(model.x_eq, dtype=float)
    controller = pid if not np.any(shift) else (lambda t, x: pid(t, np.asarray(x, dtype=float) - shift))
    runs, mets = _runs(model, controller, x0s, x_eq, duration, progress, reset=pid.reset, rig=rig)
    return PIDLabResult(mjcf=model.params.mjcf, params=model.params, gains=gains, x_eq=x_eq, x0s=x0s,
                        duration=float(duration), rollouts=tuple(runs), metrics=tuple(mets))


def compare_pid(lab: LabResult, model: CartPoleModel | None = None, *,
                progress: Callable[[float], None] | None = None, **tuning) -> PIDLabResult:
    """The PID baseline beside an LQR lab: :func:`run_pid_lab` from the lab's own starts, for its duration, on its
    MJCF (same physics), measured from the same ``x*``.

    Parameters
    ----------
    lab : LabResult
        From :func:`run_lab`.
    model : CartPoleModel, optional
        The lab's model, if already built (else built from ``lab.params``).
    progress : callable, optional
        Called with the fraction of the five runs done.

    Raises
    ------
    PIDError
        As :func:`run_pid_lab`, e.g. on a two- or three-pole cart.
    """
    return run_pid_lab(lab.params if model is None else model, x0s=lab.x0s, duration=lab.duration,
                       progress=progress, rig=lab.rig, **tuning)


def view_first_run(lab: LabResult, watcher: Callable) -> tuple[LabResult, object]:
    """Show the lab's first start live and log the run shown: ``(lab with rollouts[0] the shown run, shown)``.

    ``watcher`` is :func:`cartpole.viz.viewer.watch` (or anything with :func:`~cartpole.sim.simulate`'s call shape
    ``watcher(source, controller, x0, duration) -> Rollout``); it runs the lab's LQR law from ``lab.x0s[0]`` for
    ``lab.duration`` with simulate's physics, as the logged run ran it (the compiled C of
    :func:`~cartpole.export.inloop.in_loop` when there is a compiler), so its rollout must equal the logged
    ``lab.rollouts[0]`` step for step, and this is checked. The shown rollout then replaces the logged one (the same
    numbers, so every metric stands).
    When the window was closed early the shown run is the first part of the logged one (checked the same way) and
    the full logged run is kept.

    Raises
    ------
    ViewerUnavailable
        From ``watcher``, when there is no display (raised before any physics runs; ``lab`` is untouched).
    LabError
        The shown run differs from the logged one (it cannot, unless MuJoCo is not deterministic here).
    """
    logged = lab.rollouts[0]
    law = lab.controller()
    if lab.rig is None:
        # the law the logged run ran: the one compiled implementation when there is a compiler (as in _runs); the
        # Python class and the C agree only to round-off, which is not the same run on every CPU
        law, _ = in_loop(plant_model(lab.params), law)
    shown = watcher(lab.params, law, lab.x0s[0], lab.duration)
    n = shown.ctrl.shape[0]
    if n > logged.ctrl.shape[0] or not (np.array_equal(shown.x, logged.x[:n + 1])
                                        and np.array_equal(shown.ctrl, logged.ctrl[:n])):
        raise LabError("The run shown in the live viewer differs from the logged run of the first start; MuJoCo "
                       "is not deterministic here, so report this with your MuJoCo version.")
    if n < logged.ctrl.shape[0]:
        return lab, shown
    return replace(lab, rollouts=(shown,) + tuple(lab.rollouts[1:])), shown


def balances(result) -> bool:
    """Every start of a lab run (:class:`LabResult` or :class:`PIDLabResult`) balanced: the handout's settling time
    finite (every pole angle within 0.05 rad of upright for good), the cart never at its limit, no divergence."""
    return all(np.isfinite(m.settling_time_seed) and not m.hit_limit and not m.diverged for m in result.metrics)


def delay_margin(plant=None, *, loop=None, max_delay: float = 0.1, pid: bool = False, progress=None) -> dict:
    """The largest delay (whole physics steps) at which the lab's controller still balances all five starts.

    The delays ``0, h, 2h, ...`` up to ``max_delay`` are tried in turn on the rig ``loop`` (its ``delay`` replaced)
    until one fails (:func:`balances`); the margin is the last that held (:func:`rig_margin`).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    loop : LoopOptions, optional
        The rig (period, sensors, estimator, delay compensation); default the perfect loop.
    max_delay : float
        Largest delay tried, s.
    pid : bool
        Also the cascaded PID's margin (one pole on a cart).
    progress : callable, optional
        Called with the fraction of the delays tried (0..1).

    Returns
    -------
    dict
        :func:`rig_margin`'s, with the setting ``delay`` (s).
    """
    model = plant_model(plant)  # built once, for the step and for every run of the search
    h = float(model.dt)
    delays = [k * h for k in range(int(np.floor(max_delay / h + 1e-9)) + 1)]
    return rig_margin(model, loop=loop, setting="delay", values=delays, pid=pid, progress=progress)


#: Sensor noise levels :func:`noise_margin` tries below its largest, as fractions of it (0 and halvings).
NOISE_FRACTIONS = (0.0,) + tuple(2.0 ** -k for k in range(9, -1, -1))


def noise_margin(plant=None, *, loop=None, max_noise: float = 0.05, pid: bool = False, progress=None) -> dict:
    """The largest sensor noise (standard deviation, each sensor's units) at which the lab's controller still
    balances all five starts on the rig ``loop``: 0 and ``max_noise`` halved nine times to ``max_noise`` in turn
    (:data:`NOISE_FRACTIONS`), until one fails (:func:`rig_margin`, setting ``sensor_noise``).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    loop : LoopOptions, optional
        The rig; it needs an estimator (default ``kf`` once a sensor option is given) and usually encoders.
    max_noise : float
        Largest noise tried (m on slides, rad on hinges), > 0.
    pid : bool
        Also the cascaded PID's (on the measurements).
    progress : callable, optional

    Returns
    -------
    dict
        :func:`rig_margin`'s, with the setting ``sensor_noise``.
    """
    values = [float(max_noise) * f for f in NOISE_FRACTIONS]
    return rig_margin(plant, loop=loop, setting="sensor_noise", values=values, pid=pid, progress=progress)


def rig_margin(plant=None, *, loop=None, setting: str, values, pid: bool = False, progress=None) -> dict:
    """The largest value of one rig setting at which the lab's controller still balances all five starts.

    The ``values`` are tried in increasing order on the rig ``loop`` (``setting`` replaced by each) until one fails
    (:func:`balances`); the margin is the last that held.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    loop : LoopOptions, optional
        The rig; default the perfect loop.
    setting : str
        A :class:`~cartpole.sim.options.LoopOptions` field (``delay``, ``sensor_noise``, ...).
    values : sequence of float
        Increasing values of it, in its units.
    pid : bool
        Also the cascaded PID's margin (one pole on a cart).
    progress : callable, optional
        Called with the fraction of the values tried (0..1).

    Returns
    -------
    dict
        ``lqr`` (the margin; None when the first value already fails), ``lqr_first_failure`` (None when none
        fails), ``lqr_runs`` (per value tried: ``setting`` -> the value, ``balances``, ``settling_time_seed_max`` (s,
        the worst start's handout settling time; None when one never settles) and ``residual_angle_max`` (rad, the
        largest pole error over any run's last second)), with ``pid`` the same for the PID; ``setting`` and
        ``tried`` (the values tried).
    """
    model = plant_model(plant)
    loop = LoopOptions() if loop is None else loop
    values = [float(v) for v in values]
    out, tried = {"setting": setting}, set()
    for name in ("lqr", "pid") if pid else ("lqr",):
        margin = failed = None
        curve = []
        for i, v in enumerate(values):
            run = run_lab(model, loop=loop.replace(**{setting: v}))
            res = run if name == "lqr" else compare_pid(run, model)
            ok = balances(res)
            ts = [float(m.settling_time_seed) for m in res.metrics]
            curve.append({setting: v, "balances": bool(ok),
                          "settling_time_seed_max": max(ts) if all(np.isfinite(ts)) else None,
                          "residual_angle_max": float(res.residual_error[:, list(res.params.hinges)].max())})
            tried.add(v)
            if progress is not None:
                progress((i + 1) / len(values))
            if not ok:
                failed = v
                break
            margin = v
        out[name], out[f"{name}_first_failure"] = margin, failed
        out[f"{name}_runs"] = curve
    out["tried"] = sorted(tried)
    return out
