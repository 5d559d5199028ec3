"""The SQP on the collocation NLP (cartpole.solvers.sqp) reaches IPOPT's optimum of the same problem."""
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.ocp.bounds import OCPError, bounds_from_model
from cartpole.ocp.collocation import DirectCollocation
from cartpole.ocp.guess import initial_guesses, stretched
from cartpole.solvers.sqp import CollocationSQP, SQPError, SQPOptions
from cartpole.ocp.trajectory import Trajectory

N, T = 100, 2.0


def _standard(name):
    """The benchmark's standard problem on a shipped cart: the problem, the start and the benchmark's guess."""
    model = build_model(read_params(SHIPPED_MJCF.parent / name))
    x0 = np.array(model.x_hanging)
    bounds = bounds_from_model(model, u_max=1.0, cart_max=1.4, cart_margin=0.0)
    guess = initial_guesses(model, x0, model.x_eq, T, N, bounds=bounds, count=1)[0]
    return DirectCollocation(model, N=N, T=T, bounds=bounds), x0, guess


@pytest.fixture(scope="module")
def single():
    ocp, x0, guess = _standard("cartpole.xml")
    return ocp, x0, guess, ocp.solve_once(x0, guess=guess)


@pytest.fixture(scope="module")
def two_pole():
    ocp, x0, guess = _standard("cartpole_two_pole.xml")
    return ocp, x0, guess, ocp.solve_once(x0, guess=guess)


def _assert_same_plan(a: Trajectory, b: Trajectory, ocp: DirectCollocation):
    sx, su = ocp.scale[:ocp.nx], ocp.scale[ocp.nx:]
    assert np.max(np.abs(a.x - b.x) / sx) < 1e-4  # scaled states (IPOPT stops at tol 1e-8)
    assert np.max(np.abs(a.u - b.u) / su) < 1e-4


def _assert_ipopts_optimum(traj, info, traj_ip, info_ip, ocp: DirectCollocation, x0):
    """The SQP's plan is IPOPT's: same objective (1e-6 relative), same plan, the boundary states and |ctrl| <= 1."""
    assert abs(info.objective - info_ip.objective) <= 1e-6 * abs(info_ip.objective)
    _assert_same_plan(traj, traj_ip, ocp)
    assert np.allclose(traj.x[0], x0) and np.allclose(traj.x[-1], ocp.model.x_eq, atol=1e-12)
    assert np.all(np.abs(traj.u) <= 1.0 + 1e-9)


@pytest.mark.parametrize("qp_solver", ["riccati", "daqp"])
def test_sqp_reaches_ipopts_optimum_on_the_standard_problem_from_the_same_guess(single, qp_solver):
    ocp, x0, guess, (traj_ip, info_ip) = single
    assert info_ip.success
    sqp = CollocationSQP(ocp, options=SQPOptions(qp_solver=qp_solver))
    traj, info = sqp.solve_once(x0, guess=guess)
    # every QP by the chosen solver, no fallback (the last iteration may only confirm convergence)
    mine = ("riccati", "riccati_exact") if qp_solver == "riccati" else (qp_solver,)
    assert sum(sqp.qp_counts[name] for name in mine) >= info.iterations - 1
    assert all(count == 0 for name, count in sqp.qp_counts.items() if name not in mine + ("riccati_unsettled",))
    assert sqp.qp_counts.get("riccati_unsettled", 0) == 0
    assert info.success and info.status == "Solve_Succeeded" and info.solver == "sqp"
    assert 0 < info.iterations < 200
    _assert_ipopts_optimum(traj, info, traj_ip, info_ip, ocp, x0)


def test_sqp_converges_fast_near_the_optimum_of_the_two_pole_problem_to_ipopts_optimum(two_pole):
    ocp, x0, _, (traj_ip, info_ip) = two_pole
    assert info_ip.success
    rng = np.random.default_rng(1)
    sx = ocp.scale[:ocp.nx]
    x = traj_ip.x + 1e-2 * sx * rng.standard_normal(traj_ip.x.shape)
    x[0], x[-1] = traj_ip.x[0], traj_ip.x[-1]
    u = np.clip(traj_ip.u + 1e-2 * rng.standard_normal(traj_ip.u.shape), -1.0, 1.0)
    near = Trajectory(t=traj_ip.t, x=x, u=u, xdot=traj_ip.xdot)
    sqp = CollocationSQP(ocp)
    traj, info = sqp.solve_once(x0, guess=near)
    assert info.success
    assert info.iterations <= 20  # Newton-like near the solution (measured: 7)
    assert abs(info.objective - info_ip.objective) <= 1e-6 * abs(info_ip.objective)
    _assert_same_plan(traj, traj_ip, ocp)
    # the damping has vanished: the last steps are exact-Hessian Newton steps
    assert sqp.history[-1]["damping"] < 1e-4


def test_an_infeasible_linearisation_still_gives_a_step_with_daqps_soft_rows(two_pole):
    ocp, x0, guess, _ = two_pole
    sqp = CollocationSQP(ocp, options=SQPOptions(qp_solver="daqp", max_iter=1))
    sqp.solve_once(x0, guess=guess)
    (first,) = sqp.history
    # the hard QP of the bench guess is infeasible: the soft one gives a step the filter takes
    assert sqp.qp_soft >= 1
    assert first["step"] > 0 and first["alpha"] > 0


def test_sqp_reaches_ipopts_optimum_on_the_two_pole_problem_from_the_bench_guess(two_pole):
    ocp, x0, guess, (traj_ip, info_ip) = two_pole
    assert info_ip.success
    sqp = CollocationSQP(ocp)
    traj, info = sqp.solve_once(x0, guess=guess)
    assert info.success and info.status == "Solve_Succeeded"
    assert sqp.qp_soft >= 1  # its first linearisations are infeasible: the soft QP carried it through
    _assert_ipopts_optimum(traj, info, traj_ip, info_ip, ocp, x0)


def test_sqp_failure_is_one_sentence_and_the_fallback_is_ipopts_optimum(two_pole):
    ocp, x0, guess, (_, info_ip) = two_pole
    sqp = CollocationSQP(ocp, options=SQPOptions(max_iter=3))  # far too few iterations from this guess
    _, info = sqp.solve_once(x0, guess=guess)
    assert not info.success
    assert info.status in ("QP_Failed", "Line_Search_Failed", "Maximum_Iterations_Exceeded")
    with pytest.raises(SQPError) as err:
        sqp.solve(x0, guess=guess)
    msg = str(err.value)
    assert isinstance(err.value, OCPError) and "\n" not in msg and msg.endswith(".") and "IPOPT" in msg
    traj, info_fb = sqp.solve(x0, guess=guess, fallback=True)
    assert info_fb.success and info_fb.solver == "ipopt"
    assert abs(info_fb.objective - info_ip.objective) <= 1e-9 * abs(info_ip.objective)
    assert [a.status for a in info_fb.attempts][0] == info.status


def test_sqp_refuses_problems_it_does_not_handle_in_one_sentence():
    model = build_model(read_params(SHIPPED_MJCF))
    with pytest.raises(SQPError, match="Riccati QP solver only"):
        CollocationSQP(DirectCollocation(model, N=20, T=None), options=SQPOptions(qp_solver="daqp"))  # minimum time
    for gone in ("nope", "qrqp", "hpipm"):  # CasADi's qrqp and HPIPM are no back-ends (docs/benchmarks.md)
        with pytest.raises(SQPError, match="qp_solver"):
            CollocationSQP(DirectCollocation(model, N=20, T=2.0), options=SQPOptions(qp_solver=gone))


def test_two_motors_run_through_the_sqp_and_end_at_ipopts_optimum(chain_dir):
    """Several inputs (a motor on the cart and one on the hinge): the SQP's QP has two controls per knot. Whether
    or not the SQP converges on this problem (measured at N = 12, 30 and 60: it does not, as before its QP was
    compiled), ``fallback=True`` ends at IPOPT's
    optimum from the same guess."""
    model = build_model(read_params(chain_dir / "two_motors.xml"))
    assert model.nu == 2
    x0 = np.array(model.x_hanging)
    bounds = bounds_from_model(model, u_max=1.0, cart_max=1.4, cart_margin=0.0)
    n = 12
    guess = initial_guesses(model, x0, model.x_eq, T, n, bounds=bounds, count=1)[0]
    ocp = DirectCollocation(model, N=n, T=T, bounds=bounds)
    traj_ip, info_ip = ocp.solve_once(x0, guess=guess)
    assert info_ip.success
    sqp = CollocationSQP(ocp, options=SQPOptions(max_iter=40))
    traj, info = sqp.solve(x0, guess=guess, fallback=True)
    assert sqp.history and all(np.isfinite(h["objective"]) for h in sqp.history)
    assert info.success
    assert abs(info.objective - info_ip.objective) <= 1e-6 * abs(info_ip.objective)
    assert traj.u.shape == traj_ip.u.shape == (n + 1, 2)


def test_infeasible_linearisations_do_not_count_against_max_unsettled(two_pole):
    """From the bench's guess the two-pole problem's first linearisations are infeasible (DAQP's soft rows solve
    them, the Riccati active set cannot): the SQP with max_unsettled=0 still reaches IPOPT's optimum."""
    ocp, x0, guess, (traj_ip, info_ip) = two_pole
    sqp = CollocationSQP(ocp, options=SQPOptions(max_unsettled=0))
    traj, info = sqp.solve_once(x0, guess=guess)
    assert sqp.qp_soft > 0 and sqp.qp_counts["riccati_unsettled"] >= sqp.qp_soft
    assert info.success
    _assert_ipopts_optimum(traj, info, traj_ip, info_ip, ocp, x0)


def test_feasible_qps_the_riccati_active_set_cannot_settle_stop_the_solve(single, monkeypatch):
    from cartpole.solvers import riccati_qp

    ocp, x0, guess, _ = single
    monkeypatch.setattr(riccati_qp.StageQP, "solve", lambda self, *a, **k: 3)  # never settles
    sqp = CollocationSQP(ocp, options=SQPOptions(max_unsettled=2))
    _, info = sqp.solve_once(x0, guess=guess)
    assert not info.success and info.status == "QP_Unsettled" and info.iterations == 3
    assert sqp.qp_counts["riccati_unsettled"] == 3 and sqp.qp_counts["daqp"] >= 3 and sqp.qp_soft == 0


@pytest.mark.parametrize("objective", ["tracking", "dmc_swingup"])
def test_a_running_cost_not_convex_in_the_inputs_converges_to_ipopts_optimum(objective):
    """A running objective's Lagrangian is indefinite where inputs saturate: each QP is solved on the exact Hessian
    shifted by IPOPT's inertia correction (0 first, then up from the last shift), and the SQP reaches IPOPT's
    optimum from the same guess (with the stage-wise convexification it converged only linearly)."""
    base, x0, guess = _standard("cartpole.xml")
    ocp = DirectCollocation(base.model, N=N, T=T, bounds=base.bounds, objective=objective)
    traj_ip, info_ip = ocp.solve_once(x0, guess=guess)
    assert info_ip.success
    sqp = CollocationSQP(ocp)
    traj, info = sqp.solve_once(x0, guess=guess)
    assert info.success and info.iterations < 60
    assert sqp.qp_counts["riccati_exact"] >= info.iterations - 2  # the exact Hessian's QPs, not the convexified
    assert abs(info.objective - info_ip.objective) <= 1e-6 * abs(info_ip.objective)
    _assert_same_plan(traj, traj_ip, ocp)


def test_a_running_cost_on_a_coarse_mesh_converges_without_the_shift_stalling():
    """On 30 intervals the pinned end shapes the last stages' curvature: the Riccati QP sees the held rows (their
    penalty), so the inertia shift returns to zero and the SQP converges (it stalled for 200 iterations without)."""
    base, x0, _ = _standard("cartpole.xml")
    ocp = DirectCollocation(base.model, N=30, T=T, bounds=base.bounds, objective="tracking")
    guess = initial_guesses(base.model, x0, base.model.x_eq, T, 30, bounds=base.bounds, count=1)[0]
    traj_ip, info_ip = ocp.solve_once(x0, guess=guess)
    assert info_ip.success
    sqp = CollocationSQP(ocp)
    traj, info = sqp.solve_once(x0, guess=guess)
    assert info.success and info.iterations < 40  # measured: 17
    assert sqp.history[-1]["damping"] < 1e-4
    assert abs(info.objective - info_ip.objective) <= 1e-6 * abs(info_ip.objective)
    _assert_same_plan(traj, traj_ip, ocp)


@pytest.fixture(scope="module")
def minimum_time_problem():
    base, x0, guess = _standard("cartpole.xml")
    ocp = DirectCollocation(base.model, N=N, T=None, bounds=base.bounds, objective="time")
    traj_ip, info_ip = ocp.solve_once(x0, guess=guess)
    assert info_ip.success
    return ocp, x0, guess, traj_ip, info_ip


def test_minimum_time_by_the_sqp_reaches_ipopts_minimum(minimum_time_problem):
    """A free T as the time scale tau = T / T_0, one more state free at knot 0: the same minimum as IPOPT's free-time
    NLP from the same guess (T_0 the guess's 2 s, T_min about 0.99 s)."""
    ocp, x0, guess, traj_ip, info_ip = minimum_time_problem
    sqp = CollocationSQP(ocp)
    traj, info = sqp.solve_once(x0, guess=guess)
    assert info.success and info.solver == "sqp" and info.iterations < 30  # measured: 12
    assert info.T == pytest.approx(info_ip.T, rel=1e-6) and info.objective == info.T
    assert traj.duration == pytest.approx(info.T, rel=1e-12) and traj.N == ocp.N
    np.testing.assert_allclose(traj.x[0], x0, atol=1e-12)
    np.testing.assert_allclose(traj.x[-1], ocp.model.x_eq, atol=1e-9)
    assert np.all(np.abs(traj.u) <= 1.0 + 1e-9)
    # bang-bang: the inputs may differ where they switch; the states stay close
    sx = ocp.scale[:ocp.nx]
    assert np.max(np.abs(traj.x - traj_ip.x) / sx) < 1e-2


@pytest.mark.parametrize("stretch", [0.9, 1.2])
def test_the_triples_minimum_time_converges_fast_from_its_plan_stretched(stretch):
    """The triple's bang-bang minimum time is nearly singular where it is not at a bound (interior inputs of a
    singular arc: reduced-Hessian eigenvalues of 1e-6, measured): the inertia correction's shift must decay below
    its first trial value as IPOPT's does, or every shifted step creeps along that direction (convergence only
    linear, each step delta / (delta + lambda) of the last). From the planner's minimum-time plan stretched by 0.9 or
    1.2 the SQP converges quadratically to that plan's T (measured: 10 iterations; 29 and 32 with a floor on the
    shift)."""
    from cartpole.planning.trajopt import minimum_time

    model = build_model(read_params(SHIPPED_MJCF.with_name("cartpole_three_pole.xml")))
    x0 = np.array(model.x_hanging)
    bounds = bounds_from_model(model, u_max=1.0, cart_max=1.4, cart_margin=0.0)
    T_min, plan, _ = minimum_time(model, x0, N=60, bounds=bounds, sqp=True)
    ocp = DirectCollocation(model, N=60, T=None, bounds=bounds, objective="time")
    T0 = stretch * plan.duration
    t = np.linspace(0.0, T0, ocp.N + 1)
    x, u = stretched(plan, T0, t, model.nq)
    guess = Trajectory(t=t, x=x, u=u, xdot=np.zeros_like(x))
    sqp = CollocationSQP(ocp)
    traj, info = sqp.solve_once(x0, guess=guess)
    assert info.success and info.solver == "sqp" and info.iterations <= 15
    assert info.T == pytest.approx(T_min, rel=1e-9)
    assert not sqp.qp_counts["riccati_unsettled"]
