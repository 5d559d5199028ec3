"""The supervisor in dm_control's own cart-pole episodes (cartpole.apps.envscore.supervised): it plans its swing-up
warm from a library of the task's plans, the energy law pumping while the plan is made, and is upright sooner than
the energy law alone. Each plan is charged a fixed latency (``charged_latency``), so the runs do not depend on the
machine's speed; the library is the test's own (one cold plan from hanging), not the user cache's."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from cartpole.apps.envscore import ASSETS, SUPERVISOR_OBJECTIVES, score_episode, supervised
from cartpole.models import build_model
from cartpole.planning.library import PlanLibrary, build_plan_library
from cartpole.planning.options import PlanOptions
from cartpole.supervise import SupervisorOptions, supervisor_for

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


def test_supervisor_plans_warm_from_the_library_and_is_caught_sooner_than_the_energy_law(library):
    """From dm_control's seed-0 start the supervisor's first decision is a plan made warm from the stored plan, used
    from the charged latency on; the catch takes over sooner than under the energy law alone, the episode pays more
    over the same steps, and both runs replay exactly without a warning."""
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
    assert caught is not None and caught_law is not None and caught["t"] < caught_law["t"]
    assert planned.return_ > law.return_
    assert np.all(np.abs(planned.ctrl) <= 1.0)


def test_an_empty_library_leaves_the_energy_law_in_charge():
    """With cart_plans but no stored plan the supervisor on a cart-pole does not plan (a cold plan is no quick plan):
    the energy law and the catch, as without the option."""
    mjcf = str(ASSETS / "dmc_cartpole.xml")
    model = build_model(mjcf)
    sup = supervisor_for(mjcf, model, options=SupervisorOptions(cart_plans=True),
                         plan=PlanOptions(objective=SUPERVISOR_OBJECTIVES[ENV]), library=PlanLibrary.empty(model))
    assert sup.planner is None and sup.swingup is not None
