"""Energy shaping: the law realises the cart acceleration it asks for, pumps energy the right way for either hinge
sign, a timid gain stalls short of the top in MuJoCo, and the default gains beat the hinge damping."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.control.energy import (EnergyShapingController, EnergyShapingError, default_gains, model_scales)
from cartpole.sim import replays_exactly, simulate


def _random_states(rng, n):
    return np.column_stack([rng.uniform(-0.8, 0.8, n), rng.uniform(-np.pi, np.pi, n),
                            rng.uniform(-2, 2, n), rng.uniform(-8, 8, n)])


@pytest.mark.parametrize("name", ["shipped", "flipped_offset_armature", "heavy_pole"])
def test_ctrl_gives_exactly_the_requested_cart_acceleration(name, variant_dir):
    path = None if name == "shipped" else variant_dir / f"cartpole_{name}.xml"
    model = cp.build_model(path)
    c = EnergyShapingController(model)
    lo, hi = model.params.ctrl_range[0]
    checked = 0
    for x in _random_states(np.random.default_rng(1), 200):
        ev = c.evaluate(x)
        if lo < ev["ctrl"] < hi:  # unsaturated: the model's own dynamics must give a_d exactly
            assert model.dynamics(x, ev["ctrl"])[2] == pytest.approx(ev["a"], rel=1e-9, abs=1e-9)
            checked += 1
    assert checked > 20


@pytest.mark.parametrize("name", ["shipped", "flipped_offset_armature"])
def test_energy_term_pumps_towards_the_target_for_either_hinge_sign(name, variant_dir):
    """With centring, guard and damping compensation off, dE/dt + D2 theta_dot^2 (the power the cart puts in),
    computed by finite differences of the model's pole energy along f(x, u), has the sign of E_ref - E."""
    path = None if name == "shipped" else variant_dir / f"cartpole_{name}.xml"
    model = cp.build_model(path)
    p = model.params
    c = EnergyShapingController(model, dict(k_x=0.0, k_v=0.0, energy_target=0.0, damping_softening=np.inf,
                                                  track_margin=-0.0, kick=0.0, energy_accel=1.0))
    arm = p.armature[1]
    energy = lambda x: float(model.pole_energy(x)) + 0.5 * arm * x[3] ** 2  # noqa: E731
    checked = 0
    for x in _random_states(np.random.default_rng(2), 300):
        x[0], x[2] = 0.0, 0.0  # far from the track ends so the guard is idle
        ev = c.evaluate(x)
        if abs(ev["w"]) < 0.5 or abs(ev["E"]) < 1e-3:
            continue
        xd = model.dynamics(x, ev["ctrl"])
        h = 1e-6
        dE = (energy(x + h * xd) - energy(x - h * xd)) / (2 * h)
        pumped = dE + p.damping[1] * x[3] ** 2
        assert np.sign(pumped) == np.sign(0.0 - ev["E"]), (x, pumped, ev)
        checked += 1
    assert checked > 50


def test_timid_gain_stalls_short_of_the_top_and_default_gains_do_not():
    """DESIGN.md: with k_E ~ 5 and E_ref = E_up the hinge damping caps the pumped energy below the top. Measured from
    a MuJoCo rollout (energy shaping alone, no catch): the energy deficit over the last 5 s is positive."""
    params = cp.read_params()
    model = cp.build_model(params)
    timid = EnergyShapingController(model, dict(k_energy=5.0, energy_target=0.0, damping_softening=np.inf,
                                                energy_accel=1.0))
    r = simulate(params, timid, (0, np.pi, 0, 0), 15.0)
    assert replays_exactly(r)
    E = np.asarray(model.pole_energy.map(len(r.x))(r.x.T)).ravel()
    deficit = -E[r.t >= 10.0].max()
    print(f"\ntimid k_E = 5 (no overshoot, no damping compensation): energy deficit {deficit:.4f} J "
          f"(of 2 m g l = {2 * model_scales(model)['mgl']:.4f} J)")
    assert deficit > 0
    assert np.abs(cp.wrap_angle(r.qpos[r.t >= 10.0, 1])).min() > 0.05  # never reaches the top
    # the default law (damping compensation, small overshoot, strong saturated gain) gets over the top
    default = EnergyShapingController(model)
    r2 = simulate(params, default, (0, np.pi, 0, 0), 3.0)
    E2 = np.asarray(model.pole_energy.map(len(r2.x))(r2.x.T)).ravel()
    assert E2.max() > 0
    assert np.abs(cp.wrap_angle(r2.qpos[:, 1])).min() < 0.05


def test_default_gains_scale_with_the_model(variant_dir):
    a = default_gains(cp.build_model())
    b = default_gains(cp.build_model(variant_dir / "cartpole_heavy_pole.xml"))
    # k_E a 2 mgl omega0 is the same dimensionless gain on both
    for g, m in ((a, cp.build_model()), (b, cp.build_model(variant_dir / "cartpole_heavy_pole.xml"))):
        sc = model_scales(m)
        assert g.k_energy * 2 * sc["mgl"] * sc["omega0"] / sc["a_max"] == pytest.approx(15.0)
    assert a.k_energy != pytest.approx(b.k_energy)


def test_bad_gains_raise_one_sentence():
    with pytest.raises(EnergyShapingError):
        EnergyShapingController(None, {"k_energy": -1.0})
    with pytest.raises(EnergyShapingError):
        EnergyShapingController(None, {"energy_gain": 0.0})
    with pytest.raises(EnergyShapingError):
        EnergyShapingController(None, {"no_such_gain": 1.0})



@pytest.mark.parametrize("name, what", [
    ("two_pole", "this model has 2 hinges"),
    ("three_pole", "this model has 3 hinges"),
    ("two_motors", "this model has 2 hinges"),
    ("acrobot", "this model has 2 hinges"),
    ("pendulum", "this model has no slide for a cart"),
])
def test_anything_but_one_pole_driven_by_the_cart_is_refused_with_one_sentence(name, what, chain_dir):
    from cartpole.control.energy import EnergyShapingModelError

    path = (cp.SHIPPED_MJCF.with_name(f"cartpole_{name}.xml") if name in ("two_pole", "three_pole")
            else chain_dir / f"{name}.xml")
    model = cp.build_model(path)
    with pytest.raises(EnergyShapingModelError) as err:
        EnergyShapingController(model)
    msg = str(err.value)
    assert msg == (f"Energy shaping is for one pole driven by the cart and {what}; use `method='trajopt'` "
                   "instead.")
    assert isinstance(err.value, cp.CartPoleError) and msg.count(". ") == 0 and "\n" not in msg
    with pytest.raises(EnergyShapingModelError, match="use `method='trajopt'` instead"):
        model_scales(model)


def test_a_motor_on_the_hinge_of_a_cart_is_refused(tmp_path):
    from cartpole.control.energy import EnergyShapingModelError

    xml = cp.read_params().xml.replace('joint="slider"', 'joint="hinge"', 1)
    assert 'joint="hinge"' in xml
    path = tmp_path / "hinge_motor.xml"
    path.write_text(xml)
    with pytest.raises(EnergyShapingModelError, match=r"its actuator drives joint 'hinge', not the cart's slide; "
                                                      r"use `method='trajopt'` instead\.$"):
        EnergyShapingController(cp.build_model(path))


def test_a_pole_built_off_vertical_is_pumped_from_its_own_upright(chain_dir):
    """Gymnasium's pendulum is 1 mm off vertical: the pole energy is zero at x_eq (not at qpos = 0), the law returns
    one ctrl and realises the cart acceleration it asks for."""
    model = cp.build_model(chain_dir / "gym_single_off_vertical.xml")
    assert model.x_eq[1] != 0.0
    c = EnergyShapingController(model)
    assert c.pole_energy(model.x_eq) == pytest.approx(0.0, abs=1e-12)
    assert c.pole_energy(np.zeros(4)) < 0  # qpos = 0 is below the true top
    ev = c.evaluate(model.x_eq)
    assert ev["E"] == pytest.approx(0.0, abs=1e-12)
    u = c(0.0, model.x_hanging)
    assert isinstance(u, np.ndarray) and u.shape == (1,)
    lo, hi = model.params.ctrl_range[0]
    checked = 0
    for x in _random_states(np.random.default_rng(3), 100):
        ev = c.evaluate(x)
        if lo < ev["ctrl"] < hi:
            assert model.dynamics(x, ev["ctrl"])[2] == pytest.approx(ev["a"], rel=1e-9, abs=1e-9)
            checked += 1
    assert checked > 5


def test_energy_options_are_one_validated_value_the_controller_and_the_sweep_vary_by_name():
    from cartpole.control.energy import DEFAULT_SCALING, EnergyOptions, EnergyShapingError, default_gains

    model = cp.build_model(None)
    opts = EnergyOptions(energy_gain=20.0)
    assert opts.replace(energy_gain=15.0) == EnergyOptions() and hash(opts.replace(energy_gain=15.0)) == hash(
        EnergyOptions())
    assert dict(DEFAULT_SCALING) == EnergyOptions().scaling
    # the options value, a dict of its fields and default_gains' keywords give the same gains
    assert EnergyShapingController(model, opts).gains == EnergyShapingController(model, {"energy_gain": 20.0}).gains \
        == default_gains(model, energy_gain=20.0)
    c = EnergyShapingController(model, opts.replace(k_x=0.0))
    assert c.gains.k_x == 0.0 and c.options.k_x == 0.0 and c.options.energy_gain == 20.0
    assert EnergyOptions.scalar_names() == tuple(DEFAULT_SCALING)
    with pytest.raises(EnergyShapingError, match="no field 'gain'"):
        EnergyOptions().replace(gain=1.0)
    with pytest.raises(EnergyShapingError, match="energy_accel = 2.0"):
        EnergyOptions(energy_accel=2.0)
    with pytest.raises(EnergyShapingError, match="not a number"):
        EnergyOptions(k_energy="fast")
    assert EnergyOptions(damping_softening=float("inf")).as_dict()["damping_softening"] == float("inf")
