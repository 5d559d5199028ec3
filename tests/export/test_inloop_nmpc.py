"""One implementation in the loop for the NMPC with its estimators (issue 39): the NMPC on a rig with a Kalman
filter, an EKF or the MHE runs in the MuJoCo loop as the compiled program of its export (cartpole.export.inloop.in_loop
routes it there), and its ctrl equals, every period of a MuJoCo run, the exported folder's cp_step compiled with the
strict flags and driven from the same measurements, on the shipped one-, two- and three-pole carts. The Python path
(the NMPC's own compiled step behind the Python estimators and rig) stays within PYTHON_TOL of it."""
import numpy as np
import pytest

from cartpole.codegen import compiler
from cartpole.export import load_design, run_lockstep
from cartpole.export.design import ExportDesign, build_program
from cartpole.export.folder import discard
from cartpole.export.inloop import CompiledNMPCLaw, in_loop
from cartpole.export.nmpc import nmpc_part
from cartpole.models import build_model
from cartpole.mpc.nmpc import NMPCController
from cartpole.mpc.nmpc_c import STATUS_REASONS, SolveRecord
from cartpole.mpc.options import MPCOptions
from cartpole.sim.options import LoopOptions
from cartpole.sim.rig import build_rig
from cartpole.sim.rollout import simulate

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler")

MJCF = {1: None, 2: "cartpole/assets/cartpole_two_pole.xml", 3: "cartpole/assets/cartpole_three_pole.xml"}
#: The rig of each estimator: a delay of two physics steps predicted over, 2048-count encoders.
LOOPS = {"kf": dict(estimator="kf", encoder_cpr=2048, sensor_noise=1e-3),
         "ekf": dict(estimator="ekf", encoder_cpr=2048),
         "mhe": dict(estimator="mhe", encoder_cpr=2048, mhe_horizon=0.1)}
#: The NMPC's period: its default 20 ms (4 physics steps), 10 ms on three poles, whose EKF prediction over 4 steps is
#: generated C that gcc compiles for minutes on a loaded machine (2 steps: a quarter of it).
PERIOD = {1: 0.02, 2: 0.02, 3: 0.01}
#: A short horizon keeps the compiles and the runs short; the claim is per period.
HORIZON, DURATION = 0.3, 0.4
#: The Python path (Python estimators and rig around the NMPC's compiled step) against the program on the same inputs.
PYTHON_TOL = 1e-7

_MODELS = {}


def _model(poles):
    if poles not in _MODELS:
        _MODELS[poles] = build_model(MJCF[poles])
    return _MODELS[poles]


def _design(poles, estimator):
    """The NMPC balancing from a tilted start on the rig of ``estimator``, as an export design (no offline plan)."""
    model = _model(poles)
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += 0.05
    period = PERIOD[poles]
    rig = build_rig(model, LoopOptions(period=period, delay=0.01, **LOOPS[estimator]), task="balance")
    ctl = NMPCController(model, model.params, options=MPCOptions(period=period, horizon=HORIZON), x0=x0)
    prog = build_program(model, rig, nmpc_part(ctl, None), params=model.params, title="in-loop program")

    def make():
        ctl.reset()
        return ctl
    return ExportDesign(method="nmpc", estimator=estimator, model=model, program=prog, make_controller=make, rig=rig,
                        spec=rig.spec, task="balance"), x0


@pytest.mark.parametrize("poles,estimator", [(p, e) for p in (1, 2, 3) for e in ("kf", "ekf", "mhe")],
                         ids=lambda v: str(v))
def test_the_loops_nmpc_with_its_estimator_is_the_exported_folders_cp_step_bit_for_bit(poles, estimator):
    design, x0 = _design(poles, estimator)
    model = design.model
    ctl = design.make_controller()
    loop_ctrl, loop_rig = in_loop(model, ctl, design.rig)
    assert loop_rig is not design.rig  # the compiled program, not the Python rig
    rollout = simulate(model.params, loop_ctrl, x0, DURATION, rig=loop_rig)
    assert np.all(np.isfinite(rollout.ctrl)) and np.all(np.isfinite(rollout.x_hat))
    # what the Python NMPC records, read from the C: one solve a period, timed inside the C, and no failure
    assert isinstance(loop_ctrl, CompiledNMPCLaw) and loop_ctrl.period == ctl.period
    assert len(loop_ctrl.solve_ms) == len(rollout.y) and min(loop_ctrl.solve_ms) > 0 and loop_ctrl.failures == []
    # the exported folder, compiled with the strict flags, in the same MuJoCo loop (the Python path beside it)
    folder_ctl, folder = load_design(design)
    try:
        run = run_lockstep(design, folder_ctl, x0, DURATION)
    finally:
        discard(folder)
    np.testing.assert_array_equal(rollout.y, run.y)  # the same measurements every period...
    lag, steps = design.program.lag, design.program.steps
    applied = rollout.ctrl.reshape(len(rollout.ctrl), -1)[lag::steps]
    np.testing.assert_array_equal(applied, run.c_ctrl[:len(applied)])  # ...and the same ctrl
    np.testing.assert_array_equal(rollout.ctrl, run.rollout.ctrl)
    assert run.max_ctrl_diff <= PYTHON_TOL


class _ScriptedProgram:
    """A compiled program's ``reset``, ``step`` and ``cp_nmpc_state``, its solves scripted (one record a step)."""

    def __init__(self, records):
        self.records, self.last = iter(records), None

    def reset(self):
        pass

    def step(self, t, x):
        self.last = next(self.records)
        return 0, np.zeros(1)

    def nmpc_state(self):
        return self.last


def test_the_loops_nmpc_logs_each_solve_once_and_each_safe_action_the_c_took():
    failed = SolveRecord(solves=2, t=0.02, seconds=4e-4, status=3, action=2)
    law = CompiledNMPCLaw(_ScriptedProgram([SolveRecord(1, 0.0, 1e-4, 0, 0), SolveRecord(1, 0.0, 1e-4, 0, 0), failed,
                                            SolveRecord(3, 0.04, 2e-4, 0, 0)]))
    for t in (0.0, 0.01, 0.02, 0.04):  # the second step held the ctrl: no solve
        law(t, np.zeros(4))
    np.testing.assert_allclose(law.solve_ms, [0.1, 0.4, 0.2])
    assert law.failures == [{"t": 0.02, "reason": STATUS_REASONS[3], "action": "upright LQR"}]
    law.reset()  # a new run forgets the last one's log
    assert law.solve_ms == [] and law.failures == []
