"""Objectives a user picks: each one builds and solves; user functions (MODULE:FUNCTION) and their error sentences;
dm_control's swing-up reward against an independent numpy computation."""
import casadi as ca
import numpy as np
import pytest

from cartpole.models import build_model
from cartpole.ocp import DirectCollocation, OCPError, dmc, make_objective, reward
from cartpole.ocp.objectives import dmc_swingup_function, dmc_swingup_reward, load_objective
from cartpole.validation.metrics import dmc_swingup_reward as dmc_reward_np
from chains import dmc_cartpole


@pytest.fixture(scope="module")
def model():
    return build_model()


def _solve(model, objective, T=3.0, N=30):
    ocp = DirectCollocation(model, N=N, T=None if objective == "time" else T, objective=objective)
    traj, info = ocp.solve(starts=3)
    assert info.success, (objective, info)
    assert np.allclose(traj.x[0], model.x_hanging, atol=1e-9)
    e = model.state_error(traj.x[-1])
    assert np.allclose(e, 0.0, atol=1e-6)
    assert np.all(traj.u <= model.u_high + 1e-6) and np.all(traj.u >= model.u_low - 1e-6)
    return traj, info


@pytest.mark.parametrize("objective", ["effort", "time", "tracking", "dmc_swingup"])
def test_each_named_objective_builds_and_solves_on_the_shipped_cart(model, objective):
    traj, info = _solve(model, objective)
    if objective == "time":
        assert info.objective == pytest.approx(info.T) and info.T < 3.0
    elif objective == "dmc_swingup":  # a reward's integral: positive, below T (the reward is at most 1)
        assert 0 < info.objective < 3.0
    else:
        assert info.objective > 0


def test_a_function_cost_and_a_reward_are_minimised_and_maximised(model):
    def cart_and_angle(x, u):
        return x[0] ** 2 + (1 - ca.cos(x[1])) + 0.1 * u[0] ** 2

    _, info_cost = _solve(model, cart_and_angle)
    _, info_rew = _solve(model, reward(lambda x, u: -(x[0] ** 2 + (1 - ca.cos(x[1])) + 0.1 * u[0] ** 2)))
    # the same problem with the sign flipped: the reward's integral is minus the cost's
    assert info_rew.objective == pytest.approx(-info_cost.objective, rel=1e-5)
    assert make_objective(model, cart_and_angle).is_reward is False


def test_module_function_objective_imported_from_a_file(model, tmp_path, monkeypatch):
    (tmp_path / "my_costs.py").write_text(
        "import casadi\nfrom cartpole.ocp.objectives import reward\n\n"
        "def cost(x, u):\n    return 2 * (1 - casadi.cos(x[1])) + u[0] ** 2\n\n"
        "@reward\ndef up(x, u):\n    return casadi.cos(x[1])\n\n"
        "def bad_math(x, u):\n    import math\n    return math.cos(x[1])\n\n"
        "def bad_index(x, u):\n    return x['speed']\n\n"
        "def vector(x, u):\n    return x[:2]\n\n"
        "NOT_A_FUNCTION = 3\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    obj = make_objective(model, "my_costs:cost")
    assert obj.name == "cost" and not obj.is_reward
    assert float(obj.running(model.x_hanging, 0.5)) == pytest.approx(4.25)
    up = make_objective(model, "my_costs:up")
    assert up.is_reward and float(up.running(model.x_eq, 0.0)) == pytest.approx(-1.0)  # minimised as -reward
    _solve(model, "my_costs:cost")
    for spec, words in [("no_such_module_xyz:cost", "cannot be imported"),
                        ("my_costs:missing", "has no function 'missing'"),
                        ("my_costs:NOT_A_FUNCTION", "has no function"),
                        ("my_costs:bad_math", "not a finite number.*casadi operations"),
                        ("my_costs:bad_index", "failed on CasADi symbols"),
                        ("my_costs:vector", "2x1 expression, not a scalar"),
                        ("my_costs", "not known"), ("my_costs:", "MODULE:FUNCTION")]:
        with pytest.raises(OCPError, match=words) as err:
            make_objective(model, spec)
        msg = str(err.value)
        assert "\n" not in msg and msg.endswith(".") and "Traceback" not in msg, msg


def test_running_objectives_need_a_fixed_duration(model):
    with pytest.raises(OCPError, match="needs a fixed duration"):
        DirectCollocation(model, N=10, T=None, objective="tracking")


def _reference_reward(x, u, n_poles):
    """dm_control's Balance._get_reward(sparse=False) written out again, from its definition (independent of the
    package): rewards.tolerance with bounds (0, 0) and the gaussian / quadratic sigmoids."""
    def tolerance(v, margin, value_at_margin=0.1, sigmoid="gaussian"):
        d = np.abs(v) / margin
        if sigmoid == "gaussian":
            scale = np.sqrt(-2 * np.log(value_at_margin))
            return np.exp(-0.5 * (d * scale) ** 2)
        scale = np.sqrt(1 - value_at_margin)
        return np.where(np.abs(d * scale) < 1, 1 - (d * scale) ** 2, 0.0)

    cos_abs = np.cos(np.cumsum(x[1:1 + n_poles]))  # each pole's xmat zz: absolute angle
    upright = ((cos_abs + 1) / 2).mean()
    centered = (1 + tolerance(x[0], margin=2)) / 2
    small_control = (4 + tolerance(u[0], margin=1, value_at_margin=0, sigmoid="quadratic")) / 5
    small_velocity = (1 + tolerance(x[2 + n_poles:], margin=5).min()) / 2
    return upright * small_control * small_velocity * centered


@pytest.mark.parametrize("n_poles", [1, 2])
def test_dmc_swingup_reward_equals_dm_controls_definition(tmp_path, n_poles):
    path = tmp_path / "dmc.xml"
    path.write_text(dmc_cartpole(n_poles))
    m = build_model(str(path))
    assert np.allclose(m.x_eq, 0.0)
    x, u = ca.SX.sym("x", m.nx), ca.SX.sym("u", m.nu)
    f = ca.Function("r", [x, u], [dmc_swingup_reward(m, x, u, clip_control=True)])
    plan = ca.Function("p", [x, u], [dmc_swingup_reward(m, x, u)])
    rng = np.random.default_rng(3)
    X = rng.uniform(-1, 1, (200, m.nx)) * np.r_[1.8, [7.0] * n_poles, 3.0, [12.0] * n_poles]
    U = rng.uniform(-1, 1, (200, 1))
    ref = np.array([_reference_reward(xi, ui, n_poles) for xi, ui in zip(X, U)])
    sym = np.array([float(f(xi, ui)) for xi, ui in zip(X, U)])
    assert np.allclose(sym, ref, rtol=1e-12, atol=1e-14)
    # the planner's form: the same inside ctrlrange on one pole; on more the rates' minimum smoothed (just below)
    planned = np.array([float(plan(xi, ui)) for xi, ui in zip(X, U)])
    if n_poles == 1:
        assert np.allclose(planned, ref, rtol=1e-12, atol=1e-14)
    else:
        assert np.all(planned <= ref + 1e-14) and np.all(ref - planned <= dmc.SMOOTH_MIN_WIDTH / 4 + 1e-14)
    assert np.allclose(dmc_reward_np(m, X, U), ref, rtol=1e-12, atol=1e-14)
    assert float(f(m.x_eq, [0.0])) == pytest.approx(1.0)
    # beyond dm_control's ctrlrange only the clipped form (scoring's) is dm_control's value
    wide = rng.uniform(-3, 3, (200, 1))
    ref_wide = np.array([_reference_reward(xi, ui, n_poles) for xi, ui in zip(X, wide)])
    clipped = dmc_swingup_function(m, clip_control=True)
    assert np.allclose([float(clipped(xi, ui)) for xi, ui in zip(X, wide)], ref_wide, rtol=1e-12, atol=1e-14)
    assert np.allclose(dmc_reward_np(m, X, wide), ref_wide, rtol=1e-12, atol=1e-14)
    # make_objective's running cost is the negated reward in the planner's form
    assert float(make_objective(m, "dmc_swingup").running(X[0], U[0])) == pytest.approx(-planned[0])


def test_load_objective_returns_the_function(tmp_path, monkeypatch):
    (tmp_path / "obj_mod_b.py").write_text("def f(x, u):\n    return u[0] ** 2\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert load_objective("obj_mod_b:f").__name__ == "f"
