"""Feedforward beside feedback (cartpole.apps.feedforward): the plan's ctrl alone drifts off and the pole falls; the same
plan with TVLQR feedback swings up and holds; with a wrong pole mass the runs are judged on the true MJCF. Every claim
from a MuJoCo rollout that replays exactly. One study (two trajopt solves, four runs) per module."""
import math

import numpy as np
import pytest

from cartpole.apps.feedforward import (EXTRA, RUNS, FeedforwardError, FeedforwardOptions, PlanFeedforward,
                                  check_mass_error, run_feedforward)
from cartpole.models import SHIPPED_MJCF, read_params
from cartpole.sim import replays_exactly
from cartpole.validation.metrics import UPRIGHT_TOL, swingup_success


@pytest.fixture(scope="module")
def study():
    return run_feedforward()


def test_the_study_runs_the_four_controllers_from_hanging_rest_on_the_shipped_mjcf(study):
    assert list(study.runs) == list(RUNS)
    assert study.mjcf == str(SHIPPED_MJCF)
    for name, run in study.runs.items():
        plan = study.wrong_plan if name.startswith("wrong") else study.plan
        assert run.rollout.mjcf == str(SHIPPED_MJCF)          # MuJoCo always ran the true MJCF
        assert np.array_equal(run.rollout.x[0], study.model.x_hanging)
        assert run.rollout.t[-1] == pytest.approx(plan.T + EXTRA, abs=run.rollout.dt)
        assert run.plan is plan.trajectory


def test_feedforward_alone_is_not_a_swingup_success_and_replays_exactly(study):
    run = study.runs["feedforward"]
    assert run.replays_exactly and replays_exactly(run.rollout)
    assert not run.success and not swingup_success(run.rollout, study.model)
    assert run.time_to_upright is None
    # it does get near the top (the model is exact) and then falls: the upright is unstable and nothing corrects
    assert run.max_angle_tracking_error < 0.3
    assert np.abs(run.final_angle_error).max() > UPRIGHT_TOL


def test_feedforward_plus_tvlqr_swings_up_holds_and_replays_exactly(study):
    run = study.runs["feedforward_tvlqr"]
    assert run.replays_exactly and replays_exactly(run.rollout)
    assert run.success and swingup_success(run.rollout, study.model)
    assert 0 < run.time_to_upright < run.rollout.t[-1] - 1.0
    assert np.abs(run.final_angle_error).max() < UPRIGHT_TOL
    assert run.handover_time == pytest.approx(study.plan.T, abs=run.rollout.dt)   # TVLQR hands over to the LQR
    assert run.max_angle_tracking_error < study.runs["feedforward"].max_angle_tracking_error


def test_the_open_loop_ctrl_is_exactly_the_feedforward_inside_the_tvlqr_controller(study):
    plan, params = study.plan, study.model.params
    ff = PlanFeedforward.of_plan(plan, params)
    tvlqr = plan.controller
    tvlqr.reset()
    for t in np.linspace(0.0, plan.T * 0.999, 37):
        # on the plan the feedback term vanishes, leaving the feedforward the open-loop run applies
        assert np.allclose(tvlqr(t, plan.trajectory.state(t)), ff(t), rtol=0, atol=1e-12)
    assert np.array_equal(ff(plan.T + 0.5), study.model.u_eq)         # after the plan: the upright rest input
    run = study.runs["feedforward"]
    assert np.array_equal(run.rollout.ctrl, np.array([ff(t) for t in run.rollout.t[:-1]]))


def test_wrong_mass_runs_are_judged_on_the_true_mjcf_and_replay_exactly(study):
    true, wrong = study.model.params, study.wrong_plan.model.params
    assert study.mass_error == 0.1
    assert wrong.pole_mass == pytest.approx(1.1 * true.pole_mass)
    assert wrong.pole_com_distance == pytest.approx(true.pole_com_distance)
    for name in ("wrong_mass_tvlqr", "wrong_mass_feedforward"):
        run = study.runs[name]
        assert run.replays_exactly and replays_exactly(run.rollout)
        assert run.success == swingup_success(run.rollout, study.model)   # whatever MuJoCo says, judged on x_eq
    # the wrong model makes the feedforward alone miss its own plan by more than the exact model's does
    assert (study.runs["wrong_mass_feedforward"].max_angle_tracking_error
            > study.runs["feedforward"].max_angle_tracking_error)
    assert not study.runs["wrong_mass_feedforward"].success


def test_tracking_errors_are_the_largest_deviation_from_the_followed_plan_during_it(study):
    run = study.runs["wrong_mass_tvlqr"]
    plan = study.wrong_plan.trajectory
    span = run.rollout.t <= plan.t[-1]
    e = study.model.state_error(run.rollout.x[span], plan.state(run.rollout.t[span]))
    assert run.max_angle_tracking_error == np.abs(e[:, list(study.model.hinges)]).max()
    assert run.max_cart_tracking_error == np.abs(e[:, study.model.slide]).max()
    assert run.peak_ctrl == np.abs(run.rollout.ctrl).max()


@pytest.mark.parametrize("bad", [-2, -1, -0.95, 1e308, float("nan"), float("inf"), "abc", None])
def test_a_mass_error_that_is_not_a_finite_number_above_minus_one_is_one_sentence(bad):
    with pytest.raises(FeedforwardError) as exc:
        check_mass_error(bad)
    msg = str(exc.value)
    assert "\n" not in msg and msg.endswith(".") and "mass error" in msg


def test_a_bad_mass_error_is_refused_before_anything_is_solved(monkeypatch):
    import cartpole.planning.trajopt as pipeline

    def no_solve(*a, **k):
        raise AssertionError("trajopt ran before the input was checked")

    monkeypatch.setattr(pipeline, "trajopt_swingup", no_solve)
    with pytest.raises(FeedforwardError):
        FeedforwardOptions(mass_error=math.nan)
    with pytest.raises(FeedforwardError):
        FeedforwardOptions(extra=0.5)
    with pytest.raises(FeedforwardError, match="options must be a FeedforwardOptions"):
        run_feedforward(None, {"mass_error": 0.1})


def test_a_zero_mass_error_reuses_the_plan_and_repeats_the_true_runs(study):
    again = run_feedforward(read_params(), FeedforwardOptions(mass_error=0.0), plan=study.plan)
    assert again.wrong_plan is study.plan
    for a, b in (("wrong_mass_tvlqr", "feedforward_tvlqr"), ("wrong_mass_feedforward", "feedforward")):
        assert np.array_equal(again.runs[a].rollout.x, study.runs[b].rollout.x)
        assert again.runs[a].success == study.runs[b].success


def test_the_figure_has_one_angle_panel_per_pole_the_cart_and_each_ctrl_with_legends(study):
    from cartpole.viz.feedforward_plot import feedforward_figure

    params = study.model.params
    runs = {RUNS[n]: r.rollout for n, r in study.runs.items()}
    plans = {"plan": study.plan.trajectory, "wrong plan": study.wrong_plan.trajectory}
    fig = feedforward_figure(runs, plans, params, model=study.model)
    axes = fig.get_axes()
    assert len(axes) == len(params.hinges) + 1 + params.nu
    labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
    assert labels == list(plans) + list(runs)
    assert "deg" in axes[0].get_ylabel() and "(m)" in axes[1].get_ylabel() and "N x ctrl" in axes[2].get_ylabel()
    assert axes[-1].get_xlabel().startswith("time (s)")
    for a in axes:   # every run and every plan drawn on every panel (lines broken at wraps are still one line)
        assert len([ln for ln in a.get_lines() if ln.get_label() in runs]) == len(runs)
        assert len([ln for ln in a.get_lines() if ln.get_label() in plans]) == len(plans)

