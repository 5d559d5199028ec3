"""run_swingup on the shipped asset and every variant, and the pure swing-up metrics."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.swingup import SwingupError, run_swingup
from cartpole.sim import Rollout, replays_exactly
from cartpole.validation.swingup_metrics import (cart_clearance, swingup_metrics, swingup_success,
                                                 time_to_upright)


def test_energy_swingup_brings_the_pole_up_and_holds_it(any_mjcf):
    params = cp.read_params(any_mjcf)
    res = run_swingup(params, method="energy")
    r = res.rollout
    assert replays_exactly(r, params)
    assert res.caught_at is not None
    assert res.success and swingup_success(r, params)
    lo, hi = params.cart_range
    assert np.all((r.qpos[:, 0] > lo) & (r.qpos[:, 0] < hi))  # never at the joint limit
    assert np.all(np.abs(r.ctrl) <= params.u_max)
    # the switch into the catch is at a MuJoCo state inside the estimated basin
    k = int(round(res.caught_at / r.dt))
    e = r.x[k].copy()
    e[1] = cp.models.wrap_angle(e[1])
    assert e @ res.basin.S @ e < res.basin.rho
    assert len(res.metrics["switches"]) == 1
    print(f"\n{getattr(any_mjcf, 'name', any_mjcf)}: time to upright {res.metrics['time_to_upright']:.3f} s, "
          f"caught at {res.caught_at:.3f} s, cart clearance {res.metrics['cart_clearance']:.3f} m")


def _rollout(theta, s=None, dt=0.01):
    n = len(theta) - 1
    s = np.zeros(n + 1) if s is None else s
    return Rollout(t=np.arange(n + 1) * dt, qpos=np.column_stack([s, theta]), qvel=np.zeros((n + 1, 2)),
                   ctrl=np.zeros((n, 1)))


def test_time_to_upright_is_the_first_time_it_stays_upright():
    th = np.concatenate([np.linspace(np.pi, 0.3, 50), [0.04, 0.2, 0.03], np.full(300, 2 * np.pi + 0.01)])
    r = _rollout(th)
    k = 50 + 2  # first index from which |wrapped theta| < 0.05 until the end
    assert time_to_upright(r) == pytest.approx(r.t[k])
    assert time_to_upright(_rollout(np.full(10, 1.0))) is None


def test_success_needs_hold_no_limit_contact_and_ctrl_in_range():
    params = cp.read_params()
    up = _rollout(np.full(201, 0.01))
    assert swingup_success(up, params, hold=1.0)
    assert not swingup_success(up, params, hold=5.0)  # shorter than the hold
    s = np.zeros(201)
    s[10] = params.cart_range[1]
    assert not swingup_success(_rollout(np.full(201, 0.01), s), params)
    assert cart_clearance(_rollout(np.full(201, 0.01), s), params) == 0.0
    bad = Rollout(t=up.t, qpos=up.qpos, qvel=up.qvel, ctrl=np.full((200, 1), 1.5))
    assert not swingup_success(bad, params)
    m = swingup_metrics(up, params)
    assert m["success"] and m["time_to_upright"] == 0.0


@pytest.mark.parametrize("x0", [(0, np.pi, 0), (0, np.nan, 0, 0), (1.6, np.pi, 0, 0), (-2, 0, 0, 0)])
def test_bad_start_states_raise(x0):
    with pytest.raises(SwingupError):
        run_swingup(None, x0=x0)


def test_unknown_method_raises():
    with pytest.raises(SwingupError):
        run_swingup(None, method="magic")
