"""One implementation in the loop (issue 39): the MuJoCo loop runs the compiled program of the export (built once
per content through cartpole.codegen), and it gives, every period of a whole MuJoCo run, exactly the ctrl of the
exported folder's cp_step compiled with the strict flags and driven from the same measurements; the Python
classes (the path without a compiler) agree with it on the same inputs to 1e-9, and so does the controller state
the swing-up reports (the energy law's switch log, the TVLQR's hand-over time), read from the C.

The matrix: LQR, PID, TVLQR and energy on one pole, LQR and TVLQR on two and three poles, each with estimator none,
KF and EKF (energy shaping drives one pole only). The export refuses a KF for a swing-up (a filter linearised at
upright); the swing-up command runs one, so its in-loop program is checked here with the KF swapped into the EKF
design. Two and three poles track a short plan (the LQR's own motion on the exact discrete step, then the catch):
the same C and tables as a collocation plan, without minutes of planning."""
from dataclasses import replace

import numpy as np
import pytest

from cartpole.codegen import compiler
from cartpole.control.linear import LinearFeedback
from cartpole.control.model_rollout import model_rollout
from cartpole.control.tvlqr import TVLQRController
from cartpole.export import design_export, load_design, run_lockstep
from cartpole.export.controllers import tvlqr_part
from cartpole.export.design import ExportDesign, build_program
from cartpole.export.folder import discard
from cartpole.export.inloop import compile_program, run_compiled
from cartpole.models import build_model
from cartpole.ocp.trajectory import Trajectory
from cartpole.riccati import tvlqr
from cartpole.sim.options import LoopOptions
from cartpole.sim.rig import build_rig

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler")

MJCF = {1: None, 2: "cartpole/assets/cartpole_two_pole.xml", 3: "cartpole/assets/cartpole_three_pole.xml"}
LOOPS = {"none": None,
         "kf": LoopOptions(period=0.01, delay=0.01, estimator="kf", encoder_cpr=2048, sensor_noise=1e-3),
         "ekf": LoopOptions(period=0.01, delay=0.01, estimator="ekf", encoder_cpr=2048),
         "mhe": LoopOptions(period=0.01, delay=0.01, estimator="mhe", encoder_cpr=2048)}
ESTIMATORS = tuple(LOOPS)
#: The Python reference against the C on the same inputs (the same algorithm in numpy's and C's arithmetic).
PYTHON_TOL = 1e-9
#: Seconds of each run: short, the claim is per period, not about the end state.
DURATION = 0.4
#: Seconds of the short plan the chains track (the catch holds after it, inside DURATION: the hand-over is run).
SHORT_PLAN = 0.2

CASES = ([(1, m, e) for m in ("lqr", "pid", "tvlqr", "energy") for e in ESTIMATORS]
         + [(n, m, e) for n in (2, 3) for m in ("lqr", "tvlqr") for e in ESTIMATORS])

_MODELS, _DESIGNS, _STARTS = {}, {}, {}


def _model(poles):
    if poles not in _MODELS:
        _MODELS[poles] = build_model(MJCF[poles])
    return _MODELS[poles]


def _tilted(model, angle=0.05):
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += angle
    return x0


def _short_plan_design(model, estimator):
    """A TVLQR design along a short plan: the catch's own motion from a tilted start on the exact discrete step,
    knots every 10 physics steps, gains on the loop's period, then that catch."""
    rig = build_rig(model, LOOPS[estimator], task="swingup")
    steps = 1 if rig is None else int(rig.steps)
    catch = LinearFeedback.for_model(model, period=None if steps == 1 else steps * model.dt)
    n = int(round(SHORT_PLAN / model.dt))
    xs, us = model_rollout(model, catch, _tilted(model), n, u_limits=np.column_stack([catch.u_low, catch.u_high]))
    us = np.vstack([us, us[-1:]])
    knots = np.arange(0, n + 1, 10)
    xdot = np.array([np.asarray(model.f(x, u), dtype=float).ravel() for x, u in zip(xs[knots], us[knots])])
    traj = Trajectory(t=knots * model.dt, x=xs[knots], u=us[knots], xdot=xdot)
    tv = TVLQRController(traj, tvlqr(model, traj, dt=steps * model.dt), catch)

    def make():
        tv.reset()
        return tv
    program = build_program(model, rig, tvlqr_part(tv), title="TVLQR along a short plan")
    return ExportDesign(method="tvlqr", estimator=estimator, model=model, program=program, make_controller=make,
                        rig=rig, spec=None if rig is None else rig.spec, task="swingup", plan_end=tv.T)


def _design(poles, method, estimator):
    key = (poles, method, estimator)
    if key in _DESIGNS:
        return _DESIGNS[key]
    model = _model(poles)
    if method == "tvlqr" and poles > 1:
        design = _short_plan_design(model, estimator)
    elif method in ("tvlqr", "energy") and estimator == "kf":  # the swing-up's KF: the EKF design, its rig swapped
        base = _design(poles, method, "ekf")
        rig = build_rig(model, LOOPS["kf"], task="swingup")
        program = build_program(model, rig, base.program.controller, title="the swing-up with a KF")
        design = replace(base, estimator="kf", rig=rig, spec=rig.spec, program=program)
    else:
        design = design_export(model, method, LOOPS[estimator], rho=1.0 if method == "energy" else None)
    _DESIGNS[key] = design
    return design


#: s into the energy swing-up from hanging at which its cases start: outside the catch's basin, entering it within
#: DURATION (the switch is run).
ENERGY_START = 0.8


def _start(model, method, poles):
    if method == "tvlqr" and poles == 1:
        return np.array(model.x_hanging, dtype=float)
    if method == "energy":
        if "energy" not in _STARTS:
            pumping = run_compiled(_design(poles, method, "none"), model.x_hanging, ENERGY_START)
            _STARTS["energy"] = pumping.x[-1].copy()
        return _STARTS["energy"]
    return _tilted(model)


def _recording(design):
    """``design`` whose fresh Python controllers are kept in the returned list (to read their state after a run)."""
    made = []

    def make():
        made.append(design.make_controller())
        return made[-1]
    return replace(design, make_controller=make), made


@pytest.mark.parametrize("poles,method,estimator", CASES, ids=lambda v: str(v))
def test_the_loops_compiled_program_is_the_exported_folders_cp_step_bit_for_bit(poles, method, estimator):
    model = _model(poles)
    design, made = _recording(_design(poles, method, estimator))
    x0 = _start(model, method, poles)
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
    python = made[-1]  # the controller run_lockstep ran beside the C: its state is the C's
    if method == "energy":
        c_log, py_log = rollout.info["switches"], python.switches
        assert [s.mode for s in c_log] == [s.mode for s in py_log]
        np.testing.assert_allclose([s.t for s in c_log], [s.t for s in py_log], rtol=0, atol=1e-12)
        np.testing.assert_allclose([s.cost for s in c_log], [s.cost for s in py_log], rtol=PYTHON_TOL)
        if estimator == "none":  # the start is outside the basin and the exact state enters it in the run
            assert [s.mode for s in c_log] == ["catch"] and c_log[0].t > 0
    if method == "tvlqr":
        handover = rollout.info["handover_time"]
        assert (handover is None) == (python.handover_time is None)
        if poles > 1:  # the short plan ends inside the run: the catch took over
            assert handover == pytest.approx(python.handover_time, abs=1e-12) and handover >= design.plan_end - 1e-12


def test_a_compiled_program_is_built_once_per_design_and_each_load_keeps_a_run_of_its_own():
    model = _model(1)
    design = _design(1, "pid", "none")  # the PID's integrator: state a shared load would mix
    first, second = compile_program(design), compile_program(design)
    assert first.library == second.library  # the cache: one library for one design's files...
    assert first.lib_path != second.lib_path  # ...each controller loading its own copy
    alone = compile_program(design)
    x, other = _tilted(model), _tilted(model, -0.1)
    for ctl in (first, second, alone):
        ctl.reset()
    for k in range(20):  # interleaved with a run on other states, the first run is the run alone
        t = k * model.dt
        second.step(t, other)
        np.testing.assert_array_equal(first.step(t, x)[1], alone.step(t, x)[1])


def test_the_exported_folder_loads_its_own_copy_of_the_one_compiled_library():
    from pathlib import Path

    model = _model(1)
    design = design_export(model, "lqr", None)
    inloop = compile_program(design)
    folder_ctl, folder = load_design(design)
    try:  # the same bytes (compiled once), loaded from the folder: static memory of its own
        assert Path(folder_ctl.lib_path).parent == folder
        assert Path(folder_ctl.lib_path).read_bytes() == Path(inloop.library).read_bytes()
        inloop.reset()
        folder_ctl.reset()
        x = _tilted(model)
        np.testing.assert_array_equal(inloop.step(0.0, x)[1], folder_ctl.step(0.0, x)[1])
    finally:
        discard(folder)


def test_a_controller_without_that_state_has_no_accessor():
    from cartpole.export import ExportError

    ctl = compile_program(design_export(_model(1), "lqr", None))
    with pytest.raises(ExportError, match="cp_switch_state"):
        ctl.switch_state()


def test_the_float32_program_balances_in_the_loop():
    model = _model(1)
    design = design_export(model, "lqr", LOOPS["kf"])
    ctl = compile_program(design, "float")
    rollout = run_compiled(design, _start(model, "lqr", 1), 3.0, ctl=ctl)
    e = model.state_error(rollout.x[-1])
    assert np.all(np.abs(e[list(model.hinges)]) < 0.05) and rollout.info["diverged"] is None


def test_runs_in_concurrent_threads_each_load_a_program_of_their_own():
    import threading

    model = _model(1)
    design = _design(1, "energy", "none")
    x0 = _start(model, "energy", 1)
    ref = run_compiled(design, x0, DURATION)  # the main thread: the library itself
    out, paths = {}, {}

    def run(i):
        ctl = compile_program(design)
        paths[i] = ctl.lib_path
        out[i] = run_compiled(design, x0, DURATION, ctl=ctl)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert len({paths[0], paths[1], compile_program(design).lib_path}) == 3  # a copy each: static memory apart
    for i in range(2):  # interleaved steps of the two runs did not touch each other's state
        np.testing.assert_array_equal(out[i].ctrl, ref.ctrl)
        assert [s.t for s in out[i].info["switches"]] == [s.t for s in ref.info["switches"]]
