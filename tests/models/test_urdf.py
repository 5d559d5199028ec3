"""URDF cart-poles (cartpole.models.urdf): the motor a transmission (or the only prismatic joint) implies is added on
the right joint with the joint's effort as its ctrl range; the exact model agrees with MuJoCo's finite differences;
the quirks of Bullet, Isaac Gym, ROS and Drake files load; what cannot be decided is refused naming the option."""
import mujoco
import numpy as np
import pytest

from cartpole.models import (MJCFError, build_model, is_urdf, load_model, mujoco_model, read_params, urdf_session)
from cartpole.sim import make_mujoco
from cartpole.validation.jacobians import check_jacobians, random_states
from urdf_layouts import BULLET, DRAKE, ISAAC, LAYOUTS, ROS, write_layout


@pytest.fixture(params=sorted(LAYOUTS))
def layout(request, tmp_path):
    return request.param, write_layout(request.param, tmp_path)


def test_the_motor_drives_the_expected_joint_with_the_effort_as_its_ctrl_range(layout):
    name, path = layout
    _, joint, effort, source = LAYOUTS[name]
    p = read_params(path)
    assert p.nu == 1 and p.joint_names[p.actuators[0].joint] == joint
    assert p.joints[p.actuators[0].joint].kind == "slide"
    assert p.actuators[0].gear == 1.0  # ctrl is the cart's force in N
    np.testing.assert_array_equal(p.ctrl_range[0], [-effort, effort])
    added = p.urdf.actuators[0]
    assert added.joint == joint and added.source == source and added.unit == "N"
    assert p.mjcf == str(path) and p.urdf.path == str(path)
    m = make_mujoco(p)[0]  # MuJoCo runs the same motor (compiled from the params' MJCF text)
    assert m.nu == 1 and mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(m.actuator_trnid[0, 0])) == joint
    assert not any(m.jnt_actfrclimited)  # the effort clamp became the ctrl range


def test_the_exact_model_agrees_with_mujoco_finite_differences(layout):
    _, path = layout
    model = build_model(read_params(path))
    x, u = random_states(model.params, 6, seed=7)
    for discrete in (False, True):  # eps 1e-5: at 1e-6 the difference quotient of one step carries ~1e-6 round-off
        assert check_jacobians(model, x, u, discrete=discrete, eps=1e-5).worst < 1e-6


def test_mujoco_keeps_the_urdf_damping_friction_and_continuous_joints(tmp_path):
    text = BULLET.replace('velocity="5"/>', 'velocity="5"/>\n    <dynamics damping="0.3" friction="0.2"/>')
    path = tmp_path / "f.urdf"
    path.write_text(text)
    p = read_params(path)
    s, h = p.slide, p.hinges[0]
    assert p.joints[s].damping == 0.3 and p.joints[s].frictionloss == 0.2
    np.testing.assert_array_equal(p.joints[s].range, [-15, 15])
    assert np.all(np.isinf(p.joints[h].range))  # continuous: an unlimited hinge


def test_the_isaac_rail_inside_the_cart_is_excluded_and_point_masses_load(tmp_path):
    p = read_params(write_layout("isaac", tmp_path))
    said = " ".join(p.urdf.changes)
    assert "link 'slider' (welded to the world) and its child 'cart' are excluded" in said
    assert "point mass" in said
    m = mujoco_model(p)
    assert m.nexclude == 1
    assert p.pole_mass == 1.0 and p.cart_mass == 1.0


def test_drake_tags_and_point_masses_load_with_a_bounded_inertia(tmp_path):
    p = read_params(write_layout("drake", tmp_path))
    assert p.joint_names == ("CartSlider", "PolePin")
    assert any("boundinertia" in c for c in p.urdf.changes)
    assert p.carried_by(p.hinges[0])[1] == pytest.approx(0.5)
    assert p.pole_inertia_about_hinge == pytest.approx(0.25, rel=1e-9)


def test_a_package_mesh_is_found_above_the_urdf(tmp_path):
    p = read_params(write_layout("ros", tmp_path))
    assert any("cart.obj" in c and "read from" in c for c in p.urdf.changes)
    assert mujoco_model(p).nmesh == 1


def test_a_missing_collision_mesh_is_refused_naming_it(tmp_path):
    path = tmp_path / "ros.urdf"
    path.write_text(ROS)  # outside its package: cart.obj cannot be found
    with pytest.raises(MJCFError, match=r"collision mesh 'package://cart_pole_description/meshes/cart\.obj'.*<box>"):
        read_params(path)


def test_a_missing_visual_mesh_is_left_out_and_said_when_visuals_are_kept(tmp_path):
    text = DRAKE.replace('<link name="world"/>', '<mujoco><compiler discardvisual="false"/></mujoco>\n'
                         '  <link name="world"/>').replace(
        '<geometry><box size="0.24 0.12 0.12"/></geometry>', '<geometry><mesh filename="package://gone/c.obj"/>'
        '</geometry>')
    path = tmp_path / "d.urdf"
    path.write_text(text)
    p = read_params(path)
    assert any("visual mesh 'package://gone/c.obj'" in c and "left out" in c for c in p.urdf.changes)


def test_a_mechanical_reduction_is_recorded_and_ctrl_stays_the_joint_force(tmp_path):
    path = tmp_path / "r.urdf"
    path.write_text(BULLET.replace("</robot>", """<transmission type="SimpleTransmission" name="t">
      <actuator name="m"/><joint name="slider_to_cart"/><mechanicalReduction>20</mechanicalReduction>
    </transmission></robot>"""))
    p = read_params(path)
    assert p.gear == 1.0 and p.u_max == 1000.0
    assert p.urdf.actuators[0].mechanical_reduction == 20.0 and "not applied" in p.urdf.actuators[0].sentence()


@pytest.mark.parametrize("limit", ['effort="0" lower="-15" upper="15"', 'lower="-15" upper="15"',
                                   'effort="1e30" lower="-15" upper="15"'])
def test_no_effort_limit_leaves_the_motor_unlimited(tmp_path, limit):
    path = tmp_path / "u.urdf"
    path.write_text(BULLET.replace('effort="1000.0" lower="-15" upper="15"', limit))
    p = read_params(path)
    assert np.all(np.isinf(p.ctrl_range)) and "unlimited" in p.urdf.actuators[0].sentence()


TWO_PRISMATIC = BULLET.replace("</robot>", """<link name="cart2">
    <inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="cart_to_cart2" type="prismatic"><parent link="cart"/><child link="cart2"/><axis xyz="0 1 0"/>
    <limit effort="10" lower="-1" upper="1" velocity="1"/></joint></robot>""")


def test_two_prismatic_joints_without_transmission_are_refused_naming_the_argument(tmp_path):
    path = tmp_path / "two.urdf"
    path.write_text(TWO_PRISMATIC)
    with pytest.raises(MJCFError, match=r"2 prismatic joints \('slider_to_cart', 'cart_to_cart2'\).*actuated_joints="):
        read_params(path)
    with urdf_session(option="--actuated-joint NAME"), pytest.raises(MJCFError, match="--actuated-joint NAME"):
        read_params(path)
    p = read_params(path, actuated_joints=["cart_to_cart2", "slider_to_cart"])
    assert [p.joint_names[a.joint] for a in p.actuators] == ["cart_to_cart2", "slider_to_cart"]
    np.testing.assert_array_equal(p.ctrl_range, [[-10, 10], [-1000, 1000]])


def test_actuated_joints_override_the_transmissions_and_reloads_keep_them(tmp_path):
    path = write_layout("ros", tmp_path)
    p = read_params(path, actuated_joints=["pole_hinge"])
    assert p.joint_names[p.actuators[0].joint] == "pole_hinge" and p.urdf.actuators[0].unit == "N m"
    assert np.all(np.isinf(p.ctrl_range))  # the hinge gives no effort
    assert any("overridden" in c for c in p.urdf.changes)
    m = make_mujoco(p)[0]  # not the file's transmission again
    assert mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(m.actuator_trnid[0, 0])) == "pole_hinge"
    with urdf_session(["pole_hinge"]):  # the command line's choice, for every read inside
        assert read_params(path).joint_names[read_params(path).actuators[0].joint] == "pole_hinge"


@pytest.mark.parametrize("joint, why", [("nope", "is not a joint"), ("world_to_rail", "is a fixed joint")])
def test_an_actuated_joint_that_cannot_be_driven_is_refused(tmp_path, joint, why):
    path = write_layout("ros", tmp_path)
    with pytest.raises(MJCFError, match=f"Joint '{joint}' {why} of URDF.*actuated_joints=.*'cart_slider', 'pole_hinge'"):
        read_params(path, actuated_joints=[joint])


def test_actuated_joints_on_an_mjcf_are_refused():
    with pytest.raises(MJCFError, match="URDF only|of a URDF"):
        read_params(None, actuated_joints=["slider"])


def test_urdf_text_loads_like_a_file():
    p = read_params(xml=ISAAC)
    assert p.mjcf == "" and p.urdf.path == "" and p.nu == 1
    m, path, text = load_model(xml=ISAAC)
    assert m.nu == 1 and "<actuator>" in text and path == ""


def test_an_unknown_transmission_type_is_refused_naming_the_argument(tmp_path):
    path = tmp_path / "d.urdf"
    path.write_text(BULLET.replace("</robot>", """<transmission name="diff">
      <type>transmission_interface/DifferentialTransmission</type>
      <joint name="slider_to_cart"/><joint name="cart_to_pole"/></transmission></robot>"""))
    with pytest.raises(MJCFError, match="DifferentialTransmission.*actuated_joints="):
        read_params(path)
    assert read_params(path, actuated_joints=["slider_to_cart"]).nu == 1


def test_ros2_control_effort_interfaces_become_motors(tmp_path):
    path = tmp_path / "r2.urdf"
    path.write_text(ISAAC.replace("</robot>", """<ros2_control name="CartPoleSystem" type="system">
      <joint name="slider_to_cart"><command_interface name="effort"/><state_interface name="position"/></joint>
      <joint name="cart_to_pole"><state_interface name="position"/></joint></ros2_control></robot>"""))
    p = read_params(path)
    assert p.urdf.actuators[0].source == "ros2_control" and p.joint_names[p.actuators[0].joint] == "slider_to_cart"


@pytest.mark.parametrize("text, expected", [
    ('<?xml version="1.0"?>\n<!-- a <mujoco> comment -->\n<robot name="r"/>', True),
    ("<!DOCTYPE robot>\n<robot/>", True),
    ('<!-- <robot> --><mujoco model="robot"/>', False),
    ('<mujoco model="robot"><worldbody/></mujoco>', False),
])
def test_a_urdf_is_told_by_its_root_element(text, expected):
    assert is_urdf(text) is expected


def test_the_effort_read_as_no_limit_is_the_largest_force_the_toolkit_accepts():
    from cartpole.models.params import MAX_ACTUATOR_FORCE
    from cartpole.models.urdf import EFFORT_AS_UNLIMITED

    assert EFFORT_AS_UNLIMITED == MAX_ACTUATOR_FORCE


CART_INERTIA = '<inertia ixx="1.0" ixy="0.0" ixz="0.0" iyy="1.0" iyz="0.0" izz="1.0"/>\n    </inertial>\n  </link>\n  <joint'
POLE_INERTIA = '<origin xyz="0 0 0.5"/>\n      <mass value="10"/>\n      <inertia ixx="1" ixy="0.0" ixz="0.0" iyy="1" iyz="0.0" izz="1"/>'


def _pole_inertia(text, moments, rpy="0 0 0"):
    ixx, iyy, izz = moments
    return text.replace(POLE_INERTIA, f'<origin xyz="0 0 0.5" rpy="{rpy}"/>\n      <mass value="10"/>\n      '
                                      f'<inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/>')


def _run(path, steps=400):
    m, d = make_mujoco(read_params(path))[:2]
    d.qpos[1] = 0.4
    out = []
    for k in range(steps):
        d.ctrl[0] = 300.0 * np.sin(0.05 * k)
        mujoco.mj_step(m, d)
        out.append(np.r_[d.qpos, d.qvel])
    return np.array(out)


@pytest.mark.parametrize("link, moments, rpy", [
    ("pole", ("1e-7", "0.8", "1e-7"), "0 0 0"),      # Drake's thin rod: a moment only about the hinge (y)
    ("pole", ("1e-7", "0.8", "1e-7"), "0 0.4 0"),    # the same, its frame turned about the hinge
    ("pole", ("0", "0.8", "0"), "0 0 0"),            # a rod with no moments across the hinge at all
    ("cart", ("1e-7", "1.0", "1e-7"), "0 0 0"),      # the cart never turns: any mend keeps its dynamics
])
def test_an_inertia_no_body_has_is_mended_keeping_the_moment_about_the_hinge(tmp_path, link, moments, rpy):
    """MuJoCo refuses principal moments with A + B < C (Drake's cart-pole gives its pole ixx = izz = 1e-7); raising
    the moments across the hinge leaves a planar chain's motion as the file's: the same run, step for step, as a
    twin whose inertia is a body's with the same moment about the hinge."""
    bad, twin = tmp_path / "bad.urdf", tmp_path / "twin.urdf"
    if link == "pole":
        bad.write_text(_pole_inertia(BULLET, moments, rpy))
        twin.write_text(_pole_inertia(BULLET, ("0.5", moments[1], "0.5"), rpy))
    else:
        ixx, iyy, izz = moments
        bad.write_text(BULLET.replace(CART_INERTIA, CART_INERTIA.replace(
            'ixx="1.0" ixy="0.0" ixz="0.0" iyy="1.0" iyz="0.0" izz="1.0"', f'ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" '
            f'iyz="0" izz="{izz}"'), 1))
        twin.write_text(BULLET)
    p = read_params(bad)
    assert any(f"'{link}' give principal moments of inertia no body has" in c for c in p.urdf.changes)
    assert p.pole_inertia_about_hinge == pytest.approx(read_params(twin).pole_inertia_about_hinge, rel=1e-12)
    np.testing.assert_allclose(_run(bad), _run(twin), rtol=0, atol=1e-9)


def test_an_inertia_no_body_has_across_the_hinge_is_refused(tmp_path):
    path = tmp_path / "bad.urdf"
    path.write_text(_pole_inertia(BULLET, ("1", "1e-3", "1e-3")))  # the excess is about x, not the hinge's y
    with pytest.raises(MJCFError, match=r"link 'pole' principal moments of inertia 0\.001, 0\.001 and 1 kg m\^2, "
                                        r"which no body has.*correct its <inertia>"):
        read_params(path)


def test_products_of_inertia_left_out_are_read_as_zero(tmp_path):
    path = tmp_path / "p.urdf"
    path.write_text(BULLET.replace('<inertia ixx="1" ixy="0.0" ixz="0.0" iyy="1" iyz="0.0" izz="1"/>',
                                   '<inertia ixx="1" iyy="1" izz="1"/>'))
    p = read_params(path)
    assert any("link 'pole' gives <inertia> without ixy, ixz, iyz, read as 0" in c for c in p.urdf.changes)
    assert p.pole_inertia_about_hinge == pytest.approx(read_params(write_layout("bullet", tmp_path))
                                                       .pole_inertia_about_hinge, rel=1e-12)


def test_an_undeclared_world_link_is_the_world_and_any_other_undeclared_link_is_refused(tmp_path):
    start, end = BULLET.index('  <link name="slideBar">'), BULLET.index('  <link name="cart">')
    no_bar = BULLET[:start] + BULLET[end:]
    path = tmp_path / "w.urdf"
    path.write_text(no_bar.replace('<parent link="slideBar"/>', '<parent link="world"/>'))
    p = read_params(path)
    assert any("joint 'slider_to_cart' hangs from link 'world', which the file does not declare" in c
               for c in p.urdf.changes)
    assert p.nu == 1 and p.cart_mass == 1.0
    path.write_text(no_bar.replace('<parent link="slideBar"/>', '<parent link="rail"/>'))
    with pytest.raises(MJCFError, match=r"joint 'slider_to_cart' the parent link 'rail', which the file does not "
                                        r"declare; declare <link name=\"rail\"/>"):
        read_params(path)
    path.write_text(no_bar.replace('<parent link="slideBar"/>', ''))
    with pytest.raises(MJCFError, match=r"joint 'slider_to_cart' no <parent link=\.\.\.>; name its parent link"):
        read_params(path)


@pytest.mark.parametrize("edit", [
    lambda t: t.replace('<robot name="physics">', '<robot name="physics" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                        '\n  <xacro:property name="l" value="1.0"/>'),
    lambda t: t.replace('<origin xyz="0 0 0.5"/>\n      <mass value="10"/>',
                        '<origin xyz="0 0 ${l/2}"/>\n      <mass value="10"/>'),
])
def test_a_xacro_file_is_refused_saying_to_expand_it_first(tmp_path, edit):
    path = tmp_path / "c.urdf.xacro"
    text = edit(BULLET)
    assert text != BULLET
    path.write_text(text)
    with pytest.raises(MJCFError, match=r"is a xacro file .*expand it first \(ROS's `xacro FILE > robot.urdf`\)"):
        read_params(path)
    path.write_text(BULLET.replace("<robot", "<!-- written by xacro from ${name}.xacro -->\n<robot", 1))
    assert read_params(path).nu == 1  # a comment is no expression


@pytest.mark.parametrize("old, new, words", [
    ('<axis xyz="0 1 0"/>', '<axis xyz="0 1"/>', r"joint 'cart_to_pole' an axis '0 1', which is not three numbers"),
    ('<origin xyz="0.0 0.0 0"/>', '<origin xyz="0.0 0.0 0" rpy="0 x 0"/>',
     r"joint 'cart_to_pole' an origin rpy 'x', which is not a number"),
])
def test_a_joint_axis_or_origin_that_is_not_three_numbers_is_one_sentence(tmp_path, old, new, words):
    path = tmp_path / "bad.urdf"
    assert old in BULLET
    path.write_text(BULLET.replace(old, new))
    with pytest.raises(MJCFError, match=words):
        read_params(path)
