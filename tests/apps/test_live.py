"""cartpole.apps.live: the LQR the page tunes is re-designed exactly as the lab designs it, refuses bad weights in one
sentence, and keeps the gain in force when it does."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cartpole.apps.lab import run_lab
from cartpole.apps.live import LQRTuner, paced_supervisor
from cartpole.errors import CartPoleError
from cartpole.riccati import lqr
from cartpole.supervise import SupervisorOptions


@pytest.fixture(scope="module")
def lab():
    return run_lab(None, duration=0.5)


def test_a_released_weight_redesigns_the_gain_from_the_exact_linearisation(lab):
    tuner = LQRTuner(lab)
    names = [k.name for k in tuner.knobs()]
    assert len(names) == lab.A.shape[0] + lab.B.shape[1]
    hinge = lab.params.hinges[0]
    name = [n for n in names if n.startswith("Q ")][hinge]
    changed = tuner.set(name, 100.0, t=1.25)
    Q = np.array(lab.Q, float)
    Q[hinge, hinge] = 100.0
    expect = lqr(lab.A, lab.B, Q, lab.R)
    assert np.allclose(changed["K"], expect.K, rtol=1e-10, atol=1e-12)
    assert np.allclose(tuner.controller.feedback.K, expect.K, rtol=1e-10, atol=1e-12)
    assert all(re < 0 for re, _ in changed["eigenvalues"])
    assert changed["Q"][hinge] == 100.0
    x = np.array(lab.x_eq, float)
    x[hinge] += 0.1
    u_new = tuner.controller(0.0, x)
    assert not np.allclose(u_new, lab.controller()(0.0, x))  # the law in force changed


def test_bad_weights_are_one_sentence_and_leave_the_gain(lab):
    tuner = LQRTuner(lab)
    K = tuner.K.copy()
    with pytest.raises(CartPoleError, match="positive and finite"):
        tuner.set("R u", 0.0, t=0.0)
    with pytest.raises(CartPoleError, match="no weight named"):
        tuner.set("nonsense", 1.0, t=0.0)
    assert np.array_equal(tuner.K, K)


def test_the_status_names_the_law_and_the_rig(lab):
    lines = LQRTuner(lab).status(0.0, lab.x0s[0])
    assert lines[0].startswith("LQR (lqr on the continuous (A, B))")
    assert any("closed-loop eigenvalues" in line for line in lines)
    assert any("control period" in line for line in lines)


def test_watch_returns_the_run_with_its_live_log_and_it_replays(capsys):
    import cartpole as cp

    run = cp.watch(duration=0.2, wait=False)  # nobody opens the page: the run goes on at real time
    assert capsys.readouterr().out == ""
    live = run.info["live"]
    assert live["events"] == [] and live["url"].startswith("http://localhost:")
    assert run.t[-1] == pytest.approx(0.2)
    assert cp.replays_exactly(run)


def test_the_live_loop_holds_and_delays_the_ctrl_exactly_as_the_rig_does(lab):
    from cartpole.models import build_model
    from cartpole.sim import simulate
    from cartpole.sim.options import LoopOptions
    from cartpole.sim.rig import build_rig
    from cartpole.apps.live import LiveLoop

    h = lab.params.timestep
    model = build_model(lab.params)
    rig = build_rig(model, LoopOptions(period=5 * h, delay=3 * h, delay_compensation=False))
    law = lab.controller()
    by_rig = simulate(lab.params, law, lab.x0s[0], 0.3, rig=rig)
    live = simulate(lab.params, LiveLoop(law, h, steps=5, delay_steps=3), lab.x0s[0], 0.3)
    assert np.array_equal(live.ctrl, by_rig.ctrl) and np.array_equal(live.x, by_rig.x)


def test_a_period_changed_live_holds_the_ctrl_longer_from_the_next_sample(lab):
    from cartpole.apps.live import LiveLoop, LoopTuner
    from cartpole.sim import replays_exactly, simulate

    h = lab.params.timestep
    loop = LiveLoop(lab.controller(), h)
    tuner = LoopTuner(loop)
    n_change = 20

    def stepped(t, x):
        if int(round(t / h)) == n_change:
            tuner.set(LoopTuner.PERIOD, 10 * h, t)
        return loop(t, x)

    run = simulate(lab.params, stepped, lab.x0s[0], 0.4)
    ctrl = run.ctrl[:, 0]
    assert np.all(np.diff(ctrl[5:n_change]) != 0)  # every step before (past the saturated start)
    held = ctrl[n_change:n_change + 10]
    assert np.all(held == held[0]) and ctrl[n_change + 10] != held[0]
    assert replays_exactly(run)
    with pytest.raises(CartPoleError, match="control period"):
        tuner.set(LoopTuner.PERIOD, 0.0, 0.0)
    with pytest.raises(CartPoleError, match="delay"):
        tuner.set(LoopTuner.DELAY, -h, 0.0)


def test_a_delay_changed_live_shifts_the_ctrl_and_is_said(lab):
    from cartpole.apps.live import LiveLoop, LoopTuner

    h = lab.params.timestep
    calls = []
    loop = LiveLoop(lambda t, x: calls.append(t) or np.array([t]), h)
    tuner = LoopTuner(loop)
    x = np.asarray(lab.x0s[0])
    for k in range(3):
        loop(k * h, x)
    changed = tuner.set(LoopTuner.DELAY, 4 * h, 3 * h)
    assert changed["delay"] == pytest.approx(4 * h)
    u = [float(loop(k * h, x)[0]) for k in range(3, 9)]
    assert calls[-1] == pytest.approx(8 * h + 4 * h)  # the ctrl computed at step 8 acts at step 12
    assert u[:4] == [u[0]] * 4  # steps 3..6 keep the ctrl computed at step 2 (nothing newer has arrived)
    assert f"delay {4 * h:g} s (uncompensated" in tuner.status(0.0, x)[0]


def test_a_pid_gain_set_on_the_page_changes_the_law_and_its_eigenvalues(lab):
    from cartpole.apps.lab import compare_pid
    from cartpole.apps.live import PIDTuner
    from cartpole.control.pid import CascadedPID, closed_loop_matrix

    pid = compare_pid(lab)
    law = CascadedPID(pid.gains, lab.params)
    tuner = PIDTuner(law, lab.A, lab.B)
    kp = next(k for k in tuner.knobs() if k.name.startswith("PID kp "))
    assert kp.value == pid.gains.kp and min(kp.low, kp.high) <= kp.value <= max(kp.low, kp.high)
    x = np.array(lab.x_eq, float)
    x[lab.params.hinges[0]] += 0.05
    before = law(0.0, x)
    changed = tuner.set(kp.name, 2.0 * pid.gains.kp, t=0.5)
    assert law.gains.kp == 2.0 * pid.gains.kp and changed["gains"]["kp"] == law.gains.kp
    expect = np.linalg.eigvals(closed_loop_matrix(lab.A, lab.B, law.gains, slide=law.slide, hinge=law.hinge))
    got = np.array([complex(*e) for e in changed["eigenvalues"]])
    assert np.allclose(np.sort_complex(got), np.sort_complex(expect), rtol=1e-12)
    law.reset()
    assert not np.allclose(law(0.0, x), before)
    with pytest.raises(CartPoleError, match="no PID gain named"):
        tuner.set("PID nonsense", 1.0, 0.0)
    assert law.gains.kp == 2.0 * pid.gains.kp


class _Decision:
    def __init__(self, t, kind):
        self.t, self.kind = t, kind


def test_the_page_names_the_swingup_law_in_charge_and_its_state():
    from types import SimpleNamespace

    from cartpole.apps.live import controller_status

    sup = SimpleNamespace(mode="brake", decisions=[_Decision(1.5, "plan_failed")], plans=1, failures=1)
    assert controller_status(sup, 2.0, None)[0] == "supervisor: fallback: passive brake (re-plans once calm)"
    assert "plan_failed at 1.50 s" in controller_status(sup, 2.0, None)[1]
    switching = SimpleNamespace(mode="catch", switches=[SimpleNamespace(t=3.25, mode="catch")])
    assert controller_status(switching, 4.0, None) == ["energy shaping + LQR catch: catch: the LQR, inside its basin",
                                                       "1 switch(es), last to catch at 3.25 s"]
    tracker = SimpleNamespace(handover_time=None)
    assert controller_status(tracker, 0.5, None) == ["TVLQR along the plan: tracking"]
    tracker.handover_time = 2.5
    assert controller_status(tracker, 3.0, None) == ["TVLQR along the plan: catch (the LQR) since 2.50 s"]


def test_watch_with_the_pid_runs_it_after_the_lqr_and_both_replay(capsys):
    import cartpole as cp

    run = cp.watch(duration=0.1, wait=False, pid=True)
    live = run.info["live"]
    pid_run = live["pid"]["rollout"]
    assert live["loop"]["delay"] == 0.0 and live["pid"]["events"] == []
    assert len(pid_run.ctrl) == len(run.ctrl) and not np.array_equal(pid_run.ctrl, run.ctrl)
    assert cp.replays_exactly(run) and cp.replays_exactly(pid_run)


def test_the_loop_is_live_only_where_the_controller_sees_mujocos_state():
    from types import SimpleNamespace

    from cartpole.apps.live import LiveLoop, LoopTuner, live_loop

    params = SimpleNamespace(timestep=0.005)

    def rig(**kw):
        base = dict(spec=None, steps=2, delay_steps=0, compensate=True)
        base.update(kw)
        return SimpleNamespace(for_run=lambda i: ("run", i), **base)

    law = object()
    ran, given, tuner = live_loop(SimpleNamespace(rig=None, period=0.005, params=params), law)
    assert isinstance(ran, LiveLoop) and given is None and isinstance(tuner, LoopTuner) and ran.steps == 1
    ran, given, tuner = live_loop(SimpleNamespace(rig=rig(delay_steps=3, compensate=False), period=0.01,
                                                  params=params), law)
    assert (ran.steps, ran.delay_steps) == (2, 3) and given is None
    for fixed in (rig(spec="encoders"), rig(delay_steps=3, compensate=True)):  # an estimator; a predicted delay
        ran, given, tuner = live_loop(SimpleNamespace(rig=fixed, period=0.01, params=params), law)
        assert ran is law and given == ("run", 0) and tuner is None


def test_a_paced_swingup_mpc_gets_its_period_as_step_budget():
    """In a run paced in real time an MPC step later than its period would stall the loop: paced_supervisor bounds
    the acrobot's swing-up MPC by its period (the late step then applies the previous solution shifted); a budget
    the caller set is kept."""
    mpc = SimpleNamespace(period=0.01, step_budget=None)
    sup = SimpleNamespace(mpc=mpc, planner=None, options=SupervisorOptions(swingup_mpc=True))
    assert paced_supervisor(sup) is sup
    assert mpc.step_budget == pytest.approx(0.01) and sup.options.mpc_step_budget == pytest.approx(0.01)
    mine = SimpleNamespace(period=0.01, step_budget=0.5)
    sup = SimpleNamespace(mpc=mine, planner=None, options=SupervisorOptions(swingup_mpc=True, mpc_step_budget=0.5))
    paced_supervisor(sup)
    assert mine.step_budget == 0.5 and sup.options.mpc_step_budget == 0.5
