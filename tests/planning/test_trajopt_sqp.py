"""trajopt_swingup(solver="sqp"): the effort stage by the SQP gives IPOPT's plan, and IPOPT takes over when it fails."""
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, read_params
from cartpole.planning import trajopt as pipeline
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.planning.options import PlanOptions


@pytest.fixture(scope="module")
def params():
    return read_params(SHIPPED_MJCF)


@pytest.fixture(scope="module")
def ipopt_plan(params):
    return trajopt_swingup(params, options=PlanOptions(solver="ipopt", exact_discrete=False))


def _effort_attempts(plan):
    return [a for a in plan.solve_info.attempts if a.stage.startswith("effort")]


def test_the_effort_stage_by_sqp_reaches_ipopts_plan(params, ipopt_plan):
    plan = trajopt_swingup(params, options=PlanOptions(solver="sqp", exact_discrete=False))
    info, ref = plan.solve_info, ipopt_plan.solve_info
    assert info.success and info.solver == "sqp"
    tried = _effort_attempts(plan)
    assert [a.stage for a in tried] == ["effort (sqp)"] and tried[0].chosen
    # the minimum-time stage before it refined by the SQP too: the same minimum to the solvers' tolerances
    assert plan.T == pytest.approx(ipopt_plan.T, rel=1e-6)
    assert [a.stage for a in plan.solve_info.attempts if a.chosen and a.stage.startswith("time N=60")] == \
        ["time N=60 (sqp)"]
    assert abs(info.objective - ref.objective) <= 1e-6 * abs(ref.objective)
    scale = np.abs(ipopt_plan.trajectory.x).max(axis=0) + 1e-3
    assert np.abs((plan.trajectory.x - ipopt_plan.trajectory.x) / scale).max() < 1e-3
    assert np.abs(plan.trajectory.u - ipopt_plan.trajectory.u).max() < 1e-3


def test_an_sqp_that_does_not_converge_hands_the_effort_stage_to_ipopt(params, ipopt_plan, monkeypatch):
    monkeypatch.setattr(pipeline, "SQP_MAX_ITER", 1)
    plan = trajopt_swingup(params, options=PlanOptions(solver="sqp", exact_discrete=False))
    tried = _effort_attempts(plan)
    assert [a.stage for a in tried] == ["effort (sqp)", "effort"]
    assert not tried[0].success and not tried[0].chosen and tried[1].chosen
    assert plan.solve_info.solver == "ipopt"
    assert plan.solve_info.objective == pytest.approx(ipopt_plan.solve_info.objective, rel=1e-9)


def test_the_default_plans_the_effort_stage_by_sqp(params, ipopt_plan):
    plan = trajopt_swingup(params, options=PlanOptions(exact_discrete=False))
    assert plan.options.solver == "auto"
    assert plan.solve_info.solver == "sqp" and [a.stage for a in _effort_attempts(plan)] == ["effort (sqp)"]
    assert plan.solve_info.objective == pytest.approx(ipopt_plan.solve_info.objective, rel=1e-6)


def test_ipopt_options_given_keep_the_effort_stage_ipopts(params):
    plan = trajopt_swingup(params, options=PlanOptions(exact_discrete=False, solver_options={"ipopt": {"tol": 1e-8}}))
    assert plan.solve_info.solver == "ipopt" and [a.stage for a in _effort_attempts(plan)] == ["effort"]
