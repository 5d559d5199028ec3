"""The basin never counts MuJoCo's divergence reset as a catch, on a model whose qpos0 is upright."""
import mujoco
import numpy as np
import pytest

from cartpole.control.linear import LinearFeedback
from cartpole.models import SHIPPED_MJCF, build_model, mujoco_warnings, read_params
from cartpole.validation.basin import catch_outcomes, estimate_basin


def _blows_up(x0, catch, steps):
    """Independently of the package: does a plain mj_step loop of the catch from x0 raise any warning?"""
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = x0[:m.nq], x0[m.nq:]
    mujoco.mj_forward(m, d)
    for _ in range(steps):
        x = np.concatenate([d.qpos, d.qvel])
        with np.errstate(all="ignore"):
            d.ctrl[:] = np.clip(catch(0.0, x), -1, 1)
        mujoco.mj_step(m, d)
        if sum(int(w.number) for w in d.warning):
            return True
    return False


@pytest.fixture(scope="module")
def params():
    p = read_params(None)
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    assert np.allclose(m.qpos0, 0.0) and np.allclose(build_model(p).x_eq, 0.0)  # qpos0 is upright
    return p


@pytest.fixture(autouse=True)
def quiet():
    with mujoco_warnings(lambda msg: None):
        yield


def test_a_reset_lands_upright_at_rest_yet_is_a_failure(params):
    catch = LinearFeedback.for_model(build_model(params))
    starts = np.array([[0.0, 0.05, 0.0, 0.0], [0.0, 0.05, 0.0, 1e12], [0.0, 0.3, 0.0, 1e5]])
    ok, dv = catch_outcomes(params, catch, starts, 1.0)
    assert dv.tolist() == [False, True, True] and ok.tolist() == [True, False, False]


def test_diverged_samples_are_failures_and_the_basin_shrinks(params):
    # The lab catch, sampled in a metric that hardly weighs the hinge rate: many samples start with rates MuJoCo
    # cannot integrate; it resets them to qpos0 (upright, at rest), which used to look caught.
    c = LinearFeedback.for_model(build_model(params))
    S = np.array(c.S)
    S[3, :] = S[:, 3] = 0.0
    S[3, 3] = 1e-21
    catch = LinearFeedback(c.K, c.x_eq, c.u_eq, hinges=c.hinges, u_limits=c.u_limits, S=S)
    est = estimate_basin(params, catch, n=40, duration=0.5)
    steps = int(round(0.5 / params.timestep))
    truth = np.array([_blows_up(x, catch, steps) for x in est.samples])
    assert truth.any() and np.array_equal(est.diverged, truth)
    assert not np.any(est.success & est.diverged)
    assert est.summary()["diverged"] == int(truth.sum())
    assert est.rho <= est.safety_factor * est.costs[truth].min() + 1e-15
    # what the estimate would have been had MuJoCo's resets counted as catches
    genuine = ~est.success & ~est.diverged
    old = est.safety_factor * min(est.costs[genuine].min() if genuine.any() else np.inf, est.rho_cover)
    assert est.rho < old
