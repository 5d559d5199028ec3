"""The MJCF reader: parameters come from the compiled MjModel; anything not a cart-pole is refused clearly."""
import mujoco
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, MJCFError, build_model, read_params
from cartpole.validation.jacobians import random_states
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
    by_name = {b.name: b for b in p.bodies}
    np.testing.assert_array_equal(by_name["pole"].ipos, m.body_ipos[pole])
    np.testing.assert_array_equal(by_name["pole"].inertia, m.body_inertia[pole])
    np.testing.assert_array_equal(by_name["pole"].iquat, m.body_iquat[pole])
    assert p.pole_com_distance == pytest.approx(m.body_ipos[pole][2], rel=1e-12)
    assert p.gear == m.actuator_gear[0, 0]
    np.testing.assert_array_equal(p.damping, [m.dof_damping[0], m.dof_damping[1]])
    assert p.integrator == "Euler" and p.timestep == m.opt.timestep
    np.testing.assert_array_equal(p.cart_range, m.jnt_range[0])
    assert (p.nq, p.nu, p.slide, p.hinges, p.joint_names) == (2, 1, 0, (1,), ("slider", "hinge"))


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
    hinge = p.joints[p.hinges[0]]
    np.testing.assert_allclose(hinge.axis, [0, -1, 0])
    np.testing.assert_allclose(p.bodies[hinge.body].pos, [0.03, 0, 0.08])
    assert p.armature[1] == 0.002


def test_unlimited_joints_read_as_infinite_ranges():
    xml = variant_xml("rk4_fine_step").replace('limited="true" range="-1.5 1.5"', "")
    p = read_params(xml=xml)
    assert np.all(np.isinf(p.cart_range))


def test_scaled_pole_changes_mass_length_and_inertia_consistently():
    p = read_params()
    q = p.scaled_pole(1.1, 0.9)
    assert q.pole_mass == pytest.approx(1.1 * p.pole_mass)
    assert q.cart_mass == p.cart_mass
    assert q.pole_com_distance == pytest.approx(0.9 * p.pole_com_distance)
    assert q.pole_inertia_about_hinge == pytest.approx(1.1 * 0.81 * p.pole_inertia_about_hinge)


def test_scaled_pole_scales_every_link_of_a_chain():
    p = read_params(SHIPPED_MJCF.with_name("cartpole_three_pole.xml"))
    q = p.scaled_pole(1.2, 1.5)
    assert q.pole_mass == pytest.approx(1.2 * p.pole_mass) and q.cart_mass == p.cart_mass
    # links 2 and 3 hang from the scaled tips of the links below them
    np.testing.assert_allclose([b.pos[2] for b in q.bodies[2:]], [1.5 * b.pos[2] for b in p.bodies[2:]])
    assert q.bodies[1].pos[2] == p.bodies[1].pos[2]  # the first hinge stays on the cart


BASE = variant_xml("rk4_fine_step")
NO_CONTACT = '<flag contact="disable"/>'

REFUSED = {
    "free joint": (BASE.replace("</worldbody>", '<body name="ball" pos="0 1 2"><freejoint/>'
                                '<geom type="sphere" size="0.1" contype="0" conaffinity="0"/></body></worldbody>'),
                   r"1 free.*joint\(s\).*without free or ball joints"),
    "ball joint": (BASE.replace('type="hinge" axis="0 1 0"', 'type="ball"'), r"1 ball.*joint\(s\)"),
    "no actuator": (BASE.replace('<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/>', ""),
                    r"no actuator"),
    "tendon": (BASE.replace("<actuator>", '<tendon><fixed name="t"><joint joint="slider" coef="1"/>'
                            '<joint joint="hinge" coef="1"/></fixed></tendon><actuator>'), r"1 tendon\(s\)"),
    "equality": (BASE.replace("<actuator>", '<equality><joint joint1="slider" joint2="hinge"/></equality><actuator>'),
                 r"equality constraint"),
    "position servo with a time constant": (
        BASE.replace('<motor name="motor" joint="slider"',
                     '<position name="motor" joint="slider" kp="5" timeconst="0.05"'),
        r"actuator 'motor' activation dynamics \(dyntype filterexact.*activation state the toolkit does not model yet"),
    "filtered general actuator": (
        BASE.replace('<motor name="motor" joint="slider" gear="20"',
                     '<general name="motor" joint="slider" gear="20" dyntype="filter" dynprm="0.05"'),
        r"dyntype filter, .*activation state the toolkit does not model yet.*use a plain motor"),
    "intvelocity": (BASE.replace('<motor name="motor" joint="slider" gear="20"',
                                 '<intvelocity name="motor" joint="slider" kp="5" actrange="-1 1"'),
                    r"dyntype integrator"),
    "dcmotor": (BASE.replace('<motor name="motor" joint="slider" gear="20"',
                             '<dcmotor name="motor" joint="slider" motorconst="0.1" resistance="2"'),
                r"dcmotor type.*biastype=\"affine\""),
    "actuator delay": (BASE.replace('<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/>',
                                    '<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1" delay="0.01" '
                                    'nsample="4"/>'), r"delays actuator 'motor'"),
    "damper actuator": (BASE.replace('<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"',
                                     '<damper name="motor" joint="slider" kv="5" ctrlrange="0 1"'),
                        r"gain that is not fixed"),
    "force range on a biased actuator": (
        BASE.replace('<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/>',
                     '<general name="motor" joint="slider" gear="20" biastype="affine" biasprm="0 0 -0.1" '
                     'ctrlrange="-1 1" forcerange="-50 50"/>'), r"depends on the state"),
    "a pole touching the floor at upright": (
        BASE.replace(NO_CONTACT, "").replace('<body name="cart" pos="0 0 1.2">', '<body name="cart" pos="0 0 0.3">')
        .replace('<body name="pole" pos="0 0 0.05">', '<body name="pole" pos="0 0 -0.4">'),
        r"geoms 'floor' and 'pole_geom' touch at the upright equilibrium \(0.12 m deep\).*contype=\"0\""),
    "fluid density": (BASE.replace('integrator="RK4">', 'integrator="RK4" density="1.2">'), r"fluid forces"),
    "fluid viscosity": (BASE.replace('integrator="RK4">', 'integrator="RK4" viscosity="0.1">'), r"fluid forces"),
    "wind": (BASE.replace('integrator="RK4">', 'integrator="RK4" wind="1 0 0">'), r"fluid forces"),
    "gravcomp": (BASE.replace('<body name="pole"', '<body name="pole" gravcomp="1"'), r"gravcomp"),
    "force range that bites": (BASE.replace('ctrlrange="-1 1"/>', 'ctrlrange="-1 1" forcerange="-0.5 0.5"/>'),
                               r"forcerange \[-0.5, 0.5\]"),
    "force range that bites under a small gear": (
        BASE.replace('gear="20" ctrlrange="-1 1"/>', 'gear="0.5" ctrlrange="-1 1" forcerange="-0.7 0.7"/>'),
        r"forcerange \[-0.7, 0.7\]"),
    "actuator force range on the joint": (BASE.replace('type="slide"', 'type="slide" actuatorfrcrange="-5 5"'),
                                          r"actuatorfrcrange"),
    "actuation disabled": (BASE.replace(NO_CONTACT, '<flag contact="disable" actuation="disable"/>'),
                           r"disables actuation"),
    "ctrl clamping disabled": (BASE.replace(NO_CONTACT, '<flag contact="disable" clampctrl="disable"/>'),
                               r"disables ctrl clamping"),
    "not-finite gear": (BASE.replace('gear="20"', 'gear="nan"'), r"not finite in actuator_gear"),
    "not-finite gravity": (BASE.replace('gravity="0 0 -9.81"', 'gravity="0 0 inf"'), r"not finite in opt.gravity"),
    "tilted rail without equilibrium": (BASE.replace('type="slide" axis="1 0 0"', 'type="slide" axis="1 0 0.2"')
                                        .replace('joint="slider"', 'joint="hinge"'), r"no upright rest.*'slider'"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_mjcf_that_is_not_a_cart_pole_is_refused_with_one_sentence(case):
    xml, pattern = REFUSED[case]
    with pytest.raises(MJCFError, match=pattern) as info:
        build_model(read_params(xml=xml))
    msg = str(info.value)
    assert "\n" not in msg and "Traceback" not in msg and msg.endswith(".")


def test_file_that_does_not_parse_is_refused(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(MJCFError, match="does not compile") as info:
        read_params(bad)
    assert "\n" not in str(info.value)


def test_missing_file_is_refused(tmp_path):
    with pytest.raises(MJCFError, match="does not exist"):
        read_params(tmp_path / "nope.xml")


ACCEPTED = {
    "force range that cannot bite": BASE.replace('ctrlrange="-1 1"/>', 'ctrlrange="-1 1" forcerange="-50 50"/>'),
    "floor with default contacts that nothing reaches": BASE.replace(NO_CONTACT, ""),
    "explicit contact pair that never touches": BASE.replace("<actuator>", '<contact><pair geom1="floor" '
                                                             'geom2="pole_geom"/></contact><actuator>').replace(
        NO_CONTACT, ""),
    "contacts off by contype": BASE.replace(NO_CONTACT, "").replace(
        '<geom name="floor" type="plane" size="3 3 0.1"/>',
        '<geom name="floor" type="plane" size="3 3 0.1" contype="0" conaffinity="0"/>'),
    "pole built pointing down": BASE.replace('fromto="0 0 0 0 0 0.6"', 'fromto="0 0 0 0 0 -0.6"'),
    "motor on the hinge": BASE.replace('<motor name="motor" joint="slider"', '<motor name="motor" joint="hinge"'),
    "force range the gear multiplies": BASE.replace('ctrlrange="-1 1"/>', 'ctrlrange="-1 1" forcerange="-5 5"/>'),
    "frictionloss": BASE.replace('type="slide"', 'type="slide" frictionloss="0.1"'),
    "position servo": BASE.replace('<motor name="motor" joint="slider"',
                                   '<position name="motor" joint="slider" kp="5"'),
    "velocity servo": BASE.replace('<motor name="motor" joint="slider"',
                                   '<velocity name="motor" joint="slider" kv="5"'),
}


@pytest.mark.parametrize("case", list(ACCEPTED))
def test_what_the_model_models_exactly_is_accepted(case):
    model = build_model(read_params(xml=ACCEPTED[case]))
    np.testing.assert_allclose(model.dynamics(model.x_eq, model.u_eq), 0.0, atol=1e-12)


def test_a_pole_built_pointing_down_has_its_upright_at_pi():
    model = build_model(read_params(xml=ACCEPTED["pole built pointing down"]))
    assert abs(model.x_eq[1]) == pytest.approx(np.pi, abs=1e-9) and model.x_hanging[1] == pytest.approx(0, abs=1e-9)


def test_asymmetric_ctrlrange_is_kept_per_side():
    p = read_params(xml=BASE.replace('ctrlrange="-1 1"', 'ctrlrange="-0.4 1.5"'))
    np.testing.assert_array_equal(p.ctrl_range, [[-0.4, 1.5]])
    assert p.u_max == 0.4


@pytest.mark.parametrize("flag, field", [("gravity", "gravity"), ("damper", "damping"), ("spring", "stiffness")])
def test_disabled_gravity_dampers_and_springs_are_modelled_as_absent(flag, field):
    xml = BASE.replace('type="slide"', 'type="slide" stiffness="3"').replace(
        NO_CONTACT, f'<flag contact="disable" {flag}="disable"/>')
    on = read_params(xml=BASE.replace('type="slide"', 'type="slide" stiffness="3"'))
    off = read_params(xml=xml)
    if field == "gravity":
        assert on.g > 0 and off.g == 0
    else:
        assert getattr(on.joints[0], field) > 0 and getattr(off.joints[0], field) == 0


def test_gravity_with_a_horizontal_part_is_held_by_a_constant_ctrl():
    p = read_params(xml=BASE.replace('gravity="0 0 -9.81"', 'gravity="1e-3 0 -9.81"'))
    model = build_model(p)
    total = sum(b.mass for b in p.bodies)
    assert model.u_eq[0] == pytest.approx(-total * 1e-3 / p.gear, rel=1e-9)
    np.testing.assert_allclose(model.dynamics(model.x_eq, model.u_eq), 0.0, atol=1e-12)


# ---- motor models: MuJoCo's affine actuators on joints, modelled exactly ---------------------------------------------
MOTOR = '<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/>'
AFFINE = {
    # force = gain * ctrl + b0 + b1 * length + b2 * velocity, length = gear * qpos, joint force = gear * force
    "general with every bias term": '<general name="motor" joint="slider" gear="20" gainprm="1.5" biastype="affine" '
                                    'biasprm="0.3 -2 -0.4" ctrlrange="-1 1"/>',
    "dc motor with back-EMF on the hinge": MOTOR + '<general name="dc" joint="hinge" gear="0.5" gainprm="0.2" '
                                                   'biastype="affine" biasprm="0.01 0 -0.3" ctrlrange="-1 1"/>',
    "position servo": '<position name="motor" joint="slider" gear="2" kp="8" kv="3" ctrlrange="-1 1"/>',
    "position servo with dampratio": '<position name="motor" joint="slider" kp="8" dampratio="0.7" ctrlrange="-1 1"/>',
    "velocity servo": '<velocity name="motor" joint="slider" kv="6" ctrlrange="-1 1"/>',
    "actuator damping and armature": '<motor name="motor" joint="slider" gear="20" damping="0.001" armature="0.0002" '
                                     'ctrlrange="-1 1"/>',
    "two actuators on the cart": MOTOR + '<velocity name="brake" joint="slider" kv="2" ctrlrange="-0.5 0.5"/>',
}
# The slider's reference is moved off zero: actuator length is gear * qpos, not gear * (qpos - qpos0).
AFFINE_TEMPLATE = BASE.replace('type="slide" axis="1 0 0"', 'type="slide" axis="1 0 0" ref="0.2"')


def _affine_xml(case, integrator="RK4"):
    return AFFINE_TEMPLATE.replace(MOTOR, AFFINE[case]).replace('integrator="RK4"', f'integrator="{integrator}"')


def _load(m, d, x, u):
    mujoco.mj_resetData(m, d)
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:m.nq], x[m.nq:], u
    mujoco.mj_forward(m, d)


def test_actuator_gain_bias_and_transmission_are_read_from_the_compiled_model():
    xml = _affine_xml("position servo with dampratio")
    p = read_params(xml=xml)
    m = mujoco.MjModel.from_xml_string(xml)
    a = p.actuators[0]
    assert (a.transmission, a.gain) == (m.actuator_gear[0, 0], m.actuator_gainprm[0, 0]) == (1.0, 8.0)
    np.testing.assert_array_equal(a.bias, m.actuator_biasprm[0, :3])
    assert a.bias[2] < 0 and a.biased  # MuJoCo compiles dampratio into a damping gain -kv
    plain = read_params(xml=BASE).actuators[0]
    assert (plain.gear, plain.transmission, plain.gain, plain.biased) == (20.0, 20.0, 1.0, False)


def test_actuator_damping_and_armature_join_the_joints_as_gear_squared_times_theirs():
    p = read_params(xml=_affine_xml("actuator damping and armature"))
    slider = p.actuated[0]
    assert p.damping[slider] == pytest.approx(p.joints[slider].damping + 400 * 0.001, rel=1e-15)
    assert p.armature[slider] == pytest.approx(p.joints[slider].armature + 400 * 0.0002, rel=1e-15)


@pytest.mark.parametrize("case", list(AFFINE))
def test_affine_actuator_dynamics_equal_mujoco_qacc_at_random_states(case):
    xml = _affine_xml(case)
    model = build_model(read_params(xml=xml))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    xs, us = random_states(model.params, 50, seed=11)
    for x, u in zip(xs, us):
        _load(m, d, x, u)
        np.testing.assert_allclose(model.dynamics(x, u)[m.nq:], d.qacc, rtol=1e-9, atol=1e-9)
        force = np.asarray(model.actuator_bias(x)).ravel() + model.actuation @ u
        np.testing.assert_allclose(force, d.qfrc_actuator, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "implicit", "RK4"])
@pytest.mark.parametrize("case", list(AFFINE))
def test_affine_actuator_step_equals_one_mj_step_for_every_integrator(case, integrator):
    """Euler keeps the actuators' velocity bias explicit (its implicit part is damping only); implicitfast and
    implicit include it in the implicit step, as MuJoCo does."""
    xml = _affine_xml(case, integrator)
    model = build_model(read_params(xml=xml))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    xs, us = random_states(model.params, 30, seed=12)
    for x, u in zip(xs, us):
        _load(m, d, x, u)
        mujoco.mj_step(m, d)
        np.testing.assert_allclose(model.step_np(x, u), np.concatenate([d.qpos, d.qvel]), rtol=0, atol=1e-9)


def test_the_integrators_differ_on_a_velocity_bias_so_the_step_test_can_tell_them_apart():
    """Stepping the Euler file with the implicitfast treatment (velocity bias implicit) misses mj_step by far more
    than the 1e-9 the step test demands: the per-integrator handling is what makes that test pass."""
    xml = _affine_xml("velocity servo", "Euler")
    wrong = build_model(read_params(xml=xml), integrator="implicitfast")
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    x, u = (a[0] for a in random_states(wrong.params, 1, seed=13))
    _load(m, d, x, u)
    mujoco.mj_step(m, d)
    assert np.abs(wrong.step_np(x, u) - np.concatenate([d.qpos, d.qvel])).max() > 1e-6


@pytest.mark.parametrize("case", ["general with every bias term", "dc motor with back-EMF on the hinge"])
def test_affine_actuator_discrete_jacobians_match_central_differences_of_mj_step(case):
    xml = _affine_xml(case, "implicitfast")
    model = build_model(read_params(xml=xml))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)

    def mj(x, u):
        _load(m, d, x, u)
        mujoco.mj_step(m, d)
        return np.concatenate([d.qpos, d.qvel])

    xs, us = random_states(model.params, 10, seed=14)
    eps = 1e-6
    for x, u in zip(xs, us):
        Ad, Bd = model.linearize(x, u, discrete=True)
        cols = [(mj(x + eps * e, u) - mj(x - eps * e, u)) / (2 * eps) for e in np.eye(model.nx)]
        np.testing.assert_allclose(Ad, np.column_stack(cols), atol=1e-6 * np.abs(Ad).max())
        cols = [(mj(x, u + eps * e) - mj(x, u - eps * e)) / (2 * eps) for e in np.eye(model.nu)]
        np.testing.assert_allclose(Bd, np.column_stack(cols), atol=1e-6 * np.abs(Bd).max())


@pytest.mark.parametrize("case", ["general with every bias term", "dc motor with back-EMF on the hinge",
                                  "position servo"])
def test_upright_rest_with_a_biased_actuator_holds_mujoco_for_one_second(case):
    """u* cancels the bias's constant and position parts (b0, b1 gear q*)."""
    xml = _affine_xml(case, "Euler")
    model = build_model(read_params(xml=xml))
    np.testing.assert_allclose(model.dynamics(model.x_eq, model.u_eq), 0.0, atol=1e-12)
    np.testing.assert_allclose(model.dynamics(model.x_hanging, model.u_hanging), 0.0, atol=1e-12)
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qpos[:], d.ctrl[:] = model.x_eq[:m.nq], model.u_eq
    for _ in range(round(1.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert np.abs(d.qpos - model.x_eq[:m.nq]).max() < 1e-6 and np.abs(d.qvel).max() < 1e-6
