"""Planning in a worker process: bounded by the plan budget (killed at it, nothing left running), the same plan as in
the caller's thread, and a supervised run through it that replays exactly."""
import multiprocessing
import os
import signal
import time
from dataclasses import dataclass

import numpy as np
import pytest

from cartpole.errors import CartPoleError
from cartpole.ocp.trajectory import Trajectory
from cartpole.sim import Knockdown, replays_exactly, simulate
from cartpole.supervise import Supervisor, SupervisorError, SupervisorOptions
from cartpole.supervise.worker import REAP_TIMEOUT, PlanTimeout, PlanWorker, run_planner, run_within

#: s: what killing and reaping the child may add to the budget on a loaded machine.
KILL_SLACK = 3.0


def _children() -> set:
    """This process's child pids, running or zombies (Linux's ``/proc/<pid>/task/<tid>/children``)."""
    pids = set()
    for tid in os.listdir(f"/proc/{os.getpid()}/task"):
        try:
            with open(f"/proc/{os.getpid()}/task/{tid}/children") as f:
                pids |= {int(p) for p in f.read().split()}
        except OSError:  # a thread that ended meanwhile
            pass
    return pids


#: The children this process had when the running test started: a test suite's process may keep children of other
#: tests (a sweep's fork server, a compile, the idle planning worker of another test's supervisor, ended only when
#: that supervisor is collected), which are not this test's.
_BEFORE: dict = {}


@pytest.fixture(autouse=True)
def _children_before():
    _BEFORE["pids"] = _children()
    _BEFORE["workers"] = {p.pid for p in multiprocessing.active_children()}


def _no_child_left():
    """No child process left by the test, running or a zombie (none beyond the children there were before it)."""
    assert {p.pid for p in multiprocessing.active_children()} - _BEFORE["workers"] == set()
    assert _children() - _BEFORE["pids"] == set()


def _planning(planning_lab, **options):
    params, model, base, planner = planning_lab
    return Supervisor(model, base.catch, base.rho, base.brake, planner=planner, options=SupervisorOptions(**options))


def test_a_plan_over_the_budget_is_killed_at_the_budget_and_the_run_goes_on(planning_lab):
    params, model, base, _ = planning_lab
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=lambda x0: time.sleep(60.0),
                     options=SupervisorOptions(plan_in_worker=True, plan_budget=0.5, warm_worker=False))
    x = np.asarray(model.x_hanging, float)
    start = time.perf_counter()
    u = sup(0.0, x)
    took = time.perf_counter() - start
    assert 0.5 <= took < 0.5 + KILL_SLACK
    assert [d.kind for d in sup.decisions] == ["plan_timeout", "plan_failed"]
    timeout, failed = sup.decisions
    assert timeout.detail["wall_s"] >= 0.5 and timeout.detail["budget_s"] == 0.5
    assert "budget" in failed.detail["reason"] and failed.detail["wall_s"] >= 0.5
    _no_child_left()
    assert np.allclose(u, base.brake(0.0, x)) and np.allclose(sup(0.01, x), base.brake(0.01, x))  # braking, retry later
    assert sup.summary()["unreachable"][0]["reason"] == failed.detail["reason"]


def test_a_failed_plan_in_the_worker_keeps_its_sentence_and_a_crash_is_raised():
    def no_plan():
        raise CartPoleError("No swing-up found within T <= 1 s after 1 attempts.")
    with pytest.raises(CartPoleError, match="No swing-up found"):
        run_planner(no_plan, 10.0)
    with pytest.raises(RuntimeError, match="ZeroDivisionError"):
        run_planner(lambda: 1 / 0, 10.0)
    with pytest.raises(PlanTimeout, match="plan_budget"):
        run_planner(lambda: time.sleep(60.0), 0.2)
    _no_child_left()


def test_the_worker_is_polled_without_blocking_and_killed_on_demand():
    worker = PlanWorker(lambda seconds: time.sleep(seconds))
    start = time.perf_counter()
    worker.submit(60.0)
    assert worker.poll() is False and time.perf_counter() - start < 0.5
    os.kill(worker.pid, 0)  # running
    worker.kill()
    _no_child_left()
    with pytest.raises(CartPoleError, match="died without an answer"):
        worker.result()


def test_the_worker_keeps_its_memory_between_requests_and_a_kill_starts_a_new_one():
    seen = []

    def handler(request):
        seen.append(request)
        return list(seen)
    worker = PlanWorker(handler)
    assert worker.wait("a", 30.0) == ["a"] and worker.wait("b", 30.0) == ["a", "b"]  # one child, kept
    assert seen == [] and worker.forks == 1  # the parent's list untouched
    worker.kill()
    assert worker.wait("c", 30.0) == ["c"] and worker.forks == 2  # a new child, forked from the parent as it is
    start = time.perf_counter()
    worker.close()
    assert time.perf_counter() - start < REAP_TIMEOUT / 2  # the idle child saw its pipe close and ended
    _no_child_left()


def test_plan_in_worker_must_be_a_bool_and_planning_while_running_needs_it():
    with pytest.raises(SupervisorError, match="plan_in_worker"):
        SupervisorOptions(plan_in_worker="yes")
    with pytest.raises(SupervisorError, match="plan_while_running needs plan_in_worker=True"):
        SupervisorOptions(plan_in_worker=False, plan_while_running=True)
    with pytest.raises(SupervisorError, match="warm_worker"):
        SupervisorOptions(warm_worker=1)
    assert SupervisorOptions(plan_while_running=True).in_worker and not SupervisorOptions().in_worker


@dataclass
class _HoldPlan:
    """A plan that pickles (a worker sends it back): hold ``x_end`` with ``u`` for ``duration`` s."""

    trajectory: Trajectory
    u: np.ndarray

    @classmethod
    def at(cls, model, duration: float):
        x = np.tile(np.asarray(model.x_eq, float), (2, 1))
        u = np.asarray(model.u_eq, float)
        return cls(Trajectory(t=np.array([0.0, duration]), x=x, u=np.tile(u, (2, 1)), xdot=np.zeros_like(x)), u)

    def controller(self, t, x):
        return self.u


def _paced(sup, x, until, dt=0.01, limit=20.0, t0=0.0):
    """Call ``sup`` every ``dt`` s of simulated and (at least) wall time from ``t0`` s, as a run paced in real time
    does, until ``until(sup)`` or ``limit`` s; returns each call's ``(t, wall s, ctrl)``."""
    calls, t = [], t0
    while not until(sup) and t < t0 + limit:
        start = time.perf_counter()
        u = sup(t, x)
        calls.append((t, time.perf_counter() - start, u))
        time.sleep(dt)
        t += dt
    return calls


def test_planning_while_running_the_run_steps_on_and_the_plan_is_charged_the_time_it_came_in(planning_lab):
    params, model, base, _ = planning_lab

    def planner(x0):
        time.sleep(1.0)
        return _HoldPlan.at(model, 2.0)
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=planner,
                     options=SupervisorOptions(plan_in_worker=True, plan_while_running=True, latency=0.05,
                                               funnel=10.0, warm_worker=False))
    x = np.asarray(model.x_hanging, float)
    calls = _paced(sup, x, lambda s: s.mode == "track")
    plan = next(d for d in sup.decisions if d.kind == "plan")
    came = next(d for d in sup.decisions if d.kind == "track")
    assert plan.detail["wall_s"] >= 1.0 and plan.t == 0.0
    assert came.t == pytest.approx(plan.detail["charged_s"])  # tracked from the simulated time it came in
    waiting = [c for c in calls if c[0] < came.t]
    assert len(waiting) >= 10 and max(w for _, w, _ in waiting[1:]) < 0.5  # the run went on meanwhile
    assert all(np.allclose(u, base.brake(t, x)) for t, _, u in waiting)
    sup.close()
    _no_child_left()


def test_planning_while_running_a_plan_over_the_budget_is_killed_and_fails(planning_lab):
    params, model, base, _ = planning_lab
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=lambda x0: time.sleep(60.0),
                     options=SupervisorOptions(plan_in_worker=True, plan_while_running=True, plan_budget=0.5,
                                               warm_worker=False))
    x = np.asarray(model.x_hanging, float)
    start = time.perf_counter()
    _paced(sup, x, lambda s: s.failures > 0)
    assert time.perf_counter() - start < 0.5 + KILL_SLACK
    assert [d.kind for d in sup.decisions][:2] == ["plan_timeout", "plan_failed"]
    assert sup.decisions[1].detail["wall_s"] >= 0.5
    _no_child_left()


def test_a_plan_through_the_worker_is_the_plan_made_in_the_callers_thread(planning_lab):
    params, model, base, planner = planning_lab
    x0 = np.asarray(model.x_hanging, float)
    here = planner(x0)
    there = run_planner(lambda: planner(x0), 120.0)
    _no_child_left()
    for a, b in ((here.trajectory.t, there.trajectory.t), (here.trajectory.x, there.trajectory.x),
                 (here.trajectory.u, there.trajectory.u), (here.gains.K, there.gains.K)):
        assert np.array_equal(a, b)
    x = x0 + 0.01
    assert np.array_equal(here.controller(0.3, x), there.controller(0.3, x))


def test_a_knockdown_run_planning_in_the_worker_replays_exactly_and_equals_the_run_planning_in_thread(planning_lab):
    params, model, _, _ = planning_lab
    runs = []
    for in_worker in (False, True):
        sup = _planning(planning_lab, charged_latency=0.5, plan_in_worker=in_worker, plan_budget=120.0)
        force = Knockdown(1.5, 0.3, seed=4).start(params, x_eq=model.x_eq, hinges=model.hinges)
        runs.append((sup, simulate(params, sup, np.asarray(model.x_hanging, float), 6.0, disturbance=force)))
    (sup_here, here), (sup_there, there) = runs
    assert sup_there.plans >= 2 and sup_there.server.forks == 1 and replays_exactly(there, params)
    assert sup_there.prepare_s is not None and sup_here.prepare_s is None  # warmed here before the fork
    sup_there.close()
    assert np.array_equal(here.ctrl, there.ctrl)
    assert [d.kind for d in sup_here.decisions] == [d.kind for d in sup_there.decisions]
    _no_child_left()


def test_planning_while_running_a_plan_the_catch_overtook_is_dropped_and_its_worker_ended(planning_lab):
    params, model, base, _ = planning_lab
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=lambda x0: time.sleep(60.0),
                     options=SupervisorOptions(plan_in_worker=True, plan_while_running=True, warm_worker=False))
    hanging, upright = np.asarray(model.x_hanging, float), np.asarray(model.x_eq, float)
    sup(0.0, hanging)
    assert sup.mode == "wait" and sup.server.busy
    first = sup.server.pid
    assert np.allclose(sup(0.01, upright), base.catch(0.01, upright))  # caught meanwhile
    sup(0.02, hanging)
    kinds = [d.kind for d in sup.decisions]
    assert kinds == ["catch", "plan_dropped"]
    with pytest.raises(ProcessLookupError):  # the old plan dropped with its child, reaped
        os.kill(first, 0)
    assert sup.mode == "wait" and sup.server.busy and sup.server.pid != first  # a new plan asked for
    sup.close()
    _no_child_left()


def test_a_child_forked_after_the_parent_prepared_and_after_a_kill_builds_no_compiled_code(planning_lab):
    from cartpole import codegen

    params, model, base, planner = planning_lab
    sup = _planning(planning_lab, plan_in_worker=True, plan_budget=120.0)
    assert sup.prepare(again=True) > 0 and sup.prepare() == 0.0  # once per model and process
    x0 = np.asarray(model.x_hanging, float) + 0.02

    def plan_and_count(_):
        before = (set(codegen._BUILT), codegen._load.cache_info().currsize)
        plan = planner(x0)
        return before, (set(codegen._BUILT), codegen._load.cache_info().currsize), plan.trajectory.duration
    worker = PlanWorker(plan_and_count)
    try:
        for _ in range(2):  # the first child, then one forked after a kill: both as warm as the parent
            before, after, T = worker.wait(None, 120.0)
            assert after == before and T > 0  # no C generated, compiled or loaded anew in the child
            worker.kill()
        assert worker.forks == 2
    finally:
        worker.close()
    _no_child_left()


def test_the_supervisor_prepares_its_planner_here_before_its_first_fork_and_only_then(planning_lab, monkeypatch):
    params, model, base, _ = planning_lab
    monkeypatch.setattr("cartpole.supervise.supervisor._PREPARED", set())  # no supervisor of this model prepared yet
    seen = []

    def planner(x0):
        seen.append(os.getpid())
        return _HoldPlan.at(model, 2.0)
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=planner,
                     options=SupervisorOptions(plan_in_worker=True, latency=0.05, funnel=10.0))
    with sup:
        sup(0.0, np.asarray(model.x_hanging, float))
        assert seen == [os.getpid()] and sup.prepare_s is not None  # the warm-up here; the plan in the child
        assert sup.mode == "wait" and sup.server.forks == 1 and sup.server.pid != os.getpid()
    assert sup.server is None
    _no_child_left()
    again = Supervisor(model, base.catch, base.rho, base.brake, planner=planner,
                       options=SupervisorOptions(plan_in_worker=True, latency=0.05, funnel=10.0))
    with again:
        again(0.0, np.asarray(model.x_hanging, float))
        assert seen == [os.getpid()] and again.prepare_s == 0.0  # prepared in this process already
    _no_child_left()


def _busy(planning_lab):
    """A supervisor planning while running whose plan (a minute's sleep) is on its way in its worker."""
    params, model, base, _ = planning_lab
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=lambda x0: time.sleep(60.0),
                     options=SupervisorOptions(plan_while_running=True, warm_worker=False))
    sup(0.0, np.asarray(model.x_hanging, float))
    assert sup.server.busy
    return sup


def test_no_child_is_left_after_an_exception_in_the_loop_or_a_supervisor_dropped_unclosed(planning_lab):
    import gc

    from cartpole.sim import SimOptions

    params, model, base, _ = planning_lab

    def raise_once_planning(m, d):
        if sup.server is not None and sup.server.busy:
            raise RuntimeError("the loop broke")
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=lambda x0: time.sleep(60.0),
                     options=SupervisorOptions(plan_while_running=True, warm_worker=False))
    with pytest.raises(RuntimeError, match="the loop broke"):
        with sup:
            simulate(params, sup, np.asarray(model.x_hanging, float), 1.0,
                     options=SimOptions(on_step=raise_once_planning))
    _no_child_left()
    sup = _busy(planning_lab)
    del sup
    gc.collect()
    _no_child_left()


_ORPHAN = """
import sys, time
from cartpole.supervise.worker import PlanWorker
worker = PlanWorker(lambda seconds: time.sleep(seconds))
worker.submit(600.0)
print(worker.pid, flush=True)
time.sleep(600.0)
"""


def test_a_planning_child_dies_with_its_parent_even_killed_outright(tmp_path):
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-c", _ORPHAN], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": os.getcwd()})
    try:
        child = int(proc.stdout.readline())
        os.kill(child, 0)  # planning
        proc.send_signal(signal.SIGKILL)  # no exception, no atexit: only the kernel can end the child
        proc.wait(30)
        deadline = time.monotonic() + REAP_TIMEOUT
        while time.monotonic() < deadline and _alive(child):
            time.sleep(0.05)
        assert not _alive(child)
    finally:
        proc.kill()
        proc.wait()


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, or no process, is not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _live_processes():
    """``(pid, stat fields after the command's name)`` of every live (not zombie) process: field 1 is its parent's pid,
    field 3 its session's id."""
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[0] != "Z":
            yield int(pid), fields


def _session_alive(sid: int) -> list[int]:
    """Live (not zombie) processes of session ``sid``."""
    return [pid for pid, fields in _live_processes() if int(fields[3]) == sid]


def _cmdline(pid: int) -> bytes | None:
    """The command line of ``pid`` (None once it has ended)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read()
    except OSError:
        return None


def _forks_of(pid: int) -> list[int]:
    """Live (not zombie) children of ``pid`` that are forks of it (the same command line: a planning worker), not
    programs it ran (a compiler's command line is its own)."""
    cmdline = _cmdline(pid)
    return [child for child, fields in _live_processes()
            if int(fields[1]) == pid and cmdline is not None and _cmdline(child) == cmdline]


@pytest.mark.slow
def test_sigterm_of_the_cli_while_its_worker_plans_leaves_no_process(tmp_path):
    import signal
    import subprocess
    import sys

    # From hanging the supervisor asks for its first plan at t = 0: the warm-up plan made here, then the worker
    # forked for that plan and kept until the run ends. A minute of knockdowns, a plan after each, lasts many times
    # the poll's 0.1 s on any machine, so the worker is seen before the command ends; the SIGTERM ends it long before.
    mjcf = os.path.abspath("cartpole/assets/cartpole_two_pole.xml")
    proc = subprocess.Popen([sys.executable, "-m", "cartpole", "swingup", "--mjcf", mjcf, "--knockdown", "1:0.3",
                             "--duration", "60", "--no-video", "--json", "--out", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "MUJOCO_GL": "egl", "PYTHONPATH": os.getcwd()}, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 600
        while proc.poll() is None and time.monotonic() < deadline and not _forks_of(proc.pid):
            time.sleep(0.1)  # until the supervisor's worker is forked (after the warm-up here)
        assert proc.poll() is None, ("the command ended before its supervisor forked a planning worker: "
                                     f"{proc.stderr.read()}")
        assert _forks_of(proc.pid), "no planning worker forked within 600 s"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 128 + signal.SIGTERM, err
        assert "Traceback" not in err
        deadline = time.monotonic() + REAP_TIMEOUT
        while _session_alive(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert _session_alive(proc.pid) == []
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_the_warm_up_is_not_charged_to_the_first_plan_nor_counted_against_its_budget(planning_lab, monkeypatch):
    params, model, base, _ = planning_lab
    monkeypatch.setattr("cartpole.supervise.supervisor._PREPARED", set())

    def planner(x0):
        time.sleep(1.5 if os.getpid() == parent else 1.0)  # the warm-up here, then the plan: together over the budget
        return _HoldPlan.at(model, 2.0)
    parent = os.getpid()
    with Supervisor(model, base.catch, base.rho, base.brake, planner=planner,
                    options=SupervisorOptions(plan_in_worker=True, plan_budget=2.0, funnel=10.0)) as sup:
        sup(0.0, np.asarray(model.x_hanging, float))
        plan = sup.decisions[-1]
        assert plan.kind == "plan" and sup.prepare_s >= 1.5 and not sup.prepare_timed_out
        assert 1.0 <= plan.detail["wall_s"] < 2.0  # the plan's own time only
    _no_child_left()


def test_planning_while_running_a_replan_is_made_while_the_old_plan_is_tracked_and_dropped_when_lost(planning_lab):
    params, model, base, _ = planning_lab

    def planner(x0, guess=None):
        time.sleep(0.5)
        return _HoldPlan.at(model, 20.0)
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=planner,
                     options=SupervisorOptions(plan_while_running=True, warm_worker=False, latency=0.05,
                                               funnel=10.0, replan_every=0.5))
    x = np.asarray(model.x_hanging, float)
    with sup:
        calls = _paced(sup, x, lambda s: any(d.kind == "replan" for d in s.decisions))
        replan = next(d for d in sup.decisions if d.kind == "replan")
        came = calls[-1][0]
        in_flight = [c for c in calls if replan.t < c[0] < came]
        assert replan.detail["wall_s"] >= 0.5 and replan.detail["charged_s"] == pytest.approx(came - replan.t)
        assert len(in_flight) >= 10 and max(w for _, w, _ in in_flight) < 0.25  # tracked on meanwhile
        assert all(np.allclose(u, model.u_eq) for _, _, u in in_flight) and sup.mode == "track"
        more = _paced(sup, x, lambda s: s.replan_asked is not None, t0=came + 0.01)  # the next re-plan on its way
        sup.options = sup.options.replace(funnel=0.1)  # the plan is lost: its re-plan dropped, a plan asked
        sup(more[-1][0] + 0.01, x)
        kinds = [d.kind for d in sup.decisions]
        assert kinds[-2:] == ["lost", "plan_dropped"] and sup.decisions[-1].detail["replan"]
        assert sup.mode == "wait" and sup.server.busy and sup.replan_asked is None
    _no_child_left()


def test_run_within_stops_a_call_at_its_budget_and_restores_the_alarm_handler():
    before = signal.getsignal(signal.SIGALRM)
    start = time.perf_counter()
    assert run_within(lambda: time.sleep(30.0), 0.3) is False
    assert 0.3 <= time.perf_counter() - start < 0.3 + KILL_SLACK
    assert run_within(lambda: None, 5.0) is True
    assert signal.getsignal(signal.SIGALRM) is before and signal.getitimer(signal.ITIMER_REAL)[0] == 0.0
    with pytest.raises(ValueError, match="its own"):  # the call's own failure is the caller's to see
        run_within(lambda: (_ for _ in ()).throw(ValueError("its own")), 5.0)


def test_a_prepare_over_the_plan_budget_is_stopped_there_and_reported(planning_lab, monkeypatch, caplog):
    params, model, base, _ = planning_lab
    monkeypatch.setattr("cartpole.supervise.supervisor._PREPARED", set())
    sup = Supervisor(model, base.catch, base.rho, base.brake, planner=lambda x0: time.sleep(60.0),
                     options=SupervisorOptions(plan_in_worker=True, plan_budget=0.5))
    with caplog.at_level("WARNING", logger="cartpole.supervise.supervisor"):
        took = sup.prepare()
    assert 0.5 <= took < 0.5 + KILL_SLACK and sup.prepare_timed_out
    assert any("plan_budget" in r.getMessage() for r in caplog.records)
    assert sup.prepare() == 0.0  # what it built is kept: the model counts as prepared
    quick = Supervisor(model, base.catch, base.rho, base.brake, planner=lambda x0: _HoldPlan.at(model, 2.0),
                       options=SupervisorOptions(plan_in_worker=True, plan_budget=0.5))
    assert quick.prepare(again=True) < 0.5 and not quick.prepare_timed_out
