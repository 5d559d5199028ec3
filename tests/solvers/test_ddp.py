"""Box-DDP on the exact discrete model: the swing-up it finds replays in MuJoCo to round-off, stays inside the ctrl box
and the rail, reaches upright, and is the optimum IPOPT finds for the same discrete problem (two methods, one
answer); clamped inputs get no feedback; bad problems are one sentence."""
import casadi as ca
import numpy as np
import pytest

from cartpole.models import build_model
from cartpole.ocp.bounds import bounds_from_model
from cartpole.sim import replay
from cartpole.solvers.ddp import DDP, DDPError, DDPOptions, DDPProblem, ddp_for_model

STEPS = 4  # the ctrl held for 4 MJCF steps (20 ms): the held model is exact, so the plan replays in MuJoCo


@pytest.fixture(scope="module")
def model():
    return build_model()


@pytest.fixture(scope="module")
def swingup(model):
    ddp = ddp_for_model(model, 2.5, steps=STEPS)
    return ddp, ddp.solve(model.x_hanging)


def _ipopt_same_problem(model, ddp, result, bounds):
    """The same discrete problem (held model, effort, box, rail, terminal upright) by multiple shooting in IPOPT,
    started from the DDP's answer."""
    N, nx, nu = ddp.N, model.nx, model.nu
    F = model.hold(STEPS).step
    opti = ca.Opti()
    X, U = opti.variable(nx, N + 1), opti.variable(nu, N)
    opti.subject_to(X[:, 0] == model.x_hanging)
    for k in range(N):
        opti.subject_to(X[:, k + 1] == F(X[:, k], U[:, k]))
    opti.subject_to(opti.bounded(bounds.u_low[0], U, bounds.u_high[0]))
    s = model.params.slide
    opti.subject_to(opti.bounded(bounds.cart_center - bounds.cart_max, X[s, :], bounds.cart_center + bounds.cart_max))
    e = X[:, N] - model.x_eq
    h = model.hinges[0]
    opti.subject_to(ca.vertcat(e[s], ca.sin(e[h]), 1 - ca.cos(e[h]), e[nx // 2:]) == 0)
    opti.minimize(ddp.dt * ca.sumsqr(U))
    opti.set_initial(X, np.asarray(result.x).T)
    opti.set_initial(U, np.asarray(result.u).T)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes"})
    return float(opti.solve().value(opti.f))


def test_ddp_swings_the_pole_up_inside_every_limit_and_replays_in_mujoco(model, swingup):
    ddp, r = swingup
    assert r.converged and r.status == "converged", (r.status, r.violation)
    b = bounds_from_model(model)
    assert np.all(r.u >= b.u_low) and np.all(r.u <= b.u_high)
    s = model.params.slide
    assert np.abs(r.x[:, s] - b.cart_center).max() <= b.cart_max + ddp.options.constraint_tolerance
    assert np.abs(model.state_error(r.x[-1])).max() < 1e-5
    run = replay(None, model.x_hanging, np.repeat(r.u, STEPS, axis=0))
    assert run.info.get("diverged") is None
    np.testing.assert_allclose(run.x[::STEPS], r.x, atol=1e-9, rtol=0)
    assert r.t[-1] == pytest.approx(ddp.N * STEPS * model.dt)


def test_ddp_reaches_the_optimum_ipopt_finds_for_the_same_discrete_problem(model, swingup):
    ddp, r = swingup
    cost = _ipopt_same_problem(model, ddp, r, bounds_from_model(model))
    assert r.cost == pytest.approx(cost, rel=1e-4)
    assert r.cost == pytest.approx(ddp.dt * float(np.sum(r.u ** 2)), rel=1e-12)  # effort, without penalties


def test_a_binding_ctrl_bound_is_held_and_its_clamped_steps_get_no_feedback(model):
    b = bounds_from_model(model, u_max=0.5)
    ddp = ddp_for_model(model, 3.0, steps=STEPS, bounds=b)
    r = ddp.solve(model.x_hanging)
    assert r.converged, r.status
    at = np.isclose(np.abs(r.u[:, 0]), 0.5, rtol=0, atol=1e-9)
    assert at.sum() >= 5 and np.abs(r.u).max() <= 0.5 + 1e-12
    # the box QP's answer: where the input sits on its bound the step has no feedback, elsewhere it has
    assert np.all(r.K[at] == 0.0)
    assert np.all(np.abs(r.K[~at]).max(axis=(1, 2)) > 0.0)


def test_a_running_reward_is_maximised_without_a_terminal_goal(model):
    """dm_control's smooth swing-up reward, negated, as a running cost over 3 s and no terminal constraint: the DDP
    ends with more reward than the zero-ctrl rollout and its rollout is still exact."""
    ddp = ddp_for_model(model, 3.0, steps=STEPS, objective="dmc_swingup", x_goal=False)
    U0 = 0.5 * np.sin(2 * np.pi * np.arange(ddp.N) * ddp.dt / 1.6)[:, None]
    r = ddp.solve(model.x_hanging, U0)
    start = ddp_for_model(model, 3.0, steps=STEPS, objective="dmc_swingup", x_goal=False,
                          options=DDPOptions(max_iterations=0, max_outer=1)).solve(model.x_hanging, U0)
    assert r.cost < start.cost - 0.5  # seconds of reward gained (the reward is at most 1 per second)
    run = replay(None, model.x_hanging, np.repeat(r.u, STEPS, axis=0))
    np.testing.assert_allclose(run.x[::STEPS], r.x, atol=1e-9, rtol=0)


@pytest.mark.parametrize("kwargs, says", [
    ({"N": 0}, "whole number of steps"),
    ({"dt": -1.0}, "positive number of seconds"),
    ({"u_low": [1.0], "u_high": [-1.0]}, "low < high"),
    ({"x_goal": [0.0, 0.0]}, "goal must be 4 numbers"),
])
def test_bad_problems_are_one_sentence(model, kwargs, says):
    args = dict(dt=model.dt, N=10, u_low=[-1.0], u_high=[1.0])
    args.update(kwargs)
    with pytest.raises(DDPError, match=says):
        DDP(model.step, args.pop("dt"), args.pop("N"), DDPProblem(**args), options=DDPOptions(compiled=False))


def test_minimum_time_is_refused_and_a_bad_start_is_one_sentence(model, swingup):
    with pytest.raises(DDPError, match="search over T"):
        ddp_for_model(model, 1.0, objective="time", options=DDPOptions(compiled=False))
    with pytest.raises(DDPError, match="4 finite numbers"):
        swingup[0].solve([0.0, np.nan, 0.0, 0.0])
