"""The measurement model h(x, u) equals MuJoCo's sensordata after mj_forward, for every supported sensor kind, on
MJCFs written here (the shipped one- and two-pole carts, a chain with every modelled feature, a motor on a hinge,
gravity disabled); the first state from the first measurement recovers the measured positions and keeps the rest."""
from __future__ import annotations

import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
from chains import CHAINS

from cartpole.estimation import (
    KINDS,
    SensorError,
    initial_state,
    measurement_function,
    sensor_spec,
)
from cartpole.models import SHIPPED_MJCF, build_model, read_params, wrap_angle
from cartpole.validation.jacobians import random_states

SHIPPED_TWO = SHIPPED_MJCF.parent / "cartpole_two_pole.xml"


def instrumented(text: str, sensors: str, sites: dict[str, str]) -> str:
    """``text`` with ``<site>`` lines added to bodies (``{body name: sites}``, "world" for the worldbody) and
    ``sensors`` as its <sensor> block."""
    for body, lines in sites.items():
        pattern = r"(<worldbody>)" if body == "world" else rf'(<body name="{body}"[^>]*>)'
        text, n = re.subn(pattern, rf"\1\n{lines}", text, count=1)
        assert n == 1, body
    return text.replace("</mujoco>", f"<sensor>\n{sensors}\n</sensor>\n</mujoco>")


def frame_sensors(tip: str, mid: str, body: str, parent: str) -> str:
    """Every frame and site sensor kind on the site ``tip``, with references ``mid`` (a site), ``parent`` (a body)."""
    return f"""
  <accelerometer name="acc" site="{tip}"/>
  <gyro name="gyro" site="{tip}"/>
  <velocimeter name="vel" site="{tip}"/>
  <framepos name="com" objtype="body" objname="{body}"/>
  <framepos name="origin" objtype="xbody" objname="{body}"/>
  <framepos name="tip_in_mid" objtype="site" objname="{tip}" reftype="site" refname="{mid}"/>
  <framepos name="tip_in_parent" objtype="site" objname="{tip}" reftype="xbody" refname="{parent}"/>
  <framexaxis name="xaxis" objtype="site" objname="{tip}"/>
  <frameyaxis name="yaxis" objtype="body" objname="{body}" reftype="site" refname="{mid}"/>
  <framezaxis name="zaxis" objtype="site" objname="{tip}" reftype="body" refname="{parent}"/>
  <framelinvel name="linvel" objtype="site" objname="{tip}"/>
  <framelinvel name="linvel_mid" objtype="site" objname="{tip}" reftype="site" refname="{mid}"/>
  <frameangvel name="angvel" objtype="site" objname="{tip}"/>
  <frameangvel name="angvel_parent" objtype="site" objname="{tip}" reftype="xbody" refname="{parent}"/>
  <framelinacc name="linacc" objtype="site" objname="{tip}"/>
  <frameangacc name="angacc" objtype="site" objname="{tip}"/>
  <framepos name="fixed_in_tip" objtype="site" objname="fixed" reftype="site" refname="{tip}"/>"""


TIP = '<site name="tip" pos="0.01 0.02 0.6" quat="0.9 0.1 0.3 0.2"/>\n<site name="mid" pos="0 0.01 0.3" euler="0.3 0 0.2"/>'
FIXED = '<site name="fixed" pos="0.3 -0.2 1.1" quat="0.7 0.2 -0.1 0.4"/>'

CASES = {
    "one_pole": instrumented(Path(SHIPPED_MJCF).read_text(), """
  <jointpos name="x" joint="slider"/>
  <jointpos name="th" joint="hinge" cutoff="1.0"/>
  <jointvel name="xd" joint="slider" noise="0.01"/>
  <jointvel name="thd" joint="hinge" cutoff="4"/>
  <actuatorfrc name="force" actuator="motor"/>
  <jointactuatorfrc name="cart_force" joint="slider"/>
  <jointactuatorfrc name="hinge_force" joint="hinge"/>
  <framepos name="geom" objtype="geom" objname="pole_geom" reftype="site" refname="fixed"/>
  <accelerometer name="clipped" site="tip" cutoff="3"/>""" + frame_sensors("tip", "mid", "pole", "cart"),
        {"pole": TIP, "world": FIXED}),
    "two_pole": instrumented(Path(SHIPPED_TWO).read_text(), """
  <jointpos joint="hinge2"/>
  <jointvel joint="hinge2"/>""" + frame_sensors("tip", "mid", "pole2", "pole"),
        {"pole2": TIP, "world": FIXED}),
    "everything_chain": instrumented(CHAINS["everything_RK4"], """
  <jointpos joint="elbow"/>
  <actuatorfrc actuator="push"/>""" + frame_sensors("tip", "mid", "link2", "link1"),
        {"link2": TIP, "world": FIXED}),
    "motor_on_a_hinge": instrumented(CHAINS["two_motors"], """
  <actuatorfrc name="wrist_force" actuator="wrist"/>
  <jointactuatorfrc name="wrist_joint" joint="hinge2"/>""" + frame_sensors("tip", "mid", "pole2", "pole"),
        {"pole2": TIP, "world": FIXED}),
    "no_gravity": instrumented(Path(SHIPPED_MJCF).read_text().replace('<flag contact="disable"/>',
                                                                      '<flag contact="disable" gravity="disable"/>'),
                               frame_sensors("tip", "mid", "pole", "cart"), {"pole": TIP, "world": FIXED}),
}


def _mujoco(text: str):
    m = mujoco.MjModel.from_xml_string(text)
    return m, mujoco.MjData(m)


def _sensordata(m, d, x, u) -> np.ndarray:
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:m.nq], x[m.nq:], u
    mujoco.mj_forward(m, d)
    return d.sensordata.copy()


def test_the_cases_cover_every_supported_kind():
    kinds = {s.kind for text in CASES.values() for s in sensor_spec(read_params(xml=text)).sensors}
    assert kinds == set(KINDS)


@pytest.mark.parametrize("case", sorted(CASES))
def test_measurement_function_equals_mujocos_sensordata(case):
    params = read_params(xml=CASES[case])
    model = build_model(params)
    spec = sensor_spec(params)
    h = measurement_function(model, spec)
    m, d = _mujoco(CASES[case])
    X, U = random_states(params, 40, seed=7)
    U = U * 1.5  # also outside the ctrl range: MuJoCo clips ctrl, and so does h
    worst = 0.0
    Y = []
    for x, u in zip(X, U):
        y = _sensordata(m, d, x, u)
        Y.append(y)
        worst = max(worst, float(np.max(np.abs(np.asarray(h(x, u)).ravel() - y))))
    assert worst < 1e-9, worst
    if case == "one_pole":  # the cutoffs bite at some of these states, and h clamps where MuJoCo does
        Y = np.array(Y)
        names = spec.names
        assert np.any(np.abs(Y[:, names.index("th")]) == 1.0)
        assert np.any(np.abs(Y[:, names.index("clipped_x"):names.index("clipped_z") + 1]) == 3.0)


def test_measurement_function_refuses_a_spec_from_another_model():
    spec = sensor_spec(read_params(xml=CASES["two_pole"]))
    with pytest.raises(SensorError):
        measurement_function(build_model(SHIPPED_MJCF), spec)


def _first_state(text, n=25, seed=8):
    params = read_params(xml=text)
    model = build_model(params)
    spec = sensor_spec(params)
    h = measurement_function(model, spec)
    X, U = random_states(params, n, seed=seed)
    return model, spec, [(x, initial_state(model, spec, np.asarray(h(x, u)).ravel())) for x, u in zip(X, U)]


def test_first_state_of_the_default_encoders_is_the_measurement_with_zero_rates():
    model = build_model(SHIPPED_MJCF)
    spec = sensor_spec(model, encoder_cpr=1024)
    y = np.array([0.1234, -2.5])
    np.testing.assert_array_equal(initial_state(model, spec, y), np.concatenate([y, np.zeros(model.nq)]))


def test_first_state_solves_a_hinge_from_the_tip_position_and_takes_the_cart_from_its_encoder():
    text = instrumented(Path(SHIPPED_MJCF).read_text(), """
  <jointpos name="x" joint="slider"/>
  <jointvel name="xd" joint="slider"/>
  <framepos name="tip" objtype="site" objname="tip"/>""", {"pole": TIP})
    model, _, pairs = _first_state(text)
    for x, x0 in pairs:
        assert x0[0] == x[0]
        assert abs(wrap_angle(x0[1] - x[1])) < 1e-8
        assert np.all(x0[model.nq:] == 0)


def test_first_state_solves_every_joint_of_the_two_pole_cart_from_frame_sensors_alone():
    text = instrumented(Path(SHIPPED_TWO).read_text(), """
  <framepos name="cart" objtype="xbody" objname="cart"/>
  <framepos name="tip1" objtype="site" objname="tip1"/>
  <framezaxis name="up2" objtype="body" objname="pole2"/>
  <gyro name="gyro" site="tip1"/>""", {"pole": '<site name="tip1" pos="0 0 0.6"/>'})
    model, _, pairs = _first_state(text)
    for x, x0 in pairs:
        err = wrap_angle(x0[:model.nq] - x[:model.nq])
        err[model.slide] = x0[model.slide] - x[model.slide]
        assert np.max(np.abs(err)) < 1e-8, (x, x0)
        assert np.all(x0[model.nq:] == 0)


def test_a_joint_no_position_sensor_sees_keeps_its_hanging_value():
    text = instrumented(Path(SHIPPED_MJCF).read_text(), """
  <jointpos name="x" joint="slider"/>
  <gyro name="gyro" site="tip"/>
  <accelerometer name="acc" site="tip"/>""", {"pole": TIP})
    model, _, pairs = _first_state(text, n=5)
    for x, x0 in pairs:
        assert x0[0] == x[0] and x0[1] == model.x_hanging[1] and np.all(x0[model.nq:] == 0)


def test_first_state_refuses_a_measurement_of_the_wrong_size():
    model = build_model(SHIPPED_MJCF)
    with pytest.raises(SensorError):
        initial_state(model, sensor_spec(model), np.zeros(3))
