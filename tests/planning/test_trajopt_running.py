"""A running objective whose refinement converges from no guess keeps the swing-up the time stage found: never "no
swing-up found" where one exists (issue 23, deliverable 2)."""
import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.collocation import OCPNotSolved
from cartpole.planning import trajopt
from cartpole.planning.options import PlanOptions
from cartpole.sim import replays_exactly, simulate


def test_a_running_objective_that_converges_nowhere_keeps_the_time_plan(monkeypatch):
    model = build_model(SHIPPED_MJCF)

    def refuse(ocp, x0, name, guess, stage, *, sqp=False):
        raise OCPNotSolved("No swing-up found (refinement refused by the test)", attempts=())

    monkeypatch.setattr(trajopt, "_continue_from", refuse)
    sp = trajopt.trajopt_swingup(model.params, plan_model=model, options=PlanOptions(objective="tracking"))
    info = sp.solve_info
    assert info.success and "not converged from any guess: the time plan kept" in info.status
    assert sp.T_min is not None and sp.T == np.float64(sp.trajectory.t[-1] - sp.trajectory.t[0])
    assert sp.T > sp.T_min  # the time plan, resting at upright until T = T_min + the running objective's hold
    # and it is a swing-up: tracked in MuJoCo, it ends upright, and the log replays
    run = simulate(model.params, sp.controller, model.x_hanging, sp.T + 1.0)
    assert run.info.get("diverged") is None  # a blown-up run is reset to qpos0, upright on this file
    assert run.t[-1] >= sp.T + 1.0 - 1e-9
    err = np.abs(np.angle(np.exp(1j * (run.x[-1][list(model.hinges)] - model.x_eq[list(model.hinges)]))))
    assert np.all(err < 0.05) and replays_exactly(run)
