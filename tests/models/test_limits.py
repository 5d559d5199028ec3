"""cartpole.models.limits: a file without ctrlrange or with an unlimited rail is read as written, and a swing-up gets
one stated default bound (or the caller's u_max / cart_max); a default start just outside a joint range is moved
onto its edge."""
import numpy as np
import pytest

from cartpole.models import (SHIPPED_MJCF, LimitsError, START_SNAP, default_cart_max, default_u_max, motor_drive,
                             planning_limits, read_params, start_on_range)

LAB = SHIPPED_MJCF.read_text()


def lab(*, ctrlrange=True, rail='limited="true" range="-1.5 1.5"', hinge=""):
    """The shipped cart-pole's text with its ctrlrange, its slide's limits or its hinge's range changed."""
    xml = LAB if ctrlrange else LAB.replace(' ctrlrange="-1 1"', "")
    xml = xml.replace('limited="true" range="-1.5 1.5"', rail)
    if hinge:
        xml = xml.replace('<joint name="hinge" type="hinge" axis="0 1 0" damping="0.01"/>',
                          f'<joint name="hinge" type="hinge" axis="0 1 0" damping="0.01" {hinge}/>')
        xml = xml.replace('<mujoco model="cartpole">', '<mujoco model="cartpole">\n  <compiler angle="radian"/>')
    return read_params(xml=xml)


@pytest.mark.parametrize("rail", ['range="-inf inf" limited="false"', 'limited="false"', 'range="-inf inf"'])
def test_an_unlimited_rail_written_any_way_reads_as_unlimited(rail):
    p = lab(rail=rail)
    assert np.all(np.isinf(p.cart_range))


def test_a_file_without_ctrlrange_reads_unlimited_and_gets_the_stated_one_g_default():
    p = lab(ctrlrange=False)
    assert np.all(np.isinf(p.ctrl_range))
    q, lim = planning_limits(p)
    total = sum(b.mass for b in p.bodies)
    u = float(default_u_max(p)[0])
    assert u == pytest.approx(total * 9.80665 / p.gear, rel=1e-3)  # 1 g0 on everything the cart moves
    assert np.allclose(q.ctrl_range, [[-u, u]]) and lim.u_source == ("default",) and lim.defaulted
    assert np.array_equal(q.cart_range, p.cart_range) and lim.cart_source == "file"
    assert len(lim.notes) == 1 and f"{u:.4g}" in lim.notes[0] and "--u-max" in lim.notes[0]
    assert lim.to_dict()["u_high"] == [u] and lim.to_dict()["defaulted"] is True


def test_an_unlimited_rail_gets_three_chain_lengths():
    p = lab(rail='limited="false"')
    q, lim = planning_limits(p)
    L = 2 * p.pole_com_distance
    assert default_cart_max(p) == pytest.approx(3 * L, rel=1e-4)
    assert np.allclose(q.cart_range, [-3 * L, 3 * L], rtol=1e-4) and lim.cart_source == "default"
    assert np.array_equal(q.ctrl_range, p.ctrl_range) and lim.u_source == ("file",)
    assert any("--cart-max" in n for n in lim.notes)


def test_a_file_with_every_bound_is_planned_as_written():
    p = read_params()
    q, lim = planning_limits(p)
    assert q is p and not lim.defaulted and lim.notes == ()


def test_u_max_and_cart_max_replace_the_bounds_inside_the_files():
    p = read_params()
    q, lim = planning_limits(p, u_max=0.5, cart_max=1.0)
    assert np.allclose(q.ctrl_range, [[-0.5, 0.5]]) and np.allclose(q.cart_range, [-1.0, 1.0])
    assert lim.u_source == ("u_max",) and lim.cart_source == "cart_max" and not lim.defaulted
    free, _ = planning_limits(lab(ctrlrange=False, rail='limited="false"'), u_max=3.0, cart_max=5.0)
    assert np.allclose(free.ctrl_range, [[-3, 3]]) and np.allclose(free.cart_range, [-5, 5])


@pytest.mark.parametrize("kw, words", [
    ({"u_max": 2.0}, ["wider than", "ctrlrange", "`u_max` at most 1"]),
    ({"cart_max": 2.0}, ["wider than", "slide range", "`cart_max` at most 1.5"]),
    ({"u_max": -1.0}, ["not a positive", "`u_max`"]),
    ({"cart_max": float("nan")}, ["not a positive", "`cart_max`"]),
    ({"u_max": [1.0, 1.0]}, ["2 values", "1 actuator"]),
])
def test_a_bound_mujoco_would_not_honour_is_refused_naming_the_argument(kw, words):
    with pytest.raises(LimitsError) as info:
        planning_limits(read_params(), **kw)
    msg = str(info.value)
    assert msg.endswith(".") and "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_a_hinge_driven_pendulum_without_ctrlrange_gets_the_horizontal_holding_torque():
    xml = (SHIPPED_MJCF.parent / "dmc_pendulum.xml").read_text().replace(' ctrlrange="-1 1" ctrllimited="true"', "")
    p = read_params(xml=xml)
    q, lim = planning_limits(p)
    m, l, _ = p.carried_by(p.hinges[0])
    assert q.ctrl_range[0][1] == pytest.approx(m * 9.80665 * l / abs(p.actuators[0].gear), rel=1e-3)
    assert lim.cart_range is None and "horizontal" in lim.notes[0]
    with pytest.raises(LimitsError, match="no slide joint; drop it"):
        planning_limits(p, cart_max=1.0)


def test_a_default_start_a_hair_outside_a_hinge_range_is_moved_onto_its_edge():
    p = lab(hinge='limited="true" range="-3.14159 3.14159"')
    x, moves = start_on_range([0, np.pi, 0, 0], p)
    assert x[1] == pytest.approx(3.14159) and len(moves) == 1
    assert moves[0].joint == "hinge" and moves[0].before == np.pi and "--x0" in moves[0].sentence()
    far, none = start_on_range([0, np.pi, 0, 0], lab(hinge='limited="true" range="-3.04 3.04"'))
    assert far[1] == np.pi and none == ()  # 0.1 rad out: left for the start check to refuse
    inside, kept = start_on_range([0, 1.0, 0, 0], p)
    assert inside[1] == 1.0 and kept == ()
    assert START_SNAP == 1e-3


def test_a_motor_drive_is_the_driven_joint_the_gears_sign_and_the_ctrl_range():
    p = read_params()
    drive = motor_drive(p)
    assert drive.joint == p.actuated[0] == p.slide and drive.sign == 1.0 and drive.limited
    assert (drive.low, drive.high) == tuple(p.ctrl_range[0]) and (drive.mid, drive.half) == (0.0, 1.0)
    flipped = motor_drive(read_params(xml=LAB.replace('gear="20"', 'gear="-20"')), [[-0.4, 1.2]])
    assert flipped.sign == -1.0 and (flipped.low, flipped.high) == (-0.4, 1.2)
    assert flipped.mid == pytest.approx(0.4) and flipped.half == pytest.approx(0.8)
    unlimited = motor_drive(lab(ctrlrange=False))
    assert not unlimited.limited and np.isinf(unlimited.half)


@pytest.mark.parametrize("kw, words", [({"actuator": 1}, "`actuator`"), ({"u_limits": [-1.0, 0.0, 1.0]}, "`u_limits`")])
def test_a_motor_drive_of_an_actuator_or_range_the_model_lacks_is_refused_naming_the_argument(kw, words):
    with pytest.raises(LimitsError, match=words):
        motor_drive(read_params(), **kw)
