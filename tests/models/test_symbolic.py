"""The symbolic model against MuJoCo: exact Jacobians, the discrete step against mj_step, energy consistency.

Every comparison is with an independent computation: MuJoCo's own forward dynamics and step, differentiated
by central differences here, never with numbers copied from a previous run.
"""
import mujoco
import numpy as np
import pytest

from cartpole.models import build_model, read_params, wrap_angle
from cartpole.models.symbolic import linearize

N_RANDOM = 100


def _mujoco(path):
    m = mujoco.MjModel.from_xml_path(str(path))
    return m, mujoco.MjData(m)


def _random_states(params, n, seed):
    """States with nonzero velocities and controls, away from the joint limits (no constraint forces)."""
    rng = np.random.default_rng(seed)
    lo, hi = params.cart_range
    s_max = min(1.0, 0.6 * (hi - lo) / 2) if np.isfinite(hi - lo) else 1.0
    x = np.column_stack([rng.uniform(-s_max, s_max, n), rng.uniform(-np.pi, np.pi, n),
                         rng.uniform(-2, 2, n), rng.uniform(-6, 6, n)])
    u = rng.uniform(-params.u_max, params.u_max, (n, 1))
    x[0], u[0] = 0.0, 0.0  # upright rest is always checked
    return x, u


def _qacc(m, d, x, u):
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:2], x[2:], u
    mujoco.mj_forward(m, d)
    return np.concatenate([d.qvel, d.qacc])


def _mj_step(m, d, x, u):
    mujoco.mj_resetData(m, d)
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:2], x[2:], u
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


def test_continuous_dynamics_equal_mujoco_forward_dynamics(any_mjcf):
    model = build_model(any_mjcf)
    m, d = _mujoco(any_mjcf)
    xs, us = _random_states(model.params, N_RANDOM, 1)
    for x, u in zip(xs, us):
        np.testing.assert_allclose(model.dynamics(x, u), _qacc(m, d, x, u), rtol=1e-9, atol=1e-9)


def test_symbolic_A_B_match_central_differences_of_mujoco_qacc(any_mjcf):
    model = build_model(any_mjcf)
    m, d = _mujoco(any_mjcf)
    xs, us = _random_states(model.params, N_RANDOM, 2)
    worst = 0.0
    for x, u in zip(xs, us):
        A, B = model.linearize(x, u)
        A_fd, B_fd = _central_diff(lambda xx, uu: _qacc(m, d, xx, uu), x, u, 1e-6)
        worst = max(worst, _rel_err(A, A_fd), _rel_err(B, B_fd))
    assert worst < 1e-6, f"worst relative Jacobian error {worst:.2e}"


def test_discrete_step_equals_one_mj_step(any_mjcf):
    model = build_model(any_mjcf)
    m, d = _mujoco(any_mjcf)
    xs, us = _random_states(model.params, N_RANDOM, 3)
    for x, u in zip(xs, us):
        np.testing.assert_allclose(model.step_np(x, u), _mj_step(m, d, x, u), rtol=0, atol=1e-9)


def test_discrete_Ad_Bd_match_central_differences_of_mj_step(any_mjcf):
    model = build_model(any_mjcf)
    m, d = _mujoco(any_mjcf)
    xs, us = _random_states(model.params, 25, 4)
    worst = 0.0
    for x, u in zip(xs, us):
        Ad, Bd = model.linearize(x, u, discrete=True)
        A_fd, B_fd = _central_diff(lambda xx, uu: _mj_step(m, d, xx, uu), x, u, 1e-6)
        worst = max(worst, _rel_err(Ad, A_fd), _rel_err(Bd, B_fd))
    assert worst < 1e-6, f"worst relative discrete Jacobian error {worst:.2e}"


def test_mjd_transitionFD_agrees_where_mujoco_offers_it(any_mjcf):
    """MuJoCo's own derivative (not for RK4) as a second, independent reference at upright."""
    model = build_model(any_mjcf)
    if model.integrator == "RK4":
        pytest.skip("mjd_transitionFD does not support RK4; the central-difference test covers it")
    m, d = _mujoco(any_mjcf)
    mujoco.mj_resetData(m, d)
    mujoco.mj_forward(m, d)
    A = np.zeros((4, 4))
    B = np.zeros((4, 1))
    mujoco.mjd_transitionFD(m, d, 1e-7, True, A, B, None, None)
    Ad, Bd = model.linearize(discrete=True)
    # mjd_transitionFD differentiates qpos in the tangent space, identical to qpos for slide/hinge joints
    assert _rel_err(Ad, A) < 1e-6 and _rel_err(Bd, B) < 1e-6


def test_energy_rate_equals_power_of_damping_and_actuator(any_mjcf):
    """dE/dt along f must equal gear*u*s_dot - d1 s_dot^2 - d2 theta_dot^2: checks M, bias and gravity together."""
    import casadi as ca

    model = build_model(any_mjcf)
    p = model.params
    x = ca.SX.sym("x", 4)
    dEdx = ca.Function("dE", [x], [ca.gradient(model.energy(x), x)])
    xs, us = _random_states(p, 30, 5)
    for xk, uk in zip(xs, us):
        rate = float(np.asarray(dEdx(xk)).ravel() @ model.dynamics(xk, uk))
        power = p.gear * uk[0] * xk[2] - p.damping[0] * xk[2] ** 2 - p.damping[1] * xk[3] ** 2
        # armature adds rotor kinetic energy that `energy` (bodies only) leaves out
        power -= p.armature @ (xk[2:] * model.dynamics(xk, uk)[2:])
        assert rate == pytest.approx(power, rel=1e-9, abs=1e-9)


def test_mass_matrix_equals_mujocos(any_mjcf):
    model = build_model(any_mjcf)
    m, d = _mujoco(any_mjcf)
    xs, _ = _random_states(model.params, 10, 6)
    for x in xs:
        d.qpos[:] = x[:2]
        mujoco.mj_forward(m, d)
        M = np.zeros((2, 2))
        mujoco.mj_fullM(m, d, M)
        np.testing.assert_allclose(np.asarray(model.mass_matrix(x)), M, rtol=1e-12, atol=1e-14)


def test_pole_energy_is_zero_upright_and_minus_2mgl_hanging(any_mjcf):
    model = build_model(any_mjcf)
    p = model.params
    assert float(model.pole_energy([0, 0, 0, 0])) == pytest.approx(0.0, abs=1e-12)
    assert float(model.pole_energy([0.3, np.pi, 0, 0])) == pytest.approx(
        -2 * p.pole_mass * p.g * p.pole_com_distance, rel=1e-12)


def test_upright_rest_is_an_equilibrium(any_mjcf):
    model = build_model(any_mjcf)
    np.testing.assert_allclose(model.dynamics(np.zeros(4), 0.0), 0.0, atol=1e-14)


def test_linearize_returns_both_continuous_and_discrete_forms():
    model = build_model()
    lin = linearize(model)
    assert lin["A"].shape == (4, 4) and lin["B"].shape == (4, 1)
    assert lin["Ad"].shape == (4, 4) and lin["Bd"].shape == (4, 1)
    assert lin["dt"] == model.params.timestep and lin["integrator"] == "Euler"
    # small-dt consistency: Ad ~ I + A dt
    np.testing.assert_allclose(lin["Ad"], np.eye(4) + lin["A"] * lin["dt"], atol=5 * lin["dt"] ** 2 * 30)


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
