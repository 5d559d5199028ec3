"""run_swingup on the shipped asset and every variant (the swing-up metrics are tested in tests/validation)."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.swingup import SwingupError, run_swingup
from cartpole.sim import replays_exactly
from cartpole.validation.metrics import swingup_success


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


@pytest.mark.parametrize("x0", [(0, np.pi, 0), (0, np.nan, 0, 0), (1.6, np.pi, 0, 0), (-2, 0, 0, 0)])
def test_bad_start_states_raise(x0):
    with pytest.raises(SwingupError):
        run_swingup(None, x0=x0)


def test_unknown_method_raises():
    with pytest.raises(SwingupError):
        run_swingup(None, method="magic")
