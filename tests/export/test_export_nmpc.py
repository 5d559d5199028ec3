"""The exported NMPC (real-time iteration, the condensed QP solved in C) in the MuJoCo swing-up: the Python
controller's ctrl at every control step in double, swung up and held in float32, both runs replaying bit for bit."""
import numpy as np
import pytest
from mj_replay import replay_with_mj_step

from cartpole.errors import CartPoleError
from cartpole.export import design_export, load_design, run_lockstep
from cartpole.export.folder import discard
from cartpole.models import build_model
from cartpole.validation.metrics import swingup_success


def _replays(rollout):
    qpos, qvel = replay_with_mj_step(rollout.mjcf, rollout.qpos[0], rollout.qvel[0], rollout.ctrl)
    return np.array_equal(qpos, rollout.qpos) and np.array_equal(qvel, rollout.qvel)


def test_nmpc_export_swings_up_step_for_step_like_python():
    model = build_model(None)
    design = design_export(model, "nmpc", None)
    assert design.program.period == 0.02 and design.program.steps == 4  # the NMPC's own period
    runs = {}
    for real in ("double", "float"):
        ctl, folder = load_design(design, real)
        try:
            runs[real] = run_lockstep(design, ctl, model.x_hanging, 8.0)
        finally:
            discard(folder)
    d, f = runs["double"], runs["float"]
    assert d.max_ctrl_diff <= 1e-9 and np.all(d.codes == 0)
    for run in (d, f):
        assert swingup_success(run.rollout, model.params) and _replays(run.rollout)
        assert run.rollout.info["diverged"] is None


def test_a_prestabilised_nmpc_is_refused():
    from cartpole.export.nmpc import nmpc_part

    class Fake:
        prestabilize = True

    with pytest.raises(CartPoleError, match="pre-stabilised"):
        nmpc_part(Fake(), None)
