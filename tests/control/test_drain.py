"""The energy drain (:class:`~cartpole.control.drain.EnergyDrain`): on dm_control's acrobot swinging as one body, the
worst case for a damper on the elbow (the elbow still, the chain rigid), it reaches the upright's energy in MuJoCo
much sooner than the joints' damping alone and than the supervisor's passive brakes, stops there, and its errors."""
import numpy as np
import pytest

from cartpole.control import SWINGUP_CATCH_R, EnergyDrain, EnergyDrainError, LinearFeedback
from cartpole.models import build_model, read_params
from cartpole.sim import replays_exactly, simulate
from cartpole.sim.disturbance import joint_inertia_and_authority
from cartpole.supervise import PassiveBrake

ACROBOT = "cartpole/assets/dmc_acrobot.xml"
START_ENERGY = 50.0  # J above the upright's: a chain swinging over the top, more than a knock leaves (13-32 J, docs)


@pytest.fixture(scope="module")
def acrobot():
    params = read_params(ACROBOT)
    return params, build_model(params)


def _swinging(model, energy):
    """Hanging, the whole chain turning at the shoulder rate that gives it ``energy`` J (elbow rate zero)."""
    x0 = np.asarray(model.x_hanging, float).copy()
    inertia = float(np.asarray(model.mass_matrix(x0))[0, 0])
    x0[model.nq] = np.sqrt(2.0 * (energy - float(model.energy(x0))) / inertia)
    return x0


def _energies(run, model):
    return np.array([float(model.energy(np.concatenate([q, v]))) for q, v in zip(run.qpos, run.qvel)])


def _to_upright(params, model, law, x0, duration):
    """The MuJoCo run of ``law`` from ``x0``, its energies, and the first time (s) they are at most the upright's."""
    run = simulate(params, law, x0, duration)
    e = _energies(run, model)
    below = np.nonzero(e <= 0.0)[0]
    return run, e, (float(run.t[below[0]]) if len(below) else np.inf)


def test_the_drain_takes_the_acrobots_energy_to_the_upright_sooner_than_its_damping_and_the_brakes(acrobot):
    params, model = acrobot
    x0 = _swinging(model, START_ENERGY)
    inertia, _ = joint_inertia_and_authority(params, np.asarray(model.x_eq, float))
    limits = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R).u_limits
    soft = PassiveBrake(model, inertia, 1.5, limits)
    drain = EnergyDrain(model, below=soft, u_limits=limits)
    duration = 40.0
    run, e, t_drain = _to_upright(params, model, drain, x0, duration)
    # measured: the drain 15.9 s, damping alone (ctrl 0) 26.7 s, the soft brake 25.3 s, the stiff one 39.1 s
    t_damping = _to_upright(params, model, lambda t, x: np.zeros(1), x0, duration)[2]
    t_soft = _to_upright(params, model, soft, x0, duration)[2]
    assert t_drain < 0.75 * min(t_damping, t_soft), (t_drain, t_damping, t_soft)
    k = np.nonzero(e <= 0.0)[0][0]
    # it puts energy in for part of a swing (about 1 J at first, measured), never much above where it started, and
    # once at the target the passive brake keeps it there
    assert e[:k].max() < 1.05 * e[0] and e[k:].max() < 1e-6 * e[0], (e[:k].max(), e[k:].max())
    assert np.all(np.abs(np.asarray(run.ctrl)) <= 1.0 + 1e-12)
    assert replays_exactly(run, params) and not run.info.get("diverged", False)


def test_at_or_below_the_target_the_drain_hands_over(acrobot):
    _, model = acrobot
    calm = np.asarray(model.x_hanging, float)
    assert np.allclose(EnergyDrain(model, below=lambda t, x: np.array([0.3]))(0.0, calm), 0.3)
    assert np.allclose(EnergyDrain(model)(0.0, calm), model.u_eq)
    fast = _swinging(model, START_ENERGY)
    fast[model.nq + 1] = 10.0  # the elbow fast: full ctrl against it
    assert np.allclose(EnergyDrain(model)(0.0, fast), -1.0)
    fast[model.nq + 1] = -1.0  # slow: full ctrl with it
    assert np.allclose(EnergyDrain(model)(0.0, fast), -1.0)
    fast[model.nq + 1] = 1.0
    assert np.allclose(EnergyDrain(model)(0.0, fast), 1.0)


def test_a_flipped_gear_or_an_uneven_range_flips_or_scales_the_drains_ctrl(acrobot):
    """The ctrl that pushes the elbow forward is the gear's sign; each side of the range is used as it is."""
    params, model = acrobot
    fast = _swinging(model, START_ENERGY)
    fast[model.nq + 1] = 1.0  # slow: full ctrl with the elbow's motion
    flipped = build_model(read_params(xml=params.xml.replace('gear="2"', 'gear="-2"')))
    assert np.allclose(EnergyDrain(flipped)(0.0, fast), -1.0)
    uneven = [[-0.25, 0.5]]
    assert np.allclose(EnergyDrain(model, u_limits=uneven)(0.0, fast), 0.5)
    assert np.allclose(EnergyDrain(flipped, u_limits=uneven)(0.0, fast), -0.25)


def test_the_drain_says_what_is_wrong_with_its_model_or_rate(acrobot):
    _, model = acrobot
    with pytest.raises(EnergyDrainError, match="rate must be a positive number"):
        EnergyDrain(model, rate=0.0)
    with pytest.raises(EnergyDrainError, match="joint the motor does not drive"):
        EnergyDrain(build_model(read_params("cartpole/assets/dmc_pendulum.xml")))
