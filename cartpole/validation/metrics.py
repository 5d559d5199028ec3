"""Replay metrics: small pure functions of a logged run's arrays (``t`` (n+1,), ``x`` (n+1, 4), ``ctrl`` (n, 1)).

Pass a :class:`~cartpole.sim.rollout.Rollout` as ``run.t``, ``run.x``, ``run.ctrl``; :func:`summarize`
does that for every metric of the lab at once, :func:`swingup_metrics` for a swing-up.

Two settling times, because they answer different questions:

* :func:`settling_time_seed` is the lab handout's definition, computed exactly as its ``settling_time``
  does: find every sample with ``|theta| > 0.05 rad``; none -> ``0.0``; otherwise the time of the sample
  *after* the last exceedance. It looks at the pole angle only, so a cart still rolling back to the
  middle (or the pole still swinging inside the band) counts as settled. One deviation: when the very last
  sample still exceeds the band the handout returns the final time stamp, which reads as "settled at the
  end"; we return ``inf`` (never settled). The handout logged the state *before* each of its 1200 steps
  (t = 0 .. 5.995 s); a :class:`Rollout` also holds the final state (t = 6.0 s), which changes nothing
  unless the run never settles.
* :func:`settling_time_strict` asks for the whole state: the first time after which every one of
  ``|s - s*| <= 0.01 m``, ``|theta - theta*| <= 0.01 rad``, ``|s_dot| <= 0.01 m/s`` and
  ``|theta_dot| <= 0.01 rad/s`` holds at every later sample up to the end of the run (``inf`` if the last
  sample is outside that box).

The swing-up's metrics use the same functions (all on the logged physics steps, angle errors wrapped to
(-pi, pi]):

* *upright*: ``|wrapped theta| < UPRIGHT_TOL`` (0.05 rad, the lab's settling band);
* *at rest*: additionally ``|theta_dot| < REST_RATE_TOL`` (0.1 rad/s) and ``|s_dot| < REST_SPEED_TOL`` (0.1 m/s);
* *time to upright*: :func:`settling_time_seed` of the run, the first logged time after which the pole stays
  within the band until the end of the log (``None`` in :func:`swingup_metrics` when it never does);
* *cart clearance*: :func:`track_margin`, the smallest distance to a cart joint limit over the run;
* *success*: upright and at rest over the last ``hold`` seconds, the cart never within ``limit_tol`` of its joint
  limit (where MuJoCo's limit constraint would push it), and every ctrl inside the ctrl range.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole.models import CartPoleParams, wrap_angle

#: Upright band on the wrapped |theta - theta*| in rad: the lab handout's settling band, the swing-up's upright
#: test and the catch basin's final-state test.
UPRIGHT_TOL = 0.05

#: "At rest" besides upright: |theta_dot| (rad/s) and |s_dot| (m/s) below these.
REST_RATE_TOL = 0.1
REST_SPEED_TOL = 0.1

#: Half-widths of the strict settling box on [s (m), theta (rad), s_dot (m/s), theta_dot (rad/s)].
STRICT_TOLERANCE = (0.01, 0.01, 0.01, 0.01)


def _times_states(t, x) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float).ravel()
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[0] != t.shape[0] or x.shape[1] < 2:
        raise ValueError(f"Need t (n+1,) and x (n+1, 4); got t {t.shape} and x {x.shape}.")
    return t, x


def settling_time_seed(t, x, *, band: float = UPRIGHT_TOL, theta_eq: float = 0.0) -> float:
    """The lab handout's settling time: the time after which ``|theta|`` stays within ``band``.

    Parameters
    ----------
    t : (n+1,) array, s
    x : (n+1, 4) array
        States ``[s, theta, s_dot, theta_dot]``; only ``theta`` (rad) is used.
    band : float, rad
        The handout's threshold, :data:`UPRIGHT_TOL` (0.05 rad).
    theta_eq : float, rad
        Upright angle (0 in this toolkit); the wrapped error ``theta - theta_eq`` is tested.

    Returns
    -------
    float, s
        ``t[0]`` (the handout's ``0.0`` for a run from t = 0) if ``|theta|`` never exceeds ``band``; otherwise
        ``t`` of the sample after the last sample with ``|theta| > band``; ``inf`` when that last exceedance is
        the final sample. For a swing-up this is the time to upright.
    """
    t, x = _times_states(t, x)
    above = np.flatnonzero(np.abs(wrap_angle(x[:, 1] - theta_eq)) > band)
    if above.size == 0:
        return float(t[0])
    k = int(above[-1]) + 1
    return float(t[k]) if k < t.size else float("inf")


def settling_time_strict(t, x, x_eq=None, *, tol=STRICT_TOLERANCE) -> float:
    """First time after which the whole state stays inside a box around the equilibrium until the end.

    Parameters
    ----------
    t : (n+1,) array, s
    x : (n+1, 4) array
        States ``[s, theta, s_dot, theta_dot]``.
    x_eq : (4,) array, optional
        Equilibrium ``x*`` (default the origin); the angle error is wrapped.
    tol : (4,) sequence
        Half-widths of the box, in m, rad, m/s, rad/s (default :data:`STRICT_TOLERANCE`).

    Returns
    -------
    float, s
        ``t[k]`` for the smallest ``k`` such that every sample ``k..n`` is inside the box; ``inf`` if the final
        sample is outside (the run never settled).
    """
    t, x = _times_states(t, x)
    x_eq = np.zeros(x.shape[1]) if x_eq is None else np.asarray(x_eq, dtype=float)
    e = x - x_eq
    e[:, 1] = wrap_angle(e[:, 1])
    inside = np.all(np.abs(e) <= np.asarray(tol, dtype=float), axis=1)
    if not inside[-1]:
        return float("inf")
    outside = np.flatnonzero(~inside)
    return float(t[outside[-1] + 1]) if outside.size else float(t[0])


def peak_ctrl(ctrl) -> float:
    """Largest ``|ctrl|`` applied (MuJoCo ctrl units; force is ``gear`` times this), 0 for an empty log."""
    ctrl = np.asarray(ctrl, dtype=float)
    return float(np.abs(ctrl).max()) if ctrl.size else 0.0


def saturation_fraction(ctrl, ctrl_range, *, atol: float = 1e-12) -> float:
    """Fraction (0..1) of physics steps whose ctrl sits at a bound of ``ctrl_range`` (within ``atol``).

    Parameters
    ----------
    ctrl : (n, 1) or (n,) array
        ctrl applied during each step (already clipped, as a :class:`Rollout` logs it).
    ctrl_range : (2,) array
        ``[low, high]``; infinite bounds never saturate.
    """
    u = np.asarray(ctrl, dtype=float).ravel()
    if u.size == 0:
        return 0.0
    lo, hi = (float(v) for v in ctrl_range)
    at_bound = (u <= lo + atol) | (u >= hi - atol)
    return float(np.mean(at_bound))


def track_margin(x, cart_range) -> float:
    """Smallest distance in m of the cart to either end of its slide range over the run.

    Parameters
    ----------
    x : (n+1, 4) or (n+1, 2) array
        States or ``qpos``; column 0 is the cart position in m.
    cart_range : (2,) array
        Slide joint range ``[low, high]`` in m (``inf`` when unlimited).

    Returns
    -------
    float, m
        ``min_k min(s_k - low, high - s_k)``: ``inf`` for an unlimited rail, ``<= 0`` when the cart reached
        (or, through MuJoCo's soft limit, passed) a joint limit.
    """
    s = np.asarray(x, dtype=float)[:, 0]
    lo, hi = (float(v) for v in cart_range)
    return float(np.min(np.minimum(s - lo, hi - s)))


@dataclass(frozen=True)
class RunMetrics:
    """Every metric of one run (see the module docstring for the definitions).

    Attributes
    ----------
    settling_time_seed : float, s (``inf`` if never)
    settling_time_strict : float, s (``inf`` if never)
    peak_ctrl : float, ctrl units
    saturation_fraction : float, 0..1
    track_margin : float, m
    """

    settling_time_seed: float
    settling_time_strict: float
    peak_ctrl: float
    saturation_fraction: float
    track_margin: float

    @property
    def hit_limit(self) -> bool:
        """True when the cart reached a joint limit (``track_margin <= 0``)."""
        return self.track_margin <= 0.0

    @property
    def settled(self) -> bool:
        """Strict settling time finite and the cart never reached its limit."""
        return bool(np.isfinite(self.settling_time_strict) and not self.hit_limit)


def summarize(run, *, x_eq=None, ctrl_range=(-np.inf, np.inf), cart_range=(-np.inf, np.inf),
              tol=STRICT_TOLERANCE) -> RunMetrics:
    """All metrics of a :class:`~cartpole.sim.rollout.Rollout` (anything with ``t``, ``x``, ``ctrl``).

    Parameters
    ----------
    run : Rollout
    x_eq : (4,) array, optional
        Equilibrium (default origin).
    ctrl_range, cart_range : (2,) arrays
        From :class:`~cartpole.models.params.CartPoleParams` (``ctrl_range``, ``cart_range``).
    tol : (4,) sequence
        Strict settling box (m, rad, m/s, rad/s).
    """
    x_eq = np.zeros(4) if x_eq is None else np.asarray(x_eq, dtype=float)
    return RunMetrics(
        settling_time_seed=settling_time_seed(run.t, run.x, theta_eq=float(x_eq[1])),
        settling_time_strict=settling_time_strict(run.t, run.x, x_eq, tol=tol),
        peak_ctrl=peak_ctrl(run.ctrl),
        saturation_fraction=saturation_fraction(run.ctrl, ctrl_range),
        track_margin=track_margin(run.x, cart_range),
    )


def cart_range_used(rollout) -> tuple[float, float]:
    """``(min, max)`` cart position in m over a :class:`~cartpole.sim.rollout.Rollout`."""
    s = rollout.qpos[:, 0]
    return float(s.min()), float(s.max())


def ctrl_within_range(rollout, params: CartPoleParams) -> bool:
    """Whether every applied ctrl of ``rollout`` lies inside ``params.ctrl_range``."""
    lo, hi = params.ctrl_range
    return bool(np.all((rollout.ctrl >= lo) & (rollout.ctrl <= hi)))


def held_upright(rollout, *, hold: float = 1.0) -> bool:
    """Whether the last ``hold`` seconds (and at least the final state) of ``rollout`` are upright and at rest."""
    if rollout.t[-1] - rollout.t[0] < hold:
        return False
    last = rollout.t >= rollout.t[-1] - hold - 1e-12
    th = np.abs(wrap_angle(rollout.qpos[last, 1]))
    return bool(np.all(th < UPRIGHT_TOL) and np.all(np.abs(rollout.qvel[last, 1]) < REST_RATE_TOL)
                and np.all(np.abs(rollout.qvel[last, 0]) < REST_SPEED_TOL))


def swingup_success(rollout, params: CartPoleParams, *, hold: float = 1.0, limit_tol: float = 1e-3) -> bool:
    """The swing-up succeeded: held upright at rest for the last ``hold`` s, cart never at its limit, ctrl in range.

    Parameters
    ----------
    rollout : Rollout
    params : CartPoleParams
        The MJCF's parameters (cart and ctrl ranges).
    hold : float
        Seconds at the end that must be upright and at rest.
    limit_tol : float
        m: coming closer than this to a cart limit (:func:`track_margin`) counts as hitting it.

    Returns
    -------
    bool
    """
    return bool(held_upright(rollout, hold=hold) and track_margin(rollout.qpos, params.cart_range) > limit_tol
                and ctrl_within_range(rollout, params))


def swingup_metrics(rollout, params: CartPoleParams, *, hold: float = 1.0) -> dict:
    """All swing-up metrics of a :class:`~cartpole.sim.rollout.Rollout` in one JSON-ready dict.

    Returns
    -------
    dict
        ``success`` (bool, :func:`swingup_success`), ``time_to_upright`` (s, :func:`settling_time_seed`; None if
        the pole is not upright at the end), ``peak_ctrl`` (ctrl units), ``cart_min``, ``cart_max``,
        ``cart_clearance`` (m, :func:`track_margin`), ``duration`` (s).
    """
    lo, hi = cart_range_used(rollout)
    t_up = settling_time_seed(rollout.t, rollout.x)
    return {"success": swingup_success(rollout, params, hold=hold),
            "time_to_upright": t_up if np.isfinite(t_up) else None,
            "peak_ctrl": peak_ctrl(rollout.ctrl), "cart_min": lo, "cart_max": hi,
            "cart_clearance": track_margin(rollout.qpos, params.cart_range),
            "duration": float(rollout.t[-1] - rollout.t[0])}
