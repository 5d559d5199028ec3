"""Sensors: the spec read from the MJCF (or an encoder per joint), its overrides and one-sentence refusals, the
measurement covariance, and the seeded sampler against MuJoCo's own sensordata and the exact measurement model."""
from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cartpole.estimation import (
    EstimationError,
    SensorError,
    SensorSampler,
    SensorSpec,
    measurement_function,
    sensor_spec,
)
from cartpole.estimation.sensors import Sensor
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.validation.jacobians import random_states

SITES = '<site name="tip" pos="0.01 0.02 0.6" quat="0.9 0.1 0.3 0.2"/>'


def with_sensors(sensors: str, *, flags: str = "") -> str:
    """The shipped cart-pole's text with a site at the pole's tip and ``sensors`` as its <sensor> block."""
    text = Path(SHIPPED_MJCF).read_text()
    text = text.replace('mass="0.1"/>', f'mass="0.1"/>\n        {SITES}', 1)
    text = text.replace('<flag contact="disable"/>', f'<flag contact="disable" {flags}/>')
    return text.replace("</mujoco>", f"<sensor>\n{sensors}\n</sensor>\n</mujoco>")


MIXED = with_sensors("""
  <jointpos name="x" joint="slider" noise="0.002"/>
  <jointpos name="th" joint="hinge" noise="0.001"/>
  <gyro name="gyro" site="tip" noise="0.05"/>
  <accelerometer name="acc" site="tip" noise="0.1"/>
  <actuatorfrc name="f" actuator="motor"/>""")


@pytest.fixture(scope="module")
def mixed():
    params = read_params(xml=MIXED)
    return params, build_model(params)


def test_default_spec_is_one_encoder_per_joint_with_positions_only():
    params = read_params(SHIPPED_MJCF)
    spec = sensor_spec(params)
    assert spec.names == tuple(f"{n}_encoder" for n in params.joint_names)
    assert spec.units == tuple("m" if j.kind == "slide" else "rad" for j in params.joints)
    assert [s.target for s in spec.sensors] == list(range(params.nq))
    assert spec.position_only and not spec.measures_rates
    assert np.all(spec.noise_std == 0) and np.all(spec.resolution == 0) and np.all(spec.bias == 0)
    assert np.all(spec.measurement_covariance() == 0)


def test_encoder_cpr_and_resolution_set_the_quanta_and_the_covariance_counts_them_as_uniform():
    params = read_params(SHIPPED_MJCF)
    spec = sensor_spec(params, encoder_cpr=2048, encoder_resolution=1e-4, noise_std=0.003)
    expect = np.array([1e-4 if j.kind == "slide" else 2 * np.pi / 2048 for j in params.joints])
    np.testing.assert_array_equal(spec.resolution, expect)
    np.testing.assert_allclose(spec.measurement_covariance(), np.diag(0.003**2 + expect**2 / 12), rtol=1e-15)
    # a uniform error on [-res/2, res/2] has variance res^2 / 12
    e = np.random.default_rng(0).uniform(-0.5, 0.5, 200_000)
    assert abs(e.var() - 1 / 12) < 2e-3


def test_mjcf_sensors_are_read_with_mujocos_noise_addresses_units_and_names(mixed):
    params, _ = mixed
    m = mujoco.MjModel.from_xml_string(MIXED)
    spec = sensor_spec(params)
    assert spec.names == ("x", "th", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z", "f")
    assert spec.ny == m.nsensordata
    assert [s.adr for s in spec.sensors] == list(m.sensor_adr)
    np.testing.assert_array_equal(spec.noise_std, np.repeat(m.sensor_noise, m.sensor_dim))
    assert spec.units == ("m", "rad") + ("rad/s",) * 3 + ("m/s^2",) * 3 + ("20 N",)
    assert spec.measures_rates and not spec.position_only


def test_noise_and_bias_override_by_one_number_or_by_sensor_name(mixed):
    params, _ = mixed
    spec = sensor_spec(params, noise_std={"gyro": 0.2}, bias=0.5)
    assert spec.noise_std.tolist() == [0.002, 0.001, 0.2, 0.2, 0.2, 0.1, 0.1, 0.1, 0.0]
    assert np.all(spec.bias == 0.5)
    spec = sensor_spec(params, noise_std=0.0, bias={"x": -0.01})
    assert np.all(spec.noise_std == 0) and spec.bias.tolist() == [-0.01] + [0.0] * 8


def test_to_dict_is_json_and_the_arrays_are_read_only(mixed):
    params, _ = mixed
    spec = sensor_spec(params, encoder_cpr=1000)
    doc = json.loads(json.dumps(spec.to_dict()))
    assert doc["ny"] == spec.ny and doc["names"] == list(spec.names) and doc["units"] == list(spec.units)
    assert doc["resolution"][1] == pytest.approx(2 * np.pi / 1000) and doc["position_only"] is False
    assert doc["sensors"][2]["frame"]["objtype"] == "site"
    for arr in (spec.noise_std, spec.resolution, spec.bias, spec.measurement_covariance()):
        with pytest.raises(ValueError):
            arr[0] = 1.0


def _one_sentence(exc: BaseException) -> str:
    msg = str(exc)
    assert "\n" not in msg and msg.endswith(".") and msg[0].isupper(), msg
    return msg


@pytest.mark.parametrize("sensor, name, kind", [
    ('<touch name="pad" site="tip"/>', "pad", "touch"),
    ('<rangefinder name="lidar" site="tip"/>', "lidar", "rangefinder"),
    ('<user name="mine" dim="1" needstage="pos" datatype="real"/>', "mine", "user"),
    ('<force name="load" site="tip"/>', "load", "force"),
    ('<framequat name="att" objtype="site" objname="tip"/>', "att", "framequat"),
    ('<framepos name="cam" objtype="camera" objname="track"/>', "cam", "camera"),
    ('<jointpos name="late" joint="slider" delay="0.01" nsample="3"/>', "late", "delay"),
])
def test_sensors_that_cannot_be_modelled_exactly_are_refused_in_one_sentence(sensor, name, kind):
    with pytest.raises(SensorError) as info:
        sensor_spec(read_params(xml=with_sensors(sensor)))
    msg = _one_sentence(info.value)
    assert f"'{name}'" in msg and kind in msg
    assert isinstance(info.value, EstimationError)


def test_a_model_with_sensors_disabled_is_refused():
    with pytest.raises(SensorError) as info:
        sensor_spec(read_params(xml=with_sensors('<jointpos joint="slider"/>', flags='sensor="disable"')))
    assert "disables sensors" in _one_sentence(info.value)


@pytest.mark.parametrize("kwargs, words", [
    ({"noise_std": -0.1}, "noise"), ({"noise_std": math.nan}, "noise"), ({"noise_std": {"slider_encoder": "a"}},
                                                                          "noise"),
    ({"noise_std": {"nope": 0.1}}, "'nope'"), ({"bias": math.inf}, "bias"), ({"bias": {"nope": 1}}, "'nope'"),
    ({"encoder_cpr": 0}, "whole number"), ({"encoder_cpr": 2.5}, "whole number"), ({"encoder_cpr": True},
                                                                                    "whole number"),
    ({"encoder_cpr": "2048"}, "whole number"), ({"encoder_cpr": math.inf}, "whole number"),
    ({"encoder_resolution": 0.0}, "resolution"), ({"encoder_resolution": -1e-3}, "resolution"),
    ({"encoder_resolution": math.nan}, "resolution"), ({"encoder_resolution": "fine"}, "resolution"),
])
def test_bad_settings_are_refused_in_one_sentence(kwargs, words):
    with pytest.raises(SensorError) as info:
        sensor_spec(SHIPPED_MJCF, **kwargs)
    assert words in _one_sentence(info.value)


def test_a_whole_float_cpr_is_accepted_and_a_hand_built_sensor_is_validated():
    assert sensor_spec(SHIPPED_MJCF, encoder_cpr=4096.0).resolution[1] == pytest.approx(2 * np.pi / 4096)
    with pytest.raises(SensorError):
        Sensor(name="s", kind="jointpos", target=0, dim=1, noise_std=-1.0)
    with pytest.raises(SensorError):
        Sensor(name="s", kind="framepos", target=0, dim=1)


def _set(m, d, x, u):
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:m.nq], x[m.nq:], u
    mujoco.mj_forward(m, d)


def test_sampler_without_noise_equals_the_measurement_function_and_mujocos_sensordata(mixed):
    params, model = mixed
    spec = sensor_spec(params, noise_std=0.0)
    h = measurement_function(model, spec)
    m = mujoco.MjModel.from_xml_string(MIXED)
    d = mujoco.MjData(m)
    sampler = SensorSampler(spec, m, seed=3)
    X, U = random_states(params, 30, seed=4)
    for x, u in zip(X, U):
        _set(m, d, x, u)
        y = sampler(d)
        np.testing.assert_array_equal(y, d.sensordata)
        np.testing.assert_allclose(y, np.asarray(h(x, u)).ravel(), rtol=0, atol=1e-9)


def test_default_encoders_read_qpos_without_mj_forward():
    params = read_params(SHIPPED_MJCF)
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    d = mujoco.MjData(m)
    d.qpos[:] = [0.3, 2.0]
    y = SensorSampler(sensor_spec(params), m)(d)
    np.testing.assert_array_equal(y, d.qpos)


def test_quantised_samples_are_multiples_of_the_quantum_within_half_of_it():
    params = read_params(SHIPPED_MJCF)
    spec = sensor_spec(params, encoder_cpr=500, encoder_resolution=2e-3)
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    d = mujoco.MjData(m)
    sampler = SensorSampler(spec, m)
    res = spec.resolution
    X, _ = random_states(params, 200, seed=5)
    for x in X:
        d.qpos[:] = x[:m.nq]
        y = sampler(d)
        assert np.all(np.abs(y - d.qpos) <= res / 2 + 1e-15)
        np.testing.assert_allclose(y / res, np.round(y / res), rtol=0, atol=1e-9)


def test_noise_has_the_specified_std_bias_shifts_the_mean_and_the_seed_reproduces_the_draws(mixed):
    params, _ = mixed
    spec = sensor_spec(params, bias={"x": 0.05, "gyro": -0.2})
    m = mujoco.MjModel.from_xml_string(MIXED)
    d = mujoco.MjData(m)
    X, U = random_states(params, 1, seed=6)
    _set(m, d, X[0], U[0])
    sampler = SensorSampler(spec, m, seed=11)
    Y = np.array([sampler(d) for _ in range(20_000)])
    noisy = spec.noise_std > 0
    np.testing.assert_allclose(Y.std(axis=0)[noisy], spec.noise_std[noisy], rtol=0.03)
    np.testing.assert_allclose(Y.mean(axis=0), sampler.clean(d) + spec.bias, rtol=0, atol=4 * spec.noise_std.max()
                               / np.sqrt(len(Y)) + 1e-12)
    np.testing.assert_array_equal(Y[:, ~noisy], np.broadcast_to((sampler.clean(d) + spec.bias)[~noisy],
                                                                (len(Y), int((~noisy).sum()))))
    again = SensorSampler(spec, m, seed=11)
    np.testing.assert_array_equal(np.array([again(d) for _ in range(50)]), Y[:50])
    other = SensorSampler(spec, m, seed=12)
    assert not np.array_equal(other(d), Y[0])


def test_sampler_refuses_a_spec_from_another_model(mixed):
    params, _ = mixed
    spec = sensor_spec(params)
    with pytest.raises(SensorError) as info:
        SensorSampler(spec, mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF)))
    _one_sentence(info.value)


def test_a_hand_built_spec_has_the_per_entry_arrays_of_its_sensors():
    spec = SensorSpec(sensors=(Sensor("a", "jointpos", 0, 1, noise_std=0.1, units="m"),
                               Sensor("b", "framepos", 1, 3, resolution=0.01, bias=2.0, units="m")))
    assert spec.ny == 4 and spec.names == ("a", "b_x", "b_y", "b_z")
    assert spec.noise_std.tolist() == [0.1, 0, 0, 0] and spec.bias.tolist() == [0, 2, 2, 2]
    np.testing.assert_allclose(np.diag(spec.measurement_covariance()), [0.01] + [1e-4 / 12] * 3)
