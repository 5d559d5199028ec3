"""The catch basin estimate: inspectable, consistent, and its samples below rho really succeed in MuJoCo."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.control import LinearFeedback
from cartpole.models import wrap_angle
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.basin import BasinCache, BasinError, BasinEstimate, estimate_basin


@pytest.fixture(scope="module")
def basin():
    return estimate_basin(None, n=200, seed=3)


def test_estimate_is_frozen_and_read_only(basin):
    assert isinstance(basin, BasinEstimate)
    with pytest.raises(Exception):
        basin.rho = 1.0
    for arr in (basin.samples, basin.costs, basin.success, basin.S, basin.box):
        assert not arr.flags.writeable
    assert basin.samples.shape == (200, 4) and basin.costs.shape == (200,) and basin.success.shape == (200,)
    assert (basin.n, basin.seed) == (200, 3)


def test_rho_is_the_documented_level(basin):
    costs = np.einsum("ni,ij,nj->n", basin.samples, basin.S, basin.samples)
    assert np.allclose(costs, basin.costs)
    assert np.all(costs <= basin.level * (1 + 1e-12))
    failed = costs[~basin.success]
    assert failed.size > 0  # the sample reaches beyond the basin, so rho is set by a failure
    assert basin.rho_sampled == failed.min()
    assert basin.rho == pytest.approx(basin.safety_factor * min(basin.rho_sampled, basin.rho_cover))
    assert np.all(basin.success[costs < basin.rho])
    assert basin.n_inside > 5


def test_samples_below_rho_succeed_when_rechecked_independently(basin):
    """Re-run a few samples below rho with the logging simulator (not the basin's own loop) and check them."""
    params = cp.read_params()
    catch = LinearFeedback.for_model(cp.build_model(params))
    inside = np.flatnonzero(basin.costs < basin.rho)
    pick = inside[np.argsort(basin.costs[inside])[-4:]]  # the hardest ones: nearest rho
    for i in pick:
        r = simulate(params, catch, basin.samples[i], basin.duration)
        assert replays_exactly(r)
        assert abs(wrap_angle(r.qpos[-1, 1])) < 0.05 and abs(r.qvel[-1, 1]) < 0.1 and abs(r.qvel[-1, 0]) < 0.1
        assert np.all(np.abs(r.qpos[:, 0]) < 1.5 - basin.limit_margin)


def test_batched_verdicts_equal_single_runs_of_the_logging_simulator(basin):
    """Successes and failures alike: the batched catch runs give the verdict of one ``simulate`` per start."""
    params = cp.read_params()
    catch = LinearFeedback.for_model(cp.build_model(params))
    picks = np.r_[np.flatnonzero(basin.success)[:3], np.flatnonzero(~basin.success)[:3]]
    assert picks.size == 6
    lo, hi = params.cart_range[0] + basin.limit_margin, params.cart_range[1] - basin.limit_margin
    for i in picks:
        r = simulate(params, catch, basin.samples[i], basin.duration)
        end = r.x[-1]
        ok = (np.all((lo < r.qpos[1:, 0]) & (r.qpos[1:, 0] < hi)) and abs(wrap_angle(end[1])) < 0.05
              and abs(end[3]) < 0.1 and abs(end[2]) < 0.1)
        assert ok == basin.success[i], i


def test_cache_estimates_once_per_model(variant_dir):
    cache = BasinCache()
    a = cache.get(None, n=20)
    assert cache.get(None, n=20) is a and len(cache) == 1
    b = cache.get(variant_dir / "cartpole_heavy_pole.xml", n=20)
    assert b is not a and len(cache) == 2
    assert not np.allclose(a.S, b.S)


def test_bad_settings_raise():
    with pytest.raises(BasinError):
        estimate_basin(None, n=0)
    with pytest.raises(BasinError):
        estimate_basin(None, n=5, safety_factor=1.5)


TWO_POLE = cp.SHIPPED_MJCF.with_name("cartpole_two_pole.xml")


@pytest.fixture(scope="module")
def two_pole_basin():
    return estimate_basin(TWO_POLE, n=80, seed=1, duration=3.0)


def test_two_pole_basin_perturbs_every_state_and_its_verdicts_are_the_logging_simulators(two_pole_basin):
    b = two_pole_basin
    params = cp.read_params(TWO_POLE)
    model = cp.build_model(params)
    catch = LinearFeedback.for_model(model)
    np.testing.assert_array_equal(b.S, catch.S)
    assert b.samples.shape == (80, 6) and b.box.shape == (6,) and b.K.shape == (1, 6)
    np.testing.assert_array_equal(b.x_eq, model.x_eq)
    assert np.all(np.abs(b.errors).max(axis=0) > 0)  # every component moved: cart, both angles, all rates
    assert np.all(np.abs(b.errors).max(axis=0) == b.box)
    np.testing.assert_allclose(b.costs, catch.cost_to_go(b.samples), rtol=1e-10)
    assert 0 < b.success.sum() < b.n  # the sample reaches beyond the basin
    assert np.all(b.success[b.costs < b.rho]) and b.n_inside > 3
    picks = np.r_[np.flatnonzero(b.success)[:2], np.flatnonzero(~b.success)[:2]]
    lo, hi = params.cart_range[0] + b.limit_margin, params.cart_range[1] - b.limit_margin
    for i in picks:
        r = simulate(params, catch, b.samples[i], b.duration)
        assert replays_exactly(r)
        e = model.state_error(r.x[-1])
        ok = (np.all((lo < r.qpos[1:, 0]) & (r.qpos[1:, 0] < hi)) and np.all(np.abs(e[[1, 2]]) < 0.05)
              and np.all(np.abs(e[[4, 5]]) < 0.1) and abs(e[3]) < 0.1)
        assert ok == b.success[i], i


def test_basin_of_a_pole_built_off_vertical_is_sampled_around_its_x_eq(chain_dir):
    path = chain_dir / "gym_single_off_vertical.xml"
    model = cp.build_model(path)
    b = estimate_basin(path, n=60, seed=0, duration=3.0)
    np.testing.assert_array_equal(b.x_eq, model.x_eq)
    np.testing.assert_allclose(b.samples - model.x_eq, b.errors, atol=0)
    assert abs(np.mean(b.samples[:, 1]) - model.x_eq[1]) < 0.2
    assert b.rho > 0 and np.all(b.success[b.costs < b.rho])
    from cartpole.validation.basin import catch_succeeds
    # x_eq itself is a rest
    assert catch_succeeds(path, LinearFeedback.for_model(model), [model.x_eq], 2.0).tolist() == [True]
