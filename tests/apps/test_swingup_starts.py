"""Swing-ups re-planned from starts other than hanging rest, tracked on a plan that is exact for MuJoCo's step.

The collocation plan obeys the continuous dynamics; MuJoCo steps the MJCF's integrator (semi-implicit Euler at
5 ms on the shipped carts), and that integrator's per-step error along the plan is a disturbance TVLQR had to
reject every step (on the three-pole cart it made the re-planned swing-up from the cart at 0.3 m lose the track
and hit the rail). ``trajopt_swingup`` predicts TVLQR on the exact discrete step and, where it strays from the plan,
re-solves the plan on the exact discrete model with a ctrl margin
(:func:`cartpole.planning.trajopt.exact_discrete_plan`) and TVLQR tracks that. Every claim here is a MuJoCo rollout
that replays exactly; success is :func:`cartpole.validation.metrics.swingup_metrics` over the last 3 s.
"""
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.ocp.bounds import bounds_from_params
from cartpole.planning.trajopt import exact_discrete_plan, trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.metrics import swingup_metrics
from cartpole.planning.options import PlanOptions

HOLD = 3.0


def _params(name):
    return read_params(SHIPPED_MJCF if name == "one_pole" else SHIPPED_MJCF.with_name(f"cartpole_{name}.xml"))


def _run(params, plan, x0):
    model = build_model(params)
    ro = simulate(params, plan.controller, x0, plan.T + HOLD + 2.0)
    assert replays_exactly(ro, params)
    np.testing.assert_array_equal(ro.x[0], x0)
    return ro, swingup_metrics(ro, model, hold=HOLD)


@pytest.fixture(scope="module")
def single():
    params = _params("one_pole")
    return params, trajopt_swingup(params, options=PlanOptions(exact_discrete=False))


def test_the_exact_discrete_plan_is_a_solution_of_the_mjcf_step_with_a_ctrl_margin(single):
    params, plan = single
    model = build_model(params)
    bounds = bounds_from_params(params)
    x0 = model.x_hanging
    exact = exact_discrete_plan(model, plan.trajectory, x0, bounds, dt=params.timestep, u_margin=0.1)
    assert exact is not None and exact.status == "Solve_Succeeded"
    assert exact.t.size == round(plan.T / params.timestep) and exact.x.shape == (exact.t.size + 1, model.nx)
    np.testing.assert_allclose(exact.x[0], x0, atol=1e-12)
    np.testing.assert_allclose(exact.x[-1], plan.trajectory.x[-1], atol=1e-8)
    # each step is one step of the MJCF's integrator (model.step agrees with mj_step), unlike the collocation plan
    steps = np.array([np.asarray(model.step(exact.x[k], exact.u[k])).ravel() for k in range(exact.t.size)])
    assert np.abs(steps - exact.x[1:]).max() < 1e-8
    assert exact.defect_after < 1e-8 < exact.defect_before
    half = 0.5 * (bounds.u_high - bounds.u_low)
    assert np.all(exact.u <= bounds.u_high - 0.1 * half + 1e-9) and np.all(exact.u >= bounds.u_low + 0.1 * half - 1e-9)
    # the feed-forward alone, replayed in MuJoCo, follows the plan (up to the unstable growth of round-off)
    from cartpole.sim import replay
    ro = replay(params, x0, exact.u)
    k = exact.t.size // 2
    assert np.abs(model.state_error(ro.x[k], exact.x[k])).max() < 1e-6


def test_tvlqr_on_the_exact_plan_keeps_mujoco_on_it_and_hands_over_at_its_end():
    params = _params("two_pole")
    model = build_model(params)
    plan = trajopt_swingup(params, options=PlanOptions(exact_discrete=True))
    assert plan.discrete is not None and plan.gains.has_reference
    ro, m = _run(params, plan, model.x_hanging)
    assert m["success"], m
    assert plan.controller.handover_time == pytest.approx(plan.discrete.t_final)
    assert plan.controller.handover_time == pytest.approx(plan.T, abs=params.timestep)
    # from the plan's own start, MuJoCo stays on the exact plan: no defect left for the feedback to reject
    on = ro.t < plan.discrete.t_final - 1e-9
    k = np.round((ro.t[on] - plan.discrete.t[0]) / params.timestep).astype(int)
    err = np.abs(model.state_error(ro.x[on], plan.discrete.x[k])).max()
    print(f"two_pole: defect of the collocation plan {plan.discrete.defect_before:.3g}, tracking error {err:.3g}")
    assert err < 1e-4
    lo, hi = np.asarray(params.ctrl_range, float).T
    assert np.all(plan.discrete.u < hi) and np.all(plan.discrete.u > lo)


def test_the_triple_replanned_with_the_cart_off_centre_swings_up_and_holds():
    params = _params("three_pole")
    model = build_model(params)
    x0 = np.array(model.x_hanging, dtype=float)
    x0[model.slide] = 0.3
    plan = trajopt_swingup(params, x0)
    # the prediction on the exact discrete step strays from the collocation plan, so the plan is re-solved on it
    assert plan.discrete is not None and plan.gains.has_reference
    ro, m = _run(params, plan, x0)
    print(f"three_pole from the cart at 0.3 m: {m}, discrete plan {plan.discrete and plan.discrete.as_dict()}")
    assert m["success"], m


def test_auto_keeps_the_collocation_plan_where_tvlqr_is_predicted_to_track_it():
    from cartpole.control.tvlqr import TVLQRController
    from cartpole.planning.trajopt import TRACK_TOL, predicted_tracking_error

    params = _params("two_pole")
    model = build_model(params)
    plan = trajopt_swingup(params)  # exact_discrete="auto"
    assert plan.discrete is None and not plan.gains.has_reference
    # the prediction is the MuJoCo run (the MJCF's own model): its largest hinge deviation is within TRACK_TOL
    err = predicted_tracking_error(model, TVLQRController(plan.trajectory, plan.gains, plan.catch,
                                                         u_limits=params.ctrl_range), plan.trajectory, model.x_hanging)
    ro, m = _run(params, plan, model.x_hanging)
    n = int(round(plan.T / params.timestep))
    dev = max(np.abs(ro.x[k][list(model.hinges)] - plan.trajectory.state(ro.t[k])[list(model.hinges)]).max()
              for k in range(1, n + 1))
    assert err == pytest.approx(dev, abs=1e-9) and err <= TRACK_TOL
    assert m["success"], m


def test_without_the_exact_plan_the_controller_tracks_the_collocation_plan_as_before(single):
    params, plan = single
    assert plan.discrete is None and not plan.gains.has_reference
    assert plan.controller.T == pytest.approx(plan.T)
    ro, m = _run(params, plan, build_model(params).x_hanging)
    assert m["success"], m
