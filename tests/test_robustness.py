"""The trajopt + TVLQR swing-up holds up in MuJoCo when the planning model is wrong and the start is off.

Success (each from a MuJoCo rollout that replays exactly): upright and held (|wrapped theta| < 0.05 rad and
the cart inside the track for the last second), the cart never at its joint limit, |ctrl| within range.
"""
import numpy as np
import pytest

from cartpole.models import build_model, read_params, wrap_angle
from cartpole.ocp.pipeline import trajopt_swingup
from cartpole.sim import replays_exactly, simulate

HANGING = np.array([0.0, np.pi, 0.0, 0.0])


def swung_up_and_held(rollout, params, hold: float = 1.0) -> tuple[bool, str]:
    """The success test of the module docstring; returns (ok, reason)."""
    last = rollout.t >= rollout.t[-1] - hold
    theta = wrap_angle(rollout.qpos[:, 1])
    lo, hi = params.cart_range
    if not np.all(np.abs(theta[last]) < 0.05):
        return False, f"pole not held upright: max |theta| {np.abs(theta[last]).max():.3f} rad in the last {hold} s"
    s = rollout.qpos[:, 0]
    if not (np.all(s > lo + 1e-6) and np.all(s < hi - 1e-6)):
        return False, f"cart reached its joint limit (s in [{s.min():.3f}, {s.max():.3f}] m)"
    clo, chi = params.ctrl_range
    if not np.all((rollout.ctrl >= clo) & (rollout.ctrl <= chi)):
        return False, "ctrl outside the ctrl range"
    if not replays_exactly(rollout, params):
        return False, "rollout does not replay exactly"
    return True, "ok"


def _run(params, plan, x0, extra=2.0):
    ro = simulate(params, plan.controller, x0, plan.T + extra)
    ok, why = swung_up_and_held(ro, params)
    assert ok, why
    return ro


@pytest.fixture(scope="module")
def shipped():
    return read_params()


def test_pipeline_swings_up_every_variant(any_mjcf):
    params = read_params(any_mjcf)
    plan = trajopt_swingup(params)
    assert plan.solve_info.success and plan.T_min is not None and plan.T > plan.T_min
    ro = _run(params, plan, HANGING)
    assert plan.controller.handover_time == pytest.approx(plan.T, abs=params.timestep)
    # the pole reaches upright (within 0.05 rad for good) before the plan ends plus one second
    theta = np.abs(wrap_angle(ro.qpos[:, 1]))
    up = ro.t[np.nonzero(theta >= 0.05)[0][-1] + 1]
    assert up < plan.T + 1.0


@pytest.mark.parametrize("mass_factor,length_factor", [(1.1, 1.1), (0.9, 0.9), (1.1, 0.9), (0.9, 1.1)])
def test_wrong_pole_mass_and_length_in_the_model(shipped, mass_factor, length_factor):
    wrong = build_model(shipped.scaled_pole(mass_factor, length_factor))
    assert wrong.params.pole_mass != shipped.pole_mass
    plan = trajopt_swingup(shipped, model=wrong)
    assert plan.model is wrong
    _run(shipped, plan, HANGING)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_start_offsets_with_the_nominal_plan(shipped, seed):
    rng = np.random.default_rng(100 + seed)
    x0 = HANGING + rng.uniform(-1, 1, 4) * np.array([0.05, 0.1, 0.1, 0.2])
    plan = trajopt_swingup(shipped)  # planned from hanging rest; TVLQR absorbs the offset
    _run(shipped, plan, x0)


def test_wrong_model_and_offset_start_together(shipped):
    plan = trajopt_swingup(shipped, model=build_model(shipped.scaled_pole(1.1, 1.1)))
    _run(shipped, plan, HANGING + np.array([0.05, -0.1, 0.1, -0.2]))


def test_a_start_several_turns_around_is_the_same_swing_up(shipped):
    x0 = HANGING + np.array([0, 4 * np.pi, 0, 0])  # MuJoCo hinge angles never wrap
    plan = trajopt_swingup(shipped, x0)
    assert plan.solve_info.success
    _run(shipped, plan, x0)
