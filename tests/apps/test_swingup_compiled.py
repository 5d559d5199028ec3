"""The swing-up's real-time controllers in the MuJoCo loop are the export's compiled C (issue 39): the energy law with
its catch and the TVLQR with its catch run as one ``cp_step`` per period when a C compiler exists, and what the run
reports from the controller's state (the switch log, the hand-over, caught_at) is read from the C. The Python
classes, the path without a compiler, are the reference: on the same start they give the same run."""
import numpy as np
import pytest

import cartpole.export.inloop as inloop
from cartpole.apps.swingup import SwingupOptions, run_swingup
from cartpole.codegen import compiler
from cartpole.control.switching import SwitchingController
from cartpole.control.tvlqr import TVLQRController
from cartpole.export.inloop import CompiledNMPCLaw, CompiledSwitching, CompiledTracker
from cartpole.mpc.nmpc import NMPCController
from cartpole.sim import LoopOptions, replays_exactly

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler")

#: The Python classes against the C over a swing-up: the same law in numpy's and C's arithmetic (the EKF's rounding
#: differences grow a little through the closed loop).
RUN_TOL = 1e-7
#: s after the hand-over over which a run on encoders is compared: later, a rounding difference of 1e-15 moves an
#: encoder count and the two runs part (the step-by-step claim on the same inputs is tests/export/test_inloop.py's).
RIG_SPAN = 0.5
RIG = LoopOptions(period=0.01, delay=0.01, estimator="ekf", encoder_cpr=2048)


def _python_run(monkeypatch, **kw):
    """The same swing-up on the Python classes: ``in_loop`` sees no compiler."""
    with monkeypatch.context() as mp:
        mp.setattr(inloop, "compiler", lambda: None)
        return run_swingup(None, **kw)


def _same_switches(a, b):
    assert [s["mode"] for s in a] == [s["mode"] for s in b]
    np.testing.assert_allclose([s["t"] for s in a], [s["t"] for s in b], rtol=0, atol=1e-12)
    np.testing.assert_allclose([s["cost"] for s in a], [s["cost"] for s in b], rtol=1e-6)


@pytest.mark.parametrize("loop", [LoopOptions(), RIG], ids=["exact_state", "ekf_rig"])
def test_the_energy_swingup_runs_the_compiled_program_and_reports_the_switches_the_c_made(monkeypatch, loop):
    res = run_swingup(None, "energy", SwingupOptions(loop=loop))
    assert isinstance(res.controller, CompiledSwitching)  # the C ran, and its switch log is what is reported
    assert [s["mode"] for s in res.metrics["switches"]] == ["catch"] and res.caught_at is not None
    assert res.handover_at == res.metrics["switches"][-1]["t"] == res.controller.switches[-1].t
    assert replays_exactly(res.rollout)
    ref = _python_run(monkeypatch, method="energy", options=SwingupOptions(loop=loop))
    assert isinstance(ref.controller, SwitchingController)
    n = len(res.rollout.ctrl) if loop.estimator is None else np.searchsorted(res.rollout.t, res.handover_at + RIG_SPAN)
    np.testing.assert_allclose(res.rollout.ctrl[:n], ref.rollout.ctrl[:n], rtol=0, atol=RUN_TOL)
    _same_switches(res.metrics["switches"], ref.metrics["switches"])
    assert res.handover_at == pytest.approx(ref.handover_at, abs=1e-12)
    if loop.estimator is None:
        assert res.caught_at == pytest.approx(ref.caught_at, abs=1e-12) and res.success == ref.success


def test_the_trajopt_swingup_runs_the_compiled_tvlqr_and_reports_the_hand_over_the_c_made(monkeypatch):
    res = run_swingup(None, method="trajopt")
    assert isinstance(res.controller, CompiledTracker)
    assert res.success and res.handover_at == res.controller.handover_time
    assert res.handover_at >= float(res.plan.t[-1] - res.plan.t[0]) - 1e-12  # the catch takes over at the plan's end
    ref = _python_run(monkeypatch, method="trajopt")
    assert isinstance(ref.controller, TVLQRController)
    np.testing.assert_allclose(res.rollout.ctrl, ref.rollout.ctrl, rtol=0, atol=RUN_TOL)
    assert res.handover_at == pytest.approx(ref.handover_at, abs=1e-12)
    _same_switches(res.metrics["switches"], ref.metrics["switches"])


def test_the_nmpc_swingup_runs_the_compiled_program_and_reports_each_solve_the_c_timed(monkeypatch):
    loop = LoopOptions(duration=1.0)  # the swing-up's first second: the hardest QPs, short to run
    res = run_swingup(None, "mpc", SwingupOptions(loop=loop))
    ran = res.controller
    assert isinstance(ran, CompiledNMPCLaw)  # the exported program ran, its log read from the C
    steps = int(round(res.rollout.t[-1] / ran.period)) + 1
    assert abs(len(ran.solve_ms) - steps) <= 1 and min(ran.solve_ms) > 0
    assert res.metrics["failures"] == len(ran.failures) and (ran.period, ran.horizon) == pytest.approx((0.02, 1.2))
    assert replays_exactly(res.rollout)
    ref = _python_run(monkeypatch, method="mpc", options=SwingupOptions(loop=loop))
    assert isinstance(ref.controller, NMPCController)  # its own compiled step, the Python loop around it
    np.testing.assert_allclose(res.rollout.ctrl, ref.rollout.ctrl, rtol=0, atol=RUN_TOL)
    assert res.metrics["failures"] == ref.metrics["failures"]
