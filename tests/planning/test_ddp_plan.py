"""The receding-horizon DDP swing-up (cartpole.planning.ddp_plan.receding_swingup) and the planner that starts from
it on chains driven at a hinge: dm_control's acrobot from its own seed-0 start, where the minimum-time multi-start
and the pumping search found no swing-up ("No swing-up found ... after 64 attempts")."""
from __future__ import annotations

import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.ocp.bounds import bounds_from_params
from cartpole.ocp.dmc import episode_starts
from cartpole.planning.ddp_plan import RECEDING_ANGLE, RECEDING_RATE, receding_swingup
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.metrics import swingup_success

ACROBOT = SHIPPED_MJCF.with_name("dmc_acrobot.xml")


@pytest.fixture(scope="module")
def acrobot():
    params = read_params(ACROBOT)
    model = build_model(params)
    return params, model, episode_starts(model, "dmc_acrobot_swingup", 1, seed=0)[0]


def test_receding_swingup_is_an_exact_rollout_that_ends_at_rest_upright(acrobot):
    params, model, x0 = acrobot
    rec = receding_swingup(model, x0, bounds_from_params(params, cart_margin=0.1))
    assert rec.info.success and rec.trajectory is not None
    traj = rec.trajectory
    xs = [traj.x[0]]
    for u in traj.u[:-1]:
        xs.append(np.asarray(model.step(xs[-1], u), float).ravel())
    np.testing.assert_allclose(np.array(xs), traj.x, rtol=0, atol=1e-9)  # the model's own step, nothing stretched
    err = model.state_error(traj.x[-1])
    assert np.all(np.abs(err[list(model.hinges)]) <= RECEDING_ANGLE)
    assert np.all(np.abs(traj.x[-1][[model.nq + i for i in model.hinges]]) <= RECEDING_RATE)
    assert rec.info.T == pytest.approx(traj.duration)


def test_receding_swingup_that_does_not_reach_upright_says_so(acrobot):
    params, model, _ = acrobot
    rec = receding_swingup(model, model.x_hanging, bounds_from_params(params, cart_margin=0.1), T_max=0.3)
    assert not rec.info.success and rec.trajectory is None and rec.info.status == "T_max reached"


def test_acrobot_planned_from_dm_controls_seed_0_start_swings_up_in_mujoco(acrobot):
    """The planner's first stage on a chain driven at a hinge is the receding-horizon DDP: from dm_control's seed-0
    start it plans (within the budget the supervisor gives it) and TVLQR + catch swing up in MuJoCo."""
    params, model, x0 = acrobot
    sp = trajopt_swingup(params, x0=tuple(x0), options=PlanOptions(search_s=30.0))
    assert "receding-horizon DDP" in sp.solve_info.guess
    assert any(a.stage == "receding-horizon DDP" and a.success for a in sp.solve_info.attempts)
    run = simulate(params, sp.controller, x0, sp.trajectory.duration + 2.0)
    assert swingup_success(run, model)
    assert replays_exactly(run)
