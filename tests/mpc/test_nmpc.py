"""Nonlinear MPC (real-time iteration) in the MuJoCo loop: swing-up, pushes, model error, two poles, failures."""
import numpy as np
import pytest

from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.mpc.nmpc import NMPCController, NMPCError, nmpc_swingup
from cartpole.mpc.ipopt_baseline import IpoptMPC
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.metrics import swingup_success
from cartpole.mpc.options import MPCOptions

TWO_POLE = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
THREE_POLE = SHIPPED_MJCF.with_name("cartpole_three_pole.xml")


def _push(t0: float, force: float):
    """``force`` N on the cart for 0.1 s from ``t0`` s."""
    return lambda t: force if t0 <= t < t0 + 0.1 - 1e-12 else 0.0


def _tilted(model, *angles):
    x = np.array(model.x_eq, dtype=float)
    for h, a in zip(model.hinges, angles):
        x[h] += a
    return x


@pytest.fixture(scope="module")
def params():
    return read_params(None)


@pytest.fixture(scope="module")
def model(params):
    return build_model(params)


@pytest.fixture(scope="module")
def swingup(params, model):
    return nmpc_swingup(params, plan_model=model)


@pytest.fixture(scope="module")
def tvlqr_plan(params, model):
    return trajopt_swingup(params, x0=model.x_hanging, plan_model=model)


@pytest.fixture(scope="module")
def balance(params, model):
    return NMPCController(model, params)


@pytest.fixture(scope="module")
def balance_py(params, model):
    """The Python step (the no-compiler path and the C step's reference), where a test injects QP failures."""
    return NMPCController(model, params, options=MPCOptions(c_step=False))


@pytest.fixture(scope="module")
def swingup_py(params, model, swingup):
    """``swingup``'s controller on the Python step, from the same offline plan."""
    return NMPCController(model, params, options=swingup.options.replace(c_step=False), guess=swingup._plan,
                          x0=model.x_hanging)


def test_nmpc_swings_the_pole_up_from_hanging_rest_and_holds_it(params, model, swingup):
    swingup.reset()
    ro = simulate(params, swingup, model.x_hanging, 3.5)
    assert swingup_success(ro, params)
    assert replays_exactly(ro)
    assert swingup.failures == []
    steps = swingup.steps
    n = len(ro.ctrl)
    assert len(swingup.solve_ms) == -(-n // steps)  # one solve per control instant
    # the ctrl is held between control instants
    held = ro.ctrl[: n - n % steps].reshape(-1, steps, model.nu)
    assert np.all(held == held[:, :1, :])
    assert swingup.period == pytest.approx(steps * params.timestep)
    assert swingup.horizon == pytest.approx(swingup.N * swingup.period)


def test_nmpc_recovers_from_a_push_that_the_tvlqr_pipeline_does_not_survive(params, model, swingup, tvlqr_plan):
    """60 N for 0.1 s at 1.0 s, as the pole nears upright: the middle of a region (0.95-1.1 s, 55-65 N) where NMPC
    recovered and TVLQR did not in every run we made, compiled or not (recoveries near the rail are sensitive to
    rounding, single pushes at the region's edge are not a fair test)."""
    push = _push(1.0, 60.0)
    swingup.reset()
    tvlqr_plan.controller.reset()
    ro_mpc = simulate(params, swingup, model.x_hanging, 6.0, push=push)
    ro_tv = simulate(params, tvlqr_plan.controller, model.x_hanging, 6.0, push=push)
    assert np.max(ro_mpc.info["push"]) == 60.0 and np.max(ro_tv.info["push"]) == 60.0
    assert replays_exactly(ro_mpc) and replays_exactly(ro_tv)
    assert not swingup_success(ro_tv, params)
    assert swingup_success(ro_mpc, params)
    assert swingup.failures == []


@pytest.mark.parametrize("mass_factor", [0.8, 1.2])
def test_nmpc_swings_up_when_the_planning_models_pole_mass_is_20_percent_off(params, mass_factor):
    wrong = build_model(params.scaled_pole(mass_factor))
    ctrl = nmpc_swingup(params, plan_model=wrong)
    ro = simulate(params, ctrl, wrong.x_hanging, 4.0)
    assert replays_exactly(ro)
    assert swingup_success(ro, params)


def test_nmpc_balances_the_two_pole_cart_through_pushes():
    params2 = read_params(TWO_POLE)
    model2 = build_model(params2)
    ctrl = NMPCController(model2, params2)
    push = lambda t: 10.0 if 1.0 <= t < 1.1 - 1e-12 else (-10.0 if 2.5 <= t < 2.6 - 1e-12 else 0.0)  # noqa: E731
    ro = simulate(params2, ctrl, _tilted(model2, 0.1, -0.1), 4.5, push=push)
    assert np.count_nonzero(ro.info["push"]) == 2 * round(0.1 / params2.timestep)
    assert replays_exactly(ro)
    assert swingup_success(ro, params2)
    assert ctrl.failures == []


def test_nmpc_balances_the_three_pole_cart_through_a_push_on_the_prestabilised_qp():
    params3 = read_params(THREE_POLE)
    model3 = build_model(params3)
    ctrl = NMPCController(model3, params3)
    assert ctrl.prestabilize  # chosen for the fast upright modes of three poles over 1.2 s
    ro = simulate(params3, ctrl, _tilted(model3, 0.05), 5.0, push=_push(2.0, 3.0))
    assert replays_exactly(ro)
    assert swingup_success(ro, params3)
    assert ctrl.failures == []


def test_prestabilised_and_plain_condensing_solve_the_same_qp(params, model):
    x = _tilted(model, 0.3)
    plain = NMPCController(model, params, options=MPCOptions(horizon=0.6, prestabilize=False))
    stab = NMPCController(model, params, options=MPCOptions(horizon=0.6, prestabilize=True))
    assert not plain.prestabilize and stab.prestabilize
    np.testing.assert_allclose(stab(0.0, x), plain(0.0, x), atol=1e-6)
    for (a, b) in zip(stab.plan, plain.plan):
        np.testing.assert_allclose(a, b, atol=1e-6)


def test_a_qp_that_always_fails_near_upright_falls_back_to_the_upright_lqr_and_never_raises(params, model,
                                                                                            balance_py, monkeypatch):
    balance = balance_py
    assert balance.step_implementation == "python"
    monkeypatch.setattr(balance, "_solve_qp", lambda *args: None)  # every QP "fails"
    balance.reset()
    ro = simulate(params, balance, _tilted(model, 0.05), 2.5, push=_push(0.5, 5.0))
    assert replays_exactly(ro)
    assert len(balance.failures) == len(balance.solve_ms) == -(-len(ro.ctrl) // balance.steps)
    assert {f["action"] for f in balance.failures} == {"upright LQR"}
    assert all("QP" in f["reason"] for f in balance.failures)
    assert swingup_success(ro, params)
    # what was applied at each instant is the LQR of the period, clipped
    k = balance.steps * np.arange(len(balance.failures))
    u_lqr = np.array([balance.lqr(0.0, x) for x in ro.x[k]])
    np.testing.assert_array_equal(ro.ctrl[k], u_lqr)


def test_a_qp_failing_mid_swing_up_follows_the_previous_plan_and_the_swing_up_still_succeeds(params, model,
                                                                                             swingup_py, monkeypatch):
    swingup = swingup_py
    real = swingup._solve_qp
    calls = {"n": 0}

    def flaky(*args):  # the QPs of instants 15..24 (0.3 s to 0.5 s) fail
        calls["n"] += 1
        return None if 16 <= calls["n"] <= 25 else real(*args)

    monkeypatch.setattr(swingup, "_solve_qp", flaky)
    swingup.reset()
    ro = simulate(params, swingup, model.x_hanging, 3.5)
    assert [f["action"] for f in swingup.failures] == ["previous plan"] * 10
    assert [round(f["t"], 9) for f in swingup.failures] == [round(swingup.period * k, 9) for k in range(15, 25)]
    assert replays_exactly(ro)
    assert swingup_success(ro, params)


def test_a_start_one_turn_from_upright_balances_without_unwinding(params, model, balance):
    balance.reset()
    x0 = _tilted(model, 2 * np.pi + 0.05)
    ro = simulate(params, balance, x0, 2.5)
    assert swingup_success(ro, params)
    assert abs(ro.qpos[-1, model.hinges[0]] - (model.x_eq[model.hinges[0]] + 2 * np.pi)) < 0.05


def test_gauss_newton_iterated_to_convergence_reaches_the_ipopt_solution_of_the_same_nlp(params, model):
    x0 = _tilted(model, 0.4)
    gn = NMPCController(model, params, x0=x0, options=MPCOptions(horizon=0.6, init_iterations=100))
    ip = IpoptMPC(model, params, options=MPCOptions(horizon=0.6), x0=x0, ipopt_options={"ipopt.tol": 1e-10})
    assert gn.init_info["converged"] and ip.init_info["converged"]
    S_gn, U_gn = gn.plan
    S_ip, U_ip = ip.plan
    np.testing.assert_allclose(U_gn, U_ip, atol=1e-5)
    np.testing.assert_allclose(S_gn, S_ip, atol=1e-5)


def test_compiled_and_virtual_machine_functions_and_both_qp_solvers_give_the_same_control(params, model,
                                                                                        monkeypatch):
    monkeypatch.delenv("CARTPOLE_NO_COMPILE", raising=False)
    x = _tilted(model, 0.2)
    ref = NMPCController(model, params, options=MPCOptions(horizon=0.6, qp_solver="daqp"))
    others = [NMPCController(model, params, options=MPCOptions(horizon=0.6, qp_solver="daqp", compiled=False)),
              NMPCController(model, params, options=MPCOptions(horizon=0.6, qp_solver="qpoases")),
              NMPCController(model, params, options=MPCOptions(horizon=0.6))]  # the C step (cartpole/csrc/nmpc.c.jinja)
    assert ref.library is not None and others[0].library is None
    assert ref.step_implementation == "python" and others[2].step_implementation == "c"
    u = ref(0.0, x)
    for other in others:
        np.testing.assert_allclose(other(0.0, x), u, atol=1e-7)


def test_iterating_to_convergence_each_instant_matches_ipopt_resolving_the_same_nlp(params, model):
    x0 = _tilted(model, 0.4)
    gn = NMPCController(model, params, options=MPCOptions(horizon=0.6, iterations=50, tol=1e-9))
    ip = IpoptMPC(model, params, options=MPCOptions(horizon=0.6), ipopt_options={"ipopt.tol": 1e-10})
    np.testing.assert_allclose(gn(0.0, x0), ip(0.0, x0), atol=1e-5)
    np.testing.assert_allclose(gn.plan[1], ip.plan[1], atol=1e-5)


@pytest.mark.parametrize("kwargs", [{"period": 0.0}, {"horizon": -1.0}, {"iterations": 0}, {"Q": np.eye(3)},
                                    {"R": -1.0}, {"qp_solver": "osqp"}, {"guess": (np.zeros((3, 4)), np.zeros(2))},
                                    {"x0": [0.0, np.nan, 0.0, 0.0]}, {"tol": -1.0}])
def test_bad_construction_arguments_raise_one_sentence(params, model, kwargs):
    kwargs = dict(kwargs)
    own = {k: kwargs.pop(k) for k in list(kwargs) if k in ("guess", "x0")}  # the controller's own arguments
    with pytest.raises(NMPCError) as err:
        NMPCController(model, params, options=MPCOptions(horizon=0.6).replace(**kwargs), **own)
    assert isinstance(err.value, CartPoleError)
    msg = str(err.value)
    assert "\n" not in msg and msg.endswith(".")


def test_nmpc_swings_the_two_pole_cart_up_from_hanging_rest():
    """Not required by the issue, reported: the double pole swung up and held by NMPC from its offline plan."""
    params2 = read_params(TWO_POLE)
    model2 = build_model(params2)
    ctrl = nmpc_swingup(params2, plan_model=model2, options=MPCOptions(init_iterations=200))
    assert ctrl.init_info["converged"]
    ro = simulate(params2, ctrl, model2.x_hanging, 6.0)
    assert replays_exactly(ro)
    assert swingup_success(ro, params2)
    assert ctrl.failures == []


def test_two_motors_plain_and_prestabilised_agree_and_balance(chain_dir):
    params2 = read_params(chain_dir / "two_motors.xml")
    model2 = build_model(params2)
    assert model2.nu == 2
    x = _tilted(model2, 0.1)
    ctrls = [NMPCController(model2, params2, options=MPCOptions(horizon=0.6, prestabilize=pre))
             for pre in (False, True)]
    np.testing.assert_allclose(ctrls[0](0.0, x), ctrls[1](0.0, x), atol=1e-6)
    for ctrl in ctrls:
        ctrl.reset()
        ro = simulate(params2, ctrl, x, 3.0)
        assert replays_exactly(ro)
        assert swingup_success(ro, params2)


@pytest.mark.parametrize("prestabilize", [False, True])
def test_the_c_step_and_the_python_step_agree_instant_by_instant_through_a_push(params, model, prestabilize):
    # the same first iterate, then each controller its own MuJoCo-free sequence of states (the C's ctrl applied
    # through the exact discrete model): the QP solvers differ (DAQP, the C's dual active set), the QP does not
    opts = MPCOptions(horizon=0.6, prestabilize=prestabilize)
    c = NMPCController(model, params, options=opts)
    py = NMPCController(model, params, options=opts.replace(c_step=False))
    assert (c.step_implementation, py.step_implementation) == ("c", "python")
    x = _tilted(model, 0.3)
    for k in range(25):
        t = k * c.period
        u_c, u_py = c(t, x), py(t, x)
        np.testing.assert_allclose(u_c, u_py, atol=1e-8)
        for a, b in zip(c.plan, py.plan):
            np.testing.assert_allclose(a, b, atol=1e-7)
        x = np.asarray(c.functions.stage(x, u_c + (0.3 if k == 5 else 0.0))[0]).ravel()
    assert c.failures == py.failures == [] and len(c.solve_ms) == 25


def test_the_c_step_takes_the_same_safe_action_as_the_python_step_on_a_state_that_is_not_finite(params, model):
    c = NMPCController(model, params, options=MPCOptions(horizon=0.6))
    py = NMPCController(model, params, options=MPCOptions(horizon=0.6, c_step=False))
    x = _tilted(model, 0.1)
    x[0] = np.nan
    np.testing.assert_array_equal(c(0.0, x), py(0.0, x))
    assert [f["action"] for f in c.failures] == [f["action"] for f in py.failures] == ["previous plan"]
    assert c.failures[0]["reason"] == py.failures[0]["reason"]  # the C's status says why, as Python does
    assert len(c.step_c_ms) == 1 and c.step_c_ms[0] > 0  # the step timed inside the C


def test_without_a_compiler_the_controller_runs_the_python_step(params, model, monkeypatch):
    monkeypatch.setenv("CARTPOLE_NO_COMPILE", "1")
    ctl = NMPCController(model, params, options=MPCOptions(horizon=0.6))
    assert ctl.step_implementation == "python"
    assert np.all(np.isfinite(ctl(0.0, _tilted(model, 0.1))))


def test_the_c_step_is_built_once_per_model_and_settings_and_each_controller_keeps_its_own_state(params, model):
    xa, xb = _tilted(model, 0.1), _tilted(model, -0.2)
    a = NMPCController(model, params, x0=xa, options=MPCOptions(horizon=0.6))
    b = NMPCController(model, params, x0=xb, options=MPCOptions(horizon=0.6))
    assert a._c.library == b._c.library  # the first iterate is run-time data, not compiled in
    u_a = a(0.0, xa)
    u_b = b(0.0, xb)
    a.reset()
    np.testing.assert_array_equal(a(0.0, xa), u_a)  # b's run did not touch a's static state
    assert not np.allclose(u_a, u_b)
