"""Swing-ups whose catch respects the sensors (issue 41, deliverable 5): from 2048-count encoders through the EKF, the
catch and the estimator are designed so that the ctrl noise the quantisation causes in the hold stays below a
fraction of the ctrl range (:func:`cartpole.apps.margins.noise_limited_catch`), predicted from the loop and measured
in MuJoCo; the runs replay exactly from their logged ctrl."""
import re

import numpy as np
import pytest

from cartpole.analysis import AnalysisError, loop_margins, sampled_loop
from cartpole.apps.margins import PROCESS_NOISE_LADDER, noise_limited_catch
from cartpole.apps.swingup import DEFAULT_CTRL_NOISE, SwingupOptions, run_swingup
from cartpole.riccati import default_weights
from cartpole.models import SHIPPED_MJCF, build_model, read_params, steps_per_period
from cartpole.planning.trajopt import handover_catch
from cartpole.sim import LoopOptions, replays_exactly, simulate
from cartpole.sim.rig import build_rig, delay_steps, estimator_factory
from cartpole.validation.metrics import (REST_RATE_TOL, REST_SPEED_TOL, held_upright, pole_angle_errors,
                                         rest_tolerance, swingup_success)

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


def test_ekf_swingup_of_the_three_pole_cart_from_encoders_holds_at_rest_to_its_sensors_with_a_quiet_ctrl_as_predicted():
    """The issue's test on the three-pole cart: success, the ctrl's standard deviation over the last 4 s below a
    tenth of the range (it was half of it), the prediction beside it and within a factor of two. At rest means at
    rest to the rig's sensors (:func:`cartpole.validation.metrics.rest_tolerance`): the motion left in the hold is what
    the encoders' quantisation drives through the loop, the predicted state noise beside MuJoCo's, and it is not at
    rest by the exact-state bounds of 0.1 rad/s and 0.1 m/s, which no catch reaches from 2048 counts (next tests)."""
    res, measured, model = _quiet_hold(THREE)
    span = model.u_high - model.u_low
    assert res.success, res.metrics
    assert np.all(measured < 0.1 * span)
    cn = res.metrics["ctrl_noise"]
    ratio = np.asarray(cn["measured_fraction"]) / cn["predicted_fraction"]
    assert np.all((0.5 < ratio) & (ratio < 2.0))
    rates = [model.nq + j for j in range(model.nq)]  # cart speed and hinge rates
    predicted = np.asarray(cn["predicted_state_std"])[rates]
    measured_rates = np.asarray(cn["measured_state_std"])[rates]
    assert np.all((0.7 < measured_rates / predicted) & (measured_rates / predicted < 2.5))
    rig = build_rig(model, LoopOptions(**RIG), task="swingup")
    assert res.metrics["rest_tolerance"] == pytest.approx(rest_tolerance(model, rig).tolist())
    assert swingup_success(res.rollout, model, rig=rig) and not swingup_success(res.rollout, model)
    x, t = res.rollout.x, res.rollout.t
    assert np.abs(x[t >= t[-1] - 1.0][:, rates]).max() > max(REST_RATE_TOL, REST_SPEED_TOL)


def _three_pole_catch_hold(tmp_path, gear_factor):
    """The three-pole swing-up's catch as it is designed for the issue's rig (R and process noise from
    :func:`noise_limited_catch`), holding from a 5 mrad tilt for 10 s on MuJoCo with the motor's gear scaled by
    ``gear_factor`` (the estimator and the catch still believe the MJCF's): ``(run, rig, model, upper gain margin
    predicted for the loop with the rig's Kalman filter)``."""
    params = read_params(THREE)
    model = build_model(params)
    loop = LoopOptions(**RIG)
    steps = steps_per_period(loop.period, params.timestep)
    found = noise_limited_catch(model, loop, DEFAULT_CTRL_NOISE, _catch_gain(params, model, loop),
                                default_weights(model)[1])
    loop = loop.replace(process_noise=found["process_noise"])
    catch = handover_catch(params, model, None, found["R"], steps=steps)
    kf = estimator_factory(model, loop, "kf", steps)[1]()
    lqg = sampled_loop(model, catch.K, steps=steps, delay_steps=delay_steps(loop.delay, model.dt), compensate=True,
                       kalman=kf, x=model.x_eq)
    upper = loop_margins(lqg).gain_margin[1]
    text = THREE.read_text()
    plant = tmp_path / f"three_pole_gear_{gear_factor:g}.xml"
    stronger = lambda m: f'gear="{float(m.group(1)) * float(gear_factor):.12g}"'  # noqa: E731
    plant.write_text(re.sub(r'gear="([0-9.eE+-]+)"', stronger, text))
    x0 = np.array(model.x_eq, float)
    x0[list(model.hinges)] += 0.005
    rig = build_rig(model, loop, task="swingup")
    return simulate(plant, catch, x0, 10.0, rig=rig), rig, model, upper


def test_the_sensed_rest_still_fails_the_same_catch_limit_cycling_past_its_gain_margin(tmp_path):
    """The counter-example: the same catch on the same rig, its motor 2 % stronger than the upper gain margin the
    loop predicts (LQG's, through the Kalman filter), grows into an oscillation. Its fastest rate passes the sensors'
    bound in the last second and is still growing, so the rest test fails, while the nominal motor's hold, whose
    motion is the quantisation's, passes it. (How far past the bound the 10 s run gets turns on round-off, the
    growth being slow 2 % past the margin: twice over on one machine, 1.65 times on an AVX-512 one, from 1.14 at
    2-3 s.)"""
    nominal, rig, model, upper = _three_pole_catch_hold(tmp_path, 1.0)
    assert 1.0 < upper < 2.0
    layout = dict(x_eq=model.x_eq, hinges=model.hinges, slide=model.slide)
    tol = rest_tolerance(model, rig)
    assert held_upright(nominal, tolerance=tol, **layout) and not held_upright(nominal, **layout)
    cycling, _, _, _ = _three_pole_catch_hold(tmp_path, 1.02 * upper)
    assert not cycling.info.get("diverged")
    assert not held_upright(cycling, tolerance=tol, **layout)
    hinges = list(model.hinges)

    def fastest(run, start, end):  # the largest hinge rate over [start, end) s, in units of its bound
        w = (run.t >= start) & (run.t < end)
        return np.max(np.abs(run.qvel[w][:, hinges]).max(axis=0) / tol[hinges])
    end = cycling.t[-1]
    assert fastest(cycling, end - 1.0, end + 1.0) > 1.0 >= fastest(nominal, end - 1.0, end + 1.0)
    assert fastest(cycling, end - 1.0, end + 1.0) > 1.2 * fastest(cycling, 2.0, 4.0)  # growing, not a noise burst
    assert np.abs(pole_angle_errors(cycling.x[cycling.t >= end - 1.0], x_eq=model.x_eq, hinges=model.hinges)).max() < 0.5  # not fallen


def _rest_floor(model, params, cpr, R_factors=(1.0, 16.0, 256.0)):
    """The smallest predicted standard deviation of the cart speed and hinge rates in the hold (the largest of
    them) over the catch's R and the estimator's process noise that the design searches, from ``cpr``-count hinge
    encoders at the issue's rig."""
    loop = LoopOptions(**{**RIG, "encoder_cpr": cpr})
    gain, R = _catch_gain(params, model, loop), default_weights(model)[1]
    rates = [model.nq + j for j in range(model.nq)]
    floor = np.inf
    for factor in R_factors:
        for noise in PROCESS_NOISE_LADDER:
            found = noise_limited_catch(model, loop.replace(process_noise=noise), 0.99, gain, R * factor)
            floor = min(floor, float(np.max(found["predicted_state_std"][rates])))
    return floor


def test_the_three_pole_rest_noise_from_2048_counts_is_the_encoders_floor_not_the_designs():
    """Over the catch's R (x1 to x256) and every process noise the design tries, the sensor-driven standard deviation
    of the three-pole cart's rates in the hold stays at or above half the rest tolerance from 2048-count encoders (so
    a second's peak, 2-3 standard deviations, passes 0.1), and so it does for the minimum-variance LQG; it scales
    with the count (q^2/12 is the only noise), and 16 times finer encoders put it far below."""
    params = read_params(THREE)
    model = build_model(params)
    coarse = _rest_floor(model, params, 2048)
    assert coarse >= 0.5 * REST_RATE_TOL
    # the minimum-variance choice: an LQG weighting only the rates, its filter told of almost no process noise
    loop = LoopOptions(**{**RIG, "process_noise": 0.001})
    rates = [model.nq + j for j in range(model.nq)]
    Q = np.diag([1e-3] * model.nq + [1.0] * model.nq)
    steps = steps_per_period(loop.period, params.timestep)
    quiet = noise_limited_catch(model, loop, 0.99, lambda R: handover_catch(params, model, Q, R, steps=steps).K,
                                0.01 * np.eye(model.nu))
    assert np.max(quiet["predicted_state_std"][rates]) >= 0.5 * REST_RATE_TOL
    assert _rest_floor(model, params, 32768, R_factors=(16.0,)) < 0.1 * coarse


def test_the_default_process_noise_is_lowered_before_the_catch_is_weakened(two_pole):
    """On the two-pole cart the estimator's default process noise alone puts 18 % of the range on the ctrl; the
    design lowers it (the model is MuJoCo's own integrator) and keeps the catch's R where that is enough."""
    params, model = two_pole
    loop = LoopOptions(**RIG)
    gain = _catch_gain(params, model, loop)
    R = default_weights(model)[1]
    loud = noise_limited_catch(model, loop, 0.99, gain, R)
    assert loud["process_noise"] is None and loud["factor"] == 1.0
    quiet = noise_limited_catch(model, loop, 0.02, gain, R)
    assert quiet["met"] and quiet["process_noise"] is not None
    assert np.max(quiet["predicted_fraction"]) <= 0.02 < np.max(loud["predicted_fraction"])


def test_a_process_noise_given_is_kept_and_the_catch_R_raised_instead(two_pole):
    params, model = two_pole
    loop = LoopOptions(process_noise=3.0, **RIG)
    found = noise_limited_catch(model, loop, 0.1, _catch_gain(params, model, loop), default_weights(model)[1])
    assert found["process_noise"] == 3.0 and found["factor"] > 1 and found["met"]
    assert np.all(found["R"] == found["factor"] * default_weights(model)[1])


def test_a_limit_no_design_reaches_is_an_error_when_asked_and_the_quietest_design_otherwise(two_pole):
    params, model = two_pole
    loop = LoopOptions(**RIG)
    gain, R = _catch_gain(params, model, loop), default_weights(model)[1]
    with pytest.raises(AnalysisError, match="`ctrl_noise`"):
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


def test_the_supervisor_catch_is_designed_for_its_sensors_when_asked():
    """The supervisor's catch takes ``--ctrl-noise`` as the energy and trajopt catches do: on the one-pole cart from
    2048-count encoders through the EKF it swings up, holds, and its ctrl noise in the hold is the design's, the
    prediction beside the measured figure."""
    res = run_swingup(SHIPPED_MJCF, "supervisor",
                      SwingupOptions(ctrl_noise=DEFAULT_CTRL_NOISE, loop=LoopOptions(duration=8.0, **RIG)))
    assert replays_exactly(res.rollout)
    assert res.success, res.metrics
    cn = res.metrics["ctrl_noise"]
    assert not cn["default"] and cn["met"] and cn["measured_window_s"] == pytest.approx(4.0)
    assert np.all(np.asarray(cn["predicted_fraction"]) <= DEFAULT_CTRL_NOISE)
    assert np.all(np.asarray(cn["measured_fraction"]) < 0.1)
    ratio = np.asarray(cn["measured_fraction"]) / cn["predicted_fraction"]
    assert np.all((0.5 < ratio) & (ratio < 2.0))
