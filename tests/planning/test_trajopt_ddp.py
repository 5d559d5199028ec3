"""trajopt_swingup(solver="ddp"): the plan's last stage by box-DDP on the exact discrete step. One- and two-pole
swing-ups succeed in MuJoCo and replay; the plan is exact on the step; every objective the collocation takes;
the minimum time by a T search; IPOPT takes over (and says so in the attempts) when DDP does not converge."""
import numpy as np
import pytest

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.planning import ddp_plan
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import SimOptions, replays_exactly, simulate
from cartpole.validation.metrics import swingup_metrics
from cartpole.planning.options import PlanOptions


def _runs(params, plan):
    run = simulate(params, plan.controller, plan.model.x_hanging, plan.T + 3.0)
    met = swingup_metrics(run, params)
    assert run.info.get("diverged") is None
    assert met["success"], met
    assert replays_exactly(run, params)
    return run


def _exact(plan):
    d = plan.discrete
    assert d is not None and plan.solve_info.solver == "ddp" and plan.solve_info.success
    model = plan.model
    xn = np.asarray(model.step.map(d.u.shape[0])(d.x[:-1].T, d.u.T)).T
    assert np.abs(xn - d.x[1:]).max() < 1e-9  # the plan is a solution of the MJCF's own step
    assert d.defect_after < 1e-9 < d.defect_before
    assert np.abs(model.state_error(d.x[-1])).max() < 1e-5  # ends upright
    return d


@pytest.mark.parametrize("name", ["cartpole.xml", "cartpole_two_pole.xml"])
def test_ddp_swings_up_one_and_two_poles_in_mujoco_and_the_plan_is_exact_on_the_step(name):
    params = read_params(SHIPPED_MJCF.parent / name)
    plan = trajopt_swingup(params, options=PlanOptions(solver="ddp"))
    d = _exact(plan)
    lo, hi = np.asarray(params.ctrl_range, float).T
    assert np.all(d.u >= lo - 1e-12) and np.all(d.u <= hi + 1e-12)
    stages = [a.stage for a in plan.solve_info.attempts]
    assert any(s.startswith("effort (ddp)") for s in stages) and stages[0].startswith("time")
    _runs(params, plan)


@pytest.mark.parametrize("objective", ["tracking", "dmc_swingup"])
def test_ddp_takes_the_running_objectives_of_the_collocation(objective):
    params = read_params(SHIPPED_MJCF)
    plan = trajopt_swingup(params, options=PlanOptions(solver="ddp", objective=objective))
    _exact(plan)
    assert plan.objective == objective
    assert [a for a in plan.solve_info.attempts if a.stage.startswith(f"{objective} (ddp)") and a.chosen]
    if objective == "dmc_swingup":  # a reward, reported with the user's sign
        assert plan.solve_info.objective > 0
    _runs(params, plan)


def test_the_minimum_time_by_ddp_is_a_search_over_T_near_the_collocations():
    params = read_params(SHIPPED_MJCF)
    plan = trajopt_swingup(params, options=PlanOptions(solver="ddp", objective="time"))
    d = _exact(plan)
    searched = [a for a in plan.solve_info.attempts if a.stage.startswith("time (ddp)")]
    assert len(searched) >= 2 and sum(a.chosen for a in searched) == 1
    best = min(a.T for a in searched if a.success)
    assert plan.T == pytest.approx(best) and plan.solve_info.objective == pytest.approx(best)
    assert all(not a.success for a in searched if a.T < best)  # every shorter one tried failed
    # the discrete minimum time is the continuous one to within a few steps
    assert abs(plan.T - plan.T_min) <= 5 * d.dt
    _runs(params, plan)


def test_a_ddp_that_does_not_converge_hands_the_stage_to_ipopt(monkeypatch):
    real = ddp_plan.ddp_stage

    def failing(*args, **kw):
        kw["options"] = kw["options"].replace(ddp=ddp_plan.DDPOptions(max_iterations=1, max_outer=1))
        return real(*args, **kw)

    monkeypatch.setattr(ddp_plan, "ddp_stage", failing)
    plan = trajopt_swingup(read_params(SHIPPED_MJCF), options=PlanOptions(solver="ddp", exact_discrete=False))
    info = plan.solve_info
    assert info.solver == "ipopt" and info.success and plan.discrete is None
    ddp = [a for a in info.attempts if "(ddp)" in a.stage]
    assert len(ddp) == 2 and not any(a.success or a.chosen for a in ddp)  # with the margin, then without
    stages = [a.stage for a in info.attempts]
    assert stages.index(ddp[-1].stage) < stages.index("effort")  # DDP first, then IPOPT's effort stage


def test_the_solver_flag_is_for_trajopt_only(tmp_path, capsys):
    rc = main(["swingup", "--method", "energy", "--json", "--no-video", "--solver", "ddp", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--method trajopt" in err[0] and list(tmp_path.iterdir()) == []


def test_ddp_at_a_given_T_starts_from_rest_and_holds_the_period():
    """A given T (no earlier stage): DDP from zero ctrl, held over a 20 ms control period on the exact hold."""
    params = read_params(SHIPPED_MJCF)
    plan = trajopt_swingup(params, period=0.02, options=PlanOptions(solver="ddp", T=2.0))
    d = plan.discrete
    assert plan.solve_info.solver == "ddp" and d is not None and d.dt == pytest.approx(0.02)
    hold = build_model(params).hold(4)
    xn = np.asarray(hold.step.map(d.u.shape[0])(d.x[:-1].T, d.u.T)).T
    assert np.abs(xn - d.x[1:]).max() < 1e-9
    run = simulate(params, plan.controller, plan.model.x_hanging, plan.T + 3.0,
                   options=SimOptions(control_period=0.02))
    assert swingup_metrics(run, params)["success"] and replays_exactly(run, params)
