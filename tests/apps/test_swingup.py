"""run_swingup on the shipped asset and every variant (the swing-up metrics are tested in tests/validation)."""
import numpy as np
import pytest

from cartpole.models import PeriodError
from cartpole.sim.rig import RigError

import cartpole as cp
from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF
from cartpole.control.energy import EnergyOptions
from cartpole.apps.swingup import (MethodTry, SwingupError, SwingupOptions, auto_methods, check_start, default_method,
                                   method_list, run_swingup)
from cartpole.mpc.options import MPCOptions
from cartpole.planning.options import PlanOptions
from cartpole.sim import replays_exactly
from cartpole.sim.options import LoopError, LoopOptions
from cartpole.validation.metrics import swingup_success


def test_energy_swingup_brings_the_pole_up_and_holds_it(any_mjcf):
    params = cp.read_params(any_mjcf)
    res = run_swingup(params, "energy")
    r = res.rollout
    assert replays_exactly(r, params)
    assert res.caught_at is not None
    assert res.success and swingup_success(r, params)
    lo, hi = params.cart_range
    assert np.all((r.qpos[:, 0] > lo) & (r.qpos[:, 0] < hi))  # never at the joint limit
    assert np.all(np.abs(r.ctrl) <= params.u_max)
    # the switch into the catch is at a MuJoCo state inside the estimated basin
    k = int(round(res.caught_at / r.dt))
    e = r.x[k].copy()
    e[1] = cp.wrap_angle(e[1])
    assert e @ res.basin.S @ e < res.basin.rho
    assert len(res.metrics["switches"]) == 1
    print(f"\n{getattr(any_mjcf, 'name', any_mjcf)}: time to upright {res.metrics['time_to_upright']:.3f} s, "
          f"caught at {res.caught_at:.3f} s, cart clearance {res.metrics['cart_clearance']:.3f} m")


@pytest.mark.parametrize("x0", [(0, np.pi, 0), (0, np.nan, 0, 0), (1.6, np.pi, 0, 0), (-2, 0, 0, 0)])
def test_bad_start_states_raise(x0):
    with pytest.raises(SwingupError):
        run_swingup(None, x0=x0)


def test_unknown_method_raises():
    with pytest.raises(SwingupError):
        run_swingup(None, "magic")


TWO_POLE = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")


def test_energy_refuses_a_chain_before_anything_runs():
    stages = []
    with pytest.raises(CartPoleError, match=r"^Energy shaping is for one pole .*2 hinges.*`method='trajopt'`") as err:
        run_swingup(TWO_POLE, "energy", progress=lambda stage, f: stages.append(stage))
    assert "\n" not in str(err.value)
    assert stages == []  # no basin estimate, no simulation


def _tried(res):
    return [(t.method, t.solver, t.outcome) for t in res.methods_tried]


def test_the_default_chooses_by_the_models_structure():
    """Energy shaping first for one pole driven by the cart; the planner first for a chain or a hinge-driven model
    (energy said not to apply, and why); the DDP planner after the planner; planner settings put the planner first."""
    one = cp.build_model(None)
    assert [(t.method, t.solver, t.outcome) for t in auto_methods(one)] == [
        ("energy", None, ""), ("trajopt", None, ""), ("trajopt", "ddp", "")]
    for path, why in ((TWO_POLE, "2 hinges"), (SHIPPED_MJCF.with_name("dmc_acrobot.xml"), "2 hinges"),
                      (SHIPPED_MJCF.with_name("dmc_pendulum.xml"), "no slide")):
        tries = auto_methods(cp.build_model(path))
        assert tries[0].method == "energy" and tries[0].outcome == "not applicable" and why in tries[0].reason
        assert "--method" not in tries[0].reason  # the default runs the planner next; no advice to do it
        assert [(t.method, t.solver, t.outcome) for t in tries[1:]] == [("trajopt", None, ""), ("trajopt", "ddp", "")]
        assert default_method(cp.build_model(path)) == "trajopt"
    assert default_method(one) == "energy"
    ddp_first = auto_methods(one, plan=PlanOptions(solver="ddp"))
    assert [(t.method, t.solver, t.outcome) for t in ddp_first] == [("energy", None, "not applicable"),
                                                                     ("trajopt", "ddp", "")]
    assert auto_methods(one, objective="time")[0].outcome == "not applicable"


@pytest.mark.parametrize("method, words", [("magic", "Unknown swing-up method 'magic'; choose one of auto"),
                                           ([], "No swing-up method given"),
                                           ([MethodTry("energy", "ddp")], "a trajopt entry takes one of"),
                                           ([MethodTry("trajopt", "newton")], "a trajopt entry takes one of")])
def test_a_bad_method_list_is_one_sentence(method, words):
    with pytest.raises(SwingupError, match=words):
        method_list(method)
    with pytest.raises(SwingupError, match=words):
        run_swingup(None, method)


def test_the_default_falls_back_to_the_planner_when_energy_shaping_fails():
    """A one-pole cart: energy shaping runs first; pumping too gently to get up (an energy gain of 0.5, not 15) it
    fails in MuJoCo, the planner runs next and swings up, and the DDP planner is not needed."""
    res = run_swingup(None, options=SwingupOptions(energy={"energy_gain": 0.5}))
    assert _tried(res) == [("energy", None, "failed"), ("trajopt", "auto", "success"), ("trajopt", "ddp", "skipped")]
    assert res.methods_tried[0].reason == "not upright at rest over the last second"
    assert all(t.seconds > 0 for t in res.methods_tried[:2]) and res.methods_tried[2].seconds == 0
    assert res.method == "trajopt" and res.success and res.plan is not None
    assert replays_exactly(res.rollout, cp.read_params())


def test_a_planner_that_finds_no_plan_ends_the_planners_and_the_run_before_it_is_kept(monkeypatch):
    """The planner raising (no plan found) is recorded as an error; the DDP planner, which starts from the same
    search, is skipped; the energy run that failed before it is the result. With nothing run, the error is raised."""
    from cartpole.ocp.collocation import OCPNotSolved
    import cartpole.planning.trajopt as trajopt

    def no_plan(*args, **kwargs):
        raise OCPNotSolved("No swing-up found within T <= 1 s after 1 attempt; that proves nothing.")

    monkeypatch.setattr(trajopt, "trajopt_swingup", no_plan)
    res = run_swingup(None, options=SwingupOptions(energy={"energy_gain": 0.5}))
    assert _tried(res) == [("energy", None, "failed"), ("trajopt", None, "error"), ("trajopt", "ddp", "skipped")]
    assert res.methods_tried[1].reason.startswith("No swing-up found") and res.method == "energy"
    with pytest.raises(OCPNotSolved):
        run_swingup(TWO_POLE)


def test_no_method_starts_after_the_time_budget():
    res = run_swingup(None, ["energy", "trajopt"], SwingupOptions(energy={"energy_gain": 0.5}, time_budget=1e-3))
    assert _tried(res) == [("energy", None, "failed"), ("trajopt", None, "skipped")]
    assert "`time_budget`" in res.methods_tried[1].reason and "`method='trajopt'`" in res.methods_tried[1].reason
    with pytest.raises(SwingupError, match="time budget"):
        SwingupOptions(time_budget=-1.0)


def test_a_run_cut_short_by_the_duration_given_ends_the_turn():
    """A failure within a duration shorter than the method's own says nothing of the method: nothing else runs."""
    res = run_swingup(None, options=SwingupOptions(loop=LoopOptions(duration=0.5)))
    assert _tried(res) == [("energy", None, "failed"), ("trajopt", None, "skipped"), ("trajopt", "ddp", "skipped")]
    assert "the run of 0.5 s was shorter than the method's own 10 s" in res.methods_tried[0].reason
    assert "`duration`" in res.methods_tried[1].reason and res.method == "energy"


def test_caught_at_only_when_the_catch_held_and_the_handover_has_its_own_name():
    """Caught and held: caught_at is the hand-over. Knocked down by a push after the hand-over, with no time to
    come back: the hand-over is still reported (handover_at), caught_at is None."""
    held = run_swingup(None, "energy")
    assert held.success and held.caught_at is not None and held.caught_at == held.handover_at
    assert _tried(held) == [("energy", None, "success")]
    t = held.handover_at
    knocked = run_swingup(None, "energy", SwingupOptions(loop=LoopOptions(duration=t + 1.5, push=[(t + 0.5, 40.0)])))
    assert not knocked.success and knocked.metrics["time_to_upright"] is None
    assert knocked.handover_at == pytest.approx(t) and knocked.caught_at is None
    assert knocked.metrics["handover_at"] == knocked.handover_at


def test_start_state_count_and_order_come_from_the_model():
    params = cp.read_params(TWO_POLE)
    with pytest.raises(SwingupError, match=r"has 4 number\(s\); give exactly 6: slider \(m\), hinge \(rad\), "
                                           r"hinge2 \(rad\), then their rates in the same order\."):
        check_start([0, np.pi, 0, 0], params)
    x = check_start([0.1, np.pi, 0.2, 0, 0, 0], params)
    assert x.shape == (6,)
    with pytest.raises(SwingupError, match="slide 'slider' is outside"):
        check_start([1.5, np.pi, 0, 0, 0, 0], params)


def test_default_start_is_the_models_hanging_rest():
    model = cp.build_model()
    res = run_swingup(model, "energy", SwingupOptions(loop=LoopOptions(duration=0.5)))
    np.testing.assert_array_equal(res.rollout.x[0], model.x_hanging)
    assert res.rollout.qpos.shape[1] == model.nq and res.rollout.ctrl.shape[1] == model.nu


def test_dmc_swingup_objective_earns_more_return_than_the_minimum_time_plan(tmp_path):
    """On a cart-pole with dm_control's conventions (RK4 at 0.01 s, gear 10, 1 kg cart, 1 m pole of 0.1 kg, rail
    +-1.8 m): the plan that maximises dm_control's smooth reward earns more of its return in MuJoCo than the
    minimum-time plan, over dm_control's 1000 steps of 0.01 s, from hanging rest and from a start 0.01 off it."""
    from chains import dmc_cartpole
    from cartpole.validation.metrics import dmc_swingup_return

    path = tmp_path / "dmc_cartpole.xml"
    path.write_text(dmc_cartpole(1))
    model = cp.build_model(str(path))
    cache = cp.BasinCache()
    for x0 in ([0.0, np.pi, 0.0, 0.0], [0.01, np.pi - 0.01, -0.01, 0.01]):
        got = {}
        for objective in ("dmc_swingup", "time"):
            res = run_swingup(model, "trajopt", SwingupOptions(plan=PlanOptions(objective=objective),
                                                                loop=LoopOptions(duration=10.0)),
                              x0=x0, basin_cache=cache)
            assert replays_exactly(res.rollout, model.params) and res.success
            ret = dmc_swingup_return(res.rollout, model, 0.01)
            got[objective] = ret
            if objective == "dmc_swingup":  # reported by the run, computed from the logged rollout
                assert res.metrics["return"] == pytest.approx(ret, abs=1e-9) and res.metrics["return_steps"] == 1000
            else:
                assert "return" not in res.metrics
        print(f"\nx0 = {x0}: dm_control return, dmc_swingup plan {got['dmc_swingup']:.1f}, minimum-time plan "
              f"{got['time']:.1f} (of 1000)")
        assert got["dmc_swingup"] > got["time"]
        assert got["dmc_swingup"] >= 880  # the criterion (measured 883-884)


def test_trajopt_reports_the_basin_of_the_hand_over_controller():
    """The basin run_swingup reports for trajopt is the hand-over LQR's (the controller that takes over), the same
    as one estimated directly for that controller; and it is not the energy method's catch (R = 1)."""
    from cartpole.control import SWINGUP_CATCH_R, LinearFeedback
    from cartpole.planning.trajopt import handover_catch
    from cartpole.validation.basin import estimate_basin

    params = cp.read_params(SHIPPED_MJCF)
    res = run_swingup(params, "trajopt")
    catch = handover_catch(params)
    direct = estimate_basin(params, catch)
    assert np.array_equal(res.basin.K, catch.K) and np.array_equal(res.basin.S, catch.S)
    assert res.basin.rho == pytest.approx(direct.rho, rel=1e-12)
    assert not np.allclose(res.basin.K, LinearFeedback.for_model(cp.build_model(params), R=SWINGUP_CATCH_R).K)
    # the hand-over cost is measured with that controller's S, and the run enters its basin
    assert res.metrics["handover_cost"] < res.basin.rho
    print(f"\nhand-over LQR basin rho = {res.basin.rho:.4f}, hand-over cost {res.metrics['handover_cost']:.2e}")


def test_a_push_acts_for_a_tenth_of_a_second_is_logged_per_step_and_replays():
    params = cp.read_params()
    h = params.timestep
    res = run_swingup(params, "energy",
                      SwingupOptions(loop=LoopOptions(duration=3.0, push=[(1.0, 20.0), (2.0, -15.0)])))
    push = np.asarray(res.rollout.info["push"])
    assert push.shape == (len(res.rollout.ctrl),)
    k1, k2, n = int(round(1.0 / h)), int(round(2.0 / h)), int(round(0.1 / h))
    expected = np.zeros_like(push)
    expected[k1:k1 + n], expected[k2:k2 + n] = 20.0, -15.0
    np.testing.assert_array_equal(push, expected)
    assert res.push == ((1.0, 20.0), (2.0, -15.0))
    assert replays_exactly(res.rollout, params)  # the replay applies the logged pushes
    from cartpole.sim import replay
    unpushed = replay(params, res.rollout.x[0], res.rollout.ctrl)
    assert not np.allclose(unpushed.x, res.rollout.x)  # the push moved the cart: it is not a no-op


def test_model_error_designs_energy_shaping_and_catch_on_the_scaled_model_while_mujoco_keeps_the_file():
    from cartpole.control import SWINGUP_CATCH_R, LinearFeedback

    params = cp.read_params()
    res = run_swingup(params, "energy", SwingupOptions(loop=LoopOptions(model_error=1.2, duration=6.0)))
    wrong = cp.build_model(params.scaled_pole(1.2, 1.2))
    np.testing.assert_array_equal(res.basin.K, LinearFeedback.for_model(wrong, R=SWINGUP_CATCH_R).K)
    assert not np.allclose(res.basin.K, LinearFeedback.for_model(cp.build_model(params), R=SWINGUP_CATCH_R).K)
    assert res.model_error == 1.2 and res.rollout.mjcf == params.mjcf and replays_exactly(res.rollout, params)


def test_trajopt_with_model_error_plans_and_tracks_on_the_scaled_model():
    from cartpole.planning.trajopt import handover_catch, trajopt_swingup

    params = cp.read_params()
    wrong = cp.build_model(params.scaled_pole(0.8, 0.8))
    res = run_swingup(params, "trajopt", SwingupOptions(loop=LoopOptions(model_error=0.8, push=[(0.3, 5.0)])))
    direct = trajopt_swingup(params, plan_model=wrong)
    np.testing.assert_allclose(res.plan.x, direct.trajectory.x, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(res.basin.K, handover_catch(params, wrong).K)
    assert replays_exactly(res.rollout, params)


def _loop(**kw) -> dict:
    """SwingupOptions fields with a 0.1 s loop of ``kw``."""
    return dict(loop=LoopOptions(**{"duration": 0.1, **kw}))


@pytest.mark.parametrize("fields, error, words", [
    (lambda: _loop(push=[(1.0, np.nan)]), LoopError, "finite force"),
    (lambda: _loop(push=[(-1.0, 5.0)]), LoopError, r"start time in \[0, "),
    (lambda: _loop(push=[(1.0,)]), LoopError, "pair"), (lambda: _loop(model_error=0.0), LoopError, "scale in"),
    (lambda: _loop(model_error=np.inf), LoopError, "scale in"),
    (lambda: _loop(model_error="heavy"), LoopError, "not a number"),
    (lambda: _loop(duration=-1.0), LoopError, "must be a finite number > 0 s"),
    (lambda: _loop(period=0.013), PeriodError, "whole number of the MJCF"),
    (lambda: _loop(delay=0.007), RigError, "whole number of the MJCF"),
    (lambda: {**_loop(), "plan": PlanOptions()}, SwingupError,
     "`plan` options .* `method='trajopt'` or `method='mpc'`"),
    (lambda: {**_loop(), "mpc": MPCOptions()}, SwingupError, "`mpc` options .* `method='mpc'`"),
    (lambda: {**_loop(), "plan": "time"}, SwingupError, "SwingupOptions.plan must be a PlanOptions"),
    (lambda: {**_loop(), "horizon_s": 1.0}, TypeError, "horizon_s"),
])
def test_bad_scenarios_raise_one_sentence(fields, error, words):
    """Bad loop settings are the loop's error; a stage's options given to a method without that stage, the swing-up's
    (naming the Python arguments); all before anything runs."""
    stages = []
    with pytest.raises(error, match=words) as err:
        run_swingup(None, "energy", SwingupOptions(**fields()), progress=lambda st, f: stages.append(st))
    assert "\n" not in str(err.value) and (error is TypeError or isinstance(err.value, CartPoleError))
    assert stages == []


def test_a_ctrl_noise_limit_for_a_method_without_a_catch_names_the_argument():
    with pytest.raises(SwingupError, match="`ctrl_noise` designs the catch .* `method='energy'`, `method='trajopt'` or `method='supervisor'`"):
        run_swingup(None, "mpc", SwingupOptions(ctrl_noise=0.02, loop=LoopOptions(duration=0.1)))


def test_parse_push_reads_t_colon_f():
    from cartpole.apps.swingup import parse_push

    assert parse_push("1.5:-20") == (1.5, -20.0)
    for bad, error in (("1.5", SwingupError), ("1:2:3", SwingupError), ("a:b", SwingupError), ("nan:1", LoopError)):
        with pytest.raises(error):
            parse_push(bad)


def test_the_options_run_the_swingup_and_the_result_echoes_them():
    params = cp.read_params()
    loop = LoopOptions(duration=1.0, push=[(0.5, 10.0)], model_error=1.2)
    res = run_swingup(params, "energy", SwingupOptions(loop=loop))
    assert res.options == {"energy": EnergyOptions(), "loop": loop}
    assert res.push == ((0.5, 10.0),) and res.model_error == 1.2
    # a shorter loop runs the same swing-up, cut short (the push at 0.5 s still acts)
    short = run_swingup(params, "energy", SwingupOptions(loop=loop.replace(duration=0.75)))
    assert short.options["loop"] == loop.replace(duration=0.75)
    np.testing.assert_array_equal(short.rollout.x, res.rollout.x[:len(short.rollout.t)])


def test_swingup_options_are_values():
    a = SwingupOptions(energy={"energy_gain": 0.5}, catch_weights=(cp.Q_LAB, cp.R_LAB))
    b = SwingupOptions(energy=EnergyOptions(energy_gain=0.5), catch_weights=(cp.Q_LAB, cp.R_LAB))
    assert a == b and hash(a) == hash(b) and a != SwingupOptions()
    assert isinstance(a.energy, EnergyOptions) and not a.catch_weights[0].flags.writeable
    assert a.replace(time_budget=5.0).time_budget == 5.0 and a.time_budget is None
    with pytest.raises(SwingupError, match="has no field 'duration'"):
        a.replace(duration=1.0)


def test_mpc_takes_the_loops_period_and_refuses_two_different_ones():
    pytest.importorskip("cartpole.mpc.nmpc")
    params = cp.read_params()
    res = run_swingup(params, "mpc", SwingupOptions(loop=LoopOptions(duration=0.2, period=0.04),
                                                     mpc=MPCOptions(horizon=0.8)))
    ctrl = res.controller
    assert ctrl.period == pytest.approx(0.04) and ctrl.horizon == pytest.approx(0.8)
    assert res.options["mpc"] == MPCOptions(period=0.04, horizon=0.8)
    assert res.options["plan"] == PlanOptions(cart_margin=MPCOptions().cart_margin)
    assert len(ctrl.solve_ms) == -(-len(res.rollout.ctrl) // int(round(0.04 / params.timestep)))
    with pytest.raises(SwingupError, match="differ; give the control period once"):
        run_swingup(params, "mpc", SwingupOptions(loop=LoopOptions(duration=0.2, period=0.04),
                                                   mpc=MPCOptions(period=0.02)))


def test_a_second_swingup_finds_the_basin_on_disk_and_gets_the_identical_estimate(tmp_path, monkeypatch):
    import cartpole.validation.basin as basin_mod

    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    first = run_swingup(None, "energy", SwingupOptions(loop=LoopOptions(duration=0.5)))
    assert len(list((tmp_path / "basins").glob("*.npz"))) == 1

    def no_estimate(*a, **k):
        raise AssertionError("the basin was estimated again")

    monkeypatch.setattr(basin_mod, "catch_outcomes", no_estimate)  # what estimate_basin runs
    second = run_swingup(None, "energy", SwingupOptions(loop=LoopOptions(duration=0.5)))
    a, b = first.basin, second.basin
    for name in ("rho", "rho_sampled", "rho_cover", "n", "seed", "level", "duration", "safety_factor",
                 "limit_margin", "mjcf"):
        assert getattr(a, name) == getattr(b, name), name
    for name in ("samples", "costs", "success", "S", "K", "box", "x_eq"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    # another catch (other gains) is another key: estimated, not found
    with pytest.raises(AssertionError, match="estimated again"):
        run_swingup(None, "energy", SwingupOptions(loop=LoopOptions(duration=0.5), catch_weights=(cp.Q_LAB, cp.R_LAB)))


def test_mpc_swings_up_pushed_and_replays():
    pytest.importorskip("cartpole.mpc.nmpc")
    params = cp.read_params()
    res = run_swingup(params, "mpc", SwingupOptions(loop=LoopOptions(push=[(4.0, 10.0)])))
    ctrl = res.controller
    assert res.method == "mpc" and res.basin is None and res.caught_at is None
    steps = len(res.rollout.ctrl)
    hold = int(round(ctrl.period / params.timestep))
    assert len(ctrl.solve_ms) == -(-steps // hold)  # one solve per control step
    assert np.count_nonzero(res.rollout.info["push"]) == int(round(0.1 / params.timestep))
    assert replays_exactly(res.rollout, params)
    assert res.success, res.metrics


def test_each_method_is_a_class_sharing_the_closed_loop():
    from cartpole.apps.swingup import (DDPMPCSwingup, EnergySwingup, METHOD_CLASSES, NMPCSwingup, SupervisorSwingup,
                                       SwingupMethod, TrajoptSwingup, method_class)

    assert [method_class(m) for m in ("energy", "trajopt", "mpc", "supervisor")] == [
        EnergySwingup, TrajoptSwingup, NMPCSwingup, SupervisorSwingup]
    assert method_class("mpc", MPCOptions(solver="ddp")) is DDPMPCSwingup and issubclass(DDPMPCSwingup, NMPCSwingup)
    assert all(issubclass(c, SwingupMethod) and c.run is SwingupMethod.run for c in METHOD_CLASSES.values())
    assert DDPMPCSwingup.name == "mpc"  # the JSON method: the solver is the MPC's option
    with pytest.raises(SwingupError, match="Unknown swing-up method 'ddp'"):
        method_class("ddp")
    # a trajopt entry's solver replaces the plan's
    m = TrajoptSwingup(SwingupOptions(plan=PlanOptions(objective="time")), MethodTry("trajopt", "ddp"))
    assert m.plan_options() == PlanOptions(objective="time", solver="ddp")
