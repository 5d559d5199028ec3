"""Swing-ups whose catch respects the sensors (issue 41, deliverable 5): from 2048-count encoders through the EKF, the
catch and the estimator are designed so that the ctrl noise the quantisation causes in the hold stays below a
fraction of the ctrl range (:func:`cartpole.apps.margins.noise_limited_catch`), predicted from the loop and measured
in MuJoCo; the runs replay exactly from their logged ctrl."""
import numpy as np
import pytest

from cartpole.analysis import AnalysisError
from cartpole.apps.margins import noise_limited_catch
from cartpole.apps.swingup import DEFAULT_CTRL_NOISE, SwingupOptions, run_swingup
from cartpole.riccati import lab_weights
from cartpole.models import SHIPPED_MJCF, build_model, read_params, steps_per_period
from cartpole.planning.trajopt import handover_catch
from cartpole.sim import LoopOptions, replays_exactly
from cartpole.validation.metrics import UPRIGHT_TOL, pole_angle_errors

RIG = dict(period=0.01, delay=0.01, estimator="ekf", encoder_cpr=2048)
TWO = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
THREE = SHIPPED_MJCF.with_name("cartpole_three_pole.xml")


def _catch_gain(params, model, loop):
    steps = steps_per_period(loop.period, params.timestep)
    return lambda R: handover_catch(params, model, None, R, steps=steps).K


@pytest.fixture(scope="module")
def two_pole():
    params = read_params(TWO)
    return params, build_model(params)


#: s: long enough for a 4 s hold after either cart's plan (two poles 2.05 s, three poles 2.76 s); the JSON's
#: measured_window_s says when a plan grows past it.
DURATION = 7.0


def _quiet_hold(mjcf):
    """The issue's run (period and delay one 10 ms step, 2048-count hinge encoders, the EKF): the result, the ctrl's
    standard deviation over the last 4 s and the model."""
    res = run_swingup(mjcf, "trajopt", SwingupOptions(loop=LoopOptions(duration=DURATION, **RIG)))
    assert replays_exactly(res.rollout)
    cn = res.metrics["ctrl_noise"]
    assert cn["default"] and cn["met"] and cn["fraction"] == DEFAULT_CTRL_NOISE
    assert cn["measured_window_s"] == pytest.approx(4.0)
    model = build_model(read_params(mjcf))
    span = model.u_high - model.u_low
    t, u = res.rollout.t, res.rollout.ctrl
    measured = u[t[1:] > t[-1] - 4.0].std(axis=0)
    assert np.allclose(cn["measured_fraction"], measured / span)
    assert np.all(np.asarray(cn["predicted_fraction"]) <= DEFAULT_CTRL_NOISE)
    return res, measured, model


def test_ekf_swingup_of_the_two_pole_cart_from_encoders_holds_at_rest_with_a_quiet_ctrl_as_predicted():
    """The issue's test on the two-pole cart: success (upright and at rest), the ctrl's standard deviation over the
    last 4 s below a tenth of the range (the default design asks for 2 %), the prediction beside it and close to
    it (the linear loop at upright, the quantisation as white noise q^2/12)."""
    res, measured, model = _quiet_hold(TWO)
    span = model.u_high - model.u_low
    assert res.success, res.metrics
    assert np.all(measured < 0.1 * span)
    assert np.allclose(res.metrics["ctrl_noise"]["measured_fraction"],
                       res.metrics["ctrl_noise"]["predicted_fraction"], rtol=0.5)


def test_ekf_swingup_of_the_three_pole_cart_from_encoders_holds_upright_with_a_quiet_ctrl():
    """The three-pole cart: the catch holds every pole upright with the ctrl's standard deviation over the last 4 s
    well below a tenth of the range (it was half of it), within a factor of two of the prediction. Not at rest by
    the success test's 0.1 rad/s: one count of a 2048-count encoder (3.1 mrad) leaves a limit cycle of about
    0.2 rad/s in the hinge rates and 0.2 m/s on the cart whatever the design (docs/margins.md); finer encoders
    (32768 counts) bring it below."""
    res, measured, model = _quiet_hold(THREE)
    span = model.u_high - model.u_low
    assert np.all(measured < 0.1 * span)
    assert res.handover_at is not None and not res.metrics["diverged"]
    x, t = res.rollout.x, res.rollout.t
    errors = pole_angle_errors(x[t >= t[-1] - 4.0], x_eq=model.x_eq, hinges=list(model.hinges))
    assert np.all(np.abs(errors) < UPRIGHT_TOL)
    ratio = np.asarray(res.metrics["ctrl_noise"]["measured_fraction"]) / res.metrics["ctrl_noise"]["predicted_fraction"]
    assert np.all((0.5 < ratio) & (ratio < 2.0))


def test_the_default_process_noise_is_lowered_before_the_catch_is_weakened(two_pole):
    """On the two-pole cart the estimator's default process noise alone puts 18 % of the range on the ctrl; the
    design lowers it (the model is MuJoCo's own integrator) and keeps the catch's R where that is enough."""
    params, model = two_pole
    loop = LoopOptions(**RIG)
    gain = _catch_gain(params, model, loop)
    R = lab_weights(model)[1]
    loud = noise_limited_catch(model, loop, 0.99, gain, R)
    assert loud["process_noise"] is None and loud["factor"] == 1.0
    quiet = noise_limited_catch(model, loop, 0.02, gain, R)
    assert quiet["met"] and quiet["process_noise"] is not None
    assert np.max(quiet["predicted_fraction"]) <= 0.02 < np.max(loud["predicted_fraction"])


def test_a_process_noise_given_is_kept_and_the_catch_R_raised_instead(two_pole):
    params, model = two_pole
    loop = LoopOptions(process_noise=3.0, **RIG)
    found = noise_limited_catch(model, loop, 0.1, _catch_gain(params, model, loop), lab_weights(model)[1])
    assert found["process_noise"] == 3.0 and found["factor"] > 1 and found["met"]
    assert np.all(found["R"] == found["factor"] * lab_weights(model)[1])


def test_a_limit_no_design_reaches_is_an_error_when_asked_and_the_quietest_design_otherwise(two_pole):
    params, model = two_pole
    loop = LoopOptions(**RIG)
    gain, R = _catch_gain(params, model, loop), lab_weights(model)[1]
    with pytest.raises(AnalysisError, match="--ctrl-noise"):
        noise_limited_catch(model, loop, 1e-6, gain, R)
    best = noise_limited_catch(model, loop, 1e-6, gain, R, required=False)
    assert not best["met"] and np.max(best["predicted_fraction"]) < np.max(
        noise_limited_catch(model, loop, 0.99, gain, R)["predicted_fraction"])


@pytest.mark.parametrize("loop, words", [
    (LoopOptions(period=0.01), "needs sensors"),
    (LoopOptions(**RIG), "between 0 and 1"),
], ids=["no_sensors", "bad_fraction"])
def test_a_ctrl_noise_limit_needs_sensors_and_a_fraction_of_the_range(two_pole, loop, words):
    params, model = two_pole
    fraction = 0.1 if words == "needs sensors" else 1.5
    with pytest.raises(AnalysisError, match=words):
        noise_limited_catch(model, loop, fraction, _catch_gain(params, model, loop), 0.1)
