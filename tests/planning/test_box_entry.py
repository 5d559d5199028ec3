"""A sparse dm_control reward's own plan (cartpole.planning.box_entry): into the task's box earlier than the smooth
surrogate's plan, exact on the MJCF's step, in the box from then on, and paid exactly that in MuJoCo."""
import casadi as ca
import numpy as np

from cartpole.apps.swingup import SwingupOptions, run_swingup
from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.bounds import bounds_from_params
from cartpole.ocp.dmc import sparse_box
from cartpole.planning import box_entry
from cartpole.planning.box_entry import BOX_MARGIN, box_entry_plan, box_function, entry_step
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


def test_entry_step_builds_the_box_once_per_model_and_task_and_finds_the_first_step_staying_inside(monkeypatch):
    model = build_model(DMC_CARTPOLE)
    monkeypatch.setattr(box_entry, "_SOLVERS", {})
    built = []

    def counted(m, name, x):
        built.append(name)
        return sparse_box(m, name, x)
    monkeypatch.setattr(box_entry, "sparse_box", counted)
    s = np.linspace(0.0, 1.0, 41)[:, None]  # hanging to upright in a straight line of states
    x = (1 - s) * np.asarray(model.x_hanging, float) + s * np.asarray(model.x_eq, float)
    xs = ca.SX.sym("x", model.nx)
    g, lower, upper = sparse_box(model, SPARSE, xs)
    G = np.array([np.asarray(ca.Function("g", [xs], [g])(xk), float).ravel() for xk in x])
    for margin in (0.0, BOX_MARGIN, 1e-3):
        inside = np.all((G >= lower + margin) & (G <= upper - margin), axis=1)
        first = next(k for k in range(x.shape[0]) if inside[k:].all())
        assert 0 < first < x.shape[0] - 1 and entry_step(model, SPARSE, x, margin) == first
    assert entry_step(model, SPARSE, x[::-1]) is None  # ends hanging, outside
    assert built == [SPARSE]  # one box for every call
    assert box_function(build_model(DMC_CARTPOLE), SPARSE)[0] is box_function(model, SPARSE)[0]  # by the model's hash
