"""The exported C in the MuJoCo loop: the same ctrl as the Python controller at every control step (double), a
successful float run, and MuJoCo runs that replay bit for bit with plain mj_step."""
import numpy as np
import pytest

from cartpole.export import design_export, load_design, run_lockstep
from cartpole.export.folder import discard
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions

TWO_POLE = "cartpole/assets/cartpole_two_pole.xml"


@pytest.fixture(scope="module")
def one_pole():
    return build_model(None)


def _lockstep(model, method, loop, real, x0, duration):
    design = design_export(model, method, loop)
    ctl, folder = load_design(design, real)
    try:
        return design, run_lockstep(design, ctl, x0, duration)
    finally:
        discard(folder)


def _start(model, tilt=0.1):
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += tilt
    return x0


def _replays(run):
    from mj_replay import replay_with_mj_step

    r = run.rollout
    qpos, qvel = replay_with_mj_step(r.mjcf, r.qpos[0], r.qvel[0], r.ctrl)
    return np.array_equal(qpos, r.qpos) and np.array_equal(qvel, r.qvel)


def _upright_at_end(model, run):
    e = model.state_error(run.rollout.x[-1])
    return bool(np.all(np.abs(e[list(model.hinges)]) < 0.05)) and run.rollout.info["diverged"] is None


CASES = [
    ("lqr", None),
    ("lqr", LoopOptions(period=0.01, delay=0.01)),  # estimator none, the delay predicted through the model
    ("lqr", LoopOptions(period=0.01, delay=0.02, estimator="kf", encoder_cpr=2048, sensor_noise=1e-3)),
    ("pid", None),
    ("pid", LoopOptions(period=0.01, estimator="kf", encoder_cpr=4096)),
]


@pytest.mark.parametrize("method,loop", CASES, ids=lambda v: str(v) if isinstance(v, str) else "")
def test_double_export_gives_the_python_ctrl_at_every_step_and_replays(one_pole, method, loop):
    design, run = _lockstep(one_pole, method, loop, "double", _start(one_pole), 3.0)
    assert run.t.size == round(3.0 / design.program.period)
    assert run.max_ctrl_diff <= 1e-9
    assert np.all(run.codes == 0)
    # the ctrl MuJoCo applied is the C's, held over each period, starting after the delay
    lag, steps = design.program.lag, design.program.steps
    applied = run.rollout.ctrl[lag::steps]
    np.testing.assert_array_equal(applied, run.c_ctrl[:len(applied)])
    assert _replays(run)
    assert _upright_at_end(one_pole, run)


@pytest.mark.parametrize("method,loop", CASES[::2], ids=lambda v: str(v) if isinstance(v, str) else "")
def test_float_export_balances_too(one_pole, method, loop):
    _, run = _lockstep(one_pole, method, loop, "float", _start(one_pole), 3.0)
    assert 0 < run.max_ctrl_diff < 1e-3  # single precision: close, not equal
    assert _replays(run) and _upright_at_end(one_pole, run)


@pytest.mark.parametrize("loop", [None, LoopOptions(period=0.01, estimator="kf", encoder_cpr=4096)])
def test_two_pole_lqr_export_matches_python(loop):
    model = build_model(TWO_POLE)
    _, run = _lockstep(model, "lqr", loop, "double", _start(model, 0.02), 3.0)
    assert run.max_ctrl_diff <= 1e-9 and _replays(run) and _upright_at_end(model, run)
    _, runf = _lockstep(model, "lqr", loop, "float", _start(model, 0.02), 3.0)
    assert _replays(runf) and _upright_at_end(model, runf)
