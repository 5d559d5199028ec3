"""Joint frictionloss: MuJoCo keeps its constraint, the symbolic model gets -frictionloss tanh(v / width).

References are MuJoCo's own: its friction constraint force (``qfrc_constraint``, ``efc_force``), ``qacc`` and
``mj_step`` on the same MJCF, and the frictionless model's mass matrix; never numbers copied from a run.
"""
import casadi as ca
import mujoco
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.models.friction import (
    DEFAULT_FRICTION_WIDTH,
    FrictionWidthError,
    smooth_friction,
)
from cartpole.validation.jacobians import random_states

SLIDE_FRICTION, HINGE_FRICTION = 0.5, 0.002  # N on the cart, N m on the hinge


def _with_friction(xml, slide=SLIDE_FRICTION, hinge=HINGE_FRICTION, integrator=None):
    xml = (xml.replace('damping="0.1"/>', f'damping="0.1" frictionloss="{slide}"/>')
              .replace('damping="0.01"/>', f'damping="0.01" frictionloss="{hinge}"/>'))
    if integrator:
        xml = xml.replace('<option timestep="0.005"', f'<option timestep="0.005" integrator="{integrator}"')
    return xml


SHIPPED = SHIPPED_MJCF.read_text()
FRICTION = _with_friction(SHIPPED)


def _mujoco(xml):
    m = mujoco.MjModel.from_xml_string(xml)
    return m, mujoco.MjData(m)


def _load(m, d, x, u):
    mujoco.mj_resetData(m, d)
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:m.nq], x[m.nq:], u
    mujoco.mj_forward(m, d)


def _sliding_states(params, n, seed, floor):
    """Random states whose every joint moves at least ``floor`` (m/s or rad/s) in either direction."""
    x, u = random_states(params, n, seed=seed)
    v = x[:, params.nq:]
    x[:, params.nq:] = np.sign(v) * (floor + np.abs(v))
    return x, u


def _mujoco_slides(m, d, x, frictionloss):
    """True when MuJoCo's friction force on every joint is at its bound and opposes the velocity: MuJoCo's own
    statement that the joint is sliding (near rest, or when other forces decelerate it faster than the soft
    constraint's reference, the constraint force is smaller)."""
    v = x[m.nq:]
    return bool(np.all(np.abs(d.qfrc_constraint + frictionloss * np.sign(v)) <= 1e-12 * frictionloss))


def test_smooth_friction_force_equals_mujocos_frictionloss_force_while_sliding():
    p = read_params(xml=FRICTION)
    model = build_model(p)
    m, d = _mujoco(FRICTION)
    xs, us = _sliding_states(p, 200, 1, floor=0.3)  # 30 widths and more
    sliding = 0
    for x, u in zip(xs, us):
        _load(m, d, x, u)
        if not _mujoco_slides(m, d, x, p.frictionloss):
            continue
        sliding += 1
        force = np.asarray(model.friction(x)).ravel()
        np.testing.assert_allclose(force, d.qfrc_constraint, rtol=0, atol=1e-15)
        rows = d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF
        np.testing.assert_allclose(force[d.efc_id[:d.nefc][rows]], d.efc_force[:d.nefc][rows], rtol=0, atol=1e-15)
    assert sliding >= 150, f"MuJoCo slid in only {sliding} of 200 states"


def test_continuous_dynamics_equal_mujoco_qacc_while_sliding():
    p = read_params(xml=FRICTION)
    model = build_model(p)
    m, d = _mujoco(FRICTION)
    xs, us = _sliding_states(p, 100, 2, floor=0.3)
    for x, u in zip(xs, us):
        _load(m, d, x, u)
        if _mujoco_slides(m, d, x, p.frictionloss):
            np.testing.assert_allclose(model.dynamics(x, u)[m.nq:], d.qacc, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "implicit", "RK4"])
def test_discrete_step_equals_mj_step_while_every_joint_slides(integrator):
    """The step is not mj_step in general (MuJoCo's friction is a constraint); where MuJoCo's friction is at its bound
    and every joint moves fast enough that it stays so over the step (RK4 evaluates forces at three more points),
    the two are the same to 1e-9."""
    xml = _with_friction(SHIPPED, integrator=integrator)
    p = read_params(xml=xml)
    model = build_model(p)
    m, d = _mujoco(xml)
    xs, us = _sliding_states(p, 100, 3, floor=1.0)
    checked = 0
    for x, u in zip(xs, us):
        _load(m, d, x, u)
        if not _mujoco_slides(m, d, x, p.frictionloss):
            continue
        mujoco.mj_step(m, d)
        np.testing.assert_allclose(model.step_np(x, u), np.concatenate([d.qpos, d.qvel]), rtol=0, atol=1e-9)
        checked += 1
    assert checked >= 80


def test_friction_on_a_three_pole_chain_equals_mujocos_while_sliding():
    """Every joint of a longer chain, each with its own frictionloss."""
    path = SHIPPED_MJCF.with_name("cartpole_three_pole.xml")
    text = path.read_text()
    m0 = mujoco.MjModel.from_xml_string(text)
    losses = [0.3, 0.004, 0.003, 0.002]
    for j, loss in enumerate(losses):
        name = mujoco.mj_id2name(m0, mujoco.mjtObj.mjOBJ_JOINT, j)
        text = text.replace(f'name="{name}"', f'name="{name}" frictionloss="{loss}"', 1)
    p = read_params(xml=text)
    np.testing.assert_array_equal(p.frictionloss, losses)
    model = build_model(p)
    m, d = _mujoco(text)
    xs, us = _sliding_states(p, 100, 4, floor=1.0)
    checked = 0
    for x, u in zip(xs, us):
        _load(m, d, x, u)
        if _mujoco_slides(m, d, x, p.frictionloss):
            np.testing.assert_allclose(np.asarray(model.friction(x)).ravel(), d.qfrc_constraint, atol=1e-15)
            np.testing.assert_allclose(model.dynamics(x, u)[m.nq:], d.qacc, rtol=1e-9, atol=1e-9)
            checked += 1
    assert checked >= 30


def test_smooth_friction_is_tanh_of_velocity_over_the_width():
    p = read_params(xml=FRICTION)
    width = 0.02
    model = build_model(p, friction_width=width)
    assert model.friction_width == width
    v = np.array([width, -3 * width])
    force = np.asarray(model.friction(np.concatenate([np.zeros(p.nq), v]))).ravel()
    np.testing.assert_allclose(force, -p.frictionloss * np.tanh(v / width), rtol=1e-15)
    np.testing.assert_allclose(force, smooth_friction(p.frictionloss, v, width), rtol=1e-15)
    assert abs(force[0]) < SLIDE_FRICTION and abs(force[1]) > 0.995 * HINGE_FRICTION


def test_linearisation_at_rest_sees_friction_as_damping_frictionloss_over_width():
    """d(-fl tanh(v/w))/dv = -fl/w at v = 0: the friction model's A differs from the frictionless one by
    -M^-1 diag(fl / w) in the velocity block, with M MuJoCo's mass matrix."""
    with_f, without = build_model(read_params(xml=FRICTION)), build_model()
    nq = with_f.nq
    A1, B1 = with_f.linearize()
    A0, B0 = without.linearize()
    m, d = _mujoco(FRICTION)
    d.qpos[:] = with_f.x_eq[:nq]
    mujoco.mj_forward(m, d)
    M = np.zeros((nq, nq))
    mujoco.mj_fullM(m, d, M)
    expected = -np.linalg.solve(M, np.diag(with_f.params.frictionloss / DEFAULT_FRICTION_WIDTH))
    np.testing.assert_allclose(A1[nq:, nq:] - A0[nq:, nq:], expected, rtol=1e-9)
    np.testing.assert_array_equal(A1[:, :nq], A0[:, :nq])
    np.testing.assert_array_equal(B1, B0)
    np.testing.assert_array_equal(with_f.x_eq, without.x_eq)
    np.testing.assert_array_equal(with_f.u_eq, without.u_eq)


def test_symbolic_jacobians_of_the_friction_model_match_finite_differences_of_f():
    model = build_model(read_params(xml=FRICTION))
    xs, us = random_states(model.params, 20, seed=5)
    xs[:, model.nq:] *= 0.01  # inside the tanh's curved band, where the derivative is not trivial
    for x, u in zip(xs, us):
        A, _ = model.linearize(x, u)
        eps = 1e-7
        for i in range(model.nx):
            dx = np.zeros(model.nx)
            dx[i] = eps
            col = (model.dynamics(x + dx, u) - model.dynamics(x - dx, u)) / (2 * eps)
            np.testing.assert_allclose(A[:, i], col, rtol=1e-5, atol=1e-5 * np.abs(A).max())


def test_euler_step_treats_the_friction_slope_implicitly_so_a_narrow_width_stops_the_joint():
    """A light hinge with much friction (no gravity, so only friction and damping act) and a width a quarter of the
    rate change one step of full friction makes: the implicit step stops the hinge, the explicit one (eulerdamp off)
    chatters about rest at a few widths."""
    xml = _with_friction(SHIPPED, slide=0.5, hinge=0.05).replace(
        '<flag contact="disable"/>', '<flag contact="disable" gravity="disable"/>')
    explicit = xml.replace('gravity="disable"/>', 'gravity="disable" eulerdamp="disable"/>')
    probe = build_model(read_params(xml=xml))
    nq, hinge = probe.nq, probe.hinges[0]
    minv = np.linalg.inv(np.asarray(probe.mass_matrix(np.zeros(probe.nx))))[hinge, hinge]
    width = probe.dt * 0.05 * minv / 4
    tails = {}
    for name, text in (("implicit", xml), ("explicit", explicit)):
        model = build_model(read_params(xml=text), friction_width=width)
        x = np.zeros(model.nx)
        x[nq + hinge] = 0.5
        rates = []
        for _ in range(400):
            x = model.step_np(x, np.zeros(model.nu))
            rates.append(abs(x[nq + hinge]))
        tails[name] = max(rates[-50:]) / width
    assert tails["implicit"] < 1e-6 and tails["explicit"] > 0.5, tails


def test_disabled_frictionloss_is_read_as_none_and_mujoco_applies_none():
    xml = FRICTION.replace('<flag contact="disable"/>', '<flag contact="disable" frictionloss="disable"/>')
    p = read_params(xml=xml)
    assert not p.has_friction
    m, d = _mujoco(xml)
    _load(m, d, np.array([0.1, 0.2, 1.0, -1.0]), np.zeros(1))
    assert np.all(d.qfrc_constraint == 0)


SAME_AS_SHIPPED = {
    "frictionloss 0 written out": _with_friction(SHIPPED, slide=0, hinge=0),
    "motor as an affine general with zero bias": SHIPPED.replace(
        '<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/>',
        '<general name="motor" joint="slider" gear="20" gainprm="1" biastype="affine" biasprm="0 0 0" '
        'ctrlrange="-1 1"/>'),
    "actuator damping and armature 0 written out": SHIPPED.replace(
        'ctrlrange="-1 1"/>', 'ctrlrange="-1 1" damping="0" armature="0"/>'),
}


@pytest.mark.parametrize("case", list(SAME_AS_SHIPPED))
@pytest.mark.parametrize("width", [DEFAULT_FRICTION_WIDTH, 0.05])
def test_without_friction_or_bias_the_model_is_the_frictionless_one_bit_for_bit(case, width):
    """The same physics written with explicit zeros (frictionloss, bias, actuator damping), built with any friction
    width, gives the very same CasADi expression graphs as the shipped file (serialized Functions equal: the friction
    and bias code adds no operation) and bit-identical numbers."""
    ref = build_model()
    model = build_model(read_params(xml=SAME_AS_SHIPPED[case]), friction_width=width)
    for name in ("f", "step", "AB", "ABd", "mass_matrix", "bias", "energy"):
        assert getattr(model, name).serialize() == getattr(ref, name).serialize(), name
    xs, us = random_states(ref.params, 20, seed=6)
    for x, u in zip(xs, us):
        for name in ("f", "step"):
            np.testing.assert_array_equal(np.asarray(getattr(model, name)(x, u)), np.asarray(getattr(ref, name)(x, u)))
        for a, b in zip(model.ABd(x, u), ref.ABd(x, u)):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    np.testing.assert_array_equal(model.x_eq, ref.x_eq)
    np.testing.assert_array_equal(model.u_eq, ref.u_eq)
    assert np.all(np.asarray(model.friction(xs[1])) == 0)


def test_rebuilt_model_keeps_its_friction_width():
    model = build_model(read_params(xml=FRICTION), friction_width=0.03)
    assert model.rebuilt(dt=0.01).friction_width == 0.03


@pytest.mark.parametrize("width", [0.0, -0.01, float("nan"), float("inf"), "wide"])
def test_a_friction_width_that_is_not_a_positive_velocity_is_refused_with_one_sentence(width):
    with pytest.raises(FrictionWidthError) as info:
        build_model(read_params(xml=FRICTION), friction_width=width)
    msg = str(info.value)
    assert "\n" not in msg and msg.endswith(".")


def test_friction_function_is_symbolic_and_differentiable():
    model = build_model(read_params(xml=FRICTION))
    x = ca.SX.sym("x", model.nx)
    J = ca.Function("J", [x], [ca.jacobian(model.friction(x), x)])
    Jv = np.asarray(J(np.zeros(model.nx)))[:, model.nq:]
    np.testing.assert_allclose(Jv, -np.diag(model.params.frictionloss) / model.friction_width, rtol=1e-15)


def test_friction_treatment_lists_each_joint_with_friction_and_what_the_design_did_with_it():
    from cartpole.models import friction_treatment

    params = read_params(SHIPPED_MJCF.parent / "examples" / "cartpole_friction.xml")
    smooth = friction_treatment(params, width=0.02)
    assert [e["joint"] for e in smooth] == [j.name for j in params.joints if j.frictionloss]
    for e in smooth:
        assert e["design"] == "smooth" and e["width"] == 0.02
        assert e["damping_at_rest"] == pytest.approx(e["frictionloss"] / 0.02)
    slide = params.slide
    mixed = friction_treatment(params, width=0.02, omitted=range(params.nq), cancelled=[slide])
    assert [e["design"] for e in mixed] == ["cancelled" if i == slide else "omitted"
                                            for i, j in enumerate(params.joints) if j.frictionloss]
    assert all("damping_at_rest" not in e for e in mixed)
    assert friction_treatment(read_params(SHIPPED_MJCF), width=0.01) == []
