"""Exported swing-ups in MuJoCo: TVLQR from a plan (+ EKF) and energy shaping + LQR catch, step for step the
Python controller's ctrl (double), swung up and held in float32, the runs replaying bit for bit with mj_step."""
import numpy as np
import pytest
from mj_replay import replay_with_mj_step

from cartpole.export import design_export, load_design, run_lockstep
from cartpole.export.folder import discard
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions
from cartpole.validation.metrics import swingup_success

TWO_POLE = "cartpole/assets/cartpole_two_pole.xml"


def _replays(rollout):
    qpos, qvel = replay_with_mj_step(rollout.mjcf, rollout.qpos[0], rollout.qvel[0], rollout.ctrl)
    return np.array_equal(qpos, rollout.qpos) and np.array_equal(qvel, rollout.qvel)


def _both(design, x0, duration):
    out = {}
    for real in ("double", "float"):
        ctl, folder = load_design(design, real)
        try:
            out[real] = run_lockstep(design, ctl, x0, duration)
        finally:
            discard(folder)
    return out["double"], out["float"]


@pytest.mark.parametrize("mjcf,loop", [
    (None, None),
    (None, LoopOptions(period=0.01, estimator="ekf", encoder_cpr=2048)),
    (TWO_POLE, None),
], ids=["one-pole", "one-pole-ekf-10ms", "two-pole"])
def test_tvlqr_export_swings_up_like_python(mjcf, loop):
    model = build_model(mjcf)
    design = design_export(model, "tvlqr", loop)
    T = design.plan_end + 3.0
    d, f = _both(design, model.x_hanging, T)
    assert d.max_ctrl_diff <= 1e-9
    if loop is None:
        assert swingup_success(d.rollout, model.params) and swingup_success(f.rollout, model.params)
    else:
        for run in (d, f):
            _held_with_encoders(run.rollout, model)
    assert _replays(d.rollout) and _replays(f.rollout)
    assert d.rollout.info["diverged"] is None and f.rollout.info["diverged"] is None


def _held_with_encoders(rollout, model, hold=1.0):
    """Swung up and held, judged at the noise floor of a 2048-count encoder read every 10 ms: the pole within
    UPRIGHT_TOL and the cart off its limits as swingup_success asks, the hinge rate at rest in RMS (below half of
    REST_RATE_TOL) with single-sample spikes of the quantised estimate's chatter allowed up to twice it (measured:
    RMS 0.04 rad/s, one sample of 200 at 0.104 rad/s, where a plan different by 4e-8 in T gave 0.095)."""
    from cartpole.validation.metrics import REST_RATE_TOL, UPRIGHT_TOL, diverged, pole_angle_errors, track_margin

    params = model.params
    last = rollout.t >= rollout.t[-1] - hold - 1e-12
    x = rollout.x[last]
    rates = x[:, [model.nq + h for h in model.hinges]]
    assert not diverged(rollout)
    assert np.abs(pole_angle_errors(x, x_eq=model.x_eq, hinges=model.hinges)).max() < UPRIGHT_TOL
    assert np.sqrt(np.mean(rates ** 2)) < 0.5 * REST_RATE_TOL and np.abs(rates).max() < 2 * REST_RATE_TOL
    assert track_margin(rollout.qpos, params.cart_range, slide=params.slide) > 1e-3


def test_tvlqr_export_plans_from_the_given_start():
    model = build_model(None)
    x0 = np.array([0.2, np.pi - 0.3, 0.0, 0.5])
    design = design_export(model, "tvlqr", None, x0=x0)
    d, _ = _both(design, x0, design.plan_end + 3.0)
    assert d.max_ctrl_diff <= 1e-9 and swingup_success(d.rollout, model.params)


def test_energy_export_swings_up_and_catches_like_python():
    from cartpole.control import SWINGUP_CATCH_R, LinearFeedback
    from cartpole.validation.basin import BasinCache

    model = build_model(None)
    rho = BasinCache.on_disk().get(model.params, LinearFeedback.for_model(model, R=SWINGUP_CATCH_R)).rho
    design = design_export(model, "energy", None, rho=rho)
    d, f = _both(design, model.x_hanging, 10.0)
    assert d.max_ctrl_diff <= 1e-9
    assert swingup_success(d.rollout, model.params) and swingup_success(f.rollout, model.params)
    assert _replays(d.rollout) and _replays(f.rollout)


def test_lqr_with_ekf_and_delay_matches_python():
    model = build_model(None)
    design = design_export(model, "lqr", LoopOptions(period=0.01, delay=0.01, estimator="ekf", encoder_cpr=2048))
    x0 = np.array(model.x_eq, float)
    x0[1] += 0.1
    d, f = _both(design, x0, 3.0)
    assert d.max_ctrl_diff <= 1e-9 and _replays(d.rollout) and _replays(f.rollout)
    assert abs(model.state_error(f.rollout.x[-1])[1]) < 0.05
