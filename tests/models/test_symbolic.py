"""The symbolic model against MuJoCo: exact Jacobians, the discrete step against mj_step, energy consistency.

Every comparison is with an independent computation: MuJoCo's own forward dynamics and step, differentiated
by central differences here, never with numbers copied from a previous run.
"""
import mujoco
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model, read_params, wrap_angle
from cartpole.models import linearize
from cartpole.validation.jacobians import random_states

N_RANDOM = 100


def _mujoco(path):
    m = mujoco.MjModel.from_xml_path(str(path))
    return m, mujoco.MjData(m)


def _random_states(params, n, seed):
    """States with nonzero velocities and controls, away from the joint limits (no constraint forces);
    the first is the upright equilibrium."""
    x, u = random_states(params, n, seed=seed)
    model = build_model(params)
    x[0], u[0] = model.x_eq, model.u_eq
    return x, u


def _qacc(m, d, x, u):
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:m.nq], x[m.nq:], u
    mujoco.mj_forward(m, d)
    return np.concatenate([d.qvel, d.qacc])


def _mj_step(m, d, x, u):
    mujoco.mj_resetData(m, d)
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:m.nq], x[m.nq:], u
    mujoco.mj_step(m, d)
    return np.concatenate([d.qpos, d.qvel])


def _central_diff(fun, x, u, eps):
    n, k = x.size, u.size
    A = np.empty((n, n))
    B = np.empty((n, k))
    for i in range(n):
        dx = np.zeros(n)
        dx[i] = eps
        A[:, i] = (fun(x + dx, u) - fun(x - dx, u)) / (2 * eps)
    for j in range(k):
        du = np.zeros(k)
        du[j] = eps
        B[:, j] = (fun(x, u + du) - fun(x, u - du)) / (2 * eps)
    return A, B


def _rel_err(X, Y):
    """Largest entry error relative to the largest entry of the reference matrix."""
    return np.abs(X - Y).max() / np.abs(Y).max()


def test_continuous_dynamics_equal_mujoco_forward_dynamics(family_mjcf):
    model = build_model(family_mjcf)
    m, d = _mujoco(family_mjcf)
    xs, us = _random_states(model.params, N_RANDOM, 1)
    for x, u in zip(xs, us):
        np.testing.assert_allclose(model.dynamics(x, u), _qacc(m, d, x, u), rtol=1e-9, atol=1e-9)


def test_symbolic_A_B_match_central_differences_of_mujoco_qacc(family_mjcf):
    model = build_model(family_mjcf)
    m, d = _mujoco(family_mjcf)
    xs, us = _random_states(model.params, N_RANDOM, 2)
    worst = 0.0
    for x, u in zip(xs, us):
        A, B = model.linearize(x, u)
        A_fd, B_fd = _central_diff(lambda xx, uu: _qacc(m, d, xx, uu), x, u, 1e-6)
        worst = max(worst, _rel_err(A, A_fd), _rel_err(B, B_fd))
    assert worst < 1e-6, f"worst relative Jacobian error {worst:.2e}"


def test_discrete_step_equals_one_mj_step(family_mjcf):
    model = build_model(family_mjcf)
    m, d = _mujoco(family_mjcf)
    xs, us = _random_states(model.params, N_RANDOM, 3)
    for x, u in zip(xs, us):
        np.testing.assert_allclose(model.step_np(x, u), _mj_step(m, d, x, u), rtol=0, atol=1e-9)


def test_discrete_Ad_Bd_match_central_differences_of_mj_step(family_mjcf):
    model = build_model(family_mjcf)
    m, d = _mujoco(family_mjcf)
    xs, us = _random_states(model.params, N_RANDOM, 4)
    worst = 0.0
    for x, u in zip(xs, us):
        Ad, Bd = model.linearize(x, u, discrete=True)
        A_fd, B_fd = _central_diff(lambda xx, uu: _mj_step(m, d, xx, uu), x, u, 1e-6)
        worst = max(worst, _rel_err(Ad, A_fd), _rel_err(Bd, B_fd))
    assert worst < 1e-6, f"worst relative discrete Jacobian error {worst:.2e}"


def test_mjd_transitionFD_agrees_where_mujoco_offers_it(family_mjcf):
    """MuJoCo's own derivative (not for RK4) as a second, independent reference at upright."""
    model = build_model(family_mjcf)
    if model.integrator == "RK4":
        pytest.skip("mjd_transitionFD does not support RK4; the central-difference test covers it")
    m, d = _mujoco(family_mjcf)
    mujoco.mj_resetData(m, d)
    d.qpos[:], d.ctrl[:] = model.x_eq[:model.nq], model.u_eq
    mujoco.mj_forward(m, d)
    A = np.zeros((model.nx, model.nx))
    B = np.zeros((model.nx, model.nu))
    mujoco.mjd_transitionFD(m, d, 1e-7, True, A, B, None, None)
    Ad, Bd = model.linearize(discrete=True)
    # mjd_transitionFD differentiates qpos in the tangent space, identical to qpos for slide/hinge joints
    assert _rel_err(Ad, A) < 1e-6 and _rel_err(Bd, B) < 1e-6


def test_energy_rate_equals_power_of_damping_and_actuator(family_mjcf):
    """dE/dt along f must equal (B u - D v) . v: checks M, bias, gravity and springs together."""
    import casadi as ca

    model = build_model(family_mjcf)
    p, nq = model.params, model.nq
    x = ca.SX.sym("x", model.nx)
    dEdx = ca.Function("dE", [x], [ca.gradient(model.energy(x), x)])
    xs, us = _random_states(p, 30, 5)
    for xk, uk in zip(xs, us):
        v, qacc = xk[nq:], model.dynamics(xk, uk)[nq:]
        rate = float(np.asarray(dEdx(xk)).ravel() @ model.dynamics(xk, uk))
        tau = np.zeros(nq)
        for a, uu in zip(p.actuators, uk):
            tau[a.joint] += a.gear * uu
        power = (tau - p.damping * v) @ v
        # armature adds rotor kinetic energy that `energy` (bodies only) leaves out
        power -= p.armature @ (v * qacc)
        assert rate == pytest.approx(power, rel=1e-8, abs=1e-8)


def test_mass_matrix_equals_mujocos(family_mjcf):
    model = build_model(family_mjcf)
    m, d = _mujoco(family_mjcf)
    xs, _ = _random_states(model.params, 10, 6)
    for x in xs:
        d.qpos[:] = x[:m.nq]
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        np.testing.assert_allclose(np.asarray(model.mass_matrix(x)), M, rtol=1e-11, atol=1e-13)


def test_single_pole_energy_is_zero_upright_and_minus_2mgl_hanging(any_mjcf):
    model = build_model(any_mjcf)
    p = model.params
    assert float(model.pole_energy(model.x_eq)) == pytest.approx(0.0, abs=1e-12)
    hanging = model.x_hanging.copy()
    hanging[model.slide] = 0.3
    assert float(model.pole_energy(hanging)) == pytest.approx(-2 * p.pole_mass * p.g * p.pole_com_distance, rel=1e-12)


def test_pole_energy_exists_only_for_one_pole():
    assert build_model(SHIPPED_MJCF.with_name("cartpole_two_pole.xml")).pole_energy is None


def test_upright_equilibrium_is_a_rest_of_the_model(family_mjcf):
    model = build_model(family_mjcf)
    np.testing.assert_allclose(model.dynamics(model.x_eq, model.u_eq), 0.0, atol=1e-12)
    np.testing.assert_allclose(model.dynamics(model.x_hanging, model.u_hanging), 0.0, atol=1e-12)


def test_upright_equilibrium_is_a_rest_of_mujoco_for_one_second(family_mjcf):
    """From x*, ctrl = u*, one second of mj_step moves no coordinate by more than 1e-6."""
    model = build_model(family_mjcf)
    m, d = _mujoco(family_mjcf)
    d.qpos[:], d.ctrl[:] = model.x_eq[:m.nq], model.u_eq
    for _ in range(int(round(1.0 / m.opt.timestep))):
        mujoco.mj_step(m, d)
    assert np.abs(d.qpos - model.x_eq[:m.nq]).max() < 1e-6 and np.abs(d.qvel).max() < 1e-6


def test_upright_puts_every_pole_centre_of_mass_above_its_hinge(family_mjcf):
    """What "upright" means, checked on MuJoCo's own kinematics at x*: each hinge's subtree COM is above it."""
    model = build_model(family_mjcf)
    m, d = _mujoco(family_mjcf)
    d.qpos[:] = model.x_eq[:m.nq]
    mujoco.mj_forward(m, d)
    up = model.params.up
    for j in model.hinges:
        body = m.jnt_bodyid[j]
        r = d.subtree_com[body] - d.xanchor[j]
        n = d.xaxis[j]
        r = r - (r @ n) * n
        assert r @ up > 0 and np.linalg.norm(r - (r @ up) * up) < 1e-6 * np.linalg.norm(r)


def test_linearize_has_one_return_shape_whatever_the_plant_and_form():
    model = build_model()
    A, B = linearize(model)
    Ad, Bd = linearize(model.params, discrete=True)
    assert A.shape == (model.nx, model.nx) and B.shape == (model.nx, model.nu)
    assert Ad.shape == A.shape and Bd.shape == B.shape
    for mine, method in zip((A, B, Ad, Bd), (*model.linearize(), *model.linearize(discrete=True))):
        np.testing.assert_array_equal(mine, method)
    np.testing.assert_array_equal(linearize(model, period=model.dt)[0], Ad)
    held, _ = linearize(model, period=3 * model.dt)
    np.testing.assert_allclose(held, model.hold(3).linearize()[0])
    # small-dt consistency: Ad ~ I + A dt
    np.testing.assert_allclose(Ad, np.eye(4) + A * model.dt, atol=5 * model.dt ** 2 * 30)


def test_model_rebuilt_at_a_control_period_equals_repeated_physics_steps_for_RK4():
    p = read_params()
    fine = build_model(p, integrator="RK4", dt=0.001)
    coarse = fine.rebuilt(dt=0.004)
    x = np.array([0.1, 0.2, -0.3, 0.5])
    a = coarse.step_np(x, 0.3)
    b = x
    for _ in range(4):
        b = fine.step_np(b, 0.3)
    np.testing.assert_allclose(a, b, atol=1e-6)


@pytest.mark.parametrize("theta, wrapped", [(2 * np.pi + 0.01, 0.01), (-np.pi, np.pi), (np.pi, np.pi),
                                            (3 * np.pi / 2, -np.pi / 2), (-4 * np.pi - 0.2, -0.2)])
def test_wrap_angle_maps_to_half_open_interval(theta, wrapped):
    assert wrap_angle(theta) == pytest.approx(wrapped, abs=1e-12)
