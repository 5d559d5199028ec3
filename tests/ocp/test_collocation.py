"""Hermite-Simpson direct collocation: defects met, bounds held, two methods agree, infeasibility named."""
import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp import OCPNotSolved
from cartpole.ocp.bounds import bounds_from_model
from cartpole.ocp.collocation import CollocationOptions, DirectCollocation, OCPError, OCPInfeasible
from cartpole.planning.trajopt import minimum_time

HANGING = np.array([0.0, np.pi, 0.0, 0.0])


@pytest.fixture(scope="module")
def shipped():
    model = build_model()
    ocp = DirectCollocation(model, N=100, T=2.0)
    traj, info = ocp.solve(HANGING)
    return model, ocp, traj, info


def _integrate(model, traj, t0, t1, x_start):
    """Integrate the model's own f with the plan's first-order-hold input (scipy, tight tolerances)."""
    sol = solve_ivp(lambda t, x: model.dynamics(x, traj.input(t)), (t0, t1), x_start, rtol=1e-10, atol=1e-10,
                    method="DOP853")
    return sol.y[:, -1]


def test_plan_meets_boundary_states_and_bounds(shipped):
    model, ocp, traj, info = shipped
    assert info.success and info.iterations > 0 and info.solver == "ipopt"
    np.testing.assert_allclose(traj.x[0], HANGING, atol=1e-12)
    np.testing.assert_allclose(traj.x[-1], [0, 0, 0, 0], atol=1e-12)  # upright rest (angle 0 from the guess)
    assert np.all(np.abs(traj.u) <= model.params.u_max + 1e-8)
    assert np.all(np.abs(traj.x[:, 0]) <= model.params.cart_range[1] - 0.1 + 1e-8)


def test_each_interval_integrates_with_the_models_f_to_the_next_knot(shipped):
    # Local defects: the collocation constraint is met when the true ODE with the plan's input, started at
    # knot k, lands at knot k+1 up to Hermite-Simpson's O(h^5) local error.
    model, _, traj, _ = shipped
    errs = [np.abs(_integrate(model, traj, traj.t[k], traj.t[k + 1], traj.x[k]) - traj.x[k + 1]).max()
            for k in range(0, traj.N, 5)]
    assert max(errs) < 1e-4


def test_plan_matches_a_dense_integration_of_its_input(shipped):
    # Two methods agree: the whole plan vs a high-order integration of its own FOH input over the swing.
    model, _, traj, _ = shipped
    t_half = traj.t[traj.N // 2]
    x_half = _integrate(model, traj, 0.0, t_half, traj.x[0])
    np.testing.assert_allclose(x_half, traj.state(t_half), atol=5e-3)


def test_state_interpolation_gives_the_collocation_midpoints(shipped):
    model, _, traj, _ = shipped
    np.testing.assert_allclose(traj.state(traj.t_mid), traj.x_mid, atol=1e-10)
    # and the midpoint satisfies the Simpson defect with the model's f at the midpoint
    h = np.diff(traj.t)[:, None]
    fc = np.array([model.dynamics(xc, uc) for xc, uc in zip(traj.x_mid, traj.u_mid)])
    defect = traj.x[1:] - traj.x[:-1] - h / 6 * (traj.xdot[:-1] + 4 * fc + traj.xdot[1:])
    assert np.abs(defect).max() < 1e-7


def test_objective_is_the_integral_of_ctrl_squared(shipped):
    _, _, traj, info = shipped
    t = np.linspace(0, traj.duration, 20001)
    u = traj.input(t)[:, 0]
    integral = np.sum(0.5 * (u[1:] ** 2 + u[:-1] ** 2) * np.diff(t))  # trapezoid on a fine grid
    assert info.objective == pytest.approx(integral, rel=1e-6)


def test_solver_is_built_once_and_reused(shipped):
    _, ocp, _, _ = shipped
    solver = ocp._build()
    traj, info = ocp.solve(HANGING)
    assert ocp._build() is solver and info.success
    warm_traj, warm = ocp.solve_once(HANGING, warm=True)
    assert warm.success and warm.iterations <= info.iterations
    np.testing.assert_allclose(warm_traj.x, traj.x, atol=1e-6)


@pytest.mark.skipif(not ca.has_nlpsol("fatrop"), reason="this CasADi has no fatrop plugin")
def test_ipopt_and_fatrop_agree(shipped):
    model, _, traj, info = shipped
    ftraj, finfo = DirectCollocation(model, N=100, T=2.0, options=CollocationOptions(solver="fatrop")).solve(HANGING)
    assert finfo.success and finfo.solver == "fatrop"
    assert finfo.objective == pytest.approx(info.objective, rel=1e-4)
    # fatrop stops at tol 1e-6 on a flat optimum: same cost, states within a few centimetres/centiradians
    np.testing.assert_allclose(ftraj.x, traj.x, atol=5e-2)


def test_minimum_time_plan_is_feasible_and_a_shorter_fixed_time_is_not(shipped):
    model = shipped[0]
    T_min, traj, info = minimum_time(model, HANGING, N=40)
    assert info.success and traj.duration == pytest.approx(T_min)
    assert np.abs(traj.u).max() <= model.params.u_max + 1e-8
    # slightly longer: feasible; clearly shorter: the ctrl bound binds
    ok, ok_info = DirectCollocation(model, N=40, T=1.05 * T_min).solve(HANGING)
    assert ok_info.success
    with pytest.raises(OCPNotSolved, match="ctrl bound") as exc:  # a local figure, never called infeasible
        DirectCollocation(model, N=40, T=0.6 * T_min).solve(HANGING)
    assert not isinstance(exc.value, OCPInfeasible) and "no proof" in str(exc.value)
    assert exc.value.attempts and not any(a.success for a in exc.value.attempts)


def test_a_short_track_raises_naming_the_cart_bound(shipped):
    with pytest.raises(OCPNotSolved, match="cart bound") as exc:
        DirectCollocation(shipped[0], N=40, T=2.0, cart_max=0.03).solve(HANGING)
    assert len(str(exc.value).split(". ")) == 1  # one sentence


def test_bad_arguments_are_clear_errors(shipped):
    model = shipped[0]
    with pytest.raises(OCPError, match="Objective"):
        DirectCollocation(model, objective="fuel")
    with pytest.raises(OCPError, match="free final time"):
        DirectCollocation(model, T=2.0, objective="time")
    with pytest.raises(OCPError, match="4 finite"):
        DirectCollocation(model, N=10, T=2.0).solve([0, np.nan, 0, 0])


def test_variants_swing_up_within_their_own_limits(any_mjcf):
    # T per model from its limits: 1.2 x its minimum time.
    model = build_model(any_mjcf)
    T_min, _, _ = minimum_time(model, HANGING, N=40)
    traj, info = DirectCollocation(model, N=60, T=1.2 * T_min).solve(HANGING)
    assert info.success
    assert np.abs(traj.u).max() <= model.params.u_max + 1e-8
    lim = model.params.cart_range[1] - 0.1
    assert np.abs(traj.x[:, 0]).max() <= lim + 1e-8
    k = traj.N // 2
    x_next = _integrate(model, traj, traj.t[k], traj.t[k + 1], traj.x[k])
    np.testing.assert_allclose(x_next, traj.x[k + 1], atol=1e-4)


# ---- any chain of poles on a cart (issue 10) -------------------------------------------------------------------
TWO_POLE = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")


def _tilted(model, angle: float = 0.3) -> np.ndarray:
    """The upright equilibrium with the first pole tilted by ``angle`` rad, at rest (a modest start)."""
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += angle
    return x0


def _assert_plan_meets_model_and_bounds(model, ocp, traj, x0, *, tol: float, every: int = 4):
    """Boundary states, per-side ctrl bounds of every actuator, the cart inside its shrunk range at the knots and
    the midpoints, and each checked interval integrating with the model's own f to the next knot (within ``tol``,
    Hermite-Simpson's O(h^5) local error)."""
    np.testing.assert_allclose(traj.x[0], x0, atol=1e-12)
    np.testing.assert_allclose(model.state_error(traj.x[-1]), 0.0, atol=1e-12)
    lo, hi = model.u_low, model.u_high
    assert np.all(traj.u >= lo - 1e-8) and np.all(traj.u <= hi + 1e-8)
    c_lo, c_hi = model.params.cart_range
    for s in (traj.x[:, model.slide], traj.x_mid[:, model.slide]):
        assert np.all(s >= c_lo + 0.1 - 1e-8) and np.all(s <= c_hi - 0.1 + 1e-8)
    errs = [np.abs(_integrate(model, traj, traj.t[k], traj.t[k + 1], traj.x[k]) - traj.x[k + 1]).max()
            for k in range(0, traj.N, every)]
    assert max(errs) < tol


@pytest.fixture(scope="module")
def two_pole():
    model = build_model(TWO_POLE)
    x0 = _tilted(model)
    ocp = DirectCollocation(model, N=60, T=2.0)
    traj, info = ocp.solve(x0)
    return model, ocp, traj, info, x0


def test_two_pole_cart_from_a_tilt_converges_meets_the_dynamics_and_keeps_its_bounds(two_pole):
    model, ocp, traj, info, x0 = two_pole
    assert model.nq == 3 and model.nu == 1
    assert info.success and traj.x.shape == (61, model.nx) and traj.u.shape == (61, model.nu)
    _assert_plan_meets_model_and_bounds(model, ocp, traj, x0, tol=1e-4)  # h = 33 ms
    # the Simpson defect holds with the model's f at the midpoints, for every state
    h = np.diff(traj.t)[:, None]
    fc = np.array([model.dynamics(xc, uc) for xc, uc in zip(traj.x_mid, traj.u_mid)])
    defect = traj.x[1:] - traj.x[:-1] - h / 6 * (traj.xdot[:-1] + 4 * fc + traj.xdot[1:])
    assert np.abs(defect).max() < 1e-7


def test_two_pole_default_goal_is_the_models_upright_equilibrium_and_states_have_nx_entries(two_pole):
    model, ocp, traj, info, x0 = two_pole
    again, info2 = ocp.solve(x0, model.x_eq)
    np.testing.assert_allclose(again.x, traj.x, atol=1e-9)
    with pytest.raises(OCPError, match=f"{model.nx} finite numbers"):
        ocp.solve(x0[:4])


@pytest.mark.parametrize("name", ["two_motors", "everything_Euler"])
def test_two_motors_and_an_asymmetric_ctrlrange_keep_each_bound_per_side(chain_dir, name):
    model = build_model(chain_dir / f"{name}.xml")
    x0 = _tilted(model)
    ocp = DirectCollocation(model, N=40, T=2.0)
    np.testing.assert_array_equal(ocp.bounds.u_low, model.u_low)
    np.testing.assert_array_equal(ocp.bounds.u_high, model.u_high)
    traj, info = ocp.solve(x0)
    assert info.success
    _assert_plan_meets_model_and_bounds(model, ocp, traj, x0, tol=1e-3)  # h = 50 ms
    if model.nu > 1:  # every motor takes part
        assert np.all(np.abs(traj.u).max(axis=0) > 1e-3)
    else:  # the range is asymmetric and the plan uses the side a symmetric |u| <= min(|low|, |high|) would cut
        lo, hi = model.u_low[0], model.u_high[0]
        assert lo != -hi
        assert traj.u.max() > min(-lo, hi) + 1e-3 or traj.u.min() < -min(-lo, hi) - 1e-3


def test_bounds_come_from_each_actuator_and_each_limited_joint(chain_dir):
    limited = build_model(chain_dir / "gym_single_off_vertical.xml")  # hinge limited to +-90 deg
    b = bounds_from_model(limited)
    assert b.bounded_joints == (limited.slide, limited.hinges[0])
    np.testing.assert_allclose([b.q_low[1], b.q_high[1]], limited.params.joints[1].range)
    np.testing.assert_allclose([b.q_low[0], b.q_high[0]], limited.params.cart_range + np.array([0.1, -0.1]))
    asym = build_model(chain_dir / "everything_Euler.xml")  # ctrlrange -0.8 1.2, slide range -1.2 1.3
    b = bounds_from_model(asym, cart_margin=0.2)
    np.testing.assert_array_equal(b.u_low, asym.u_low)
    np.testing.assert_array_equal(b.u_high, asym.u_high)
    assert b.cart_center == pytest.approx(np.mean(asym.params.cart_range))
    assert b.cart_max == pytest.approx(0.5 * np.ptp(asym.params.cart_range) - 0.2)
    free = build_model(chain_dir / "acrobot.xml")  # no cart, unlimited hinges
    b = bounds_from_model(free)
    assert b.cart_max is None and b.bounded_joints == ()
    # scales: slides in m, hinges in pi rad, rates and ctrl positive and finite
    sc = DirectCollocation(asym, N=4, T=1.0).scale
    assert sc.shape == (asym.nx + asym.nu,) and np.all(np.isfinite(sc) & (sc > 0))
    assert sc[asym.slide] == pytest.approx(0.5 * np.ptp(asym.params.cart_range) - 0.1)  # default margin
    np.testing.assert_array_equal(sc[list(asym.hinges)], np.pi)


def test_a_pendulum_without_a_cart_swings_up_from_its_default_hanging_start(chain_dir):
    model = build_model(chain_dir / "pendulum.xml")  # motor on the hinge, no slide
    ocp = DirectCollocation(model, N=40, T=2.0)
    traj, info = ocp.solve()  # default start: hanging rest; default goal: upright
    assert info.success and ocp.bounds.cart_max is None
    np.testing.assert_allclose(traj.x[0], model.x_hanging, atol=1e-12)
    np.testing.assert_allclose(model.state_error(traj.x[-1]), 0.0, atol=1e-12)
    assert np.all(traj.u >= model.u_low - 1e-8) and np.all(traj.u <= model.u_high + 1e-8)
    k = traj.N // 2
    np.testing.assert_allclose(_integrate(model, traj, traj.t[k], traj.t[k + 1], traj.x[k]), traj.x[k + 1], atol=1e-3)
