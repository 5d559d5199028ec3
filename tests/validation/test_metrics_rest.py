""""At rest" from quantised sensors (:func:`cartpole.validation.metrics.rest_tolerance`): each velocity's bound is the
exact-state one plus the rate the rig's quantised joint sensors cannot resolve within one period, derived from the
sensors, the period and the model; runs without sensors keep the exact-state bounds, and motion well past what the
counts hide (an oscillation inside the angle band, a drifting cart) still fails."""
import math
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from cartpole.estimation.sensors import Sensor, SensorSpec, sensor_spec
from cartpole.models import SHIPPED_MJCF, mujoco_model, read_params
from cartpole.sim import Rollout
from cartpole.validation.metrics import (REST_RATE_TOL, REST_SPEED_TOL, held_upright, rest_tolerance,
                                         swingup_metrics, swingup_success)

CARTS = ["cartpole.xml", "cartpole_two_pole.xml", "cartpole_three_pole.xml"]
PERIOD = 0.01


def _rig(params, cpr=2048, resolution=None, period=PERIOD):
    return SimpleNamespace(spec=sensor_spec(params, encoder_cpr=cpr, encoder_resolution=resolution), period=period)


def _exact(params):
    tol = np.full(len(params.joints), REST_RATE_TOL)
    tol[list(params.slides)] = REST_SPEED_TOL
    return tol


def _chain_com_levers(params):
    """d(x of the centre of mass of everything the first hinge carries)/d(hinge rate) at upright, by MuJoCo's own
    subtree Jacobian (independent of the toolkit's mass bookkeeping)."""
    m = mujoco_model(params)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    jac = np.zeros((3, m.nv))
    first = int(m.jnt_bodyid[params.hinges[0]])
    mujoco.mj_jacSubtreeCom(m, d, jac, first)
    return np.abs(jac[0, list(params.hinges)])


@pytest.mark.parametrize("name", CARTS)
def test_without_sensors_the_bounds_are_the_exact_states(name):
    params = read_params(SHIPPED_MJCF.with_name(name))
    assert np.array_equal(rest_tolerance(params), _exact(params))
    assert np.array_equal(rest_tolerance(params, SimpleNamespace(spec=None, period=PERIOD)), _exact(params))


@pytest.mark.parametrize("name", CARTS)
@pytest.mark.parametrize("cpr", [1024, 2048, 4096])
def test_encoders_widen_each_hinge_by_one_count_per_period_and_the_cart_by_the_chains_centre_of_mass(name, cpr):
    params = read_params(SHIPPED_MJCF.with_name(name))
    tol = rest_tolerance(params, _rig(params, cpr))
    q = 2 * math.pi / cpr
    hinges, slide = list(params.hinges), params.slide
    assert np.allclose(tol[hinges], REST_RATE_TOL + q / PERIOD)
    # the cart's encoder is exact here: it moves only as fast as the chain's centre of mass does unseen
    assert tol[slide] == pytest.approx(REST_SPEED_TOL + _chain_com_levers(params).sum() * q / PERIOD, rel=1e-6)
    coarser = rest_tolerance(params, _rig(params, cpr // 2))
    assert np.allclose(coarser - _exact(params), 2 * (tol - _exact(params)))  # in proportion to the count
    slower = rest_tolerance(params, _rig(params, cpr, period=2 * PERIOD))
    assert np.allclose(slower - _exact(params), 0.5 * (tol - _exact(params)))  # and to the sampling rate


def test_a_cart_encoder_adds_its_own_count_per_period():
    params = read_params(SHIPPED_MJCF)
    both = rest_tolerance(params, _rig(params, 2048, resolution=1e-3))
    hinges_only = rest_tolerance(params, _rig(params, 2048))
    assert both[params.slide] == pytest.approx(hinges_only[params.slide] + 1e-3 / PERIOD)
    assert np.allclose(both[list(params.hinges)], hinges_only[list(params.hinges)])


def test_the_finest_sensor_of_a_joint_counts_and_noise_alone_widens_nothing():
    params = read_params(SHIPPED_MJCF)
    h = params.hinges[0]
    coarse = Sensor(name="a", kind="jointpos", target=h, dim=1, resolution=0.01, units="rad")
    fine = Sensor(name="b", kind="jointvel", target=h, dim=1, resolution=0.05, units="rad/s")
    noisy = Sensor(name="c", kind="jointpos", target=params.slide, dim=1, noise_std=0.01, units="m")
    tol = rest_tolerance(params, SimpleNamespace(spec=SensorSpec(sensors=(coarse, fine, noisy)), period=PERIOD))
    assert tol[h] == pytest.approx(REST_RATE_TOL + 0.05)  # the rate quantum beats 0.01 rad per 10 ms (1 rad/s)
    lever = _chain_com_levers(params)[0]
    assert tol[params.slide] == pytest.approx(REST_SPEED_TOL + lever * 0.05)


def _hold(params, qvel_of_t, *, seconds=2.0, dt=0.005, angle=None):
    """A synthetic run: qvel from ``qvel_of_t(t) -> (n+1, nq)``, the hinge angles from ``angle(t)`` (default 0)."""
    t = np.arange(int(round(seconds / dt)) + 1) * dt
    nq = len(params.joints)
    qpos = np.zeros((t.size, nq))
    if angle is not None:
        qpos[:, list(params.hinges)] = angle(t)[:, None]
    return Rollout(t=t, qpos=qpos, qvel=qvel_of_t(t), ctrl=np.zeros((t.size - 1, params.nu)))


@pytest.mark.parametrize("name", CARTS)
def test_motion_the_counts_hide_is_at_rest_on_the_rig_only(name):
    """Rates at 80 % of the sensed bound: at rest for the rig, not for an exact-state run."""
    params = read_params(SHIPPED_MJCF.with_name(name))
    rig = _rig(params)
    tol = rest_tolerance(params, rig)
    run = _hold(params, lambda t: 0.8 * tol * np.sin(7.0 * t)[:, None], angle=lambda t: 0.003 * np.cos(7.0 * t))
    layout = dict(hinges=params.hinges, slide=params.slide)
    assert held_upright(run, tolerance=tol, **layout) and swingup_success(run, params, rig=rig)
    assert not held_upright(run, **layout) and not swingup_success(run, params)
    assert swingup_metrics(run, params, rig=rig)["rest_tolerance"] == pytest.approx(tol.tolist())


@pytest.mark.parametrize("name", CARTS)
def test_an_oscillation_inside_the_angle_band_or_a_drifting_cart_is_not_at_rest_even_on_the_rig(name):
    """Angles within the band but the rates past the sensed bound (a limit cycle at 20 rad/s, 0.04 rad), or the
    cart moving steadily faster than it: not at rest."""
    params = read_params(SHIPPED_MJCF.with_name(name))
    rig = _rig(params)
    tol = rest_tolerance(params, rig)
    w, a = 20.0, 0.04
    hinges = list(params.hinges)

    def swinging(t):
        v = np.zeros((t.size, len(params.joints)))
        v[:, hinges] = (a * w * np.cos(w * t))[:, None]
        return v
    assert a * w > tol[hinges].max()
    cycle = _hold(params, swinging, angle=lambda t: a * np.sin(w * t))
    assert not swingup_success(cycle, params, rig=rig)

    def drifting(t):
        v = np.zeros((t.size, len(params.joints)))
        v[:, params.slide] = 1.2 * tol[params.slide]
        return v
    assert not swingup_success(_hold(params, drifting), params, rig=rig)
