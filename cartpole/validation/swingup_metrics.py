"""Small pure metrics of a swing-up :class:`~cartpole.sim.rollout.Rollout` (what MuJoCo did).

Definitions (all on the logged physics steps, angle errors wrapped to (-pi, pi]):

* *upright*: ``|wrapped theta| < UPRIGHT_TOL`` (0.05 rad, the lab's settling band);
* *at rest*: additionally ``|theta_dot| < REST_RATE_TOL`` (0.1 rad/s) and ``|s_dot| < REST_SPEED_TOL`` (0.1 m/s);
* *time to upright*: the first logged time after which the pole stays upright until the end of the log;
* *success*: upright and at rest over the last ``hold`` seconds, the cart never within ``limit_tol`` of its joint
  limit (where MuJoCo's limit constraint would push it), and every ctrl inside the ctrl range.
"""
from __future__ import annotations

import numpy as np

from cartpole.models.params import CartPoleParams
from cartpole.models.symbolic import wrap_angle
from cartpole.validation import metrics
from cartpole.sim import Rollout

UPRIGHT_TOL = 0.05
REST_RATE_TOL = 0.1
REST_SPEED_TOL = 0.1


def time_to_upright(rollout: Rollout, *, tol: float = UPRIGHT_TOL) -> float | None:
    """First time (s) after which ``|wrapped theta| < tol`` (rad) holds to the end of the log; None if not upright
    at the end."""
    up = np.abs(wrap_angle(rollout.qpos[:, 1])) < tol
    if not up[-1]:
        return None
    bad = np.flatnonzero(~up)
    return float(rollout.t[0] if bad.size == 0 else rollout.t[bad[-1] + 1])


def cart_clearance(rollout: Rollout, params: CartPoleParams) -> float:
    """Smallest distance (m) between the cart and either joint limit over the run (inf on an unlimited track)."""
    lo, hi = params.cart_range
    s = rollout.qpos[:, 0]
    return float(min(np.min(s - lo), np.min(hi - s)))


def cart_range_used(rollout: Rollout) -> tuple[float, float]:
    """``(min, max)`` cart position in m over the run."""
    s = rollout.qpos[:, 0]
    return float(s.min()), float(s.max())


def peak_ctrl(rollout: Rollout) -> float:
    """Largest ``|ctrl|`` applied (MuJoCo ctrl units; 0 for an empty log); :func:`metrics.peak_ctrl` of the log."""
    return metrics.peak_ctrl(rollout.ctrl)


def ctrl_within_range(rollout: Rollout, params: CartPoleParams) -> bool:
    """Whether every applied ctrl lies inside ``params.ctrl_range``."""
    lo, hi = params.ctrl_range
    return bool(np.all((rollout.ctrl >= lo) & (rollout.ctrl <= hi)))


def held_upright(rollout: Rollout, *, hold: float = 1.0) -> bool:
    """Whether the last ``hold`` seconds (and at least the final state) are upright and at rest."""
    if rollout.t[-1] - rollout.t[0] < hold:
        return False
    last = rollout.t >= rollout.t[-1] - hold - 1e-12
    th = np.abs(wrap_angle(rollout.qpos[last, 1]))
    return bool(np.all(th < UPRIGHT_TOL) and np.all(np.abs(rollout.qvel[last, 1]) < REST_RATE_TOL)
                and np.all(np.abs(rollout.qvel[last, 0]) < REST_SPEED_TOL))


def swingup_success(rollout: Rollout, params: CartPoleParams, *, hold: float = 1.0,
                    limit_tol: float = 1e-3) -> bool:
    """The swing-up succeeded: held upright at rest for the last ``hold`` s, cart never at its limit, ctrl in range.

    Parameters
    ----------
    rollout : Rollout
    params : CartPoleParams
        The MJCF's parameters (cart and ctrl ranges).
    hold : float
        Seconds at the end that must be upright and at rest.
    limit_tol : float
        m: coming closer than this to a cart limit counts as hitting it.

    Returns
    -------
    bool
    """
    return bool(held_upright(rollout, hold=hold) and cart_clearance(rollout, params) > limit_tol
                and ctrl_within_range(rollout, params))


def swingup_metrics(rollout: Rollout, params: CartPoleParams, *, hold: float = 1.0) -> dict:
    """All swing-up metrics in one JSON-ready dict.

    Returns
    -------
    dict
        ``success`` (bool), ``time_to_upright`` (s or None), ``peak_ctrl`` (ctrl units), ``cart_min``,
        ``cart_max``, ``cart_clearance`` (m), ``duration`` (s).
    """
    lo, hi = cart_range_used(rollout)
    return {"success": swingup_success(rollout, params, hold=hold), "time_to_upright": time_to_upright(rollout),
            "peak_ctrl": peak_ctrl(rollout), "cart_min": lo, "cart_max": hi,
            "cart_clearance": cart_clearance(rollout, params), "duration": float(rollout.t[-1] - rollout.t[0])}
