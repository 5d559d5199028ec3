"""The rig between MuJoCo and the controller: a held, delayed ctrl schedule, sensors, estimators (LQG), and runs
that still replay exactly from their logged ctrl."""
import numpy as np
import pytest

from cartpole.apps.lab import run_lab
from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.sim import LoopOptions, build_rig, replays_exactly, simulate

ENCODERS = dict(encoder_cpr=2048, encoder_resolution=0.001)


def test_a_delayed_held_ctrl_acts_delay_steps_after_its_sample_for_one_period():
    model = build_model()
    h = model.dt
    rig = build_rig(model, LoopOptions(period=3 * h, delay=2 * h))
    assert rig.steps == 3 and rig.delay_steps == 2 and rig.estimator == "none"
    ro = simulate(model.params, lambda t, x: np.array([t]), model.x_eq, 30 * h, rig=rig)
    u = ro.ctrl[:, 0]
    assert np.all(u[:2] == 0.0)  # nothing has arrived yet
    for j in range(2, len(u)):
        issued = ((j - 2) // 3) * 3  # the sample whose ctrl acts at step j
        assert u[j] == pytest.approx((issued + 2) * h)  # the controller was asked for the time it takes effect
    np.testing.assert_allclose(ro.t_sample, np.arange(0, 30, 3) * h)
    assert replays_exactly(ro)


def test_lqg_lab_from_encoders_with_period_and_delay_settles_all_five_starts_and_replays():
    loop = LoopOptions(period=0.01, delay=0.01, estimator="kf", **ENCODERS)
    lab = run_lab(loop=loop)
    assert lab.rig.steps == 2 and lab.rig.delay_steps == 2 and lab.rig.spec.ny == model_nq()
    assert np.all(lab.settling_times_seed < 1.0), lab.settling_times_seed
    for ro in lab.rollouts:
        assert replays_exactly(ro)
        assert ro.y.shape == (ro.t_sample.size, lab.rig.spec.ny)
        # it starts from the first measurement with zero rates, never from the true state
        assert np.all(ro.x_hat[0, model_nq():] == 0.0)
        assert np.abs(ro.x_hat - ro.x_sample).max() > 0
    est = lab.estimation
    assert est["estimator"] == "kf" and est["samples"] == 5 * lab.rollouts[0].t_sample.size
    assert est["rms_error"]["hinge"] < 2e-3 and est["estimate_ms"]["median"] > 0


def model_nq():
    return build_model().nq


def test_coarser_encoders_and_noise_make_lqg_measurably_worse():
    fine = run_lab(loop=LoopOptions(period=0.01, delay=0.01, estimator="kf", **ENCODERS))
    coarse = run_lab(loop=LoopOptions(period=0.01, delay=0.01, estimator="kf", encoder_cpr=256,
                                      encoder_resolution=0.01))
    noisy = run_lab(loop=LoopOptions(period=0.01, delay=0.01, estimator="kf", sensor_noise=0.005, **ENCODERS))
    for worse in (coarse, noisy):
        assert worse.estimation["rms_error"]["hinge"] > 2 * fine.estimation["rms_error"]["hinge"]
        tail = [np.abs(r.qpos[-200:, 1]).max() for r in worse.rollouts]
        tail_fine = [np.abs(r.qpos[-200:, 1]).max() for r in fine.rollouts]
        assert np.mean(tail) > np.mean(tail_fine)


def test_runs_on_mjcf_sensors_replay_exactly_and_see_only_the_sensors(tmp_path):
    text = SHIPPED_MJCF.read_text().replace('rgba="0.8 0.2 0.2 1" mass="0.1"/>',
                                            'rgba="0.8 0.2 0.2 1" mass="0.1"/><site name="tip" pos="0 0 0.6"/>')
    text = text.replace("</mujoco>", '<sensor><jointpos joint="slider" noise="0.0005"/>'
                        '<jointpos joint="hinge" noise="0.001"/><accelerometer site="tip"/></sensor></mujoco>')
    assert 'site name="tip"' in text
    path = tmp_path / "sensed.xml"
    path.write_text(text)
    model = build_model(path)
    rig = build_rig(model, LoopOptions(period=0.01, estimator="ekf"))
    assert rig.spec.ny == 5
    from cartpole.control.linear import LinearFeedback

    x0 = model.x_eq.copy()
    x0[model.hinges[0]] = 0.05
    ro = simulate(path, LinearFeedback.for_model(model, period=0.01), x0, 3.0, rig=rig)
    assert replays_exactly(ro)
    assert np.abs(model.state_error(ro.x[-1])[list(model.hinges)]).max() < 0.02


@pytest.mark.parametrize("loop, words", [
    (LoopOptions(estimator="none", encoder_cpr=2048), "`estimator='none'`"),
    (LoopOptions(delay=0.007), "whole number"),
    (LoopOptions(period=0.013), "whole number"),
])
def test_a_rig_that_cannot_be_built_is_one_sentence(loop, words):
    from cartpole.errors import CartPoleError

    with pytest.raises(CartPoleError, match=words) as err:
        build_rig(build_model(), loop)
    assert "\n" not in str(err.value)


def test_a_perfect_loop_needs_no_rig():
    assert build_rig(build_model(), LoopOptions()) is None
    assert build_rig(build_model(), None) is None
