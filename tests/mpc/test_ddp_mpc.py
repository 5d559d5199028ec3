"""MPC by warm-started DDP in the MuJoCo loop: one and two poles swing up from hanging and hold, one solve logged
per period, no safe action needed, the runs replay exactly; the solver is picked by MPCOptions and --mpc-solver."""
import json

import numpy as np
import pytest

from cartpole.apps.swingup import run_swingup
from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF
from cartpole.mpc.ddp_mpc import DDPMPCController
from cartpole.mpc.options import MPCOptions, NMPCError
from cartpole.sim import replays_exactly


@pytest.mark.parametrize("mjcf", [SHIPPED_MJCF, SHIPPED_MJCF.with_name("cartpole_two_pole.xml")],
                         ids=["one_pole", "two_pole"])
def test_ddp_mpc_swings_up_and_holds_in_mujoco(mjcf):
    res = run_swingup(mjcf, method="mpc", mpc=MPCOptions(solver="ddp"))
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
