"""Friction compensation: the wrapper's ctrl cancels the model's smooth friction, and in MuJoCo (whose frictionloss is
the true constraint) the lab's LQR with it balances the lab's five starts, closer to the frictionless runs than
without it. References: the model's own friction Function, and MuJoCo runs of the same controller on the
frictionless cart."""
import numpy as np
import pytest

from cartpole.apps.lab import LAB_DURATION, lab_initial_conditions
from cartpole.control.friction import FrictionCompensation
from cartpole.control.linear import LinearFeedback
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.sim import simulate
from cartpole.validation.jacobians import random_states
from cartpole.validation.metrics import settling_time_seed, settling_time_strict

SLIDE_FRICTION, HINGE_FRICTION = 0.5, 0.002  # N on the cart's slider, N m on the hinge


def _friction_params(slide=SLIDE_FRICTION, hinge=HINGE_FRICTION):
    xml = (SHIPPED_MJCF.read_text()
           .replace('damping="0.1"/>', f'damping="0.1" frictionloss="{slide}"/>')
           .replace('damping="0.01"/>', f'damping="0.01" frictionloss="{hinge}"/>'))
    return read_params(xml=xml)


@pytest.fixture(scope="module")
def frictionless():
    return build_model()


@pytest.fixture(scope="module")
def with_friction():
    return build_model(_friction_params())


def test_compensation_cancels_the_models_friction_on_every_driven_joint(with_friction):
    model = with_friction
    law = LinearFeedback.for_model(model)
    comp = FrictionCompensation(law, model)
    xs, _ = random_states(model.params, 50, seed=1)
    xs[:, model.nq:] *= 0.02  # inside the ctrl range, and through the tanh's curved band
    for x in xs:
        u_f = comp.feedforward(x)
        force = model.actuation @ u_f + np.asarray(model.friction(x)).ravel()
        # the cart's friction is cancelled; the hinge's, which no actuator drives, is left as it is
        assert force[model.slide] == pytest.approx(0.0, abs=1e-15)
        assert force[model.hinges[0]] == pytest.approx(float(np.asarray(model.friction(x))[model.hinges[0], 0]))
        np.testing.assert_allclose(comp(0.0, x), np.clip(law(0.0, x) + u_f, model.u_low, model.u_high), rtol=1e-15)


def test_compensation_is_clipped_to_the_ctrl_range(with_friction):
    model = with_friction
    comp = FrictionCompensation(lambda t, x: model.u_high[0], model)
    x = np.zeros(model.nx)
    x[model.nq + model.slide] = 1.0  # sliding forwards: the compensation pushes forwards too
    assert comp(0.0, x)[0] == model.u_high[0]
    x[model.nq + model.slide] = -1.0
    assert comp(0.0, x)[0] == pytest.approx(model.u_high[0] - SLIDE_FRICTION / model.params.gear, rel=1e-12)


def test_the_width_defaults_to_the_models_and_can_be_given(with_friction):
    law = LinearFeedback.for_model(with_friction)
    assert FrictionCompensation(law, with_friction).width == with_friction.friction_width
    comp = FrictionCompensation(law, with_friction, width=0.1)
    x = np.zeros(with_friction.nx)
    x[with_friction.nq + with_friction.slide] = 0.1
    gear = with_friction.params.gear
    assert comp.feedforward(x)[0] == pytest.approx(SLIDE_FRICTION * np.tanh(1.0) / gear, rel=1e-15)


def test_the_wrapped_controllers_attributes_read_through(with_friction):
    law = LinearFeedback.for_model(with_friction)
    comp = FrictionCompensation(law, with_friction)
    assert comp.K is law.K and comp.x_eq is law.x_eq and comp.S is law.S and comp.hinges == law.hinges
    x = with_friction.x_eq + 0.01
    assert comp.cost_to_go(x) == law.cost_to_go(x)
    with pytest.raises(AttributeError):
        comp.no_such_attribute  # noqa: B018


def test_a_model_without_friction_compensates_nothing(frictionless):
    law = LinearFeedback.for_model(frictionless)
    comp = FrictionCompensation(law, frictionless)
    xs, _ = random_states(frictionless.params, 20, seed=2)
    for x in xs:
        np.testing.assert_array_equal(comp(0.0, x), law(0.0, x))


def _runs(params, controller, x0s, x_eq, duration=LAB_DURATION):
    """Per start: (largest |cart error| over the last 2 s, largest |angle error| there, the lab's settling time,
    the strict one), and whether any run diverged."""
    rows, diverged = [], False
    for x0 in x0s:
        r = simulate(params, controller, x0, duration)
        diverged |= r.info.get("diverged") is not None
        e = r.x - x_eq
        tail = r.t >= r.t[-1] - 2.0
        rows.append([np.abs(e[tail, 0]).max(), np.abs(e[tail, 1]).max(), settling_time_seed(r.t, r.x, x_eq=x_eq),
                     settling_time_strict(r.t, r.x, x_eq)])
    return np.array(rows), diverged


def test_lab_lqr_with_compensation_balances_the_five_lab_starts_on_a_cart_with_friction(frictionless, with_friction):
    """MuJoCo with 0.5 N on the slider and 0.002 N m on the hinge. Both loops balance (the pole inside the lab's
    0.05 rad band within half a second, never diverging); the hinge's stiction, which no actuator can cancel, leaves
    a small limit cycle in both, and compensation shrinks the cart's part of it."""
    law = LinearFeedback.for_model(frictionless)
    x0s = lab_initial_conditions(frictionless)
    x_eq = frictionless.x_eq
    plain, div_plain = _runs(with_friction.params, law, x0s, x_eq)
    comp, div_comp = _runs(with_friction.params, FrictionCompensation(law, with_friction), x0s, x_eq)
    assert not div_plain and not div_comp
    for rows in (plain, comp):
        assert np.all(rows[:, 2] < 0.5) and np.all(rows[:, 1] < 0.02)
    assert comp[:, 0].max() < plain[:, 0].max()


def test_compensation_restores_the_frictionless_settling_when_the_friction_is_on_the_driven_joint(frictionless):
    """Friction on the slider only (the motor's joint): without compensation the cart sticks short of the centre and
    creeps in, settling (strictly, every state error within 0.01) seconds after the frictionless run; with it the
    runs settle within 0.5 s of the frictionless ones."""
    params = _friction_params(hinge=0.0)
    model = build_model(params)
    law = LinearFeedback.for_model(frictionless)
    x0s = lab_initial_conditions(frictionless)
    x_eq = frictionless.x_eq
    duration = 10.0
    ref, _ = _runs(frictionless.params, law, x0s, x_eq, duration)
    plain, _ = _runs(params, law, x0s, x_eq, duration)
    comp, _ = _runs(params, FrictionCompensation(law, model), x0s, x_eq, duration)
    assert np.all(np.isfinite(ref[:, 3])) and np.all(np.isfinite(comp[:, 3]))
    assert np.all(np.abs(comp[:, 3] - ref[:, 3]) < 0.5)
    assert np.all(plain[:, 3] > ref[:, 3] + 2.0)


def test_linear_designs_ignore_dry_friction_and_beat_the_smooth_friction_linearisation(frictionless, with_friction):
    """Linearised at rest, the smooth friction is a viscous damping frictionloss / width (50 N s/m on the cart): an
    LQR on it expects a damping that neither the compensated plant (friction cancelled) nor MuJoCo's Coulomb friction
    has, so its gains are much higher and its runs settle later and swing the cart further than the design without
    friction, which is what LinearFeedback.for_model gives on a model with friction."""
    from cartpole.riccati import lqr
    from cartpole.riccati.weights import default_weights

    x0s = lab_initial_conditions(frictionless)
    x_eq = frictionless.x_eq
    designed = LinearFeedback.for_model(with_friction)
    np.testing.assert_array_equal(designed.K, LinearFeedback.for_model(frictionless).K)
    smooth = lqr(*with_friction.linearize(), *default_weights(with_friction))
    assert abs(smooth.K[0, 1]) > 2 * abs(designed.K[0, 1])
    on_friction = LinearFeedback(smooth.K, x_eq, with_friction.u_eq, u_limits=with_friction.params.ctrl_range,
                                 S=smooth.S, hinges=with_friction.hinges)
    for wrap in (lambda c: c, lambda c: FrictionCompensation(c, with_friction)):
        good, _ = _runs(with_friction.params, wrap(designed), x0s, x_eq)
        other, _ = _runs(with_friction.params, wrap(on_friction), x0s, x_eq)
        assert good[:, 0].max() < other[:, 0].max()
        assert good[:, 2].sum() < other[:, 2].sum()


def test_friction_design_removes_only_the_driven_joints_friction_and_wraps_in_compensation(with_friction):
    from cartpole.control.friction import friction_design
    from cartpole.sim.options import LoopOptions

    friction = friction_design(with_friction)
    design = friction.model
    assert friction.compensated and friction.plant is with_friction
    assert design.params.frictionloss[with_friction.slide] == 0.0
    assert design.params.frictionloss[with_friction.hinges[0]] == HINGE_FRICTION
    assert design.params.mjcf == with_friction.params.mjcf and design.params.xml == with_friction.params.xml
    law = LinearFeedback.for_model(design)
    comp = friction.wrap(law)
    assert isinstance(comp, FrictionCompensation) and comp.controller is law
    assert comp.frictionloss[0] == SLIDE_FRICTION
    off = friction_design(with_friction, LoopOptions(friction_compensation=False))
    assert off.model is with_friction and not off.compensated and off.wrap(law) is law


def test_a_model_whose_driven_joints_are_frictionless_needs_no_compensation(frictionless):
    from cartpole.control.friction import friction_design, friction_summary

    hinge_only = build_model(_friction_params(slide=0.0))
    for model in (frictionless, hinge_only):
        friction = friction_design(model)
        assert friction.model is model and not friction.compensated
    assert friction_summary(frictionless.params, False) is None
    assert friction_summary(hinge_only.params, False) == {"frictionloss": {"hinge": HINGE_FRICTION},
                                                          "compensation": False}
