"""MPC by warm-started DDP in the MuJoCo loop: one and two poles swing up from hanging and hold, one solve logged
per period, no safe action needed, the runs replay exactly; the solver is picked by MPCOptions and --mpc-solver."""
import json

import numpy as np
import pytest

from cartpole.apps.swingup import SwingupOptions, run_swingup
from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF
from cartpole.mpc.ddp_mpc import DDPMPCController
from cartpole.mpc.options import MPCOptions, NMPCError
from cartpole.sim import LoopOptions, replays_exactly


@pytest.mark.parametrize("mjcf", [SHIPPED_MJCF, SHIPPED_MJCF.with_name("cartpole_two_pole.xml")],
                         ids=["one_pole", "two_pole"])
def test_ddp_mpc_swings_up_and_holds_in_mujoco(mjcf):
    res = run_swingup(mjcf, "mpc", SwingupOptions(mpc=MPCOptions(solver="ddp")))
    c = res.controller
    assert isinstance(c, DDPMPCController)
    assert res.success, res.metrics
    assert replays_exactly(res.rollout)
    assert not c.failures
    # one solve per control period, the ctrl held in between (logged every physics step)
    assert len(c.solve_ms) == pytest.approx(res.rollout.ctrl.shape[0] / c.steps, abs=1)
    held = res.rollout.ctrl.reshape(-1, c.steps, c.model.nu)
    assert np.all(held == held[:, :1])
    assert c.N * c.period == pytest.approx(c.horizon) and c.period == pytest.approx(0.02)


def test_the_mpc_solver_is_an_option_and_a_flag(tmp_path, capsys):
    with pytest.raises(NMPCError, match="not one of rti, ddp"):
        MPCOptions(solver="ilqr")
    assert main(["swingup", "--method", "energy", "--mpc-solver", "ddp", "--no-video", "--out", str(tmp_path)]) == 2
    assert "use it with --method mpc" in capsys.readouterr().err
    assert main(["swingup", "--method", "mpc", "--mpc-solver", "ddp", "--duration", "4", "--no-video", "--json",
                 "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["success"] and len(doc["solve_ms"]) == 200


DMC_CARTPOLE = SHIPPED_MJCF.with_name("dmc_cartpole.xml")


def test_ddp_mpc_maximises_a_dm_control_reward_in_the_loop_and_scores_the_whole_episode():
    res = run_swingup(DMC_CARTPOLE, "mpc",
                      SwingupOptions(mpc=MPCOptions(solver="ddp", objective="dmc_cartpole_swingup")))
    c, m = res.controller, res.metrics
    assert c.objective == "dmc_cartpole_swingup" and c.terminal == "objective"
    assert res.success and not m["diverged"] and not c.failures, m
    assert replays_exactly(res.rollout)
    # the episode dm_control scores: 1000 control steps of 0.01 s, each paid at most 1
    assert m["return_steps"] == 1000 and 0.5 * m["return_steps"] < m["return"] <= m["return_steps"]
    assert res.options["plan"].objective == "dmc_cartpole_swingup"  # the seed planned for the same reward


def test_ddp_mpc_takes_the_effort_objective_and_the_legacy_keyword():
    res = run_swingup(SHIPPED_MJCF, "mpc", SwingupOptions(mpc=MPCOptions(solver="ddp", objective="effort"),
                                                       loop=LoopOptions(duration=5.0)))
    c = res.controller
    assert c.objective == "effort" and c.terminal == "lqr scaled"
    assert res.success and replays_exactly(res.rollout) and not c.failures, res.metrics
    assert "return" not in res.metrics


def test_an_objectives_terminal_weight_is_its_own_lqr_cost_to_go():
    import casadi as ca

    from cartpole.riccati import dlqr
    from cartpole.models import build_model
    from cartpole.mpc.ddp_mpc import objective_cost_to_go

    model = build_model(SHIPPED_MJCF)
    nx, nu = model.nx, model.nu
    Q = np.diag(np.arange(1.0, nx + 1))
    R = 0.3 * np.eye(nu)
    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    dx, du = x - model.x_eq, u - model.u_eq
    quad = ca.Function("quad", [x, u], [ca.bilin(ca.DM(Q), dx, dx) + ca.bilin(ca.DM(R), du, du)])
    period = 0.02
    Ad, Bd = model.hold(4).linearize(model.x_eq, model.u_eq)
    S, source = objective_cost_to_go(model, Ad, Bd, quad, period, np.eye(nx), np.eye(nu))
    assert source == "objective"
    want = dlqr(Ad, Bd, Q * period, R * period).S
    assert np.allclose(S, want, rtol=1e-9, atol=1e-12)
    # effort prices no state: no stabilising Riccati solution, the fallback LQR scaled to its input weight (1 vs 0.1)
    S_lqr = dlqr(Ad, Bd, np.eye(nx) * period, 0.1 * np.eye(nu) * period).S
    S_e, source_e = objective_cost_to_go(model, Ad, Bd, None, period, S_lqr, 0.1 * np.eye(nu))
    assert source_e == "lqr scaled" and np.allclose(S_e, 10.0 * S_lqr)


def test_the_mpc_objective_is_refused_where_it_cannot_run(tmp_path, capsys):
    with pytest.raises(NMPCError, match="not a running cost"):
        MPCOptions(solver="ddp", objective="time")
    with pytest.raises(NMPCError, match=r"`MPCOptions\(solver='ddp'\)`"):
        MPCOptions(objective="effort")  # the RTI NMPC is Gauss-Newton on the tracking cost
    assert MPCOptions(objective="tracking").objective == "tracking"
    for argv, says in ((["--method", "mpc", "--objective", "effort"], "--mpc-solver ddp"),
                       (["--method", "mpc", "--mpc-solver", "ddp", "--objective", "time"], "not a running cost"),
                       (["--method", "mpc", "--mpc-solver", "ddp", "--objective", "nosuch"], "is not known"),
                       (["--method", "energy", "--objective", "effort"], "--method trajopt or mpc")):
        out = tmp_path / argv[1]
        assert main(["swingup", *argv, "--no-video", "--json", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert not out.exists()


def test_the_cli_reports_the_mpc_objective_and_the_return(tmp_path, capsys):
    assert main(["swingup", "--mjcf", str(DMC_CARTPOLE), "--method", "mpc", "--mpc-solver", "ddp", "--objective",
                 "dmc_cartpole_swingup_sparse", "--no-video", "--json", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["objective"] == "dmc_cartpole_swingup_sparse" and doc["return_steps"] == 1000
    assert doc["success"] and not doc["diverged"] and doc["return"] > 500
    assert doc["options"]["mpc"]["objective"] == "dmc_cartpole_swingup_sparse"
