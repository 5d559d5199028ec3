"""The exact discrete model over a control period (m physics steps with the ctrl held) against m calls of mj_step."""
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, PeriodError, build_model, steps_per_period
from cartpole.validation.jacobians import random_states

GYM_DOUBLE = Path(__file__).resolve().parent.parent / "assets" / "gymnasium_inverted_double_pendulum.xml"
HOLD_FILES = {"one_pole": SHIPPED_MJCF, "two_pole": SHIPPED_MJCF.with_name("cartpole_two_pole.xml"),
              "three_pole": SHIPPED_MJCF.with_name("cartpole_three_pole.xml"), "gymnasium_double": GYM_DOUBLE}


def _held_mj_steps(m, d, x, u, steps):
    mujoco.mj_resetData(m, d)
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:m.nq], x[m.nq:], u
    for _ in range(steps):
        mujoco.mj_step(m, d)
    return np.concatenate([d.qpos, d.qvel])


def _central_diff(fun, x, u, eps):
    A = np.column_stack([(fun(x + e, u) - fun(x - e, u)) / (2 * eps) for e in np.eye(x.size) * eps])
    B = np.column_stack([(fun(x, u + e) - fun(x, u - e)) / (2 * eps) for e in np.eye(u.size) * eps])
    return A, B


@pytest.fixture(params=sorted(HOLD_FILES), scope="module")
def held(request):
    path = HOLD_FILES[request.param]
    model = build_model(path)
    m = mujoco.MjModel.from_xml_path(str(path))
    return model, m, mujoco.MjData(m)


def test_hold_of_five_steps_equals_five_mj_steps(held):
    model, m, d = held
    hold = model.hold(5)
    xs, us = random_states(model.params, 10, seed=11)
    xs[0], us[0] = model.x_eq, model.u_eq
    for x, u in zip(xs, us):
        np.testing.assert_allclose(hold.step_np(x, u), _held_mj_steps(m, d, x, u, 5), rtol=0, atol=1e-9)


def test_hold_Ad_Bd_match_central_differences_of_five_mj_steps(held):
    model, m, d = held
    hold = model.hold(5)
    xs, us = random_states(model.params, 6, seed=12)
    xs[0], us[0] = model.x_eq, model.u_eq
    worst = 0.0
    for x, u in zip(xs, us):
        Ad, Bd = hold.linearize(x, u)
        A_fd, B_fd = _central_diff(lambda xx, uu: _held_mj_steps(m, d, xx, uu, 5), x, u, 1e-6)
        worst = max(worst, np.abs(Ad - A_fd).max() / np.abs(A_fd).max(), np.abs(Bd - B_fd).max() / np.abs(B_fd).max())
    assert worst < 1e-6, f"worst relative error of the held Jacobians {worst:.2e}"


def test_hold_of_one_step_is_the_model_step():
    model = build_model()
    x, u = np.array([0.1, 0.2, -0.3, 0.4]), np.array([0.3])
    np.testing.assert_array_equal(model.hold(1).step_np(x, u), model.step_np(x, u))
    assert model.hold(3) is model.hold(3)
    assert model.hold(4).period == pytest.approx(4 * model.dt)


def test_per_step_inputs_equal_the_held_map_when_all_equal_and_the_sequence_otherwise():
    model = build_model()
    hold = model.hold(3)
    x = np.array([0.1, 0.2, -0.3, 0.4])
    np.testing.assert_allclose(np.asarray(hold.step_inputs(x, np.full((1, 3), 0.2))).ravel(),
                               hold.step_np(x, 0.2), atol=1e-15)
    U = np.array([[0.2, -0.5, 0.9]])
    seq = x
    for j in range(3):
        seq = model.step_np(seq, U[:, j])
    np.testing.assert_allclose(np.asarray(hold.step_inputs(x, U)).ravel(), seq, atol=1e-15)


@pytest.mark.parametrize("period, steps", [(None, 1), (0.002, 1), (0.01, 5), (0.0100000001, 5)])
def test_steps_per_period_counts_whole_physics_steps(period, steps):
    assert steps_per_period(period, 0.002) == steps


@pytest.mark.parametrize("period", [0.003, 0.001, 0.0, -0.01, float("nan"), float("inf"), "fast"])
def test_a_period_that_is_not_a_whole_number_of_steps_is_refused_in_one_sentence(period):
    with pytest.raises(PeriodError) as err:
        steps_per_period(period, 0.002)
    assert "\n" not in str(err.value) and "period" in str(err.value)
