"""The MJCF reader: parameters come from the compiled MjModel; anything not a cart-pole is refused clearly."""
import mujoco
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, MJCFError, read_params
from variants import VARIANTS, variant_xml


def test_shipped_asset_passes_the_labs_smoke_test():
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    assert (m.nq, m.nv, m.nu) == (2, 2, 1)


def test_shipped_asset_keeps_every_inertial_joint_and_actuator_number_of_the_lab():
    lab_xml = (SHIPPED_MJCF.read_text()
               .replace('pos="0 0 1.0">', 'pos="0 0 0.1">'))  # the lab's rail height
    lab = mujoco.MjModel.from_xml_string(lab_xml)
    ours = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    for name in ("body_mass", "body_inertia", "body_ipos", "dof_damping", "dof_armature", "actuator_gear",
                 "actuator_ctrlrange", "jnt_range", "jnt_axis"):
        np.testing.assert_array_equal(getattr(lab, name), getattr(ours, name), err_msg=name)
    assert lab.opt.timestep == ours.opt.timestep and lab.opt.integrator == ours.opt.integrator


def test_shipped_asset_hangs_the_pole_clear_of_the_floor():
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    d = mujoco.MjData(m)
    d.qpos[:] = [0.0, np.pi]
    mujoco.mj_forward(m, d)
    assert d.ncon == 0
    pole = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "pole_geom")
    tip_z = d.geom_xpos[pole][2] - 0.3 - m.geom_size[pole][0]
    assert tip_z > 0.1


def test_params_are_read_from_the_compiled_model_not_the_xml():
    p = read_params()
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    cart = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cart")
    pole = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pole")
    assert p.cart_mass == m.body_mass[cart]
    assert p.pole_mass == m.body_mass[pole]
    # the capsule's centre of mass and inertia are MuJoCo's (derived from geometry), about its COM
    np.testing.assert_allclose(p.pole_com, m.body_ipos[pole] + [0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(p.pole_inertia)), np.sort(m.body_inertia[pole]),
                               rtol=1e-12)
    assert p.gear == m.actuator_gear[0, 0]
    np.testing.assert_array_equal(p.damping, [m.dof_damping[0], m.dof_damping[1]])
    assert p.integrator == "Euler" and p.timestep == m.opt.timestep
    np.testing.assert_array_equal(p.cart_range, m.jnt_range[0])


def test_params_are_frozen_with_read_only_arrays():
    p = read_params()
    with pytest.raises(Exception):
        p.gear = 3.0
    with pytest.raises(ValueError):
        p.gravity[2] = 0.0


@pytest.mark.parametrize("name", list(VARIANTS))
def test_every_variant_is_accepted(name):
    p = read_params(xml=variant_xml(name))
    assert p.pole_mass > 0 and p.gear > 0


def test_flipped_hinge_axis_is_read_with_its_sign():
    p = read_params(xml=variant_xml("flipped_offset_armature"))
    np.testing.assert_allclose(p.hinge_axis, [0, -1, 0])
    np.testing.assert_allclose(p.hinge_offset, [0.03, 0, 0.08])
    assert p.armature[1] == 0.002


def test_unlimited_joints_read_as_infinite_ranges():
    xml = variant_xml("rk4_fine_step").replace('limited="true" range="-1.5 1.5"', "")
    p = read_params(xml=xml)
    assert np.all(np.isinf(p.cart_range))


def test_scaled_pole_changes_mass_length_and_inertia_consistently():
    p = read_params()
    q = p.scaled_pole(1.1, 0.9)
    assert q.pole_mass == pytest.approx(1.1 * p.pole_mass)
    assert q.pole_com_distance == pytest.approx(0.9 * p.pole_com_distance)
    assert q.pole_inertia_about_hinge == pytest.approx(1.1 * 0.81 * p.pole_inertia_about_hinge)


BASE = variant_xml("rk4_fine_step")

REFUSED = {
    "no slide joint": (BASE.replace('type="slide" axis="1 0 0"', 'type="hinge" axis="0 0 1"'),
                       r"2 hinge joint\(s\).*one slide joint"),
    "two actuators": (BASE.replace("</actuator>", '<motor joint="hinge" gear="1"/></actuator>'),
                      r"has 2 actuators.*one motor actuator"),
    "free joint": (BASE.replace("</worldbody>", '<body name="ball" pos="0 1 2"><freejoint/>'
                                '<geom type="sphere" size="0.1"/></body></worldbody>'),
                   r"1 free.*joint\(s\).*one slide joint"),
    "tendon": (BASE.replace("<actuator>", '<tendon><fixed name="t"><joint joint="slider" coef="1"/>'
                            '<joint joint="hinge" coef="1"/></fixed></tendon><actuator>'), r"1 tendon\(s\)"),
    "position actuator": (BASE.replace('<motor name="motor" joint="slider"', '<position name="motor" joint="slider" kp="5"'),
                          r"non-motor actuator"),
    "pole pointing down": (BASE.replace('fromto="0 0 0 0 0 0.6"', 'fromto="0 0 0 0 0 -0.6"'),
                           r"straight above its hinge"),
    "actuator on the hinge": (BASE.replace('<motor name="motor" joint="slider"', '<motor name="motor" joint="hinge"'),
                              r"actuator on something other than the slide"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_mjcf_that_is_not_a_cart_pole_is_refused_with_one_sentence(case):
    xml, pattern = REFUSED[case]
    with pytest.raises(MJCFError, match=pattern) as info:
        read_params(xml=xml)
    msg = str(info.value)
    assert "\n" not in msg and "Traceback" not in msg
    assert "supports" in msg or "convention" in msg or "must" in msg or "needs" in msg


def test_file_that_does_not_parse_is_refused(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(MJCFError, match="does not compile") as info:
        read_params(bad)
    assert "\n" not in str(info.value)


def test_missing_file_is_refused(tmp_path):
    with pytest.raises(MJCFError, match="does not exist"):
        read_params(tmp_path / "nope.xml")
