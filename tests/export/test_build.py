"""cartpole.export.build: a program is compiled translation unit by translation unit, each object cached by its
content, so a second plan on the same model compiles its tables, never the model's CasADi-generated code again."""
import numpy as np
import pytest

from cartpole import codegen
from cartpole.control.linear import LinearFeedback
from cartpole.control.model_rollout import model_rollout
from cartpole.control.tvlqr import TVLQRController
from cartpole.export.build import program_library
from cartpole.export.controllers import tvlqr_part
from cartpole.export.design import build_program
from cartpole.export.make import c_sources
from cartpole.models import build_model
from cartpole.ocp.trajectory import Trajectory
from cartpole.riccati import tvlqr
from cartpole.sim.options import LoopOptions
from cartpole.sim.rig import build_rig

pytestmark = pytest.mark.skipif(codegen.compiler() is None, reason="no C compiler")

EKF = LoopOptions(period=0.01, delay=0.01, estimator="ekf", encoder_cpr=2048)


def _plan_program(model, rig, angle, knots):
    """A TVLQR program along a short plan: the catch's own motion from ``angle`` off upright (the same C and
    tables as a collocation plan's)."""
    catch = LinearFeedback.for_model(model, period=int(rig.steps) * model.dt)
    n = 10 * knots
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += angle
    xs, us = model_rollout(model, catch, x0, n, u_limits=np.column_stack([catch.u_low, catch.u_high]))
    us = np.vstack([us, us[-1:]])
    k = np.arange(0, n + 1, 10)
    xdot = np.array([np.asarray(model.f(x, u), dtype=float).ravel() for x, u in zip(xs[k], us[k])])
    traj = Trajectory(t=k * model.dt, x=xs[k], u=us[k], xdot=xdot)
    tv = TVLQRController(traj, tvlqr(model, traj, dt=int(rig.steps) * model.dt), catch)
    return build_program(model, rig, tvlqr_part(tv), title="a short plan")


def _objects(cache):
    return {p.name for p in (cache / codegen.OBJECT_DIR).glob("*.o")}


def _stems(names):
    return sorted(n.rsplit("_", 1)[0] for n in names)


def test_a_second_plan_on_the_same_model_reuses_the_models_compiled_code(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(cache))
    model = build_model(None)
    rig = build_rig(model, EKF, task="swingup")
    first_files = c_sources(_plan_program(model, rig, 0.05, 10))
    second_files = c_sources(_plan_program(model, rig, 0.08, 12))
    assert first_files["src/cp_plan.h"] != second_files["src/cp_plan.h"]  # two plans: other tables, other lengths
    assert first_files["src/cp_generated.c"] == second_files["src/cp_generated.c"]  # one model
    first = program_library(first_files)
    after_first = _objects(cache)
    assert _stems(after_first) == sorted(rel.split("/")[-1][:-2] for rel in first_files if rel.endswith(".c"))
    second = program_library(second_files)
    new = _objects(cache) - after_first
    assert second != first
    assert [n for n in _objects(cache) if n.startswith("cp_generated_")] == [
        n for n in after_first if n.startswith("cp_generated_")]  # one object of the model's generated code
    assert _stems(new) == ["cp_data", "cp_tvlqr"]  # the plan's tables and the one file that reads them
