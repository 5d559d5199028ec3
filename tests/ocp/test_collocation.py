"""Hermite-Simpson direct collocation: defects met, bounds held, two methods agree, infeasibility named."""
import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cartpole.models import build_model
from cartpole.ocp.collocation import DirectCollocation, OCPError, OCPInfeasible
from cartpole.ocp.pipeline import minimum_time

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
    ftraj, finfo = DirectCollocation(model, N=100, T=2.0, solver="fatrop").solve(HANGING)
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
    with pytest.raises(OCPInfeasible, match="ctrl bound"):
        DirectCollocation(model, N=40, T=0.6 * T_min).solve(HANGING)


def test_a_short_track_raises_naming_the_cart_bound(shipped):
    with pytest.raises(OCPInfeasible, match="cart bound") as exc:
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
