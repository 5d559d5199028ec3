"""The dm_control suite's rewards and episode starts (cartpole.ocp.dmc) against dm_control's own definitions,
evaluated here on MuJoCo's data (xmat, site_xpos, qvel, ctrl) as dm_control's task code reads it.

The numpy reference below is dm_control's ``utils/rewards.py`` (``tolerance``, ``_sigmoids``; Apache-2.0, The
dm_control Authors) and the tasks' ``get_reward`` bodies (``suite/cartpole.py``, ``pendulum.py``, ``acrobot.py``),
copied; dm_control itself does not import beside MuJoCo 4.
"""
from __future__ import annotations

import casadi as ca
import mujoco
import numpy as np
import pytest

from cartpole.models import build_model
from cartpole.ocp import dmc
from cartpole.ocp.objectives import make_objective
from cartpole.validation.metrics import dmc_reward
from chains import ACROBOT, dmc_cartpole

ASSETS = {"pendulum": "cartpole/assets/dmc_pendulum.xml", "acrobot": "cartpole/assets/dmc_acrobot.xml"}


def _np_sigmoids(x, value_at_1, sigmoid):
    if sigmoid == "gaussian":
        return np.exp(-0.5 * (x * np.sqrt(-2 * np.log(value_at_1))) ** 2)
    if sigmoid == "hyperbolic":
        return 1 / np.cosh(x * np.arccosh(1 / value_at_1))
    if sigmoid == "long_tail":
        return 1 / ((x * np.sqrt(1 / value_at_1 - 1)) ** 2 + 1)
    if sigmoid == "reciprocal":
        return 1 / (abs(x) * (1 / value_at_1 - 1) + 1)
    if sigmoid == "cosine":
        s = x * np.arccos(2 * value_at_1 - 1) / np.pi
        with np.errstate(invalid="ignore"):
            return np.where(abs(s) < 1, (1 + np.cos(np.pi * s)) / 2, 0.0)
    if sigmoid == "linear":
        s = x * (1 - value_at_1)
        return np.where(abs(s) < 1, 1 - s, 0.0)
    if sigmoid == "quadratic":
        s = x * np.sqrt(1 - value_at_1)
        return np.where(abs(s) < 1, 1 - s**2, 0.0)
    if sigmoid == "tanh_squared":
        return 1 - np.tanh(x * np.arctanh(np.sqrt(1 - value_at_1))) ** 2
    raise ValueError(sigmoid)


def np_tolerance(x, bounds=(0.0, 0.0), margin=0.0, sigmoid="gaussian", value_at_margin=0.1):
    lower, upper = bounds
    in_bounds = np.logical_and(lower <= x, x <= upper)
    if margin == 0:
        return np.where(in_bounds, 1.0, 0.0)
    d = np.where(x < lower, lower - x, x - upper) / margin
    return np.where(in_bounds, 1.0, _np_sigmoids(d, value_at_margin, sigmoid))


def dm_reward(domain: str, sparse: bool, m, d) -> float:
    """dm_control's get_reward of the domain's task, on MuJoCo's data after mj_forward."""
    if domain == "cartpole":
        cart = d.qpos[0]
        cos = d.xmat[2:, 8]  # named.data.xmat[2:, 'zz']: every pole body
        if sparse:
            return float(np_tolerance(cart, (-.25, .25)) * np_tolerance(cos, (.995, 1)).prod())
        upright = (cos + 1) / 2
        centered = (1 + np_tolerance(cart, margin=2)) / 2
        small_control = (4 + np_tolerance(d.ctrl, margin=1, value_at_margin=0, sigmoid="quadratic")[0]) / 5
        small_velocity = (1 + np_tolerance(d.qvel[1:], margin=5).min()) / 2
        return float(upright.mean() * small_control * small_velocity * centered)
    if domain == "pendulum":
        return float(np_tolerance(d.xmat[m.body("pole").id][8], (np.cos(np.deg2rad(8)), 1)))
    target, tip = m.site("target").id, m.site("tip").id
    dist = np.linalg.norm(d.site_xpos[target] - d.site_xpos[tip])
    return float(np_tolerance(dist, bounds=(0, m.site_size[target, 0]), margin=0 if sparse else 1))


def _mjcf(domain: str, tmp_path, n_poles: int = 1) -> str:
    if domain == "cartpole":
        path = tmp_path / f"dmc_cartpole{n_poles}.xml"
        path.write_text(dmc_cartpole(n_poles))
        return str(path)
    return ASSETS[domain]


CASES = [("dmc_cartpole_swingup", 1), ("dmc_cartpole_swingup", 2), ("dmc_cartpole_swingup_sparse", 1),
         ("dmc_cartpole_swingup_sparse", 2), ("dmc_cartpole_balance", 1), ("dmc_cartpole_balance_sparse", 1),
         ("dmc_pendulum_swingup", 1),
         ("dmc_acrobot_swingup", 1), ("dmc_acrobot_swingup_sparse", 1)]


def _states(model, rng, n: int) -> np.ndarray:
    """States everywhere and near upright (where the sparse indicators switch), rates up to 12 rad/s."""
    wide = rng.uniform(-1, 1, (n, model.nx)) * np.r_[[1.8 if j == model.slide else 7.0 for j in range(model.nq)],
                                                    [3.0 if j == model.slide else 12.0 for j in range(model.nq)]]
    near = model.x_eq + rng.normal(0, 1, (n, model.nx)) * np.r_[[0.25 if j == model.slide else 0.12
                                                                  for j in range(model.nq)], [0.5] * model.nq]
    return np.vstack([wide, near])


@pytest.mark.parametrize("name,n_poles", CASES)
def test_exact_reward_equals_dm_control_on_mujocos_data(tmp_path, name, n_poles):
    t = dmc.task(name)
    path = _mjcf(t.domain, tmp_path, n_poles)
    model = build_model(path)
    m = mujoco.MjModel.from_xml_path(path)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    X = _states(model, rng, 150)
    U = rng.uniform(-1.5, 1.5, (X.shape[0], model.nu))  # beyond ctrlrange too: dm_control reads data.ctrl
    ref = []
    for x, u in zip(X, U):
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:model.nq], x[model.nq:], u
        mujoco.mj_forward(m, d)
        ref.append(dm_reward(t.domain, t.sparse, m, d))
    ref = np.array(ref)
    got = dmc_reward(model, X, U, name)
    assert np.allclose(got, ref, rtol=1e-12, atol=1e-12)
    if t.sparse:  # both values of the indicator occur among the samples
        assert 0 < np.count_nonzero(ref == 1.0) < ref.size
    assert float(dmc.reward_function(model, name)(model.x_eq, np.zeros(model.nu))) == pytest.approx(1.0)


@pytest.mark.parametrize("name,n_poles", CASES)
def test_planning_form_is_the_reward_or_a_smooth_surrogate_of_it(tmp_path, name, n_poles):
    t = dmc.task(name)
    model = build_model(_mjcf(t.domain, tmp_path, n_poles))
    rng = np.random.default_rng(8)
    X = _states(model, rng, 100)
    U = rng.uniform(-1, 1, (X.shape[0], model.nu))  # inside ctrlrange, which the OCP's bounds keep
    exact = dmc_reward(model, X, U, name)
    cost = make_objective(model, name).running
    plan = -np.array([float(cost(x, u)) for x, u in zip(X, U)])
    if t.domain == "acrobot":  # both tasks: the distance's long-tailed tolerance less the small input cost
        smooth = dmc_reward(model, X, U, "dmc_acrobot_swingup")  # decreasing in the tip's distance, as the plan's
        tail = plan + dmc.ACROBOT_INPUT_WEIGHT * np.sum(U ** 2, axis=1)
        order = np.argsort(smooth, kind="stable")
        assert np.all(np.diff(tail[order]) >= -1e-12)
        assert np.all(tail > 0) and np.all(tail <= 1)
        assert -float(cost(model.x_eq, np.zeros(model.nu))) == pytest.approx(1.0)
    elif t.sparse:  # smooth, positive, larger inside the indicator's box than outside it on average
        assert np.all((plan > 0) & (plan <= 1)) and plan[exact == 1].mean() > 2 * plan[exact == 0].mean()
        assert -float(cost(model.x_eq, np.zeros(model.nu))) == pytest.approx(1.0)
    elif len(model.hinges) == 1:
        assert np.allclose(plan, exact, rtol=1e-12, atol=1e-12)
    else:  # the least rate tolerance smoothed: below the exact reward, by at most a quarter of the width
        assert np.all(plan <= exact + 1e-12) and np.all(exact - plan <= dmc.SMOOTH_MIN_WIDTH / 4 + 1e-12)
        assert np.abs(plan - exact).max() > 1e-6
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    g = ca.Function("g", [x, u], [ca.gradient(cost(x, u), ca.vertcat(x, u))])
    for xi, ui in [(model.x_eq, np.zeros(model.nu)), (X[0], U[0]), (X[-1], U[-1])]:  # the target included
        assert np.all(np.isfinite(np.asarray(g(xi, ui))))


@pytest.mark.parametrize("sigmoid", ["gaussian", "hyperbolic", "long_tail", "reciprocal", "cosine", "linear",
                                     "quadratic", "tanh_squared"])
def test_tolerance_is_dm_controls_for_every_sigmoid(sigmoid):
    v = ca.SX.sym("v")
    xs = np.linspace(-4, 4, 161)
    for bounds, margin, vam in [((0, 0), 1.0, 0.1), ((-0.5, 1.0), 2.0, 0.3), ((0.2, np.inf), 0.5, 0.05),
                                ((0, 0), 0.0, 0.1)]:
        f = ca.Function("t", [v], [dmc.tolerance(v, bounds, margin, sigmoid, vam)])
        assert np.allclose([float(f(x)) for x in xs], np_tolerance(xs, bounds, margin, sigmoid, vam), atol=1e-14)
    with pytest.raises(ValueError):
        dmc.tolerance(v, (1, 0))
    with pytest.raises(ValueError):
        dmc.tolerance(v, margin=1, sigmoid="gaussian", value_at_margin=0)


@pytest.mark.parametrize("sigmoid", ["gaussian", "hyperbolic", "long_tail", "cosine", "quadratic", "tanh_squared"])
def test_point_bounds_keep_the_sigmoids_curvature_at_the_point(sigmoid):
    # dm_control's "in bounds" at bounds (0, 0) is the point itself, a constant 1 without curvature; a planner's
    # Hessian there must see the sigmoid's, which is what a finite difference across the point measures
    v = ca.SX.sym("v")
    f = ca.Function("t", [v], [dmc.tolerance(v, (0.3, 0.3), 2.0, sigmoid, 0.2)])
    hess = ca.Function("h", [v], [ca.hessian(f(v), v)[0]])
    h = 1e-4
    fd = (float(f(0.3 + h)) - 2 * float(f(0.3)) + float(f(0.3 - h))) / h ** 2
    assert float(f(0.3)) == 1.0 and fd < -1e-3
    assert float(hess(0.3)) == pytest.approx(fd, rel=1e-5)


def test_scoring_function_is_built_once_per_model(tmp_path):
    model = build_model(ASSETS["pendulum"])
    f = dmc.reward_function(model, "dmc_pendulum_swingup")
    assert dmc.reward_function(model, "dmc_pendulum_swingup") is f
    assert dmc.reward_function(model, "dmc_pendulum_swingup", exact=False) is not f
    other = build_model(ASSETS["pendulum"])
    assert dmc.reward_function(other, "dmc_pendulum_swingup") is not f
    assert make_objective(model, "dmc_pendulum_swingup").is_reward


def test_alias_is_the_cartpole_swingup(tmp_path):
    model = build_model(_mjcf("cartpole", tmp_path))
    assert dmc.task("dmc_swingup") is dmc.task("dmc_cartpole_swingup")
    X = _states(model, np.random.default_rng(1), 20)
    U = np.zeros((X.shape[0], 1))
    a, b = make_objective(model, "dmc_swingup"), make_objective(model, "dmc_cartpole_swingup")
    assert a.name == "dmc_swingup" and a.is_reward
    assert [float(a.running(x, u)) for x, u in zip(X, U)] == [float(b.running(x, u)) for x, u in zip(X, U)]


@pytest.mark.parametrize("name,mjcf,needs", [
    ("dmc_acrobot_swingup", "cart", "without a cart"),
    ("dmc_cartpole_swingup", "pendulum", "needs a cart"),
    ("dmc_pendulum_swingup", "acrobot", "single hinge"),
    ("dmc_acrobot_swingup_sparse", "acrobot_no_sites", "no site named 'tip' or 'target'"),
])
def test_a_task_on_a_model_that_lacks_what_it_needs_is_refused_in_one_sentence(tmp_path, name, mjcf, needs):
    if mjcf == "acrobot_no_sites":
        path = tmp_path / "acrobot.xml"
        path.write_text(ACROBOT)  # the chain family's acrobot: no tip or target site
        model = build_model(str(path))
    else:
        model = build_model(_mjcf("cartpole", tmp_path) if mjcf == "cart" else ASSETS[mjcf])
    with pytest.raises(dmc.DMCError, match=needs) as err:
        make_objective(model, name)
    msg = str(err.value)
    assert "\n" not in msg and msg.endswith(".") and name in msg
    with pytest.raises(dmc.DMCError):
        dmc.episode_starts(model, name, 3)


def test_episode_starts_follow_initialize_episode(tmp_path):
    cart = build_model(_mjcf("cartpole", tmp_path, 2))
    sw = dmc.episode_starts(cart, "dmc_cartpole_swingup", 200, seed=3)
    assert sw.shape == (200, cart.nx)
    assert np.array_equal(sw, dmc.episode_starts(cart, "dmc_cartpole_swingup_sparse", 200, seed=3))
    assert not np.array_equal(sw, dmc.episode_starts(cart, "dmc_cartpole_swingup", 200, seed=4))
    s, h1, h2 = cart.slide, cart.hinges[0], cart.hinges[1]
    assert np.std(sw[:, s]) == pytest.approx(0.01, rel=0.2) and np.mean(sw[:, h1]) == pytest.approx(np.pi, abs=0.003)
    assert np.std(sw[:, h2]) == pytest.approx(0.1, rel=0.2) and np.std(sw[:, cart.nq:]) == pytest.approx(0.01, rel=0.2)
    bal = dmc.episode_starts(cart, "dmc_cartpole_balance", 200, seed=3)
    assert np.all(np.abs(bal[:, s]) <= 0.1) and np.all(np.abs(bal[:, list(cart.hinges)]) <= 0.034)
    assert np.ptp(bal[:, s]) > 0.15
    for domain, name in [("pendulum", "dmc_pendulum_swingup"), ("acrobot", "dmc_acrobot_swingup")]:
        model = build_model(ASSETS[domain])
        x = dmc.episode_starts(model, name, 300, seed=0)
        q = x[:, :model.nq]
        assert np.all(np.abs(q) <= np.pi) and np.all(np.ptp(q, axis=0) > 0.95 * 2 * np.pi)  # anywhere
        assert np.all(x[:, model.nq:] == 0)  # at rest
    # the first episode of seed S is the first draw of RandomState(S), as dm_control's task_kwargs={'random': S}
    pend = build_model(ASSETS["pendulum"])
    assert dmc.episode_starts(pend, "dmc_pendulum_swingup", 1, seed=5)[0, 0] == np.random.RandomState(5).uniform(
        -np.pi, np.pi)
    assert dmc.task("dmc_pendulum_swingup").steps(pend.params.timestep) == 1000
    assert dmc.task("dmc_acrobot_swingup").steps(0.01) == 1000


@pytest.mark.parametrize("name,n_poles", [c for c in CASES if dmc.task(c[0]).sparse])
def test_a_sparse_tasks_box_is_exactly_where_its_reward_pays(tmp_path, name, n_poles):
    t = dmc.task(name)
    model = build_model(_mjcf(t.domain, tmp_path, n_poles))
    rng = np.random.default_rng(9)
    X = _states(model, rng, 300)
    U = rng.uniform(-1, 1, (X.shape[0], model.nu))
    x = ca.SX.sym("x", model.nx)
    g, lower, upper = dmc.sparse_box(model, name, x)
    G = np.asarray(ca.Function("g", [x], [g]).map(X.shape[0])(X.T)).T
    inside = np.all((G >= lower) & (G <= upper), axis=1)
    paid = dmc_reward(model, X, U, name)
    assert 0 < inside.sum() < inside.size
    assert np.array_equal(paid == 1.0, inside) and np.all((paid == 0.0) | (paid == 1.0))


@pytest.mark.parametrize("name,n_poles", CASES)
def test_is_sparse_task_holds_exactly_for_the_tasks_whose_reward_pays_only_zero_or_one(tmp_path, name, n_poles):
    model = build_model(_mjcf(dmc.task(name).domain, tmp_path, n_poles))
    rng = np.random.default_rng(4)
    X = _states(model, rng, 300)
    paid = dmc_reward(model, X, rng.uniform(-1, 1, (X.shape[0], model.nu)), name)
    assert dmc.is_sparse_task(name) == bool(np.all((paid == 0.0) | (paid == 1.0)))


def test_is_sparse_task_resolves_aliases_and_is_false_for_anything_but_a_tasks_name():
    assert dmc.is_sparse_task("dmc_swingup") is False  # the smooth cartpole swingup's alias
    sparse = "dmc_cartpole_swingup_sparse"
    assert dmc.is_sparse_task(sparse) is True
    for other in (None, "effort", sparse.upper(), sparse + "_x", dmc.task(sparse), 3):
        assert dmc.is_sparse_task(other) is False


def test_a_smooth_task_has_no_box(tmp_path):
    model = build_model(_mjcf("cartpole", tmp_path, 1))
    with pytest.raises(dmc.DMCError, match="no sparse box"):
        dmc.sparse_box(model, "dmc_cartpole_swingup", ca.SX.sym("x", model.nx))


def test_acrobot_planning_form_has_a_gradient_where_the_reward_is_flat():
    # hanging, the tip 3.8 m beyond the target's radius: dm_control's gaussian is about 1e-15 and so is its gradient;
    # a planner needs a slope there (the module notes)
    model = build_model(ASSETS["acrobot"])
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    exact = dmc.reward_expression(model, "dmc_acrobot_swingup", x, u, exact=True)
    plan = make_objective(model, "dmc_acrobot_swingup").running(x, u)
    grads = ca.Function("g", [x, u], [ca.gradient(exact, x), ca.gradient(plan, x)])
    g_exact, g_plan = (np.abs(np.asarray(g)).max() for g in grads(model.x_hanging + 0.1, np.zeros(model.nu)))
    assert g_exact < 1e-10 and g_plan > 1e-4 and g_plan > 1e6 * g_exact


def test_smooth_min_is_below_the_minimum_by_at_most_half_its_width_and_smooth_through_the_tie():
    a = np.linspace(0, 1, 201)[:, None]
    b = np.linspace(0, 1, 201)[None, :]
    m = dmc.smooth_min(a, b, 0.05)
    gap = np.minimum(a, b) - m
    assert np.all(gap > 0) and gap.max() == pytest.approx(0.025) and gap[0, -1] < 0.05**2 / 4
    x = ca.SX.sym("x")
    d = ca.Function("d", [x], [ca.gradient(dmc.smooth_min(x, 0.5), x)])
    slopes = [float(d(v)) for v in (0.5 - 1e-9, 0.5, 0.5 + 1e-9)]
    assert slopes == pytest.approx([0.5, 0.5, 0.5], abs=1e-6)  # no kink where the two cross
