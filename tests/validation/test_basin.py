"""The catch basin estimate: inspectable, consistent, and its samples below rho really succeed in MuJoCo."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.control.switching import lab_catch
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
    catch = lab_catch(cp.build_model(params))
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
    catch = lab_catch(cp.build_model(params))
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
