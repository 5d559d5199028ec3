"""The supervisor's swing-up law on a pendulum driven at its hinge (cartpole.supervise.pump.hinge_swingup): the value
iteration's policy for the upright band on a table of at least SWINGUP_STEP, the hinge pump beyond its rates."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cartpole.models import build_model
from cartpole.planning.value_iteration import ValuePolicy
from cartpole.supervise import pump
from cartpole.supervise.pump import HingePump, HingePumpError, hinge_swingup


@pytest.fixture
def pendulum(monkeypatch, tmp_path):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(pump, "SWINGUP_GRID", pump.SWINGUP_GRID.replace(angles=40, rates=41))
    # a servo on the hinge at a 2 ms physics step, built hanging (upright at qpos = pi)
    return build_model(Path(__file__).resolve().parents[1] / "assets" / "corpus" / "pendulum_built_hanging.xml")


def test_the_table_steps_at_least_swingup_step_and_the_pump_takes_the_fast_states(pendulum):
    law = hinge_swingup(pendulum, np.c_[pendulum.u_low, pendulum.u_high])
    assert isinstance(law, ValuePolicy) and isinstance(law.outside, HingePump)
    assert law.values.period >= pump.SWINGUP_STEP - 1e-12 and law.values.hold > 1  # several 2 ms steps a period
    assert law.values.horizon * law.values.period >= pump.SWINGUP_HORIZON - 1e-9
    fast = np.array(pendulum.x_hanging, float)
    fast[pendulum.nq + pendulum.hinges[0]] = 2.0 * law.values.rate_max
    np.testing.assert_array_equal(law(0.0, fast), law.outside(0.0, fast))


def test_a_motor_without_a_range_is_refused_as_by_the_pump(pendulum):
    with pytest.raises(HingePumpError, match="no ctrlrange"):
        hinge_swingup(pendulum, [[-np.inf, np.inf]])
