"""The supervisor in dm_control's own cart-pole episodes (cartpole.apps.envscore.supervised): it plans its swing-up
warm from a library of the task's plans, following the stored plan while the plan is made (the lead-in), tracks the
plan to its end before the catch, and earns more than the energy law alone; on the sparse task each plan in the loop
is one elastic box-entry solve from the stored plan's knot. Each plan is charged a fixed latency (``charged_latency``), so the runs do not depend on the
machine's speed; the library is the test's own (one cold plan from hanging), not the user cache's."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from cartpole.apps.envscore import ASSETS, SUPERVISOR_OBJECTIVES, score_episode, supervised
from cartpole.control import LinearFeedback
from cartpole.errors import CartPoleError
from cartpole.models import build_model
from cartpole.planning.box_entry import entry_step
from cartpole.ocp.bounds import bounds_from_params
from cartpole.planning.box_tail import STORED_MARGIN, box_tail_planner, kept_inside, on_step_grid
from cartpole.planning.library import PlanLibrary, build_plan_library
from cartpole.planning.options import PlanOptions
from cartpole.sim import simulate
from cartpole.supervise import SupervisorOptions, supervisor_for
from cartpole.supervise.lead_in import PlanLeadIn

ENV = "cartpole-swingup"
#: Environment steps of the short episodes (3.5 s): the energy law alone is caught within them.
STEPS = 350


@pytest.fixture(scope="module")
def library():
    """The plans the supervisor is warm-started from: one cold plan of the environment's objective from hanging."""
    model = build_model(str(ASSETS / "dmc_cartpole.xml"))
    lib = build_plan_library(model.params, model, [model.x_hanging],
                             options=PlanOptions(objective=SUPERVISOR_OBJECTIVES[ENV], solver="ipopt"))
    assert len(lib) == 1
    return lib


def _first(decisions, kind):
    return next((d for d in decisions if d["kind"] == kind), None)


def _energy_law(env, mjcf, x0, hold):
    return supervisor_for(mjcf, build_model(mjcf))  # no cart_plans: the energy law and the catch


def test_supervisor_plans_warm_from_the_library_and_earns_more_than_the_energy_law(library):
    """From dm_control's seed-0 start the supervisor's first decision is a plan made warm from the stored plan, used
    from the charged latency on; the catch takes over (at the plan's end), the episode pays more over the same steps
    than under the energy law alone, and both runs replay exactly without a warning."""
    latency = 0.3
    planned = score_episode(ENV, 0, controller=functools.partial(supervised, charged_latency=latency,
                                                                 library=library), max_steps=STEPS)
    law = score_episode(ENV, 0, controller=_energy_law, max_steps=STEPS)
    for ep in (planned, law):
        assert ep.replays and not ep.warned and ep.steps == STEPS
    plan = _first(planned.design["decisions"], "plan")
    assert plan is not None and plan["t"] == 0.0 and plan["warm"] and plan["charged_s"] == latency
    assert planned.design["warm_plans"] >= 1 and planned.design["plan_failures"] == 0
    track = _first(planned.design["decisions"], "track")
    assert track is not None and track["t"] == pytest.approx(latency, abs=1e-9)
    assert _first(law.design["decisions"], "plan") is None  # the law alone never plans
    caught, caught_law = (_first(ep.design["decisions"], "catch") for ep in (planned, law))
    assert caught is not None and caught_law is not None
    assert planned.return_ > law.return_
    assert np.all(np.abs(planned.ctrl) <= 1.0)


def test_an_empty_library_leaves_the_energy_law_in_charge():
    """With cart_plans but no stored plan the supervisor on a cart-pole does not plan (a cold plan is no quick plan):
    the energy law and the catch, as without the option; its planner waits for the law to run out (law_budget)."""
    mjcf = str(ASSETS / "dmc_cartpole.xml")
    model = build_model(mjcf)
    sup = supervisor_for(mjcf, model, options=SupervisorOptions(cart_plans=True),
                         plan=PlanOptions(objective=SUPERVISOR_OBJECTIVES[ENV]), library=PlanLibrary.empty(model))
    assert sup.swingup is not None
    sup(0.0, np.asarray(model.x_hanging, float))
    assert sup.mode == "swingup" and sup.plans == 0 and sup.asked is None


def test_first_plan_is_asked_from_the_library_plan_and_the_catch_waits_for_its_end(library):
    """From dm_control's near-rest start the supervisor follows the stored plan while its first plan is made (the
    lead-in), so that plan is asked at t = 0 from a state near a knot of the stored plan (not from where the energy
    law would have pumped to); the plan is tracked from the charged latency on, and the catch takes over only at the
    plan's end, not when the state first enters its basin."""
    latency = 0.3
    ep = score_episode(ENV, 0, controller=functools.partial(supervised, charged_latency=latency, library=library),
                       max_steps=STEPS)
    assert ep.replays and not ep.warned
    decisions = ep.design["decisions"]
    plan, track, catch = (_first(decisions, kind) for kind in ("plan", "track", "catch"))
    assert plan["t"] == 0.0 and plan["warm"] and plan["library_distance"] < 0.1
    assert track["t"] == pytest.approx(latency, abs=1e-9)
    assert catch is not None and catch["t"] >= track["t"] + plan["T"] - 0.011
    assert [d["kind"] for d in decisions[:3]] == ["plan", "track", "catch"]


def test_lead_in_hands_a_state_off_the_stored_plan_to_its_fallback(library):
    """The lead-in follows the stored plan only near it: a state a quarter turn off it, or a time past its end, gets
    the fallback law's ctrl."""
    mjcf = str(ASSETS / "dmc_cartpole.xml")
    model = build_model(mjcf)
    traj = library.plans[0].trajectory
    lead = PlanLeadIn(model, traj, lambda t, x: np.array([0.123]), LinearFeedback.for_model(model), float(model.dt))
    on = np.asarray(traj.state(0.2), dtype=float)
    off = on.copy()
    off[model.hinges[0]] += 0.5 * np.pi
    assert lead.leads(0.2, on) and not lead.leads(0.2, off) and not lead.leads(traj.duration + 0.1, on)
    assert lead(0.2, off)[0] == 0.123 and lead(0.2, on)[0] != 0.123


def test_sparse_plan_from_a_stored_plans_knot_enters_the_box_no_later_and_stays_in_mujoco(library):
    """The sparse task's planner in the loop (box_tail_planner) from a state near a knot of a stored plan enters
    dm_control's box no later than the stored plan's rest does, by one elastic solve on the exact step, and TVLQR
    along it keeps MuJoCo's run in the box from its entry to the plan's end; without a stored plan it refuses in one
    sentence (it never plans cold)."""
    mjcf = str(ASSETS / "dmc_cartpole.xml")
    model = build_model(mjcf)
    name = "dmc_cartpole_swingup_sparse"
    x = np.asarray(library.plans[0].trajectory.state(0.3), dtype=float) + np.r_[0.01, 0.004, 0.01, 0.02]
    guess, _ = library.knot_guesses(model, x, count=1)[0]
    planner = box_tail_planner(model.params, model, name)
    plan = planner(x, guess=guess, cold=False)
    K, K_stored = plan.discrete.box_entry["K"], entry_step(model, name, on_step_grid(guess, float(model.dt))[0], 0.0)
    assert K <= K_stored
    roll = simulate(mjcf, plan.controller, x, plan.trajectory.duration)
    inside = (np.abs(roll.qpos[:, 0]) < 0.25) & (np.cos(roll.qpos[:, model.hinges[0]]) > 0.995)
    assert np.all(inside[K:]) and not inside[0]
    with pytest.raises(CartPoleError, match="guess"):
        planner(x)


def test_a_stored_entry_plan_is_kept_inside_the_box_by_its_margin_on_the_exact_step(library):
    """What the sparse task's library keeps (kept_inside): a plan on the exact step that, from its entry on, stays
    STORED_MARGIN inside dm_control's box (the cosine and the cart), from the same start to the same end."""
    model = build_model(str(ASSETS / "dmc_cartpole.xml"))
    name = "dmc_cartpole_swingup_sparse"
    x_ref, u_ref = on_step_grid(library.plans[0].trajectory, float(model.dt))
    x, u = kept_inside(model, name, x_ref, u_ref, bounds_from_params(model.params, cart_margin=0.1))
    assert entry_step(model, name, x, margin=0.99 * STORED_MARGIN) is not None
    assert np.allclose(x[0], x_ref[0]) and np.allclose(x[-1], x_ref[-1])
    nxt = np.asarray(model.step.map(u.shape[0])(x[:-1].T, u.T)).T
    assert np.max(np.abs(nxt - x[1:])) < 1e-6


def test_after_a_failed_plan_the_stored_plan_is_followed_to_its_end_and_caught(library):
    """A first plan that fails (a planner that always refuses) leaves the lead-in following the stored plan, not the
    energy law: the catch takes over at the stored plan's end, the pole upright, and the failure is reported."""
    def failing(env, mjcf, x0, hold):
        sup = supervised(env, mjcf, x0, hold, charged_latency=0.3, library=library)

        def refuse(*args, **kwargs):
            raise CartPoleError("refused by the test")
        sup.planner = refuse
        return sup

    ep = score_episode(ENV, 0, controller=failing, max_steps=STEPS)
    assert ep.replays and not ep.warned
    decisions = ep.design["decisions"]
    assert decisions[0]["kind"] == "plan_failed" and ep.design["unreachable"]
    catch = _first(decisions, "catch")
    assert catch is not None and catch["t"] >= library.plans[0].trajectory.duration - 0.011
    assert np.cos(ep.x[-1][1]) > 0.99

