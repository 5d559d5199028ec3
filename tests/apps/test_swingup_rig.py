"""Swing-ups on a rig: from encoders only, with a control period and a delay, every method on the estimate; the runs
replay exactly from their logged ctrl."""
import numpy as np
import pytest

from cartpole.apps.swingup import SwingupOptions, run_swingup
from cartpole.models import SHIPPED_MJCF
from cartpole.sim import LoopOptions, replays_exactly

ENCODERS = dict(encoder_cpr=2048, encoder_resolution=0.001)


@pytest.mark.parametrize("mjcf", [SHIPPED_MJCF, SHIPPED_MJCF.with_name("cartpole_two_pole.xml")],
                         ids=["one_pole", "two_pole"])
def test_trajopt_tvlqr_swings_up_from_encoders_through_the_ekf_with_a_5_ms_delay(mjcf):
    # a smooth rate estimate: with the default process noise the quantised encoders leave the balanced poles
    # jittering at 0.1-0.6 rad/s, over the success test's rest tolerance (docs/rig.md)
    loop = LoopOptions(period=0.01, delay=0.005, estimator="ekf", process_noise=0.1, **ENCODERS)
    res = run_swingup(mjcf, "trajopt", SwingupOptions(loop=loop))
    assert res.success, res.metrics
    assert replays_exactly(res.rollout)
    est = res.metrics["estimation"]
    assert est["estimator"] == "ekf" and res.metrics["rig"]["delay"] == pytest.approx(0.005)
    assert all(np.isfinite(v) for v in est["rms_error"].values())
    assert np.all(res.rollout.x_hat[0, res.rollout.nq:] == 0.0)  # started from the measurement, not the truth


def test_nmpc_with_mhe_swings_up_from_noisy_encoders():
    loop = LoopOptions(period=0.01, delay=0.005, estimator="mhe", sensor_noise=0.001, **ENCODERS)
    res = run_swingup(None, "mpc", SwingupOptions(loop=loop))
    assert res.success, res.metrics
    assert replays_exactly(res.rollout)
    assert res.metrics["estimation"]["estimator"] == "mhe"
    assert res.metrics["estimation"]["rms_error"]["hinge"] < 0.05


def test_energy_swingup_on_the_rig_catches_on_the_estimate():
    res = run_swingup(None, "energy", SwingupOptions(loop=LoopOptions(period=0.01, delay=0.01, **ENCODERS)))
    assert res.success and replays_exactly(res.rollout)
    assert res.metrics["rig"]["estimator"] == "ekf"  # the default with sensors for a swing-up


FRICTION_MJCF = SHIPPED_MJCF.parent / "examples" / "cartpole_friction.xml"


@pytest.mark.parametrize("compensation", [True, False], ids=["compensated", "not_compensated"])
def test_trajopt_tvlqr_swings_up_the_cart_with_dry_friction(compensation):
    """0.5 N on the slider and 0.002 N m on the hinge, MuJoCo's friction constraint: planned on the smooth model
    (without the slider's friction when a feedforward cancels it), the swing-up and its hold succeed either way."""
    res = run_swingup(FRICTION_MJCF, "trajopt",
                      SwingupOptions(loop=LoopOptions(friction_compensation=compensation)))
    assert res.success, res.metrics
    assert replays_exactly(res.rollout)
    assert res.metrics["friction"] == {"frictionloss": {"slider": 0.5, "hinge": 0.002}, "compensation": compensation}
    assert hasattr(res.controller, "feedforward") == compensation  # the compensation wraps the controller that ran


def test_trajopt_tvlqr_through_the_ekf_on_the_cart_with_friction_and_its_compensation():
    """The EKF predicts through the smooth friction with the ctrl MuJoCo applied (the compensation included), so the
    compensated swing-up from encoders holds; an estimator on the compensated design model would see the
    compensation as a force the model lacks."""
    loop = LoopOptions(period=0.01, delay=0.005, estimator="ekf", process_noise=0.1, **ENCODERS)
    res = run_swingup(FRICTION_MJCF, "trajopt", SwingupOptions(loop=loop))
    assert res.success, res.metrics
    assert replays_exactly(res.rollout)
    assert res.metrics["friction"]["compensation"]
    assert res.metrics["estimation"]["rms_error"]["hinge"] < 0.002
