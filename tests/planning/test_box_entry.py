"""A sparse dm_control reward's own plan (cartpole.planning.box_entry): into the task's box earlier than the smooth
surrogate's plan, exact on the MJCF's step, in the box from then on, and paid exactly that in MuJoCo."""
import casadi as ca
import numpy as np

from cartpole.apps.swingup import SwingupOptions, run_swingup
from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.bounds import bounds_from_params
from cartpole.ocp.dmc import sparse_box
from cartpole.planning.box_entry import box_entry_plan
from cartpole.planning.options import PlanOptions
from cartpole.sim import replays_exactly

DMC_CARTPOLE = SHIPPED_MJCF.with_name("dmc_cartpole.xml")
SPARSE = "dmc_cartpole_swingup_sparse"


def test_the_sparse_plan_enters_the_box_earlier_and_mujoco_pays_every_step_from_there():
    model = build_model(DMC_CARTPOLE)
    res = run_swingup(model, "trajopt", SwingupOptions(plan=PlanOptions(objective=SPARSE)))
    plan = res.metrics["plan"]["discrete"]
    box = plan["box_entry"]
    assert box["K"] < box["K_surrogate"], box
    assert plan["defect_after"] < 1e-9  # exact on MuJoCo's step
    assert res.success and not res.metrics["diverged"] and replays_exactly(res.rollout)
    # dm_control pays step j for the state after it: in the box from state K on is 1000 - K + 1 steps
    assert res.metrics["return"] == res.metrics["return_steps"] - box["K"] + 1


def test_no_box_plan_when_the_reference_does_not_end_in_the_box():
    model = build_model(DMC_CARTPOLE)
    n = 20
    x_ref = np.tile(model.x_hanging, (n + 1, 1))  # hanging all along: never in the box
    u_ref = np.zeros((n, model.nu))
    b = bounds_from_params(model.params)
    assert box_entry_plan(model, SPARSE, model.x_hanging, x_ref, u_ref, model.x_hanging, b) is None
    g, lower, upper = sparse_box(model, SPARSE, ca.SX.sym("x", model.nx))
    assert np.all(np.isinf(upper[1:])) and np.all(np.isfinite(lower))  # a cosine's 1 never binds
