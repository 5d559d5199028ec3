"""Two and three poles swung up from hanging rest by trajectory optimisation alone, proven in MuJoCo (issue 11).

Each case plans with ``trajopt_swingup`` from the MJCF (no guess, no T, no mesh given: the code picks them),
runs its controller in MuJoCo from every pole hanging at rest, and asks :func:`cartpole.validation.metrics.
swingup_success` for the last 3 s: every pole within 0.05 rad of upright, every hinge rate and the cart speed
below 0.1, the cart never at its limit, ctrl inside ``ctrlrange``; the log replays exactly with ``mj_step``.
Carts: the shipped two- and three-pole files, a two-pole cart written the way dm_control extends its single-pole
file (RK4 at 0.01 s, gear 10, rail +-1.8 m) and Gymnasium's double pendulum on a cart (RK4 at 0.01 s, gear 500).
"""
import json

import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.metrics import pole_angle_errors, swingup_metrics, swingup_success

HOLD = 3.0  # s upright and at rest at the end of the run
AFTER = HOLD + 2.0  # s simulated after the plan ends: the hand-over settles, then the hold


@pytest.fixture(scope="module", params=["two_pole", "three_pole", "dmc_2poles", "gym_double"])
def chain(request, chain_dir):
    """(name, params, plan) for each cart, planned once per module."""
    name = request.param
    path = SHIPPED_MJCF.with_name(f"cartpole_{name}.xml") if name in ("two_pole", "three_pole") \
        else chain_dir / f"{name}.xml"
    params = read_params(path)
    return name, params, trajopt_swingup(params)


def test_every_pole_swings_up_from_hanging_rest_and_holds_for_3_s(chain):
    name, params, plan = chain
    model = build_model(params)
    assert len(model.hinges) == 2 or name == "three_pole"
    x0 = model.x_hanging
    rollout = simulate(params, plan.controller, x0, plan.T + AFTER)
    assert replays_exactly(rollout, params)
    np.testing.assert_array_equal(rollout.x[0], x0)
    metrics = swingup_metrics(rollout, model, hold=HOLD)
    print(f"{name}: T_min {plan.T_min:.3f} s, plan T {plan.T:.3f} s, time to upright {metrics['time_to_upright']} s, "
          f"{len(plan.solve_info.attempts)} solves, {plan.solve_info.total_iterations} iterations")
    assert swingup_success(rollout, model, hold=HOLD), metrics
    # upright here means every pole: the wrapped errors of all hinges over the last 3 s
    last = rollout.t >= rollout.t[-1] - HOLD
    assert np.abs(pole_angle_errors(rollout.x[last], x_eq=model.x_eq, hinges=model.hinges)).max() < 0.05
    # the plan itself starts at hanging rest and ends upright at rest
    np.testing.assert_allclose(plan.trajectory.x[0], x0, atol=1e-9)
    assert np.abs(model.state_error(plan.trajectory.x[-1])).max() < 1e-6


def test_the_multi_start_reports_every_attempt_and_the_guess_that_won(chain):
    name, params, plan = chain
    info = plan.solve_info
    assert info.success and info.attempts and info.guess
    stages = []
    for a in info.attempts:
        if a.stage not in stages:
            stages.append(a.stage)
        assert a.iterations >= 0 and a.status and a.N >= 2
    # a coarse minimum-time multi-start over several named guesses, its refinement, then the effort plan by the
    # SQP (the default) on every chain: the triple's too, since the Riccati QP sees its pinned end
    assert stages[0].startswith("time") and stages[-1] == "effort (sqp)"
    assert "effort" not in stages and info.solver == "sqp"
    first = [a for a in info.attempts if a.stage == stages[0]]
    assert len({a.guess for a in first}) == len(first) >= 2
    for stage in stages:
        chosen = [a for a in info.attempts if a.stage == stage and a.chosen]
        assert len(chosen) <= 1
        # the kept solution of a multi-start is its least-time converged one
        tried = [a for a in info.attempts if a.stage == stage and a.success]
        if chosen and stage.startswith("time"):
            assert chosen[0].objective == min(a.objective for a in tried)
    final = [a for a in info.attempts if a.stage == "effort (sqp)" and a.chosen]
    assert len(final) == 1 and final[0].guess == info.guess
    assert final[0].objective == pytest.approx(info.objective)
    assert plan.T == pytest.approx((1.2) * plan.T_min)
    assert info.total_iterations == sum(a.iterations for a in info.attempts)
    # the report is JSON-ready, and the plan says how long all of it took (every stage, guess and TVLQR)
    json.dumps([a.as_dict() for a in info.attempts])
    assert info.total_solve_time_s < plan.plan_time_s
