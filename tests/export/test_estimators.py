"""The exported Kalman filter against cartpole.estimation's on the same measurements, including a hinge a whole
turn away from upright (the wrapped error, h at a shifted copy of the operating point)."""
import numpy as np
import pytest

from cartpole.errors import CartPoleError
from cartpole.export import design_export, load_design
from cartpole.export.estimators import first_state_rows
from cartpole.export.folder import discard
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions


@pytest.mark.parametrize("turns", [0, 1, -2])
def test_c_kalman_filter_and_lqr_equal_the_python_ones_step_by_step(turns):
    model = build_model(None)
    loop = LoopOptions(period=0.015, estimator="kf", encoder_cpr=2048)
    design = design_export(model, "lqr", loop)
    kf = design.rig.make_estimator()
    fb = design.make_controller()
    steps = design.program.steps
    ctl, folder = load_design(design, "double")
    try:
        ctl.reset()
        rng = np.random.default_rng(3)
        hinge = model.hinges[0]
        u_prev = np.zeros(model.nu)
        for k in range(60):
            y = np.array([0.05 * np.sin(0.3 * k), 2 * np.pi * turns + 0.1 * np.cos(0.2 * k)])
            y += rng.normal(scale=1e-3, size=2)
            x_hat = kf.reset(y) if k == 0 else kf.update(y, np.tile(u_prev, (steps, 1)).T)
            u_py = np.clip(fb(k * design.program.period, x_hat), -1, 1)
            code, u_c = ctl.step(k * design.program.period, y)
            assert code == 0
            np.testing.assert_allclose(u_c, u_py, rtol=0, atol=1e-12)
            u_prev = u_c
        assert abs(x_hat[hinge] - 2 * np.pi * turns) < 1.0  # the estimate kept its turns, only the error wrapped
    finally:
        discard(folder)


def test_a_bad_measurement_repeats_the_last_ctrl_and_says_so():
    model = build_model(None)
    design = design_export(model, "lqr", None)
    ctl, folder = load_design(design, "double")
    try:
        ctl.reset()
        _, u = ctl.step(0.0, [0.0, 0.1, 0.0, 0.0])
        code, u2 = ctl.step(0.005, [np.nan, 0.1, 0.0, 0.0])
        assert code == 1 and np.array_equal(u, u2)
    finally:
        discard(folder)


def test_first_state_rows_follow_the_encoders():
    from cartpole.estimation import sensor_spec

    model = build_model(None)
    spec = sensor_spec(model, encoder_cpr=1024)
    assert first_state_rows(model, spec).tolist() == [0, 1]


def test_estimators_the_export_does_not_reproduce_are_refused():
    model = build_model(None)
    with pytest.raises(CartPoleError, match="not available"):
        design_export(model, "tvlqr", LoopOptions(estimator="kf", encoder_cpr=1024))  # a KF about upright
