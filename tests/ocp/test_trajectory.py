"""Trajectory: Hermite-Simpson interpolation (cubic-Hermite states, first-order-hold inputs) and files."""
import json

import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.trajectory import Trajectory, TrajectoryError, step_grid_trajectory


def _cubic_traj(n=7, seed=0):
    """Knots of a known cubic state and linear input: Hermite interpolation must reproduce them exactly."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 2, n))
    t[0] = 0.0
    c = rng.normal(size=(4, 4))  # x_i(t) = c0 + c1 t + c2 t^2 + c3 t^3

    def x(tt):
        tt = np.asarray(tt)[:, None]
        return c[0] + c[1] * tt + c[2] * tt**2 + c[3] * tt**3

    def xd(tt):
        tt = np.asarray(tt)[:, None]
        return c[1] + 2 * c[2] * tt + 3 * c[3] * tt**2

    u = (0.3 - 0.7 * t)[:, None]
    return Trajectory(t=t, x=x(t), u=u, xdot=xd(t)), x, xd


def test_state_reproduces_a_cubic_and_its_derivative_everywhere():
    traj, x, xd = _cubic_traj()
    tt = np.linspace(0, traj.t[-1], 57)
    np.testing.assert_allclose(traj.state(tt), x(tt), atol=1e-10)
    np.testing.assert_allclose(traj.state_derivative(tt), xd(tt), atol=1e-9)


def test_state_at_knots_is_the_knot_and_scalar_calls_return_one_row():
    traj, _, _ = _cubic_traj()
    np.testing.assert_allclose(traj.state(traj.t), traj.x, atol=1e-12)
    assert traj.state(0.3).shape == (4,) and traj.input(0.3).shape == (1,)
    assert traj.state(traj.t).shape == (traj.t.size, 4) and traj.input(traj.t).shape == (traj.t.size, 1)


def test_input_is_first_order_hold_and_clamped_outside():
    traj, _, _ = _cubic_traj()
    tt = np.linspace(-1, traj.t[-1] + 1, 101)
    expected = np.interp(tt, traj.t, traj.u[:, 0])  # numpy's linear interpolation also clamps
    np.testing.assert_allclose(traj.input(tt)[:, 0], expected, atol=1e-12)
    np.testing.assert_array_equal(traj.state(-5.0), traj.x[0])
    np.testing.assert_array_equal(traj.state(traj.t[-1] + 5), traj.x[-1])


def test_midpoint_is_the_hermite_simpson_formula():
    traj, _, _ = _cubic_traj()
    h = np.diff(traj.t)[:, None]
    xc = 0.5 * (traj.x[:-1] + traj.x[1:]) + h / 8 * (traj.xdot[:-1] - traj.xdot[1:])
    np.testing.assert_allclose(traj.state(traj.t_mid), xc, atol=1e-12)


def test_sample_is_time_first_and_includes_both_ends():
    traj, _, _ = _cubic_traj()
    t, x, u = traj.sample(0.01)
    assert t[0] == traj.t[0] and t[-1] <= traj.t[-1] and traj.t[-1] - t[-1] < 0.01
    assert x.shape == (t.size, 4) and u.shape == (t.size, 1)
    with pytest.raises(TrajectoryError):
        traj.sample(0.0)


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_save_load_round_trip(tmp_path, suffix):
    traj, _, _ = _cubic_traj()
    traj = Trajectory(t=traj.t, x=traj.x, u=traj.u, xdot=traj.xdot, x_mid=traj.state(traj.t_mid),
                      u_mid=traj.input(traj.t_mid))
    path = traj.save(tmp_path / f"plan{suffix}")
    back = Trajectory.load(path)
    for name in ("t", "x", "u", "xdot", "x_mid", "u_mid"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left behind
    if suffix == ".json":
        assert json.loads(path.read_text())["format"].startswith("cartpole.Trajectory")


def test_arrays_are_read_only_and_bad_input_is_one_clear_error(tmp_path):
    traj, _, _ = _cubic_traj()
    with pytest.raises(ValueError):
        traj.x[0, 0] = 1.0
    with pytest.raises(TrajectoryError, match="strictly increasing"):
        Trajectory(t=[0, 0, 1], x=np.zeros((3, 4)), u=np.zeros(3), xdot=np.zeros((3, 4)))
    with pytest.raises(TrajectoryError, match="shape"):
        Trajectory(t=[0, 1], x=np.zeros((3, 4)), u=np.zeros(2), xdot=np.zeros((2, 4)))
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(TrajectoryError, match="does not hold"):
        Trajectory.load(bad)


def _cubic_chain_traj(nx=6, nu=2, n=9, seed=1):
    """Knots of a known cubic state (nx,) and linear inputs (nu,): any model shape interpolates exactly."""
    rng = np.random.default_rng(seed)
    t = np.r_[0.0, np.sort(rng.uniform(0, 2, n - 1))]
    c = rng.normal(size=(4, nx))
    a, b = rng.normal(size=nu), rng.normal(size=nu)
    x = lambda tt: c[0] + c[1] * tt[:, None] + c[2] * tt[:, None] ** 2 + c[3] * tt[:, None] ** 3  # noqa: E731
    xd = lambda tt: c[1] + 2 * c[2] * tt[:, None] + 3 * c[3] * tt[:, None] ** 2  # noqa: E731
    return Trajectory(t=t, x=x(t), u=a + np.outer(t, b), xdot=xd(t)), x, xd, (a, b)


def test_any_state_and_input_size_interpolates_cubic_hermite_and_first_order_hold(tmp_path):
    traj, x, xd, (a, b) = _cubic_chain_traj()
    assert (traj.nx, traj.nu) == (6, 2)
    tt = np.linspace(0, traj.t[-1], 41)
    np.testing.assert_allclose(traj.state(tt), x(tt), atol=1e-10)
    np.testing.assert_allclose(traj.state_derivative(tt), xd(tt), atol=1e-9)
    np.testing.assert_allclose(traj.input(tt), a + np.outer(tt, b), atol=1e-12)
    assert traj.state(0.3).shape == (6,) and traj.input(0.3).shape == (2,)
    t_s, x_s, u_s = traj.sample(0.05)
    assert x_s.shape == (t_s.size, 6) and u_s.shape == (t_s.size, 2)
    full = Trajectory(t=traj.t, x=traj.x, u=traj.u, xdot=traj.xdot, x_mid=traj.state(traj.t_mid),
                      u_mid=traj.input(traj.t_mid))
    for suffix in (".npz", ".json"):
        back = Trajectory.load(full.save(tmp_path / f"chain{suffix}"))
        for name in ("t", "x", "u", "xdot", "x_mid", "u_mid"):
            np.testing.assert_array_equal(getattr(back, name), getattr(full, name))
    with pytest.raises(TrajectoryError, match="xdot"):
        Trajectory(t=traj.t, x=traj.x, u=traj.u, xdot=traj.xdot[:, :4])
    with pytest.raises(TrajectoryError, match="u_mid"):
        Trajectory(t=traj.t, x=traj.x, u=traj.u, xdot=traj.xdot, u_mid=np.zeros((traj.N, 1)))


@pytest.mark.parametrize("mjcf", ["cartpole.xml", "cartpole_two_pole.xml"])
def test_a_step_grid_trajectory_holds_each_input_over_its_step_with_f_at_every_knot(mjcf):
    model = build_model(SHIPPED_MJCF.with_name(mjcf))
    rng = np.random.default_rng(3)
    n, dt = 9, 0.02
    x = np.asarray(model.x_hanging, float) + 0.3 * rng.normal(size=(n + 1, model.nx))
    u = rng.uniform(-1.0, 1.0, size=(n, model.nu))
    traj = step_grid_trajectory(model.f, dt, x, u)
    np.testing.assert_array_equal(traj.t, dt * np.arange(n + 1))
    np.testing.assert_array_equal(traj.x, x)
    np.testing.assert_array_equal(traj.u[:-1], u)  # step k's input at knot k
    np.testing.assert_array_equal(traj.u[-1], u[-1])  # the last one held at the end
    for k in range(n + 1):  # f at each knot, one call at a time (what the box-tail planner's copy computed)
        np.testing.assert_array_equal(traj.xdot[k], model.dynamics(x[k], traj.u[k]))
    if model.nu == 1:  # one input given as a 1-D array: the same trajectory
        np.testing.assert_array_equal(step_grid_trajectory(model.f, dt, x, u[:, 0]).xdot, traj.xdot)
