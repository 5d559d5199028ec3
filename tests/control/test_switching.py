"""Switching between swing-up and LQR catch: hysteresis (no chattering), wrapped angle error, switch log."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.control import LinearFeedback
from cartpole.control.energy import EnergyShapingController
from cartpole.control.switching import SWINGUP_CATCH_R, SwitchingController, SwitchingError
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.basin import estimate_basin
from cartpole.validation.metrics import swingup_success


@pytest.fixture(scope="module")
def shipped():
    params = cp.read_params()
    model = cp.build_model(params)
    catch = LinearFeedback.for_model(model)
    return params, model, catch, estimate_basin(params, catch)


def _unit_catch():
    return LinearFeedback(np.zeros((1, 4)), u_limits=(-1, 1), S=np.eye(4))


def test_hysteresis_catch_below_rho_release_only_above_release_level():
    sw = SwitchingController(lambda t, x: 0.5, _unit_catch(), rho=1.0, release_factor=10.0)
    assert sw(0.0, [2, 0, 0, 0]) == 0.5 and sw.mode == "swingup"       # cost 4 > rho
    assert sw(0.1, [0.5, 0, 0, 0]) == 0.0 and sw.mode == "catch"       # cost 0.25 < rho
    assert sw(0.2, [2, 0, 0, 0]) == 0.0 and sw.mode == "catch"         # 4: between rho and 10 rho, stays
    assert sw(0.3, [4, 0, 0, 0]) == 0.5 and sw.mode == "swingup"       # 16 > 10 rho: released
    assert [(s.t, s.mode) for s in sw.switches] == [(0.1, "catch"), (0.3, "swingup")]
    assert sw.caught_at is None
    sw(0.0, [0.1, 0, 0, 0])  # time going back = new run: log reset
    assert [(s.t, s.mode) for s in sw.switches] == [(0.0, "catch")] and sw.caught_at == 0.0


def test_bad_levels_raise():
    with pytest.raises(SwitchingError):
        SwitchingController(lambda t, x: 0.0, _unit_catch(), rho=0.0)
    with pytest.raises(SwitchingError):
        SwitchingController(lambda t, x: 0.0, _unit_catch(), rho=1.0, release_factor=1.0)
    with pytest.raises(SwitchingError):
        SwitchingController(lambda t, x: 0.0, LinearFeedback(np.zeros((1, 4))), rho=1.0)


def test_infinite_release_factor_holds_the_catch_once_reached():
    sw = SwitchingController(lambda t, x: 0.5, _unit_catch(), rho=1.0, release_factor=float("inf"))
    assert sw(0.0, [2, 0, 0, 0]) == 0.5 and sw.mode == "swingup"       # cost 4 > rho
    assert sw(0.1, [0.5, 0, 0, 0]) == 0.0 and sw.mode == "catch"       # cost 0.25 < rho: caught
    assert sw(0.2, [1e6, 0, 0, 0]) == 0.0 and sw.mode == "catch"       # cost 1e12, far outside: still held
    assert [(s.t, s.mode) for s in sw.switches] == [(0.1, "catch")] and sw.caught_at == 0.1
    assert sw(0.0, [2, 0, 0, 0]) == 0.5 and sw.mode == "swingup"       # time going back = new run


def test_new_run_resets_the_swingup_law_too():
    class Law:
        resets = 0

        def reset(self):
            self.resets += 1

        def __call__(self, t, x):
            return 0.5

    law = Law()
    sw = SwitchingController(law, _unit_catch(), rho=1.0, release_factor=float("inf"))
    assert law.resets == 0  # building the switch leaves the law alone
    sw(0.0, [2, 0, 0, 0])
    sw(0.1, [0.5, 0, 0, 0])
    assert law.resets == 0
    sw(0.0, [2, 0, 0, 0])  # time going back: a new run
    assert law.resets == 1 and sw.mode == "swingup"
    sw.reset()
    assert law.resets == 2


@pytest.mark.parametrize("factor", [float("nan"), 0.5, 1.0, "20", None, True])
def test_release_factor_not_a_number_above_one_is_refused_in_one_sentence(factor):
    with pytest.raises(SwitchingError, match=r"^release_factor = .* must be a number above 1 \(inf: hold the catch "
                                             r"once reached\) so the release level is above the catch level\.$"):
        SwitchingController(lambda t, x: 0.0, _unit_catch(), rho=1.0, release_factor=factor)


def test_shipped_swingup_switches_once_no_chattering(shipped):
    params, model, catch, basin = shipped
    sw = SwitchingController(EnergyShapingController(model), catch, basin.rho)
    r = simulate(params, sw, (0, np.pi, 0, 0), 10.0)
    assert replays_exactly(r)
    assert len(sw.switches) == 1 and sw.switches[0].mode == "catch"
    assert sw.caught_at == sw.switches[0].t
    # the switch happened where the logged MuJoCo state is inside the basin
    k = int(round(sw.caught_at / r.dt))
    assert catch.cost_to_go(r.x[k]) < basin.rho
    assert swingup_success(r, params)


def test_start_one_turn_around_is_caught_at_once_not_swung_again(shipped):
    params, model, catch, basin = shipped
    sw = SwitchingController(EnergyShapingController(model), catch, basin.rho)
    x0 = (0.0, 2 * np.pi + 0.01, 0.0, 0.0)
    r = simulate(params, sw, x0, 3.0)
    assert replays_exactly(r)
    assert sw.switches[0].t == 0.0 and len(sw.switches) == 1
    assert np.all(np.abs(r.qpos[:, 1] - 2 * np.pi) < 0.05)  # never swung: stays at the same upright (2 pi)
    assert swingup_success(r, params)


def test_catch_is_designed_and_tested_about_x_eq_of_any_model(chain_dir):
    """The catch of a pole built off vertical holds x_eq (u = u_eq there) and its basin test wraps the error."""
    model = cp.build_model(chain_dir / "gym_single_off_vertical.xml")
    catch = LinearFeedback.for_model(model)
    np.testing.assert_array_equal(catch.x_eq, model.x_eq)
    assert catch.cost_to_go(model.x_eq) == 0.0
    turned = np.array(model.x_eq) + np.array([0.0, 2 * np.pi + 0.01, 0.0, 0.0])
    tilted = np.array(model.x_eq) + np.array([0.0, 0.01, 0.0, 0.0])
    assert catch.cost_to_go(turned) == pytest.approx(catch.cost_to_go(tilted), rel=1e-9)
    sw = SwitchingController(lambda t, x: 0.7, catch, rho=catch.cost_to_go(tilted) * 2)
    u = sw(0.0, turned)
    assert sw.mode == "catch" and isinstance(u, np.ndarray) and u.shape == (1,)
    np.testing.assert_allclose(u, catch(0.0, tilted), rtol=1e-9)
    assert sw(0.1, model.x_hanging).tolist() == [0.7] and sw.mode == "swingup"  # released far away


def test_two_pole_catch_uses_the_lab_weight_pattern_and_returns_one_ctrl_per_actuator():
    from cartpole.riccati import default_weights, lqr

    model = cp.build_model(cp.SHIPPED_MJCF.with_name("cartpole_two_pole.xml"))
    Q, R = default_weights(model)
    np.testing.assert_array_equal(np.diag(Q), [1, 10, 10, 0.1, 0.1, 0.1])
    A, B = model.linearize()
    np.testing.assert_array_equal(LinearFeedback.for_model(model).K, lqr(A, B, Q, R).K)
    np.testing.assert_array_equal(LinearFeedback.for_model(model, R=SWINGUP_CATCH_R).K, lqr(A, B, Q, np.eye(1)).K)
    assert LinearFeedback.for_model(model)(0.0, model.x_eq).shape == (1,)
