"""The exported moving-horizon estimator against cartpole.estimation's, step by step and in the MuJoCo loop, inside
the rail and with measurements beyond it (the window's bounded QP)."""
import numpy as np
import pytest
from mj_replay import replay_with_mj_step

from cartpole.export import design_export, load_design, run_lockstep
from cartpole.export.folder import discard
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions
from cartpole.validation.metrics import swingup_success


@pytest.fixture(scope="module")
def lqr_mhe():
    model = build_model(None)
    design = design_export(model, "lqr", LoopOptions(period=0.01, estimator="mhe", encoder_cpr=2048))
    ctl, folder = load_design(design, "double")
    yield model, design, ctl
    discard(folder)


@pytest.mark.parametrize("cart", [0.2, -1.2])
def test_c_mhe_and_lqr_equal_the_python_ones_step_by_step(lqr_mhe, cart):
    model, design, ctl = lqr_mhe
    mhe, fb = design.rig.make_estimator(), design.make_controller()
    steps, T = design.program.steps, design.program.period
    ctl.reset()
    rng = np.random.default_rng(5)
    u_prev = np.zeros(model.nu)
    for k in range(40):  # past the window's length (10): the slide and its arrival update too
        y = np.array([cart + 0.02 * np.sin(0.4 * k), 0.05 * np.cos(0.3 * k)]) + rng.normal(scale=1e-3, size=2)
        x_hat = mhe.reset(y) if k == 0 else mhe.update(y, np.tile(u_prev, (steps, 1)).T)
        u_py = np.clip(fb(k * T, x_hat), -1, 1)
        code, u_c = ctl.step(k * T, y)
        assert code == 0
        np.testing.assert_allclose(u_c, u_py, rtol=0, atol=1e-9)
        u_prev = u_c
    lo, hi = model.params.joint_ranges[model.slide]
    assert lo <= x_hat[model.slide] <= hi  # the estimate kept inside the rail


def test_beyond_the_rail_the_c_mhe_and_lqr_equal_the_python_ones(lqr_mhe):
    # measurements 10-14 cm past the rail's end: the window's bounded QP, condition number ~1e13 (a 2048-count
    # encoder's position weighs ~1e13 per m^2 against 1 per noise entry). Both solutions meet the QP's KKT conditions
    # (tests/estimation/test_mhe.py); their ctrl agree to 5e-9 on one machine and 2e-8 on another (measured: the
    # rounding of that conditioning, which differs with the CPU's floating point between the C and NumPy), so the
    # bound is 1e-7, not a figure of one machine; one implementation of the MHE (issue 39) will make them equal
    model, design, ctl = lqr_mhe
    mhe, fb = design.rig.make_estimator(), design.make_controller()
    steps, T = design.program.steps, design.program.period
    ctl.reset()
    u_prev, unclipped = np.zeros(model.nu), 0
    for k in range(40):
        y = np.array([1.62 + 0.02 * np.sin(0.4 * k), 0.05])
        x_hat = mhe.reset(y) if k == 0 else mhe.update(y, np.tile(u_prev, (steps, 1)).T)
        u_raw = fb(k * T, x_hat)
        u_py = np.clip(u_raw, -1, 1)
        code, u_c = ctl.step(k * T, y)
        assert code == 0
        np.testing.assert_allclose(u_c, u_py, rtol=0, atol=1e-7)
        unclipped += int(np.all(np.abs(u_raw) < 1))
        u_prev = u_c
    lo, hi = model.params.joint_ranges[model.slide]
    assert x_hat[model.slide] == pytest.approx(hi, abs=1e-9) and mhe.failures == []
    assert unclipped >= 3  # some instants compare unsaturated ctrl


def test_tvlqr_swingup_with_mhe_matches_python_in_mujoco():
    model = build_model(None)
    design = design_export(model, "tvlqr", LoopOptions(period=0.01, estimator="mhe", encoder_cpr=2048))
    T = design.plan_end + 3.0
    for real in ("double", "float"):
        ctl, folder = load_design(design, real)
        try:
            run = run_lockstep(design, ctl, model.x_hanging, T)
        finally:
            discard(folder)
        if real == "double":
            assert run.max_ctrl_diff <= 1e-9
        r = run.rollout
        qpos, qvel = replay_with_mj_step(r.mjcf, r.qpos[0], r.qvel[0], r.ctrl)
        assert np.array_equal(qpos, r.qpos) and np.array_equal(qvel, r.qvel)
        assert swingup_success(r, model.params)
