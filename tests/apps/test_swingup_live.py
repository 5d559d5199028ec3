"""cartpole.apps.swingup with a live page: the run tells the page which law is in charge (``attach``) and the page's
pushes join the run's logged push column, so the run still replays exactly; on a page paced in real time the
supervisor plans in a worker while the loop steps on."""
from __future__ import annotations

import time

import numpy as np
import pytest

from cartpole.apps.live import controller_status, paced_supervisor
from cartpole.apps.swingup import SwingupOptions, run_swingup
from cartpole.sim import Knockdown, SimOptions, replays_exactly, simulate
from cartpole.sim.options import LoopOptions
from cartpole.supervise import Supervisor, SupervisorOptions


class _Page:
    """What a web page is to the run: a step hook with ``attach(controller, push) -> push``."""

    def __init__(self):
        self.attached = []
        self.lines = []
        self.closed = self.interrupted = False

    def attach(self, controller, push=None):
        self.attached.append(controller)

        def both(t):
            return (0.0 if push is None else push(t)) + (4.0 if 0.1 <= t < 0.2 else 0.0)
        return both

    def __call__(self, m, d):
        self.lines = controller_status(self.attached[-1], float(d.time), None)
        return True


def test_the_swingup_attaches_its_law_and_logs_the_pages_push_with_the_scheduled_one():
    page = _Page()
    res = run_swingup(None, "energy", SwingupOptions(loop=LoopOptions(duration=0.5, push=((0.3, -2.0),))),
                      on_step=page)
    assert len(page.attached) == 1 and hasattr(page.attached[0], "switches")
    assert page.lines[0].startswith("energy shaping + LQR catch: swing-up")
    push = res.rollout.info["push"]
    h = res.rollout.t[1] - res.rollout.t[0]
    t = res.rollout.t[:-1]
    assert np.all(push[(t >= 0.1 - h / 2) & (t < 0.2 - h / 2)] == 4.0)
    assert np.all(push[(t >= 0.3 - h / 2) & (t < 0.4 - h / 2)] == -2.0)
    assert replays_exactly(res.rollout)


class _Paced:
    """What a live page is to the run's pacing (as :class:`cartpole.viz.web.WebLive`): each step waits for wall time
    to catch up with simulated time (``realtime``), and its wall time is logged (s, ``time.perf_counter``)."""

    realtime = True

    def __init__(self):
        self.start = None
        self.steps = []  # (simulated t, wall time) of each step

    def __call__(self, m, d):
        now = time.perf_counter()
        if self.start is None:
            self.start = now - float(d.time)
        ahead = float(d.time) - (now - self.start)
        if ahead > 0:
            time.sleep(ahead)
        self.steps.append((float(d.time), time.perf_counter()))
        return True


@pytest.fixture
def one_pole(planning_lab):
    """The lab's cart with a supervisor that plans (its own would use the energy law and never plan): tests/conftest.py's
    ``planning_lab``."""
    params, model, base, planner = planning_lab
    return params, model, Supervisor(model, base.catch, base.rho, base.brake, planner=planner,
                                     options=SupervisorOptions(plan_in_worker=True))


def test_a_knock_in_the_live_loop_is_planned_for_in_a_worker_while_the_loop_steps_on(one_pole):
    params, model, sup = one_pole
    assert paced_supervisor(sup) is sup and sup.options.plan_while_running and sup.prepare_s is not None
    page = _Paced()
    knock = Knockdown(0.2, 0.3, seed=4).start(params, x_eq=model.x_eq, hinges=model.hinges)
    with sup:
        run = simulate(params, sup, np.asarray(model.x_eq, float), 20.0, disturbance=knock,
                       options=SimOptions(on_step=page, stop=lambda t, x: sup.mode == "track"))
    assert replays_exactly(run, params)
    h = float(params.timestep)
    # the page saw the start state and then every physics step, none skipped: page.steps[k] is step k (t = k h);
    # steps are counted by index, never by comparing MuJoCo's summed d.time with a decision's k h (round-off)
    assert np.allclose([t for t, _ in page.steps], h * np.arange(len(page.steps)), rtol=0.0, atol=1e-9)
    kinds = [d.kind for d in sup.decisions]
    i = kinds.index("plan")
    assert kinds[i + 1] == "track"  # the plan asked for is the one tracked: none failed, dropped or made again
    plan, came = sup.decisions[i], sup.decisions[i + 1]
    asked, tracked = round(plan.t / h), round(came.t / h)
    arrived = round(plan.detail["charged_s"] / h)  # steps the loop took while the worker planned: the charged latency
    lead = max(1, round(plan.detail["predicted_latency_s"] / h))  # steps its start state was predicted ahead
    # the loop stepped on while the worker planned, and tracked the plan from the later of its arrival (the charged
    # latency honoured) and the state it was planned from (a plan that comes early waits for it: on a fast machine
    # the first plan beats the assumed latency, on a slow one it comes late)
    assert arrived >= 10 and tracked - asked == max(arrived, lead)
    # paced in real time, simulated time kept up with the plan's wall time (a loop that waited for the plan would
    # have stepped once while it was made), and no step from the request to the tracking waited for it
    assert plan.detail["charged_s"] >= 0.5 * plan.detail["wall_s"]
    walls = [w for _, w in page.steps[asked:tracked + 1]]
    assert max(np.diff(walls)) < 0.75 * plan.detail["wall_s"]
    assert sup.server is None


def test_the_swingup_paces_its_supervisor_for_a_live_page_and_ends_its_worker(monkeypatch):
    paced = []

    def record(sup):
        paced.append(sup)
        return sup
    monkeypatch.setattr("cartpole.apps.swingup.paced_supervisor", record)
    page = _Page()
    page.realtime = True
    res = run_swingup(None, "supervisor", SwingupOptions(loop=LoopOptions(duration=0.3)), on_step=page)
    assert len(paced) == 1 and paced[0].server is None and res.method == "supervisor"
    paced.clear()
    run_swingup(None, "supervisor", SwingupOptions(loop=LoopOptions(duration=0.3)), on_step=_Page())
    assert paced == []  # a page that does not pace in real time: the supervisor as a simulated run has it
