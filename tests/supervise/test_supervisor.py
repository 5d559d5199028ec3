"""The supervisor: catch, swing-up law, brake, plan and track, chosen at run time; honest about planning latency."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from cartpole.control.model_rollout import model_rollout
from cartpole.control import SWINGUP_CATCH_R, EnergyDrain, LinearFeedback
from cartpole.errors import CartPoleError
from cartpole.models import build_model, planning_limits, read_params, wrap_angle
from cartpole.mpc.ddp_mpc import DDPMPCController
from cartpole.mpc.nmpc import NMPCError
from cartpole.mpc.options import MPCOptions
from cartpole.ocp.trajectory import Trajectory
from cartpole.sim import Knockdown, replays_exactly, simulate
from cartpole.sim.disturbance import joint_inertia_and_authority
from cartpole.planning.options import PlanOptions
from cartpole.supervise import PassiveBrake, Supervisor, SupervisorError, SupervisorOptions, supervisor_for
from cartpole.supervise.supervisor import MPC_HORIZON, hinge_options
from cartpole.validation import BasinCache, uptime_metrics
from cartpole.validation.metrics import diverged


@pytest.fixture(scope="module")
def double(tmp_path_factory):
    params = read_params("cartpole/assets/cartpole_two_pole.xml")
    model = build_model(params)
    catch = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R)
    inertia, _ = joint_inertia_and_authority(params, np.asarray(model.x_eq))
    brake = PassiveBrake(model, inertia, 0.5, catch.u_limits)
    return params, model, catch, brake


def test_the_brake_never_adds_energy_from_fast_states(double):
    params, model, catch, brake = double
    rng = np.random.default_rng(0)
    spring = lambda x: sum(0.5 * kp * g * (x[j] - model.x_eq[j]) ** 2  # noqa: E731  the brake's own spring, J
                           for kp, g, j in zip(brake.kp, params.gears, brake.joints))
    for _ in range(5):
        x0 = np.asarray(model.x_hanging, dtype=float).copy()
        x0[model.nq + np.asarray(model.hinges)] = rng.uniform(-15, 15, len(model.hinges))
        xs, us = model_rollout(model, brake, x0, 400, u_limits=catch.u_limits)
        total = np.array([float(model.energy(x)) + spring(x) for x in xs])
        # passive: energy only leaves (hinge damping, the brake); the discrete step's own energy error on fast
        # swings is the only rise (well under 1 % of the swing's energy)
        swing = total[0] - total.min()
        assert np.max(np.maximum.accumulate(total) - total[0]) < 0.01 * swing
        assert total[-1] < total[0] - 0.5 * swing


def _stub_plan(model, duration, x_end):
    t = np.array([0.0, duration])
    x = np.vstack([x_end, x_end])
    traj = Trajectory(t=t, x=x, u=np.tile(np.asarray(model.u_eq, float), (2, 1)), xdot=np.zeros_like(x))
    return SimpleNamespace(trajectory=traj, controller=lambda t, x: np.asarray(model.u_eq, float))


def test_a_plan_is_used_only_after_its_measured_wall_time(double, monkeypatch):
    params, model, catch, brake = double
    clock = iter([0.0, 0.8] + [0.8] * 100)
    monkeypatch.setattr("cartpole.supervise.supervisor.time.perf_counter", lambda: next(clock))
    sup = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: _stub_plan(model, 2.0, model.x_eq),
                     options=SupervisorOptions(latency=0.3, funnel=10.0))
    x = np.asarray(model.x_hanging, float)
    sup(0.0, x)
    kinds = [d.kind for d in sup.decisions]
    assert kinds == ["plan"] and sup.decisions[0].detail["wall_s"] == pytest.approx(0.8)
    assert np.allclose(sup(0.5, x), brake(0.5, x)) and sup.mode == "wait"  # 0.5 s < 0.8 s: still planning
    sup(0.8, x)
    assert sup.mode == "track" and sup.decisions[-1].detail["late_s"] == pytest.approx(0.5)
    assert sup.latency == pytest.approx(1.25 * 0.8)  # the next plan is predicted over the measured latency


def test_a_failed_plan_is_logged_and_retried_after_braking(double):
    params, model, catch, brake = double
    calls = []

    def planner(x0):
        calls.append(x0)
        raise CartPoleError("No swing-up found within T <= 1 s after 1 attempts.")
    sup = Supervisor(model, catch, 1e-9, brake, planner=planner, options=SupervisorOptions(retry_after=0.5))
    x = np.asarray(model.x_hanging, float)
    for k in range(200):
        sup(k * 0.005, x)
    assert sup.failures == len(calls) >= 2 and sup.decisions[0].kind == "plan_failed"
    assert "No swing-up found" in sup.decisions[0].detail["reason"]
    unreachable = sup.summary()["unreachable"]  # reported, never hidden: each state the planner found nothing from
    assert len(unreachable) == sup.failures and np.allclose(unreachable[0]["x0"], calls[0])
    gaps = np.diff([d.t for d in sup.decisions if d.kind == "plan_failed"])
    assert np.all(gaps >= 0.5 - 1e-9)


def test_fast_states_are_braked_before_any_plan(double):
    params, model, catch, brake = double
    sup = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: pytest.fail("planned from a fast state"),
                     options=SupervisorOptions(calm_rate=5.0))
    x = np.asarray(model.x_hanging, float).copy()
    x[model.nq + model.hinges[0]] = 20.0
    assert np.allclose(sup(0.0, x), brake(0.0, x)) and sup.mode == "brake"


def test_bad_options_are_refused():
    with pytest.raises(SupervisorError, match="release_factor"):
        SupervisorOptions(release_factor=1.0)


def test_one_pole_knocked_down_swings_up_again_every_time_and_replays(tmp_path):
    params = read_params(None)
    model = build_model(params)
    sup = supervisor_for(params, model, basin_cache=BasinCache.on_disk(tmp_path))
    force = Knockdown(1.5, 0.3, seed=4).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, sup, model.x_hanging, 20.0, disturbance=force)
    assert run.info["diverged"] is None and replays_exactly(run)
    stats = uptime_metrics(run, model, events=force.events)
    assert stats["knockdowns"] >= 3 and stats["recoveries"] >= stats["knockdowns"] - 1
    kinds = [d.kind for d in sup.decisions]
    assert kinds.count("catch") >= stats["knockdowns"] and sup.plans == 0  # the energy law needs no planner


def test_each_plan_is_warm_started_from_the_library_and_joins_it(double):
    from cartpole.planning.library import PlanLibrary

    params, model, catch, brake = double
    guesses = []

    def planner(x0, guess=None):
        guesses.append(guess)
        return _stub_plan(model, 0.5, model.x_eq)
    lib = PlanLibrary.empty(model)
    sup = Supervisor(model, catch, 1e-9, brake, planner=planner, library=lib,
                     options=SupervisorOptions(latency=0.01, funnel=10.0))
    x = np.asarray(model.x_hanging, float)
    k = 0
    while len(guesses) < 2 and k < 2000:
        sup(k * 0.005, x)
        k += 1
    assert guesses[0] is None and guesses[1] is not None  # the first from nothing, the second from the first
    assert len(sup.library) == 2 and len(lib) == 0  # the given library is left as it was
    assert sup.summary()["library_plans"] == 2
    assert sup.decisions[[d.kind for d in sup.decisions].index("plan")].detail["warm"] is False


def test_a_late_plan_starts_from_its_beginning_while_the_state_is_still_at_its_start(double, monkeypatch):
    params, model, catch, brake = double
    clock = iter([0.0, 3.0] + [3.0] * 100)  # the plan takes 3 s, far over the 0.3 s predicted
    monkeypatch.setattr("cartpole.supervise.supervisor.time.perf_counter", lambda: next(clock))
    x = np.asarray(model.x_hanging, float)
    sup = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: _stub_plan(model, 2.0, x),
                     options=SupervisorOptions(latency=0.3))
    sup(0.0, x)
    sup(3.0, x)  # at rest where the plan starts: it starts now, not 2.7 s into its 2 s
    assert sup.mode == "track" and sup.plan_t0 == 3.0 and sup.decisions[-1].detail["restarted"] is True
    moved = x.copy()
    moved[model.nq + model.hinges[0]] = 3.0  # swinging away from the plan's start: its clock is kept
    sup2 = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: _stub_plan(model, 2.0, x),
                      options=SupervisorOptions(latency=0.3))
    clock2 = iter([0.0, 3.0] + [3.0] * 100)
    monkeypatch.setattr("cartpole.supervise.supervisor.time.perf_counter", lambda: next(clock2))
    sup2(0.0, x)
    sup2(3.0, moved)
    track = next(d for d in sup2.decisions if d.kind == "track")
    assert track.detail["restarted"] is False


def test_a_state_the_brake_does_not_calm_is_planned_from_after_the_calm_budget(double):
    params, model, catch, brake = double
    asked = []

    def planner(x0):
        asked.append(x0)
        raise CartPoleError("No swing-up found within T <= 1 s after 1 attempts.")
    sup = Supervisor(model, catch, 1e-9, brake, planner=planner,
                     options=SupervisorOptions(calm_budget=0.2, retry_after=0.1))
    x = np.asarray(model.x_hanging, float).copy()
    x[model.nq + model.hinges[-1]] = 30.0  # spinning, held so (the brake never calms it here)
    for k in range(30):  # 0.145 s: under the budget, only braking
        sup(k * 0.005, x)
    assert not asked and sup.mode == "brake"
    for k in range(30, 120):
        sup(k * 0.005, x)
    kinds = [d.kind for d in sup.decisions]
    assert "calm_timeout" in kinds and kinds[kinds.index("calm_timeout") + 1] == "plan_failed"
    assert sup.decisions[kinds.index("calm_timeout")].t >= 0.2 and len(asked) >= 1
    with pytest.raises(SupervisorError, match="calm_budget"):
        SupervisorOptions(calm_budget=0.0)


def test_a_plan_that_comes_early_waits_for_the_state_it_was_planned_from(double, monkeypatch):
    params, model, catch, brake = double
    clock = iter([0.0, 0.1] + [0.1] * 100)  # ready after 0.1 s; planned from the state 0.3 s ahead
    monkeypatch.setattr("cartpole.supervise.supervisor.time.perf_counter", lambda: next(clock))
    x = np.asarray(model.x_hanging, float)
    sup = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: _stub_plan(model, 2.0, x),
                     options=SupervisorOptions(latency=0.3, funnel=10.0))
    sup(0.0, x)
    sup(0.2, x)
    assert sup.mode == "wait"  # arrived, but its start is 0.3 s
    sup(0.3, x)
    assert sup.mode == "track" and sup.decisions[-1].detail["late_s"] == 0.0


def _plan_options_seen(double, monkeypatch, plan, options):
    """The PlanOptions the supervisor's planner hands the trajectory optimiser (stubbed) for ``plan`` and ``options``."""
    params, model, catch, brake = double
    seen = []
    monkeypatch.setattr("cartpole.supervise.supervisor.trajopt_swingup",
                        lambda *a, options=None, **k: seen.append(options) or _stub_plan(model, 1.0, model.x_eq))
    sup = supervisor_for(params, model, plan=plan, options=options, basin_of=lambda c: SimpleNamespace(rho=1e-9))
    sup.planner(np.asarray(model.x_hanging, float))
    return seen[0]


@pytest.mark.parametrize("exact_plans, given, expected", [(False, "auto", False), (True, "auto", "auto"),
                                                          (True, False, False)])
def test_the_supervisors_plans_skip_the_exact_discrete_resolve_only_when_told(double, monkeypatch, exact_plans, given,
                                                                               expected):
    from cartpole.planning.options import PlanOptions

    seen = _plan_options_seen(double, monkeypatch, PlanOptions(exact_discrete=given),
                              SupervisorOptions(exact_plans=exact_plans))
    assert seen.exact_discrete == expected and seen.search_s <= SupervisorOptions().plan_budget
    with pytest.raises(SupervisorError, match="exact_plans"):
        SupervisorOptions(exact_plans="no")


def test_while_tracking_it_replans_from_the_rest_of_the_plan_and_keeps_the_old_one_until_the_new_is_ready(double):
    params, model, catch, brake = double
    x_up = np.asarray(model.x_eq, float)
    guesses = []

    def planner(x0, guess=None):
        guesses.append(guess)
        t = np.linspace(0.0, 10.0 if guess is None else guess.duration, 101)
        x = np.tile(x_up, (t.size, 1))
        traj = Trajectory(t=t, x=x, u=np.tile(np.asarray(model.u_eq, float), (t.size, 1)), xdot=np.zeros_like(x))
        return SimpleNamespace(trajectory=traj, controller=lambda t, x: np.asarray(model.u_eq, float))
    sup = Supervisor(model, catch, 1e-9, brake, planner=planner,
                     options=SupervisorOptions(charged_latency=0.5, funnel=10.0, replan_every=2.0))
    steps = int(round(6.0 / model.dt))
    x_hang = np.asarray(model.x_hanging, float)  # far from the catch's basin, slow, inside the 10 rad funnel
    for k in range(steps):
        sup(k * model.dt, x_hang)
    kinds = [d.kind for d in sup.decisions]
    assert kinds[:2] == ["plan", "track"] and kinds.count("replan") >= 2, kinds
    first = next(d for d in sup.decisions if d.kind == "replan")
    swap = next(d for d in sup.decisions if d.kind == "track" and d.detail.get("replanned"))
    assert swap.t >= first.t + 0.5 - 1e-9  # the new plan only once its charged latency has passed
    # each re-plan started from the rest of the plan tracked: a guess shorter by the time already tracked
    assert guesses[0] is None and guesses[1].duration < 10.0 - 2.0 and guesses[2].duration < guesses[1].duration


def test_trajectory_tail_is_the_rest_of_a_plan_from_zero():
    from cartpole.planning.library import trajectory_tail

    t = np.linspace(0.0, 2.0, 21)
    x = np.column_stack([t, t ** 2])
    traj = Trajectory(t=t, x=x, u=t[:, None], xdot=np.column_stack([np.ones_like(t), 2 * t]))
    tail = trajectory_tail(traj, 0.5)
    assert tail.t[0] == 0.0 and tail.duration == pytest.approx(1.5) and np.allclose(tail.x[0], [0.5, 0.25])
    assert trajectory_tail(traj, 5.0).t.size == 3  # never less than the last two intervals


def test_a_slow_state_above_the_calm_energy_is_braked_and_one_below_it_is_planned_from(double):
    params, model, catch, brake = double
    asked = []

    def planner(x0, guess=None):
        asked.append(np.array(x0))
        raise CartPoleError("No swing-up found within T <= 1 s after 1 attempts.")
    sup = Supervisor(model, catch, 1e-9, brake, planner=planner,
                     options=SupervisorOptions(calm_energy=0.0, calm_budget=100.0, latency=0.01))
    slow_high = np.asarray(model.x_eq, float).copy()
    slow_high[model.nq + model.hinges[0]] = 2.0  # slow, but above the upright's energy
    assert float(model.energy(slow_high)) > 0.0
    for k in range(20):
        sup(k * 0.005, slow_high)
    assert not asked and sup.mode == "brake"
    assert sup.decisions[-1].detail["energy"] == pytest.approx(float(model.energy(slow_high)))
    sup(0.2, np.asarray(model.x_hanging, float))  # at rest hanging: below it, planned from
    assert len(asked) == 1
    with pytest.raises(SupervisorError, match="calm_energy"):
        SupervisorOptions(calm_energy=float("nan"))
    with pytest.raises(SupervisorError, match="warm_tails"):
        SupervisorOptions(warm_tails="yes")


def test_with_warm_tails_each_plan_starts_from_the_rest_of_a_stored_plan_nearest_by_knot_and_never_cold(double):
    from cartpole.planning.library import PlanLibrary
    from cartpole.supervise.supervisor import WARM_TRIES

    params, model, catch, brake = double
    calls = []

    def planner(x0, guess=None, cold=True):
        calls.append((np.array(x0), guess, cold))
        if len(calls) > 1:
            return _stub_plan(model, 0.5, model.x_eq)
        raise CartPoleError("The warm start did not converge.")
    t = np.linspace(0.0, 2.0, 5)
    x = np.array([np.asarray(model.x_hanging, float) * (1 - s) + np.asarray(model.x_eq, float) * s
                  for s in t / 2.0])
    stored = Trajectory(t=t, x=x, u=np.zeros((5, model.nu)), xdot=np.zeros_like(x))
    lib = PlanLibrary.empty(model).with_plan(stored.x[0], stored)
    sup = Supervisor(model, catch, 1e-9, brake, planner=planner, library=lib,
                     options=SupervisorOptions(latency=0.01, funnel=10.0, warm_tails=True))
    sup(0.0, np.asarray(model.x_hanging, float))
    assert len(calls) == 2 <= WARM_TRIES  # the nearest knot's tail failed: the next warm start, not a cold plan
    assert all(g is not None and c is False for _, g, c in calls)
    assert calls[0][1].duration <= stored.duration
    assert sup.decisions[-1].kind == "plan" and "library_distance" in sup.decisions[-1].detail

    tries = []

    def never(x0, guess=None, cold=True):
        tries.append(cold)
        raise CartPoleError("The warm start did not converge.")
    sup2 = Supervisor(model, catch, 1e-9, brake, planner=never, library=lib,
                      options=SupervisorOptions(latency=0.01, warm_tails=True))
    sup2(0.0, np.asarray(model.x_hanging, float))
    d = sup2.decisions[-1]
    assert d.kind == "plan_failed" and "did not converge" in d.detail["reason"] and "library_distance" in d.detail
    assert tries == [False, False]  # the plan and its mirror image, each warm, none cold


def test_the_acrobot_gets_the_hinge_driven_settings(monkeypatch):
    from cartpole.planning.library import PlanLibrary
    from cartpole.supervise.supervisor import (DRAIN_MARGIN, HINGE_BRAKE_TIME, HINGE_CALM_BUDGET,
                                               HINGE_CALM_ENERGY, HINGE_MPC_FLOOR, HINGE_REPLAN_EVERY, MPC_HORIZON,
                                               hinge_driven)

    params = read_params("cartpole/assets/dmc_acrobot.xml")
    model = build_model(params)
    assert hinge_driven(model) and not hinge_driven(build_model(read_params("cartpole/assets/cartpole.xml")))
    sup = supervisor_for(params, model, basin_of=lambda catch: SimpleNamespace(rho=1.0),
                         library=PlanLibrary.empty(model))
    o = sup.options
    assert (o.replan_every, o.calm_energy, o.calm_budget, o.calm_brake_time, o.warm_tails, o.exact_plans,
            o.calm_drain) == (HINGE_REPLAN_EVERY, HINGE_CALM_ENERGY, HINGE_CALM_BUDGET, HINGE_BRAKE_TIME, True, False,
                              True)
    # calmed by the energy drain down to the calm energy, the soft brake below it
    assert isinstance(sup.calm_brake, EnergyDrain) and sup.calm_brake.target == HINGE_CALM_ENERGY + DRAIN_MARGIN
    assert isinstance(sup.calm_brake.below, PassiveBrake) and sup.calm_brake.below is not sup.brake
    # a calm state near the upright's energy is swung up by the DDP MPC, at the MJCF's step
    assert o.swingup_mpc and isinstance(sup.mpc, DDPMPCController) and sup.mpc.period == params.timestep
    assert sup.mpc.horizon == pytest.approx(MPC_HORIZON)
    with pytest.raises(SupervisorError, match="calm_drain"):
        SupervisorOptions(calm_drain="yes")
    cart = supervisor_for("cartpole/assets/cartpole_two_pole.xml", basin_of=lambda catch: SimpleNamespace(rho=1.0),
                          library=PlanLibrary.empty(build_model(read_params("cartpole/assets/cartpole_two_pole.xml"))))
    assert cart.mpc is None and not cart.options.swingup_mpc  # the carts plan, as before
    # without a plan's objective the MPC tracks upright
    assert o == hinge_options(plan_in_worker=o.plan_in_worker) and sup.mpc.objective == "tracking"
    task = supervisor_for(params, model, basin_of=lambda catch: SimpleNamespace(rho=1.0),
                          library=PlanLibrary.empty(model), plan=PlanOptions(objective="dmc_acrobot_swingup"),
                          options=hinge_options(charged_latency=0.25))
    assert task.mpc.objective == "dmc_acrobot_swingup" and task.options.charged_latency == 0.25
    assert task.options.replace(charged_latency=None) == o
    assert o.mpc_floor == HINGE_MPC_FLOOR  # the tracking MPC does not pump from hanging: planned from below the floor
    pumped = supervisor_for(params, model, basin_of=lambda catch: SimpleNamespace(rho=1.0),
                            library=PlanLibrary.empty(model), plan=PlanOptions(objective="dmc_acrobot_swingup"))
    assert pumped.options.mpc_floor is None and pumped.mpc.objective == "dmc_acrobot_swingup"  # the task's: any state


def test_the_swing_up_mpcs_horizon_and_iterations_reach_it_and_bad_ones_are_refused():
    from cartpole.planning.library import PlanLibrary

    params = read_params("cartpole/assets/dmc_acrobot.xml")
    model = build_model(params)
    period = 0.02
    sup = supervisor_for(params, model, period=period, basin_of=lambda catch: SimpleNamespace(rho=1.0),
                         library=PlanLibrary.empty(model), options=hinge_options(mpc_horizon=1.0, mpc_iterations=3))
    assert sup.mpc.iterations == 3 and sup.mpc.horizon == pytest.approx(1.0)
    assert sup.mpc.N == round(1.0 / sup.mpc.period)
    default = supervisor_for(params, model, period=period, basin_of=lambda catch: SimpleNamespace(rho=1.0),
                             library=PlanLibrary.empty(model), options=hinge_options())
    assert default.mpc.iterations == 1 and default.mpc.horizon == pytest.approx(MPC_HORIZON)
    for bad in ({"mpc_horizon": 0.0}, {"mpc_iterations": 0}, {"mpc_iterations": 1.5}):
        with pytest.raises(SupervisorError, match=next(iter(bad))):
            SupervisorOptions(**bad)


def test_an_mpc_step_over_its_wall_time_budget_applies_the_previous_solution_shifted_and_is_counted():
    from cartpole.planning.library import PlanLibrary

    params = read_params("cartpole/assets/dmc_acrobot.xml")
    model = build_model(params)
    x = np.asarray(model.x_hanging, float)
    free = supervisor_for(params, model, basin_of=lambda catch: SimpleNamespace(rho=1e-9),
                          library=PlanLibrary.empty(model), options=hinge_options(mpc_floor=None))
    tight = supervisor_for(params, model, basin_of=lambda catch: SimpleNamespace(rho=1e-9),
                           library=PlanLibrary.empty(model),
                           options=hinge_options(mpc_floor=None, mpc_step_budget=1e-9))
    u0 = tight(0.0, x)  # the first step has no earlier solution: its own, however late
    assert tight.mode == "mpc" and np.allclose(u0, free(0.0, x))
    dt = float(params.timestep)
    for k in range(1, 4):
        _, before = tight.mpc.plan
        u = tight(k * dt, x)
        assert np.allclose(u, np.clip(before[1], tight.mpc.u_low, tight.mpc.u_high))  # the last solution, shifted
    _, late = tight.mpc.plan
    assert not np.allclose(late[0], before[1])  # the late answer is kept as the next step's warm start
    ms = tight.summary()["mpc_ms"]
    assert ms["steps"] == 4 and ms["over_budget"] == 3 == len(tight.mpc.over_budget)
    assert ms["budget_ms"] == pytest.approx(1e-6)
    assert free.summary()["mpc_ms"]["over_budget"] == 0 and free.summary()["mpc_ms"]["budget_ms"] is None
    with pytest.raises(SupervisorError, match="mpc_step_budget"):
        SupervisorOptions(mpc_step_budget=0.0)
    with pytest.raises(NMPCError, match="step_budget"):
        DDPMPCController(model, params, step_budget=-1.0)
    with pytest.raises(NMPCError, match="step_budget"):
        DDPMPCController(model, params, step_budget="fast")


class _StubMPC:
    """A swing-up MPC that records its calls (time since it took over) and resets."""

    def __init__(self, nu):
        self.calls, self.resets, self.nu = [], 0, nu

    def reset(self):
        self.resets += 1
        self.solve_ms = []

    def __call__(self, t, x):
        self.calls.append(t)
        self.solve_ms = getattr(self, "solve_ms", []) + [1.0]
        return np.full(self.nu, 0.125)


class _ConvergingMPC(_StubMPC):
    """A stub swing-up MPC that also records the states its solution is converged from."""

    def __init__(self, nu):
        super().__init__(nu)
        self.converged = []

    def converge(self, x0):
        self.reset()
        self.converged.append(np.array(x0))
        return {"iterations": 7, "status": "converged", "cost": 0.0}


def test_a_converged_mpc_take_over_brakes_until_its_charged_solve_then_acts_from_the_predicted_state(double):
    """With mpc_converge the MPC's solution is converged from the state predicted charged_latency s ahead under the
    brake; the brake acts until then, and the MPC's clock starts at that predicted state's time."""
    params, model, catch, brake = double
    e_up = float(model.energy(model.x_eq))
    band = 0.25 * (e_up - float(model.energy(model.x_hanging)))
    lat = 5 * model.dt
    sup = Supervisor(model, catch, 1e-9, brake, options=SupervisorOptions(
        swingup_mpc=True, mpc_energy=band, mpc_converge=True, charged_latency=lat), planner=lambda x0: None)
    sup.mpc = _ConvergingMPC(model.nu)
    near = np.asarray(model.x_eq, float).copy()
    near[model.hinges[0]] += 0.3
    assert np.allclose(sup(2.0, near), brake(2.0, near)) and sup.mode == "mpc" and not sup.mpc.calls
    xs, _ = model_rollout(model, brake, near, 5, t0=2.0)
    assert len(sup.mpc.converged) == 1 and np.allclose(sup.mpc.converged[0], xs[-1])
    d = sup.decisions[-1]
    assert d.kind == "mpc" and d.detail["charged_s"] == lat and d.detail["iterations"] == 7
    assert np.allclose(sup(2.0 + 2 * model.dt, near), brake(2.0, near)) and not sup.mpc.calls  # still charged
    assert np.allclose(sup(2.0 + 5 * model.dt, near), 0.125) and sup.mpc.calls == [pytest.approx(0.0)]
    assert sup.summary()["mpc_converge_s"] == [d.detail["converge_s"]]
    at_once = Supervisor(model, catch, 1e-9, brake, options=SupervisorOptions(swingup_mpc=True, mpc_energy=band),
                         planner=lambda x0: None)
    at_once.mpc = _ConvergingMPC(model.nu)
    assert np.allclose(at_once(2.0, near), 0.125) and not at_once.mpc.converged  # the default: at once, as before
    with pytest.raises(SupervisorError, match="mpc_latency"):
        SupervisorOptions(mpc_latency=0.0)


class _Designed(_StubMPC):
    """A stub MPC designed from a state, its ctrl telling which design it is."""

    def __init__(self, nu, x0, level):
        super().__init__(nu)
        self.x0, self.level = np.array(x0), level

    def __call__(self, t, x):
        super().__call__(t, x)
        return np.full(self.nu, self.level)

    def as_dict(self):
        return {"choice": f"design {self.level}", "predicted_return": 10.0 * self.level}


def test_an_mpc_designed_at_each_take_over_starts_from_the_take_over_state_when_nothing_is_charged(double):
    """With mpc_design and charged_latency=0 (an environment that waits for each action) each take-over designs a new
    MPC from the state itself and it acts at once; with a charge the design starts from the state predicted that far
    ahead under the brake and the brake acts until then; a design that fails keeps the previous MPC, saying so."""
    params, model, catch, brake = double
    e_up = float(model.energy(model.x_eq))
    band = 0.25 * (e_up - float(model.energy(model.x_hanging)))
    near = np.asarray(model.x_eq, float).copy()
    near[model.hinges[0]] += 0.3

    def supervisor(charge):
        sup = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: None, options=SupervisorOptions(
            swingup_mpc=True, mpc_energy=band, charged_latency=charge))
        sup.mpc, designs = _StubMPC(model.nu), []

        def design(x):
            designs.append(_Designed(model.nu, x, 0.25 * (len(designs) + 1)))
            return designs[-1]
        sup.mpc_design = design
        return sup, designs

    waited, designs = supervisor(0.0)
    assert np.allclose(waited(2.0, near), 0.25) and waited.mode == "mpc"
    assert len(designs) == 1 and np.array_equal(designs[0].x0, near) and designs[0].calls == [pytest.approx(0.0)]
    d = waited.decisions[-1]
    assert d.kind == "mpc" and d.detail["charged_s"] == 0.0 and d.detail["choice"] == "design 0.25"
    assert d.detail["predicted_return"] == 2.5 and d.detail["design_s"] >= 0.0 and d.detail["status"] == "designed"

    lat = 5 * model.dt
    charged, designs = supervisor(lat)
    assert np.allclose(charged(2.0, near), brake(2.0, near)) and charged.mode == "mpc"
    xs, _ = model_rollout(model, brake, near, 5, t0=2.0)
    assert np.allclose(designs[0].x0, xs[-1]) and not designs[0].calls
    assert np.allclose(charged(2.0 + 5 * model.dt, near), 0.25) and designs[0].calls == [pytest.approx(0.0)]

    def failing(x):
        raise SupervisorError("no design from here")
    kept, _ = supervisor(0.0)
    kept.mpc_design = failing
    assert np.allclose(kept(2.0, near), 0.125) and "no design from here" in kept.decisions[-1].detail["status"]


def test_the_ddp_mpc_converged_at_a_take_over_is_the_one_converged_offline_from_that_start():
    """DDPMPCController.converge(x0) starts a run from the solution its constructor converges offline for x0, and a
    later reset goes back to its own first solution."""
    params = read_params("cartpole/assets/dmc_acrobot.xml")
    model = build_model(params)
    opts = MPCOptions(solver="ddp", seed_plan=False, horizon=0.5, objective="dmc_acrobot_swingup",
                      period=params.timestep)
    x0 = np.asarray(model.x_hanging, float) + np.array([0.4, -0.3, 0.0, 0.0])
    offline = DDPMPCController(model, params, options=opts, x0=x0)
    later = DDPMPCController(model, params, options=opts)
    first = later.plan[1]
    info = later.converge(x0)
    assert info["iterations"] == offline.init_info["iterations"] > 0
    assert np.array_equal(later.plan[1], offline.plan[1]) and np.array_equal(later(0.0, x0), offline(0.0, x0))
    later.reset()
    assert np.array_equal(later.plan[1], first)
    with pytest.raises(NMPCError, match="finite"):
        later.converge(np.full(model.nx, np.nan))


def test_any_calm_state_is_swung_up_by_the_mpc_and_planned_from_once_it_fails(double):
    params, model, catch, brake = double
    asked = []

    def planner(x0, guess=None):
        asked.append(np.array(x0))
        raise CartPoleError("No swing-up found within T <= 1 s after 1 attempts.")
    e_up = float(model.energy(model.x_eq))
    band = 0.25 * (e_up - float(model.energy(model.x_hanging)))  # a quarter of the swing-up's energy
    sup = Supervisor(model, catch, 1e-9, brake, planner=planner,
                     options=SupervisorOptions(latency=0.01, swingup_mpc=True, mpc_energy=band, mpc_budget=1.0))
    sup.mpc = _StubMPC(model.nu)
    near = np.asarray(model.x_eq, float).copy()
    near[model.hinges[0]] += 0.3  # at rest, a little below the upright's energy: in the MPC's band
    assert -band < float(model.energy(near)) - e_up < 0.0
    assert np.allclose(sup(2.0, near), 0.125) and sup.mode == "mpc" and sup.decisions[-1].kind == "mpc"
    assert np.allclose(sup(2.5, near), 0.125) and sup.mpc.calls == [0.0, 0.5] and sup.mpc.resets == 1 and not asked
    sup(3.0, near)  # its budget is over without a catch: failed, and planned from instead
    kinds = [d.kind for d in sup.decisions]
    assert kinds[-2:] == ["mpc_failed", "plan_failed"] and len(asked) == 1
    assert "no catch within 1 s" in sup.decisions[-2].detail["reason"]
    sup(3.6, near)  # not again until the next catch or knock
    assert len(sup.mpc.calls) == 2 and len(asked) == 2
    thrown = near.copy()
    thrown[model.nq + model.hinges[0]] = 30.0  # knocked (thrown) after the MPC ran out: a new state
    sup(4.0, thrown)
    assert sup.mode == "brake" and len(sup.mpc.calls) == 2
    assert [d.kind for d in sup.decisions][-2:] == ["plan_failed", "brake"]  # the fallback has its own entry
    sup(4.5, near)  # calm again: the MPC tries this new state
    assert sup.mode == "mpc" and len(sup.mpc.calls) == 3 and len(asked) == 2
    floored = Supervisor(model, catch, 1e-9, brake, planner=planner,
                         options=SupervisorOptions(latency=0.01, swingup_mpc=True, mpc_energy=band, mpc_floor=band))
    floored.mpc = _StubMPC(model.nu)
    floored(0.0, np.asarray(model.x_hanging, float))  # below its floor: planned from
    assert not floored.mpc.calls and floored.decisions[-1].kind == "plan_failed" and len(asked) == 3
    assert sup.summary()["mpc_ms"] == {"median": 1.0, "max": 1.0, "steps": 3, "over_budget": 0,
                                       "budget_ms": None}  # each step's wall time, logged
    hanging = Supervisor(model, catch, 1e-9, brake, planner=planner,
                         options=SupervisorOptions(latency=0.01, swingup_mpc=True, mpc_energy=band, mpc_floor=None))
    hanging.mpc = _StubMPC(model.nu)
    x_hanging = np.asarray(model.x_hanging, float)
    assert float(model.energy(x_hanging)) - e_up < -band  # far below: without a floor, the MPC all the same
    assert np.allclose(hanging(0.0, x_hanging), 0.125) and hanging.mode == "mpc" and not asked[3:]
    knocked = x_hanging.copy()
    knocked[model.nq + model.hinges[0]] = 30.0  # knocked again while the MPC swings: far above the band
    assert float(model.energy(knocked)) - e_up > band
    hanging(0.1, knocked)
    assert [d.kind for d in hanging.decisions][-2:] == ["mpc_failed", "brake"] and hanging.mode == "brake"
    assert "energy rose" in hanging.decisions[-2].detail["reason"]
    hanging(0.2, x_hanging)  # calm again: the MPC takes it again (a knock does not spend it), still no plan
    assert hanging.mode == "mpc" and len(hanging.mpc.calls) == 2 and not asked[3:]
    with pytest.raises(SupervisorError, match="mpc_budget"):
        SupervisorOptions(mpc_budget=0.0)
    with pytest.raises(SupervisorError, match="swingup_mpc"):
        SupervisorOptions(swingup_mpc=1)


def test_a_plan_lost_above_the_mpc_floor_is_handed_to_the_mpc_and_one_lost_below_it_is_planned_again(double):
    """The rule the acrobot's run from hanging exercises (its outcome turns on round-off: tests/supervise/
    test_knockdown_runs.py), on constructed states: a tracked plan left at rest within the MPC's band (at most
    ``mpc_floor`` below the upright's energy) is handed to the swing-up MPC at once; left fast, it is calmed first
    and then handed over; left below the floor, planned from again, no MPC."""
    params, model, catch, brake = double
    e_up = float(model.energy(model.x_eq))
    band = 0.25 * (e_up - float(model.energy(model.x_hanging)))  # a quarter of the swing-up's energy
    x_hang = np.asarray(model.x_hanging, float)
    above = np.asarray(model.x_eq, float).copy()
    above[model.hinges[0]] += 0.3  # at rest, a little below the upright's energy: in the MPC's band
    below = x_hang.copy()
    below[model.hinges[-1]] += 1.0  # at rest, the last pole bent 1 rad from hanging: below the floor
    fast = above.copy()
    fast[model.nq + model.hinges[0]] = 30.0  # the same pose, thrown: not calm
    assert -band < float(model.energy(above)) - e_up < 0.0 and float(model.energy(below)) - e_up < -band
    for x in (above, below):  # each off the plan (hanging) by more than the funnel: the plan is lost there
        assert np.max(np.abs(wrap_angle(x[list(model.hinges)] - x_hang[list(model.hinges)]))) > 0.6
    results = {}
    for name, x in (("above", above), ("below", below), ("fast", fast)):
        sup = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: _stub_plan(model, 5.0, x_hang),
                         options=SupervisorOptions(charged_latency=0.01, funnel=0.6, swingup_mpc=True,
                                                   mpc_energy=band, mpc_floor=band))
        sup.mpc = _StubMPC(model.nu)
        sup(0.0, x_hang)
        sup(0.02, x_hang)
        assert [d.kind for d in sup.decisions] == ["plan", "track"]  # the plan from hanging, tracked
        sup(0.03, x)
        results[name] = sup
    tail = lambda sup, n: [(d.t, d.kind) for d in sup.decisions[-n:]]  # noqa: E731
    assert tail(results["above"], 2) == [(0.03, "lost"), (0.03, "mpc")] and results["above"].mpc.calls == [0.0]
    assert tail(results["below"], 2) == [(0.03, "lost"), (0.03, "plan")] and not results["below"].mpc.calls
    thrown = results["fast"]
    assert tail(thrown, 2) == [(0.03, "lost"), (0.03, "brake")] and not thrown.mpc.calls  # calmed first
    thrown(0.5, above)  # calm again, in the band: the MPC takes it (not spent: it never ran)
    assert tail(thrown, 1) == [(0.5, "mpc")] and thrown.mpc.calls == [0.0]


def test_the_calming_brake_acts_on_fast_states_and_the_brake_while_a_plan_is_on_its_way(double):
    params, model, catch, brake = double
    calm = (lambda t, x: np.full(model.nu, 0.25))
    sup = Supervisor(model, catch, 1e-9, brake, planner=lambda x0: _stub_plan(model, 1.0, model.x_eq),
                     options=SupervisorOptions(latency=0.5, funnel=10.0), calm_brake=calm)
    fast = np.asarray(model.x_hanging, float).copy()
    fast[model.nq + model.hinges[0]] = 20.0
    assert np.allclose(sup(0.0, fast), 0.25) and sup.mode == "brake"
    x = np.asarray(model.x_hanging, float)
    assert np.allclose(sup(0.1, x), brake(0.1, x)) and sup.mode == "wait"  # calm: planned, the brake meanwhile
    with pytest.raises(SupervisorError, match="calm_brake_time"):
        SupervisorOptions(calm_brake_time=0.0)


def test_supervisor_for_plans_within_the_default_bounds_the_command_line_uses_when_the_motor_has_no_ctrlrange():
    """A motor without ctrlrange: ``supervisor_for(path)`` designs on the bounded model the command line plans with
    (:func:`cartpole.models.planning_limits`' stated default ``|ctrl|`` bound), not on the unlimited one; MuJoCo runs
    the file itself."""
    path = "tests/assets/corpus/no_ctrlrange.xml"
    params = read_params(path)
    assert not np.all(np.isfinite(params.ctrl_range))  # the premise: unlimited in the file
    bounded, limits = planning_limits(params)
    sup = supervisor_for(path)
    assert np.all(np.isfinite(sup.catch.u_limits))
    assert np.allclose(sup.catch.u_limits, np.asarray(bounded.ctrl_range, float).reshape(sup.catch.u_limits.shape))
    same = supervisor_for(params, build_model(bounded))  # as the command line calls it
    assert np.allclose(sup.catch.K, same.catch.K) and sup.rho == pytest.approx(same.rho)


@pytest.mark.parametrize("search_s", [None, 1e6])
def test_the_supervisors_plans_are_bounded_by_its_plan_budget_when_the_plan_options_set_none(double, monkeypatch,
                                                                                              search_s):
    from cartpole.planning.options import PlanOptions

    seen = _plan_options_seen(double, monkeypatch, PlanOptions(search_s=search_s), SupervisorOptions())
    assert seen.search_s == SupervisorOptions().plan_budget


def test_a_state_outside_the_verified_basin_is_caught_when_the_catchs_run_on_the_model_reaches_the_basin(double):
    """catch_rollout: just outside the basin's level (within release_factor rho) the catch takes a state whose
    closed-loop run on the model enters the basin within the option's time (the decision says how soon); without the
    option, or with too short a run, it does not."""
    params, model, catch, brake = double
    near = np.asarray(model.x_eq, float).copy()
    near[model.hinges[0]] += 0.05
    rho = 0.5 * float(catch.cost_to_go(near))

    def no_plan(x0, **_):
        raise SupervisorError("no plan in this test")

    def supervisor(**options):
        return Supervisor(model, catch, rho, brake, planner=no_plan, options=SupervisorOptions(
            charged_latency=0.0, plan_in_worker=False, **options))

    certified = supervisor(catch_rollout=2.0)
    assert np.allclose(certified(0.0, near), catch(0.0, near)) and certified.mode == "catch"
    took = certified.decisions[-1].detail["certified_s"]
    assert 0.0 < took <= 2.0
    xs, _ = model_rollout(model, catch, near, int(round(took / model.dt)))
    assert catch.cost_to_go(xs[-1]) < rho <= catch.cost_to_go(xs[-2])  # the run's first step inside the basin
    plain = supervisor()
    plain(0.0, near)
    assert plain.mode != "catch"
    too_short = supervisor(catch_rollout=model.dt)
    too_short(0.0, near)
    assert too_short.mode != "catch"
    with pytest.raises(SupervisorError, match="catch_rollout"):
        SupervisorOptions(catch_rollout=0.0)


def test_a_swing_up_law_that_finds_no_catch_within_its_budget_hands_every_later_fall_to_the_planner(double):
    """A law that never reaches the catch (the stub pumps nothing) runs law_budget s; then the brake and the planner
    take over, and after the next catch the planner takes the next fall at once (the law stays out)."""
    params, model, catch, brake = double
    asked = []

    def planner(x0, guess=None):
        asked.append(np.array(x0))
        raise CartPoleError("No swing-up found within T <= 1 s after 1 attempts.")
    law = lambda t, x: np.full(model.nu, 0.25)  # noqa: E731
    sup = Supervisor(model, catch, 1e-9, brake, swingup=law, planner=planner,
                     options=SupervisorOptions(latency=0.01, law_budget=2.0))
    hanging = np.asarray(model.x_hanging, float)
    for t in (0.0, 1.0, 1.99):
        assert np.allclose(sup(t, hanging), 0.25) and sup.mode == "swingup" and not asked
    sup(2.0, hanging)
    kinds = [d.kind for d in sup.decisions]
    assert kinds == ["swingup", "law_failed", "plan_failed"] and len(asked) == 1
    assert "no catch within 2 s" in sup.decisions[1].detail["reason"]
    sup(2.5, np.asarray(model.x_eq, float))  # caught (rho is tiny: only the upright itself)
    assert sup.mode == "catch"
    sup(3.0, hanging)  # the next fall: planned from at once
    assert sup.mode != "swingup" and len(asked) == 2
    without = Supervisor(model, catch, 1e-9, brake, swingup=law, options=SupervisorOptions(law_budget=2.0))
    assert np.allclose(without(5.0, hanging), 0.25) and without.mode == "swingup"  # no planner: the law goes on
    with pytest.raises(SupervisorError, match="law_budget"):
        SupervisorOptions(law_budget=0.0)


def test_a_heavy_pole_the_energy_law_cannot_lift_at_the_default_bound_is_swung_up_by_a_plan(tmp_path):
    """A 1 kg point mass on a 1 m rod on a 1 kg cart, motor and rail unlimited in the file (the planning default:
    19.6 N, 1 g on the cart's load): the energy law pumps the pole to within a few tenths of a radian of upright
    and back, never into the catch's basin; the supervisor runs it law_budget s, then plans and catches it."""
    path = Path(__file__).parents[1] / "assets" / "heavy_pole_cart.xml"
    params, _ = planning_limits(read_params(path))
    model = build_model(params)
    sup = supervisor_for(params, model, options=SupervisorOptions(law_budget=8.0, plan_in_worker=False),
                         basin_cache=BasinCache.on_disk(tmp_path))
    run = simulate(model, sup, x0=np.asarray(model.x_hanging, float), duration=16.0)
    kinds = [d.kind for d in sup.decisions]
    assert kinds[:2] == ["swingup", "law_failed"] and sup.decisions[1].t == pytest.approx(8.0, abs=0.01)
    assert kinds[-1] == "catch" and uptime_metrics(run, model)["swingups"] >= 1
    assert replays_exactly(run) and not diverged(run)  # a MuJoCo reset to qpos0 would replay too
