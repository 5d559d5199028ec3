"""``cartpole lqr --margins``: the loops of the lab's linear designs on a rig, broken at the plant input, and their
margins (:mod:`cartpole.analysis`); and the same margins measured in MuJoCo (a delay and a loop gain at the ctrl).

Designs, keyed as the JSON ``margins`` object keys them:

* ``lqr``: the lab's LQR as the rig runs it on the true state (its period, its delay, predicted over when the rig
  compensates), the exact discrete model of the MJCF's integrator;
* ``lqr_continuous``: the same gain on the continuous linearisation, the textbook loop whose margins LQR guarantees
  (only for a gain designed continuous, at one physics step);
* ``lqg``: with ``estimator="kf"``, the LQR on the Kalman filter's estimate from the rig's sensors;
* ``pid``: with ``pid=True``, the cascaded PID on the state at the rig's period and delay (one pole on a cart).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cartpole.analysis import (AnalysisError, Loop, Margins, closed_loop_stable, continuous_loop, ctrl_noise_std,
                               loop_margins, pid_loop, sampled_loop, state_noise_std)
from cartpole.apps.lab import lab_equilibrium
from cartpole.control.linear import LinearFeedback
from cartpole.control.pid import CascadedPID
from cartpole.models import steps_per_period
from cartpole.riccati import default_weights
from cartpole.sim import simulate
from cartpole.sim.options import LoopOptions
from cartpole.sim.rig import build_rig, delay_steps, estimator_factory

#: Designs with no linear loop to break, and why (for the refusal's sentence).
NONLINEAR = {"energy": "energy shaping is a nonlinear law (its ctrl follows the pole's energy, not a linear map of "
                       "the state)",
             "mpc": "NMPC re-plans a nonlinear program every period, which is no fixed linear map of the state",
             "ekf": "the EKF relinearises at its estimate every period",
             "mhe": "the moving-horizon estimator solves a nonlinear program every period"}


def refuse_nonlinear(design: str) -> None:
    """Raise the :class:`~cartpole.analysis.AnalysisError` sentence for a design without a linear loop.

    Parameters
    ----------
    design : str
        A key of :data:`NONLINEAR` (``energy``, ``mpc``, ``ekf``, ``mhe``).
    """
    why = NONLINEAR.get(design, f"'{design}' is not a linear design")
    raise AnalysisError(f"Margins are read on a linear loop and {why}; ask for the margins of the LQR "
                        "(`lab_margins`, with `estimator='kf'` for LQG) or of the PID (`pid=True`).")


@dataclass(frozen=True)
class LabMargins:
    """The loops and margins of the lab's designs on one rig.

    Attributes
    ----------
    loops : dict
        Design key -> :class:`~cartpole.analysis.Loop`.
    margins : dict
        Design key -> :class:`~cartpole.analysis.Margins`.
    K : (nu, nx) array
        The LQR gain the loops close.
    steps, delay_steps : int
        Physics steps per period and of delay.
    ctrl_noise : dict
        Design key -> (nu,) predicted standard deviation of the ctrl that the sensors' noise causes
        (:func:`~cartpole.analysis.ctrl_noise_std`; ctrl units), for the designs that read sensors.
    ctrl_span : (nu,) array
        Width of each ctrl range (ctrl units), for the fractions.
    """

    loops: dict
    margins: dict
    K: np.ndarray
    steps: int
    delay_steps: int
    ctrl_noise: dict = field(default_factory=dict)
    ctrl_span: np.ndarray | None = None

    def to_dict(self) -> dict:
        """JSON ``margins``: design key -> :meth:`~cartpole.analysis.Margins.to_dict`, with ``ctrl_noise_std`` (per
        input, ctrl units) and ``ctrl_noise_fraction`` (of the ctrl range's width) for a design that reads
        sensors."""
        out = {k: m.to_dict() for k, m in self.margins.items()}
        for k, std in self.ctrl_noise.items():
            out[k]["ctrl_noise_std"] = [float(v) for v in std]
            out[k]["ctrl_noise_fraction"] = [float(v) for v in np.asarray(std) / self.ctrl_span]
        return out


def lab_margins(model, *, Q=None, R=None, discrete: bool = False, loop=None, pid: bool = False) -> LabMargins:
    """The margins of the lab's LQR (and LQG, PID) on the rig ``loop``.

    Parameters
    ----------
    model : CartPoleModel
    Q, R : arrays, optional
        LQR weights (default :func:`~cartpole.riccati.default_weights`).
    discrete : bool
        Design with dlqr at the physics step (as ``cartpole lqr --discrete``).
    loop : LoopOptions, optional
        The rig: ``period``, ``delay``, ``delay_compensation``, the estimator (``kf`` adds ``lqg``) and sensors.
    pid : bool
        Add the cascaded PID's loop.

    Returns
    -------
    LabMargins

    Raises
    ------
    AnalysisError
        An estimator with no linear loop (``ekf``, ``mhe``).
    """
    loop = LoopOptions() if loop is None else loop
    h = float(model.dt)
    m = steps_per_period(loop.period, h)
    d = delay_steps(loop.delay, h)
    Q0, R0 = default_weights(model)
    Q = Q0 if Q is None else Q
    R = R0 if R is None else R
    x_eq = lab_equilibrium(model)
    K = LinearFeedback.for_model(model, Q, R, discrete=discrete, period=m * h, x_eq=x_eq).K
    comp = bool(loop.delay_compensation)
    loops = {"lqr": sampled_loop(model, K, steps=m, delay_steps=d, compensate=comp, x=x_eq)}
    if m == 1 and not discrete:
        loops["lqr_continuous"] = continuous_loop(model, K, x=x_eq, name="lqr_continuous")
    estimator = loop.estimator_for("balance")
    if estimator in ("ekf", "mhe"):
        refuse_nonlinear(estimator)
    noise = {}
    if estimator == "kf":
        spec, make = estimator_factory(model, loop, "kf", m)
        loops["lqg"] = sampled_loop(model, K, steps=m, delay_steps=d, compensate=comp, kalman=make(), x=x_eq)
        noise["lqg"] = ctrl_noise_std(loops["lqg"], spec.measurement_covariance())
    if pid:
        loops["pid"] = pid_loop(model, CascadedPID.for_model(model).gains, steps=m, delay_steps=d,
                                compensate=comp)
    return LabMargins(loops, {k: loop_margins(v) for k, v in loops.items()}, K, m, d, noise,
                      model.u_high - model.u_low)


def whole_step_delay_margin(build, start: int, limit: int) -> int | None:
    """The largest total delay (physics steps, from ``start``) at which the loop ``build(delay_steps)`` is still
    stable, trying ``start, start + 1, ..`` up to ``limit``: what ``cartpole lqr --delay-margin`` searches in MuJoCo,
    on the linear loop.

    Parameters
    ----------
    build : callable
        ``delay_steps -> Loop``.
    start, limit : int
        First and last delay tried, physics steps.

    Returns
    -------
    int or None
        None when ``start`` is already unstable; ``limit`` when every delay tried is stable.
    """
    last = None
    for dly in range(int(start), int(limit) + 1):
        if not closed_loop_stable(build(dly).L):
            return last
        last = dly
    return last


class _Scaled:
    """A controller whose ctrl deviation from ``u_eq`` is scaled by ``k``: a gain ``k`` at the plant input."""

    def __init__(self, inner, k: float, u_eq):
        self.inner, self.k, self.u_eq = inner, float(k), np.asarray(u_eq, float)

    def __call__(self, t, x):
        return self.u_eq + self.k * (np.asarray(self.inner(t, x), float) - self.u_eq)


def mujoco_stable(model, K=None, k: float = 1.0, *, controller=None, loop=None, x_eq=None, tilt: float = 1e-3,
                  duration: float = 6.0, window: float = 1.5) -> bool:
    """Whether MuJoCo's loop is stable with the controller's ctrl deviation scaled by ``k`` (a gain ``k`` at the
    plant input: ``u = u* + k (c(t, x) - u*)``) on the rig ``loop`` (default the physics step, no delay), from a
    tilt of ``tilt`` rad on every hinge.

    This is the margin's own question asked of MuJoCo, stricter than the lab's "balances" (every pole within 0.05
    rad for good, :func:`cartpole.apps.lab.balances`): past its delay margin the lab's LQR grows into a limit cycle
    with the ctrl chattering between its limits while the pole stays within a few degrees, which the lab counts as
    balanced. Stable means: no divergence, the ctrl off its limits over the last ``window`` s (a loop that is
    unstable at the linear level grows until the ctrl saturates) and, on a rig without sensors, the largest state
    error over the last ``window`` s below the largest over the window ending 3 s earlier (it decays; with encoders
    their quantisation and the joints' dry friction leave a small limit cycle that does not, so only the ctrl
    limit decides there).

    Parameters
    ----------
    model : CartPoleModel
    K : (nu, nx) array, optional
        The gain of a state feedback ``u = u* - K (x - x*)`` (when ``controller`` is not given).
    k : float
        Loop gain at the plant input.
    controller : callable, optional
        ``u = c(t, x)`` instead of the state feedback (a fresh one per call: it may keep state).
    loop : LoopOptions, optional
        The rig (period, delay, its compensation, sensors, estimator).
    x_eq : (nx,) array, optional
        Upright (default the lab's equilibrium).
    tilt : float
        Initial hinge error, rad (small: the loop is read linear).
    duration : float
        Run length, s (at least ``window + 3``).
    window : float
        Length of the two windows compared, s (longer than the slowest oscillation near the margin).

    Returns
    -------
    bool
    """
    x_eq = lab_equilibrium(model) if x_eq is None else np.asarray(x_eq, float)
    x0 = np.array(x_eq, dtype=float)
    x0[list(model.hinges)] += tilt
    if controller is None:
        controller = LinearFeedback(np.asarray(K, float), x_eq, model.u_eq, hinges=model.hinges)
    rig = build_rig(model, loop)
    run = simulate(model.params, _Scaled(controller, k, model.u_eq) if k != 1.0 else controller, x0, duration,
                   rig=rig)
    if isinstance(run.info, dict) and run.info.get("diverged") is not None:
        return False
    err = np.abs(model.state_error(run.x, x_eq)).max(axis=1)
    t_end = float(run.t[-1])
    late = run.t >= t_end - window
    early = (run.t >= t_end - window - 3.0) & (run.t < t_end - 3.0)
    u = run.ctrl[late[1:]]
    pinned = np.any(np.isclose(u, model.u_low) | np.isclose(u, model.u_high))
    decays = err[late].max() < err[early].max() if (rig is None or rig.spec is None) else True
    return bool(np.all(np.isfinite(err)) and not pinned and decays)


def _bisect(stable, good: float, bad: float, rel: float) -> float:
    """The boundary between a stable gain ``good`` and an unstable ``bad``, to ``rel`` relative (geometric
    bisection); returns the last stable gain."""
    while abs(np.log(bad / good)) > np.log1p(rel):
        mid = float(np.sqrt(good * bad))
        if stable(mid):
            good = mid
        else:
            bad = mid
    return good


def _true_state_rig(loop):
    """The rig ``loop`` with the controller reading MuJoCo's state (period, delay and its compensation kept)."""
    return LoopOptions(period=loop.period, delay=loop.delay, delay_compensation=loop.delay_compensation)


def mujoco_margins(model, found: LabMargins, *, loop=None, rel: float = 0.01, max_delay_steps: int = 40,
                   tilt: float = 1e-3, designs=None) -> dict:
    """The margins of the lab's designs measured in MuJoCo (:func:`mujoco_stable`) beside their loops' predictions.

    Per design of ``found`` (not ``lqr_continuous``): the largest total delay in whole physics steps from the rig's
    own at which MuJoCo stays stable (the rig's delay compensation kept), with the whole steps the sampled loop
    tolerates; for the designs on the true state (``lqr``, ``pid``) also the gain band, each end bisected to ``rel``
    from a bracket at half (low) or twice (high) the predicted end (a gain at the plant input of the LQG would
    also reach its estimator, which takes the ctrl MuJoCo applied: no plant-input gain there).

    Parameters
    ----------
    model : CartPoleModel
    found : LabMargins
        :func:`lab_margins` on the rig ``loop``.
    loop : LoopOptions, optional
        The rig (default the perfect loop).
    rel : float
        Relative resolution of the gain bisection.
    max_delay_steps : int
        Longest delay tried, physics steps.
    tilt : float
        Initial hinge error, rad (with encoders take it well above their resolution).
    designs : sequence of str, optional
        Which of ``found``'s designs (default all but ``lqr_continuous``).

    Returns
    -------
    dict
        Design key -> ``delay_margin_s`` (s, measured; None when the rig's own delay already fails),
        ``delay_margin_predicted_s`` (whole physics steps of the sampled loop, s), ``delay_margin_phase_s`` (phase
        margin over crossover plus the rig's delay, s), for ``lqr`` / ``pid`` ``gain_margin`` [low, high]
        measured and ``gain_margin_predicted`` (null where unbounded), for a design that reads sensors
        ``ctrl_noise_std`` (:func:`mujoco_ctrl_noise`) and ``ctrl_noise_std_predicted`` (ctrl units); ``rel``.
    """
    loop = LoopOptions() if loop is None else loop
    h, K, m, d0 = float(model.dt), found.K, found.steps, found.delay_steps
    x_eq = lab_equilibrium(model)
    comp = bool(loop.delay_compensation)
    make_kf = None
    if "lqg" in found.loops:
        make_kf = estimator_factory(model, loop, "kf", m)[1]
    runs = {"lqr": (lambda: LinearFeedback(K, x_eq, model.u_eq, hinges=model.hinges), _true_state_rig(loop)),
            "lqg": (lambda: LinearFeedback(K, x_eq, model.u_eq, hinges=model.hinges), loop),
            "pid": (lambda: CascadedPID.for_model(model), _true_state_rig(loop))}
    builds = {"lqr": lambda d: sampled_loop(model, K, steps=m, delay_steps=d, compensate=comp, x=x_eq),
              "lqg": lambda d: sampled_loop(model, K, steps=m, delay_steps=d, compensate=comp, kalman=make_kf(),
                                            x=x_eq),
              "pid": lambda d: pid_loop(model, CascadedPID.for_model(model).gains, steps=m, delay_steps=d,
                                        compensate=comp)}
    out = {}
    for key in designs or [k for k in found.loops if k != "lqr_continuous"]:
        make, rig = runs[key]

        def stable(k=1.0, delay=None, make=make, rig=rig):
            r = rig if delay is None else rig.replace(delay=delay)
            return mujoco_stable(model, controller=make(), k=k, loop=r, x_eq=x_eq, tilt=tilt)

        measured = None
        for dly in range(d0, d0 + max_delay_steps + 1):
            if not stable(delay=dly * h):
                break
            measured = dly
        predicted = whole_step_delay_margin(builds[key], d0, d0 + max_delay_steps)
        mg = found.margins[key]
        row = {"delay_margin_s": None if measured is None else measured * h,
               "delay_margin_predicted_s": None if predicted is None else predicted * h,
               "delay_margin_phase_s": float(found.delay_steps * h + mg.delay_margin_s)}
        if key in ("lqr", "pid"):
            low, high = (float(v) for v in mg.gain_margin)
            lo = _bisect(stable, 1.0, 0.5 * low, rel) if not stable(0.5 * low) else 0.5 * low
            hi = None
            if np.isfinite(high):
                hi = _bisect(stable, 1.0, 2.0 * high, rel) if not stable(2.0 * high) else 2.0 * high
            row.update(gain_margin=[lo, hi], gain_margin_predicted=[low, high if np.isfinite(high) else None])
        if key in found.ctrl_noise:
            row["ctrl_noise_std"] = [float(v) for v in mujoco_ctrl_noise(model, make(), loop, x_eq=x_eq)]
            row["ctrl_noise_std_predicted"] = [float(v) for v in found.ctrl_noise[key]]
        out[key] = row
    out["rel"] = float(rel)
    return out


def loops_and_margins(found: LabMargins) -> list[tuple[Loop, Margins]]:
    """``(Loop, Margins)`` pairs in the report's order (for figures and tables)."""
    return [(found.loops[k], found.margins[k]) for k in found.loops]


def mujoco_ctrl_noise(model, controller, loop, *, x_eq=None, tilt: float = 0.01, duration: float = 10.0,
                      last: float = 4.0) -> np.ndarray:
    """The standard deviation of each ctrl over the last ``last`` s of a MuJoCo run on the rig ``loop`` (sensors,
    estimator) holding upright from a tilt of ``tilt`` rad: what the sensors' noise and quantisation do to the ctrl.

    Parameters
    ----------
    model : CartPoleModel
    controller : callable
        ``u = c(t, x)``.
    loop : LoopOptions
        The rig.
    x_eq : (nx,) array, optional
        Upright (default the lab's equilibrium).
    tilt : float
        Initial hinge error, rad.
    duration : float
        Run length, s.
    last : float
        The window measured, s (the start's transient has died out before it).

    Returns
    -------
    (nu,) array
        ctrl units.
    """
    x_eq = lab_equilibrium(model) if x_eq is None else np.asarray(x_eq, float)
    x0 = np.array(x_eq, dtype=float)
    x0[list(model.hinges)] += tilt
    run = simulate(model.params, controller, x0, duration, rig=build_rig(model, loop))
    u = run.ctrl[run.t[1:] > run.t[-1] - last]
    return u.std(axis=0)


#: Largest factor :func:`noise_limited_R` multiplies ``R`` by (2^30) before it gives up.
MAX_R_DOUBLINGS = 30


def noise_limited_R(model, Q, R, loop, fraction: float, *, discrete: bool = False) -> dict:
    """The lab's LQR weight ``R`` scaled up (doubled until it holds) so that the ctrl noise the rig's sensors cause
    through the LQG loop stays below ``fraction`` of the ctrl range's width: a design that respects its sensors.

    The prediction is :func:`~cartpole.analysis.ctrl_noise_std` on the loop of the gain with the rig's Kalman filter
    at upright (the linear stand-in for an EKF or MHE there), the sensors' covariance including their quantisation.

    Parameters
    ----------
    model : CartPoleModel
    Q : (nx, nx) array or None
        State weights (default :func:`~cartpole.riccati.default_weights`).
    R : (nu, nu) array, float or None
        ctrl weights to start from (default the lab's).
    loop : LoopOptions
        The rig: period, delay, sensors (an estimator and encoders or sensor noise).
    fraction : float
        Largest ctrl standard deviation from noise, as a fraction of the ctrl range's width, in (0, 1).
    discrete : bool
        As :func:`lab_margins`.

    Returns
    -------
    dict
        ``R`` (nu, nu) the weight found, ``factor`` (on the starting ``R``), ``fraction`` (asked),
        ``predicted_std`` (nu,) and ``predicted_fraction`` (nu,) at that ``R`` (ctrl units, and of the range).

    Raises
    ------
    AnalysisError
        A fraction outside (0, 1), a rig without sensors (no noise reaches the ctrl), or no ``R`` up to
        2^:data:`MAX_R_DOUBLINGS` times the start that is quiet enough.
    """
    f = float(fraction)
    if not (math.isfinite(f) and 0 < f < 1):
        raise AnalysisError(f"The ctrl noise fraction {fraction!r} is not between 0 and 1; give e.g. "
                            "`ctrl_noise=0.1` (a tenth of the ctrl range).")
    if loop is None or not loop.sensed or loop.estimator_for("balance") == "none":
        raise AnalysisError("A ctrl noise limit needs sensors: with MuJoCo's exact state no noise reaches the ctrl; "
                            "give an estimator and encoders (e.g. `estimator='kf'` `encoder_cpr=2048`).")
    Q0, R0 = default_weights(model)
    Q = Q0 if Q is None else np.asarray(Q, float)
    R = np.atleast_2d(np.asarray(R0 if R is None else R, float))
    R = R * np.eye(model.nu) if R.shape == (1, 1) and model.nu > 1 else R
    m = steps_per_period(loop.period, float(model.dt))
    x_eq = lab_equilibrium(model)
    found, _ = _noise_search(model, loop, f, lambda r: LinearFeedback.for_model(
        model, Q, r, discrete=discrete, period=m * float(model.dt), x_eq=x_eq).K, R, (loop.process_noise,),
        MAX_R_DOUBLINGS, x_eq)
    if found is not None:
        return {k: found[k] for k in ("R", "factor", "fraction", "predicted_std", "predicted_fraction")}
    raise AnalysisError(f"No R up to {2.0 ** MAX_R_DOUBLINGS:g} times the lab's keeps the ctrl noise from these "
                        f"sensors below {f:g} of the ctrl range; allow more (`ctrl_noise`) or use finer encoders.")


#: The estimator's process noise (accel_std, m/s^2 and rad/s^2 on every joint) :func:`noise_limited_catch` tries,
#: in turn below the estimator's own default, when the rig does not set it (``LoopOptions.process_noise``).
PROCESS_NOISE_LADDER = (1.0, 0.3, 0.1, 0.03, 0.01)
#: Largest factor (2^12) :func:`noise_limited_catch` multiplies the catch's ``R`` by.
MAX_CATCH_R_DOUBLINGS = 12


def noise_limited_catch(model, loop, fraction: float, gain, R, *, required: bool = True) -> dict:
    """A swing-up catch that respects its sensors: the estimator's process noise and the catch's ``R`` chosen so that
    the ctrl noise the rig's sensors cause through the catch's loop, predicted at upright, stays below ``fraction``
    of the ctrl range's width.

    The estimator's default process noise (:data:`cartpole.estimation.kalman.DEFAULT_HINGE_ACCEL_STD`, 3 rad/s^2)
    stands for unmodelled accelerations far larger than a model of the MJCF's own integrator leaves; with it the
    filter follows every encoder count and its rate estimates carry the quantisation (one count in one period) into
    the catch's gain. So, starting from ``R`` and doubling it, the estimator's process noise is lowered along
    :data:`PROCESS_NOISE_LADDER` (only when ``loop.process_noise`` is None: a value given is kept) until the
    prediction (:func:`~cartpole.analysis.ctrl_noise_std` on :func:`~cartpole.analysis.sampled_loop` with the
    rig's Kalman filter, the linear stand-in for an EKF or MHE at upright, with the period, the delay and its
    prediction) holds. The largest process noise that holds at the smallest ``R`` is taken.

    Parameters
    ----------
    model : CartPoleModel
        The design model (its ``dt`` the MJCF's physics step).
    loop : LoopOptions
        The rig: period, delay, sensors and estimator (a swing-up's).
    fraction : float
        Largest ctrl standard deviation from noise, as a fraction of the ctrl range's width, in (0, 1).
    gain : callable
        ``gain(R) -> K`` (nu, nx): the catch designed with input weight ``R`` (nu, nu) over the rig's period.
    R : (nu, nu) array or float
        The catch's input weight to start from (MuJoCo ctrl units).
    required : bool
        True: no design that holds is an error. False: the quietest design tried is returned, ``met`` False.

    Returns
    -------
    dict
        ``fraction`` (asked), ``met`` (bool), ``R`` (nu, nu) and ``factor`` (on the starting ``R``),
        ``process_noise`` (accel_std given to the estimator, or None for its default), ``predicted_std`` (nu,)
        and ``predicted_fraction`` (nu,) at that design (ctrl units, and of the range), and
        ``predicted_state_std`` (nx,): the standard deviation the sensors leave in MuJoCo's true state in the hold
        (:func:`~cartpole.analysis.state_noise_std`; m, rad, m/s, rad/s), the floor under its rest.

    Raises
    ------
    AnalysisError
        A fraction outside (0, 1), a rig without sensors or estimator, or (``required``) no design that holds.
    """
    f = float(fraction)
    if not (math.isfinite(f) and 0 < f < 1):
        raise AnalysisError(f"The ctrl noise fraction {fraction!r} is not between 0 and 1; give e.g. "
                            "`ctrl_noise=0.1` (a tenth of the ctrl range).")
    if loop is None or not loop.sensed or loop.estimator_for("swingup") == "none":
        raise AnalysisError("A ctrl noise limit needs sensors: with MuJoCo's exact state no noise reaches the ctrl; "
                            "give an estimator and encoders (e.g. `estimator='ekf'` `encoder_cpr=2048`).")
    R = np.atleast_2d(np.asarray(R, float))
    R = R * np.eye(model.nu) if R.shape == (1, 1) and model.nu > 1 else R
    ladder = (loop.process_noise,) if loop.process_noise is not None else (None,) + PROCESS_NOISE_LADDER
    found, best = _noise_search(model, loop, f, gain, R, ladder, MAX_CATCH_R_DOUBLINGS, model.x_eq)
    if found is not None:
        return found
    if not required:
        return best
    lowest = min((a for a in ladder if a is not None), default=None)
    raise AnalysisError(f"No catch with R up to {2.0 ** MAX_CATCH_R_DOUBLINGS:g} times its own and the estimator's "
                        f"process noise down to {'its default' if lowest is None else f'{lowest:g}'} "
                        f"keeps the ctrl noise from these sensors below {f:g} of the ctrl range (at best "
                        f"{np.max(best['predicted_fraction']):.3g}); allow more (`ctrl_noise`) or use finer encoders.")


def _noise_search(model, loop, f: float, gain, R, ladder, doublings: int, x_eq):
    """``(found, best)``: the first design, ``R`` doubled up to ``2^doublings`` times and for each the estimator's
    process noise along ``ladder`` (None: its default), whose ctrl noise predicted at ``x_eq`` (the loop of
    ``gain(R) -> K`` with the rig's Kalman filter, :func:`~cartpole.analysis.ctrl_noise_std`) is below ``f`` of the
    ctrl range's width (None when none is), and the quietest design tried; each a dict as
    :func:`noise_limited_catch` returns."""
    h = float(model.dt)
    m, d = steps_per_period(loop.period, h), delay_steps(loop.delay, h)
    filters = {}
    for a in ladder:
        spec, make = estimator_factory(model, loop.replace(process_noise=a), "kf", m)
        filters[a] = (make(), spec.measurement_covariance())
    span = model.u_high - model.u_low
    best = None
    for k in range(doublings + 1):
        factor = 2.0 ** k
        K = np.asarray(gain(R * factor), float)
        for a in ladder:
            kf, V = filters[a]
            closed = sampled_loop(model, K, steps=m, delay_steps=d, compensate=bool(loop.delay_compensation),
                                  kalman=kf, x=x_eq)
            std = ctrl_noise_std(closed, V)
            found = {"fraction": f, "met": bool(np.all(std <= f * span)), "R": R * factor, "factor": factor,
                     "process_noise": a, "predicted_std": std, "predicted_fraction": std / span}
            if found["met"]:
                return {**found, "predicted_state_std": state_noise_std(closed, V)}, found
            if best is None or np.max(std / span) < np.max(best["predicted_fraction"]):
                best = {**found, "predicted_state_std": state_noise_std(closed, V)}
    return None, best
