"""One implementation in the loop (issue 39): the MuJoCo loop runs the compiled program of the export (built once
per design through cartpole.codegen), and it gives, every period of a whole MuJoCo run, exactly the ctrl of the
exported folder's cp_step compiled with the strict flags and driven from the same measurements; the Python
classes (the path without a compiler) agree with it on the same inputs to 1e-9."""
import numpy as np
import pytest

from cartpole.codegen import compiler
from cartpole.export import design_export, load_design, run_lockstep
from cartpole.export.folder import discard
from cartpole.export.inloop import compile_program, run_compiled
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler")

MJCF = {1: None, 2: "cartpole/assets/cartpole_two_pole.xml", 3: "cartpole/assets/cartpole_three_pole.xml"}
LOOPS = {"none": None,
         "kf": LoopOptions(period=0.01, delay=0.01, estimator="kf", encoder_cpr=2048, sensor_noise=1e-3),
         "ekf": LoopOptions(period=0.01, delay=0.01, estimator="ekf", encoder_cpr=2048)}
#: The Python reference against the C on the same inputs (the same algorithm in numpy's and C's arithmetic).
PYTHON_TOL = 1e-9
#: Seconds of each run: short, the claim is per period, not about the end state.
DURATION = 0.4

CASES = ([(1, m, e) for m in ("lqr", "pid") for e in ("none", "kf", "ekf")]
         + [(1, m, e) for m in ("tvlqr", "energy") for e in ("none", "ekf")]
         + [(n, "lqr", e) for n in (2, 3) for e in ("none", "kf", "ekf")]
         + [(2, "tvlqr", "none")])

_MODELS = {}


def _model(poles):
    if poles not in _MODELS:
        _MODELS[poles] = build_model(MJCF[poles])
    return _MODELS[poles]


def _start(model, method):
    if method in ("tvlqr", "energy"):
        return np.array(model.x_hanging, dtype=float)
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += 0.05
    return x0


@pytest.mark.parametrize("poles,method,estimator", CASES, ids=lambda v: str(v))
def test_the_loops_compiled_program_is_the_exported_folders_cp_step_bit_for_bit(poles, method, estimator):
    model = _model(poles)
    design = design_export(model, method, LOOPS[estimator], rho=1.0 if method == "energy" else None)
    x0 = _start(model, method)
    inloop = compile_program(design)
    rollout = run_compiled(design, x0, DURATION, ctl=inloop)
    # the Python path beside the same compiled program, on the same inputs
    run = run_lockstep(design, inloop, x0, DURATION)
    assert run.max_ctrl_diff <= PYTHON_TOL
    np.testing.assert_array_equal(rollout.qpos, run.rollout.qpos)  # run_compiled is that run
    np.testing.assert_array_equal(rollout.ctrl, run.rollout.ctrl)
    # the exported folder, compiled with the strict flags, driven step by step from the loop's measurements
    folder_ctl, folder = load_design(design)
    try:
        folder_ctl.reset()
        c = np.array([folder_ctl.step(t, y)[1] for t, y in zip(run.t, run.y)])
    finally:
        discard(folder)
    np.testing.assert_array_equal(c, run.c_ctrl)
    lag, steps = design.program.lag, design.program.steps
    applied = rollout.ctrl.reshape(len(rollout.ctrl), -1)[lag::steps]
    np.testing.assert_array_equal(applied, c[:len(applied)])
    if design.rig is not None:  # the loop logs what cp_step received and the C's own estimate
        np.testing.assert_array_equal(rollout.y, run.y)
        assert rollout.x_hat.shape == (len(run.t), model.nx) and np.all(np.isfinite(rollout.x_hat))


def test_a_compiled_program_is_built_once_per_design_and_shared_state_is_refused():
    from cartpole.export import ExportError

    model = _model(1)
    design = design_export(model, "lqr", None)
    first, second = compile_program(design), compile_program(design)
    assert first.lib_path == second.lib_path  # the cache: one library for one design's files
    first.reset()
    first.step(0.0, model.x_eq)
    second.reset()  # the same static memory
    with pytest.raises(ExportError, match="reset"):
        first.step(0.01, model.x_eq)


def test_the_float32_program_balances_in_the_loop():
    from cartpole.export.inloop import InLoopController  # noqa: F401 - the float build loads the same way

    model = _model(1)
    design = design_export(model, "lqr", LOOPS["kf"])
    ctl = compile_program(design, "float")
    rollout = run_compiled(design, _start(model, "lqr"), 3.0, ctl=ctl)
    e = model.state_error(rollout.x[-1])
    assert np.all(np.abs(e[list(model.hinges)]) < 0.05) and rollout.info["diverged"] is None
