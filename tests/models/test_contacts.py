"""Contacts judged by whether MuJoCo's geometry lets them happen, not by the collision masks (issue 38, class 1)."""
import re

import mujoco
import numpy as np
import pytest

from cartpole.models import (CONTACT_MARGIN, SHIPPED_MJCF, ContactError, MJCFError, build_model, contact_report,
                             read_params)

#: A cart-pole written the way third-party files are: a floor with MuJoCo's default contype/conaffinity, contacts on.
TEMPLATE = """<mujoco model="published">
  <option timestep="0.005"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    {extra}
    <body name="cart" pos="0 0 {cart_z}">
      <joint name="slider" type="slide" axis="1 0 0" {rail}/>
      <geom name="cart_geom" type="box" size="0.1 0.05 0.05" mass="1"/>
      <body name="pole" pos="0 0 {hinge_z}">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.01"/>
        <geom name="pole_geom" type="capsule" fromto="0 0 0 0 0 {length}" size="{radius}" mass="0.1"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/></actuator>
</mujoco>"""

RAIL = 'limited="true" range="-1.5 1.5"'
LENGTH, RADIUS = 0.6, 0.02


def mjcf(tmp_path, name="model", *, cart_z=0.8, hinge_z=0.0, length=LENGTH, extra="", rail=RAIL):
    """Write the template with these numbers into ``tmp_path`` and return the path."""
    path = tmp_path / f"{name}.xml"
    path.write_text(TEMPLATE.format(cart_z=cart_z, hinge_z=hinge_z, length=length, radius=RADIUS, extra=extra,
                                    rail=rail))
    return path


def pair(report, a, b):
    """The report's pair of geoms ``a`` and ``b`` (either order)."""
    found = [p for p in report.pairs if {p.geom1, p.geom2} == {a, b}]
    assert len(found) == 1, [(p.geom1, p.geom2) for p in report.pairs]
    return found[0]


def test_a_floor_with_default_masks_that_nothing_reaches_is_accepted_and_listed_never(tmp_path):
    model = build_model(mjcf(tmp_path, cart_z=0.8))
    report = model.contacts
    assert report.enabled and {(p.geom1, p.geom2) for p in report.pairs} == {("floor", "cart_geom"),
                                                                             ("floor", "pole_geom")}
    assert all(p.classification == "never" and p.certified for p in report.pairs)
    assert all(p.clearance_bound >= CONTACT_MARGIN / 2 for p in report.pairs)
    # the hanging pole's tip is the nearest the pole comes: 0.8 - length - radius above the floor
    assert pair(report, "floor", "pole_geom").min_clearance == pytest.approx(0.8 - LENGTH - RADIUS, abs=1e-6)
    assert pair(report, "floor", "cart_geom").min_clearance == pytest.approx(0.8 - 0.05, abs=1e-9)
    report.check_swingup()  # nothing to refuse


def test_a_short_rail_allows_balancing_and_refuses_the_swing_up_naming_the_angle_from_hanging(tmp_path):
    cart_z = 0.3
    model = build_model(mjcf(tmp_path, cart_z=cart_z))  # balance: accepted
    p = pair(model.contacts, "floor", "pole_geom")
    assert p.classification == "away_from_upright" and p.upright_clearance > CONTACT_MARGIN
    assert p.min_clearance == pytest.approx(cart_z - LENGTH - RADIUS, abs=1e-6)  # deepest: hanging straight down
    assert pair(model.contacts, "floor", "cart_geom").classification == "never"
    with pytest.raises(ContactError) as info:
        model.contacts.check_swingup()
    msg = str(info.value)
    assert "'floor' and 'pole_geom'" in msg and "\n" not in msg and msg.endswith(".")
    # the tip (length + radius from the hinge) comes within the margin of the floor below this angle from hanging
    expected = np.arccos((cart_z - RADIUS - p.threshold) / LENGTH)
    angle = float(re.search(r"hinge 'hinge' within ([0-9.]+) rad of hanging", msg).group(1))
    assert angle == pytest.approx(expected, abs=0.01)
    assert "contype=\"0\"" in msg and "body 'cart'" in msg


def test_a_rail_inside_the_cart_is_refused_naming_the_rail_and_the_cart_and_their_depth(tmp_path):
    rail = '<geom name="rail" type="box" size="2 0.02 0.02" pos="0 0 0.8"/>'
    with pytest.raises(ContactError) as info:
        build_model(mjcf(tmp_path, cart_z=0.8, extra=rail))
    msg = str(info.value)
    assert "geoms 'rail' and 'cart_geom' touch at the upright equilibrium" in msg and "floor" not in msg
    assert "(0.07 m deep)" in msg  # the cart's half height 0.05 plus the rail's 0.02
    assert "give 'rail' contype=\"0\" conaffinity=\"0\"" in msg and msg.endswith(".") and "\n" not in msg
    assert isinstance(info.value, MJCFError)


def test_a_pole_inside_the_floor_at_upright_is_refused_at_the_equilibrium(tmp_path):
    with pytest.raises(ContactError, match=r"'floor' and 'pole_geom' touch at the upright equilibrium \(0.12 m deep\)"):
        build_model(mjcf(tmp_path, cart_z=0.3, hinge_z=-0.4))  # the upright pole spans z = -0.1 .. 0.5


def test_the_same_rail_without_its_contacts_is_accepted(tmp_path):
    rail = '<geom name="rail" type="box" size="2 0.02 0.02" pos="0 0 0.8" contype="0" conaffinity="0"/>'
    report = build_model(mjcf(tmp_path, extra=rail)).contacts
    assert all("rail" not in (p.geom1, p.geom2) for p in report.pairs)


def test_exclude_and_disabled_contacts_leave_no_pair(tmp_path):
    excl = mjcf(tmp_path, "excl", cart_z=0.3).read_text().replace(
        "</worldbody>", '</worldbody><contact><exclude body1="world" body2="pole"/></contact>')
    report = build_model(read_params(xml=excl)).contacts
    assert {(p.geom1, p.geom2) for p in report.pairs} == {("floor", "cart_geom")}
    off = mjcf(tmp_path, "off", cart_z=0.3).read_text().replace('<option timestep="0.005"/>',
                                                                '<option timestep="0.005"><flag contact="disable"/>'
                                                                '</option>')
    report = build_model(read_params(xml=off)).contacts
    assert not report.enabled and report.pairs == ()
    report.check_swingup()


def test_an_explicit_pair_is_judged_like_any_other(tmp_path):
    xml = mjcf(tmp_path, cart_z=0.3).read_text().replace('<geom name="floor" type="plane" size="5 5 0.1"/>',
                                                         '<geom name="floor" type="plane" size="5 5 0.1" contype="0" '
                                                         'conaffinity="0"/>')
    xml = xml.replace('mass="1"/>', 'mass="1" contype="0" conaffinity="0"/>').replace(
        'mass="0.1"/>', 'mass="0.1" contype="0" conaffinity="0"/>')
    xml = xml.replace("</worldbody>", '</worldbody><contact><pair geom1="floor" geom2="pole_geom"/></contact>')
    report = build_model(read_params(xml=xml)).contacts
    (p,) = report.pairs
    assert p.explicit and p.classification == "away_from_upright"
    with pytest.raises(ContactError, match="remove their <pair>"):
        report.check_swingup()


def test_every_touch_reported_is_a_real_mujoco_contact_and_every_never_pair_is_clear_on_a_dense_grid(tmp_path):
    """Soundness, checked by MuJoCo's own contact detection (mj_forward, ncon) and a grid far finer than the search."""
    path = mjcf(tmp_path, cart_z=0.45, extra='<geom name="post" type="box" size="0.05 0.05 0.05" pos="1.2 0 0.1"/>')
    model = build_model(path)
    report = model.contacts
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    ids = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g): g for g in range(m.ngeom)}
    touching = report.reachable
    assert {(p.geom1, p.geom2) for p in touching} >= {("floor", "pole_geom"), ("post", "pole_geom")}
    for p in touching:  # the witness configuration is closer than the threshold in MuJoCo itself
        d.qpos[:] = p.qpos
        mujoco.mj_kinematics(m, d)
        assert mujoco.mj_geomDistance(m, d, ids[p.geom1], ids[p.geom2], 10.0, None) < p.threshold
    carts, angles = np.linspace(-1.5, 1.5, 121), np.linspace(-np.pi, np.pi, 181)
    for p in report.of_class("never"):
        worst = np.inf
        for s in carts:
            for th in angles:
                d.qpos[:] = [s, th]
                mujoco.mj_kinematics(m, d)
                worst = min(worst, mujoco.mj_geomDistance(m, d, ids[p.geom1], ids[p.geom2], 10.0, None))
        assert worst >= p.clearance_bound - 1e-9 and worst >= CONTACT_MARGIN / 2


def test_an_unlimited_rail_reaches_a_post_but_slides_along_the_floor(tmp_path):
    post = '<geom name="post" type="box" size="0.05 0.5 0.5" pos="4 0 0.5"/>'
    report = build_model(mjcf(tmp_path, rail="", extra=post)).contacts
    assert pair(report, "floor", "cart_geom").classification == "never"
    p = pair(report, "post", "cart_geom")
    assert p.classification == "away_from_upright" and "slider" in p.joints
    assert "slide 'slider' between" in p.where


def test_a_three_pole_chain_with_default_contacts_is_searched_fast_and_completely():
    xml = SHIPPED_MJCF.with_name("cartpole_three_pole.xml").read_text().replace('<flag contact="disable"/>', "")
    model = build_model(read_params(xml=xml))
    report = model.contacts
    assert all(p.certified for p in report.pairs)
    # hanging from the hinge at 2.35 m, the 1.8 m chain (and its 0.02 m radius) stays 0.53 m above the floor
    floor = [p for p in report.pairs if p.geom1 == "floor"]
    assert floor and all(p.classification == "never" for p in floor)
    # a folded chain reaches its own cart: the third link can touch the cart only away from upright
    assert pair(report, "cart_geom", "pole3_geom").classification == "away_from_upright"
    assert report.evaluations < 20000


def test_the_report_is_frozen_json_ready_and_cached(tmp_path):
    import json

    model = build_model(mjcf(tmp_path, cart_z=0.3))
    report = model.contacts
    with pytest.raises(Exception):
        report.pairs = ()
    doc = json.loads(json.dumps(report.to_dict()))
    assert doc["margin"] == CONTACT_MARGIN and doc["cart_range"] == [-1.5, 1.5]
    assert {p["classification"] for p in doc["pairs"]} == {"never", "away_from_upright"}
    assert contact_report(model.params, model.x_eq, x_hanging=model.x_hanging) is report


def test_a_run_that_touches_says_so_and_is_no_swing_up_success(tmp_path):
    from cartpole.sim import simulate
    from cartpole.validation.metrics import swingup_metrics, touched

    model = build_model(mjcf(tmp_path, cart_z=0.3))
    x0 = np.array(model.x_eq, float)
    x0[model.hinges[0]] += 0.3  # falls, with no ctrl, onto the floor
    run = simulate(model.params, lambda t, x: np.zeros(model.nu), x0, 2.0)
    c = touched(run)
    assert c is not None and {c["geom1"], c["geom2"]} == {"floor", "pole_geom"} and c["steps"] > 0
    assert swingup_metrics(run, model)["contact"] == c and not swingup_metrics(run, model)["success"]
    clear = simulate(model.params, lambda t, x: np.zeros(model.nu), model.x_eq, 0.1)
    assert touched(clear) is None


def test_a_rail_beside_the_plane_of_motion_is_cleared_by_its_offset_alone(tmp_path):
    """dm_control's layout: rails along the track beside the cart, at y = +-0.1 (radius 0.02), the pole swinging in
    the x-z plane at y = 0."""
    rails = ''.join(f'<geom name="rail{i}" type="capsule" fromto="-2 {y} 0.8 2 {y} 0.8" size="0.02"/>'
                    for i, y in ((1, 0.1), (2, -0.1)))
    report = build_model(mjcf(tmp_path, extra=rails)).contacts
    for name in ("rail1", "rail2"):
        p = pair(report, name, "pole_geom")
        assert p.classification == "never" and p.certified
        assert p.clearance_bound == pytest.approx(0.1 - 0.02 - RADIUS, abs=1e-9)  # their gap across the plane
