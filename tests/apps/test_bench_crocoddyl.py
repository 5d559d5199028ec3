"""Crocoddyl's double-pendulum example on the toolkit: our DDP finds the soft-goal swing-up (and it replays in
MuJoCo); its cost is the optimum IPOPT finds for the same discrete problem; with Crocoddyl installed (an optional
extra), the converted model steps as Crocoddyl's Euler model does and both solvers reach the same cost."""
import casadi as ca
import numpy as np
import pytest

from cartpole.apps.bench.crocoddyl import DT, N, X0, crocoddyl_benchmark, double_pendulum_ddp
from cartpole.models import wrap_angle
from cartpole.sim import replay


@pytest.fixture(scope="module")
def solved():
    ddp, x0 = double_pendulum_ddp()
    return ddp, ddp.solve(x0)


def test_our_ddp_swings_crocoddyls_double_pendulum_up_and_the_plan_replays(solved):
    ddp, r = solved
    assert r.converged and r.t[-1] == pytest.approx(N * DT)
    assert np.abs(wrap_angle(r.x[-1, :2])).max() < 0.05  # the soft goal: both links near upright at T
    run = replay(ddp_mjcf(), r.x[0], r.u)
    np.testing.assert_allclose(run.x, r.x, atol=1e-9, rtol=0)


def ddp_mjcf():
    from cartpole.models import SHIPPED_MJCF

    return SHIPPED_MJCF.parent / "examples" / "crocoddyl_double_pendulum.xml"


def test_our_cost_is_the_optimum_ipopt_finds_for_the_same_problem(solved):
    ddp, r = solved
    from cartpole.models import build_model

    m = build_model(ddp_mjcf())
    opti = ca.Opti()
    X, U = opti.variable(4, N + 1), opti.variable(1, N)
    opti.subject_to(X[:, 0] == np.array(X0))
    cost = 0
    w = ca.DM([1, 1, 1, 1, 0.1, 0.1])

    def goal(x):
        res = ca.vertcat(ca.sin(x[0]), ca.sin(x[1]), 1 - ca.cos(x[0]), 1 - ca.cos(x[1]), x[2], x[3])
        return 0.5 * ca.dot(w * res, res)

    for k in range(N):
        opti.subject_to(X[:, k + 1] == m.step(X[:, k], U[:, k]))
        cost += DT * (1e-4 / DT * 0.5 * ca.sumsqr(U[:, k]) + 1e-5 / DT * goal(X[:, k]))
    opti.minimize(cost + 100.0 * goal(X[:, N]))
    opti.set_initial(X, np.asarray(r.x).T)
    opti.set_initial(U, np.asarray(r.u).T)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes"})
    assert r.cost == pytest.approx(float(opti.solve().value(opti.f)), rel=1e-6)


def test_with_crocoddyl_the_model_steps_alike_and_both_solvers_reach_one_cost():
    crocoddyl = pytest.importorskip("crocoddyl")
    from cartpole.apps.bench.crocoddyl import _crocoddyl_problem
    from cartpole.models import build_model

    problem = _crocoddyl_problem()
    model, data = problem.runningModels[0], problem.runningDatas[0]
    m = build_model(ddp_mjcf())
    rng = np.random.default_rng(0)
    for _ in range(5):
        x, u = rng.normal(size=4), rng.normal(size=1)
        model.calc(data, x, u)
        # to the 6 significant digits MuJoCo's XML writer keeps of the URDF's inertias
        np.testing.assert_allclose(np.asarray(data.xnext), m.step_np(x, u), rtol=1e-5, atol=1e-8)
    doc = crocoddyl_benchmark(repeats=1)
    assert doc["crocoddyl"] is not None and abs(doc["cost_gap"]) < 1e-6
    assert crocoddyl is not None
    # the cart-pole example: Crocoddyl from its own default guess, ours from the LQR's rollout, one optimum
    cp = doc["cartpole"]
    assert cp["crocoddyl"]["status"] == "converged" and abs(cp["cost_gap"]) < 1e-6
    assert cp["zero_guess"]["cost"] > cp["ours"]["cost"]


def _cartpole_mjcf():
    from cartpole.models import SHIPPED_MJCF

    return SHIPPED_MJCF.parent / "examples" / "crocoddyl_cartpole.xml"


def _notebook_step(x, f, dt=0.05, M=1.0, m=0.1, length=0.5, g=9.81):
    """Crocoddyl's cart-pole notebook's update, written out independently: point-mass cart-pole, semi-implicit
    Euler (velocity first, then position with the new velocity)."""
    y, th, yd, thd = x
    s, c = np.sin(th), np.cos(th)
    mu = M + m * s * s
    ydd = (f + m * g * c * s - m * length * s * thd ** 2) / mu
    thdd = (f * c / length + (M + m) * g * s / length - m * c * s * thd ** 2) / mu
    yd, thd = yd + dt * ydd, thd + dt * thdd
    return np.array([y + dt * yd, th + dt * thd, yd, thd])


def test_crocoddyls_cartpole_as_mjcf_steps_as_its_notebook_equations():
    from cartpole.models import build_model

    m = build_model(_cartpole_mjcf())
    rng = np.random.default_rng(1)
    for _ in range(20):
        x, f = rng.uniform(-3, 3, 4), rng.uniform(-20, 20)
        np.testing.assert_allclose(m.step_np(x, [f]), _notebook_step(x, f), rtol=1e-8, atol=1e-10)  # the 1e-12 inertia


def test_our_ddp_solves_crocoddyls_cartpole_to_the_ipopt_optimum_from_the_lqr_guess_not_from_zero_force():
    from cartpole.apps.bench.crocoddyl import (CP_DT, CP_FORCE_BOUND, CP_N, CP_WEIGHTS, cartpole_ddp,
                                               cartpole_lqr_guess)
    from cartpole.models import build_model

    ddp, x0 = cartpole_ddp()
    r = ddp.solve(x0, cartpole_lqr_guess())
    zero = ddp.solve(x0)
    assert r.converged and zero.converged and r.cost < zero.cost - 1.0  # from zero force: a worse local minimum
    assert np.abs(r.u).max() < 0.01 * CP_FORCE_BOUND  # the bound ours needs never acts
    assert abs(wrap_angle(r.x[-1, 1])) < 0.05  # balanced, not swung round
    run = replay(_cartpole_mjcf(), r.x[0], r.u)
    np.testing.assert_allclose(run.x, r.x, atol=1e-9, rtol=0)
    m = build_model(_cartpole_mjcf())
    w = ca.DM(CP_WEIGHTS)

    def node(x, u):
        res = w * ca.vertcat(ca.sin(x[1]), 1 - ca.cos(x[1]), x[0], x[2], x[3], u)
        return 0.5 * ca.dot(res, res)

    opti = ca.Opti()
    X, U = opti.variable(4, CP_N + 1), opti.variable(1, CP_N)
    opti.subject_to(X[:, 0] == x0)
    cost = 0
    for k in range(CP_N):
        opti.subject_to(X[:, k + 1] == m.step(X[:, k], U[:, k]))
        cost += node(X[:, k], U[:, k])
    opti.minimize(cost + node(X[:, CP_N], 0))
    opti.set_initial(X, np.asarray(r.x).T)
    opti.set_initial(U, np.asarray(r.u).T)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes"})
    assert r.cost == pytest.approx(float(opti.solve().value(opti.f)), rel=1e-6)
    assert CP_DT == pytest.approx(m.dt)
