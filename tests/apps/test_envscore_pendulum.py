"""dm_control's pendulum-swingup scored in its own episodes with the value iteration's policy (cartpole.apps.envscore,
controller ``"value"``): the episode replays exactly and earns, to the step, what the policy earns from the same start
in the toolkit's batched MuJoCo runs (a coarse grid here, for seconds)."""
from __future__ import annotations

import numpy as np
import pytest

from cartpole.apps import envscore
from cartpole.models import build_model
from cartpole.planning.value_iteration import (DMCReward, ValueIterationOptions, ValuePolicy, cached_hinge_values,
                                               policy_returns)

pytest.importorskip("dm_control")

GRID = ValueIterationOptions(angles=100, rates=101)


def test_pendulum_swingup_runs_the_value_policy_and_earns_what_it_predicts(monkeypatch, tmp_path):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(envscore, "VALUE_GRID", GRID)
    assert envscore.environment("pendulum-swingup").controller == "value"
    ep = envscore.score_episode("pendulum-swingup", 4)  # a start near hanging: seconds of pumping
    assert ep.replays and not ep.warned and ep.steps == 1000
    model = build_model(ep.mjcf)
    reward = DMCReward(model, "dmc_pendulum_swingup")
    policy = ValuePolicy(cached_hinge_values(model, reward, options=GRID), model, reward)
    assert ep.return_ == policy_returns(policy, ep.x0[None, :], ep.steps)[0]
    assert np.all(ep.rewards[-100:] == 1.0)  # up and held at the end
    assert ep.design["controller"] == "value_iteration" and ep.design["angles"] == GRID.angles
