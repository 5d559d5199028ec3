"""Replay metrics against independent computations: the handout's own settling_time code, brute force; the
pure swing-up metrics on hand-made rollouts."""
import numpy as np
import pytest

from cartpole.models import read_params
from cartpole.sim import Rollout
from cartpole.validation.metrics import (STRICT_TOLERANCE, catch_held, failure_reason, held_upright, peak_ctrl, peak_ctrl_per_actuator,
                                         saturation_fraction, settling_time_seed, settling_time_strict, summarize,
                                         swingup_metrics, swingup_success, track_margin, uptime_metrics)


def handout_settling_time(t, history, threshold=0.05):
    """The lab handout's function, verbatim (re-indented)."""
    abs_theta = np.abs(history[:, 1])
    above = np.where(abs_theta > threshold)[0]
    if len(above) == 0:
        return 0.0
    return t[above[-1] + 1] if above[-1] + 1 < len(t) else t[-1]


def brute_force_strict(t, x, tol):
    for k in range(len(t)):
        if all(np.all(np.abs(x[j]) <= tol) for j in range(k, len(t))):
            return t[k]
    return np.inf


def _decaying(seed, n=400, dt=0.005):
    rng = np.random.default_rng(seed)
    t = np.arange(n + 1) * dt
    rates = rng.uniform(0.5, 4.0, size=4)
    amp = rng.uniform(-0.3, 0.3, size=4)
    x = amp * np.exp(-np.outer(t, rates)) * np.cos(np.outer(t, rng.uniform(0, 10, size=4)))
    return t, x


@pytest.mark.parametrize("seed", range(8))
def test_seed_settling_time_is_the_handouts(seed):
    t, x = _decaying(seed)
    ref = handout_settling_time(t, x)
    assert settling_time_seed(t, x) == ref
    # and the only deviation: a run still outside the band at its last sample never settled
    x[-1, 1] = 0.2
    assert handout_settling_time(t, x) == t[-1] and settling_time_seed(t, x) == np.inf


def test_seed_settling_time_never_outside_is_zero():
    t = np.linspace(0, 1, 11)
    x = np.zeros((11, 4))
    x[:, 1] = 0.05  # the band is inclusive
    assert settling_time_seed(t, x) == 0.0 == handout_settling_time(t, x)


def test_seed_settling_time_wraps_the_angle_error():
    t = np.linspace(0, 1, 11)
    x = np.zeros((11, 4))
    x[:, 1] = 2 * np.pi + 0.01  # upright, one turn later
    assert settling_time_seed(t, x) == 0.0


@pytest.mark.parametrize("seed", range(8))
def test_strict_settling_time_matches_brute_force(seed):
    t, x = _decaying(seed, n=200)
    tol = np.array(STRICT_TOLERANCE) * 3
    assert settling_time_strict(t, x, tol=tol) == brute_force_strict(t, x, tol)


def test_strict_settling_time_uses_the_equilibrium_and_every_state():
    t = np.arange(6) * 0.1
    x = np.zeros((6, 4))
    x[:, 0] = 0.5
    assert settling_time_strict(t, x, [0.5, 0, 0, 0]) == 0.0
    assert settling_time_strict(t, x) == np.inf  # 0.5 m from the origin
    x[:3, 3] = 0.02  # pole rate out of the box until sample 3
    assert settling_time_strict(t, x, [0.5, 0, 0, 0]) == pytest.approx(0.3)


def test_peak_and_saturation():
    u = np.array([[0.2], [-1.0], [1.0], [0.99], [-0.5]])
    assert peak_ctrl(u) == 1.0
    assert saturation_fraction(u, (-1.0, 1.0)) == pytest.approx(2 / 5)
    assert saturation_fraction(u, (-np.inf, np.inf)) == 0.0
    assert saturation_fraction(u, (-0.8, 0.8)) == pytest.approx(3 / 5)  # at or beyond a bound counts
    assert saturation_fraction(u, (-1.0 - 1e-9, 1.0 + 1e-9)) == 0.0


def test_track_margin():
    x = np.zeros((4, 4))
    x[:, 0] = [0.0, 1.2, -0.4, 0.3]
    assert track_margin(x, (-1.5, 1.5)) == pytest.approx(0.3)
    assert track_margin(x, (-np.inf, np.inf)) == np.inf
    assert track_margin(x, (-1.0, 1.0)) == pytest.approx(-0.2)


def test_summarize_a_rollout():
    t, x = _decaying(3, n=100)
    ctrl = np.clip(np.sin(np.arange(100))[:, None] * 2, -1, 1)
    run = Rollout(t=t, qpos=x[:, :2], qvel=x[:, 2:], ctrl=ctrl)
    m = summarize(run, ctrl_range=(-1, 1), cart_range=(-1.5, 1.5))
    assert m.settling_time_seed == handout_settling_time(t, x)
    assert m.settling_time_strict == brute_force_strict(t, x, np.array(STRICT_TOLERANCE))
    assert m.peak_ctrl == np.abs(ctrl).max()
    assert m.saturation_fraction == np.mean(np.abs(ctrl) == 1)
    assert m.track_margin == pytest.approx(1.5 - np.abs(x[:, 0]).max())
    assert m.settled == (np.isfinite(m.settling_time_strict) and m.track_margin > 0)


def _rollout(theta, s=None, dt=0.01):
    n = len(theta) - 1
    s = np.zeros(n + 1) if s is None else s
    return Rollout(t=np.arange(n + 1) * dt, qpos=np.column_stack([s, theta]), qvel=np.zeros((n + 1, 2)),
                   ctrl=np.zeros((n, 1)))


def test_time_to_upright_is_the_first_time_it_stays_upright():
    th = np.concatenate([np.linspace(np.pi, 0.3, 50), [0.04, 0.2, 0.03], np.full(300, 2 * np.pi + 0.01)])
    r = _rollout(th)
    k = 50 + 2  # first index from which |wrapped theta| < 0.05 until the end
    assert settling_time_seed(r.t, r.x) == pytest.approx(r.t[k])
    assert swingup_metrics(r, read_params())["time_to_upright"] == pytest.approx(r.t[k])
    never = _rollout(np.full(10, 1.0))
    assert settling_time_seed(never.t, never.x) == np.inf
    assert swingup_metrics(never, read_params())["time_to_upright"] is None


def test_an_entry_into_the_upright_band_counts_as_a_swingup_only_when_held_even_at_the_runs_end():
    """A pole spinning through upright at the run's last steps has not swung up; one caught and held ``hold`` s
    before the end has, and the knock before it is recovered."""
    params = read_params()
    dt = 0.01
    spin = np.pi + 2.0 * np.arange(301) * dt * np.pi  # hanging, turning at 2 pi rad/s: upright at the last step
    spin = spin + (2 * np.pi - spin[-1])
    run = _rollout(spin, dt=dt)
    assert abs(run.qpos[-1, 1] - 2 * np.pi) < 1e-12 and abs(run.qpos[-2, 1] - 2 * np.pi) > 0.02
    m = uptime_metrics(run, params, hold=1.0, events=[(0.5, 0.8)])
    assert m["swingups"] == 0 and m["unrecovered_at"] == [0.5] and m["recoveries"] == 0
    caught = _rollout(np.concatenate([np.linspace(np.pi, 0.5, 150), np.full(151, 0.01)]), dt=dt)  # up at 1.5 s
    held = uptime_metrics(caught, params, hold=1.0, events=[(0.5, 0.8)])
    assert held["swingups"] == 1 and held["swingup_times"] == [pytest.approx(1.5)] and held["recoveries"] == 1
    assert uptime_metrics(caught, params, hold=2.0)["swingups"] == 0  # up 1.5 s before the end: not held 2 s


def test_success_needs_hold_no_limit_contact_and_ctrl_in_range():
    params = read_params()
    up = _rollout(np.full(201, 0.01))
    assert swingup_success(up, params, hold=1.0)
    assert not swingup_success(up, params, hold=5.0)  # shorter than the hold
    s = np.zeros(201)
    s[10] = params.cart_range[1]
    assert not swingup_success(_rollout(np.full(201, 0.01), s), params)
    assert track_margin(_rollout(np.full(201, 0.01), s).qpos, params.cart_range) == 0.0
    bad = Rollout(t=up.t, qpos=up.qpos, qvel=up.qvel, ctrl=np.full((200, 1), 1.5))
    assert not swingup_success(bad, params)
    m = swingup_metrics(up, params)
    assert m["success"] and m["time_to_upright"] == 0.0


def test_a_catch_held_only_when_the_run_ends_upright_at_rest_after_the_handover():
    params = read_params()
    up = _rollout(np.concatenate([np.linspace(np.pi, 0.02, 100), np.full(201, 0.01)]))
    assert catch_held(up, params, handover_at=0.9)
    assert not catch_held(up, params, handover_at=None)  # no hand-over: nothing was caught
    assert not catch_held(up, params, handover_at=up.t[-1] + 0.1)  # the run ended before the hand-over
    fell = _rollout(np.concatenate([np.linspace(np.pi, 0.02, 100), np.full(150, 0.01), np.linspace(0.01, 2.0, 51)]))
    assert not catch_held(fell, params, handover_at=0.9)  # handed over, then the pole fell: not caught
    blown = Rollout(t=up.t, qpos=up.qpos, qvel=up.qvel, ctrl=up.ctrl, info={"diverged": 2.0})
    assert not catch_held(blown, params, handover_at=0.9)  # MuJoCo reset the run: never a catch


def test_failure_reason_names_what_failed():
    params = read_params()
    assert failure_reason(swingup_metrics(_rollout(np.full(201, 0.01)), params)) == ""
    assert failure_reason(swingup_metrics(_rollout(np.full(201, 1.0)), params)) == \
        "not upright at rest over the last second"
    s = np.zeros(201)
    s[10] = params.cart_range[1]
    assert failure_reason(swingup_metrics(_rollout(np.full(201, 1.0), s), params)) == "cart reached its limit"
    assert failure_reason({"success": False, "diverged": True, "cart_clearance": 1.0}) == "diverged"


def _chain_run(seed, nq=4, n=300, dt=0.005):
    """A decaying run of a cart with nq - 1 poles, every angle one turn away from upright (wrapping matters)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n + 1) * dt
    x = rng.uniform(-0.3, 0.3, 2 * nq) * np.exp(-np.outer(t, rng.uniform(2.0, 8.0, 2 * nq)))
    x[:, 1:nq] += 2 * np.pi * rng.integers(-1, 2, nq - 1)
    return t, x


@pytest.mark.parametrize("seed", range(6))
def test_seed_settling_time_is_the_handouts_applied_to_every_pole(seed):
    t, x = _chain_run(seed)
    # the handout's function on each pole's unwrapped error, the latest of them
    per_pole = []
    for h in (1, 2, 3):
        one = np.zeros((len(t), 4))
        one[:, 1] = np.mod(x[:, h] + np.pi, 2 * np.pi) - np.pi
        per_pole.append(handout_settling_time(t, one))
    assert settling_time_seed(t, x, hinges=(1, 2, 3)) == max(per_pole)
    assert settling_time_seed(t, x) == max(per_pole)  # cart-first default: every qpos after the slide is a hinge


def test_seed_settling_time_measures_from_the_equilibrium():
    t = np.linspace(0, 1, 11)
    x = np.zeros((11, 6))
    x[:, 1], x[:, 2] = 0.01, -0.38  # the everything-chain's upright: the second link bent back
    x_eq = np.array([0, 0.01, -0.38, 0, 0, 0])
    assert settling_time_seed(t, x, x_eq=x_eq) == 0.0
    assert settling_time_seed(t, x) == np.inf
    # a model whose hinges are not after the slide (no cart: both qpos are hinges)
    x = np.zeros((11, 4))
    x[:5, 0] = 0.1
    assert settling_time_seed(t, x, hinges=(0, 1)) == pytest.approx(0.5)
    assert settling_time_seed(t, x) == 0.0  # the default layout reads column 0 as a cart


@pytest.mark.parametrize("seed", range(4))
def test_strict_settling_time_on_a_chain_matches_brute_force_on_wrapped_errors(seed):
    t, x = _chain_run(seed, n=200)
    e = x.copy()
    e[:, 1:4] = np.mod(e[:, 1:4] + np.pi, 2 * np.pi) - np.pi
    tol = STRICT_TOLERANCE * 3
    assert settling_time_strict(t, x, tol=tol) == brute_force_strict(t, e, tol)
    assert settling_time_strict(t, x, np.zeros(8), tol=tol, hinges=(1, 2, 3)) == brute_force_strict(t, e, tol)


def test_peak_ctrl_is_per_actuator_then_max():
    u = np.array([[0.2, -0.1], [-0.4, 0.3], [0.1, -0.45]])
    np.testing.assert_array_equal(peak_ctrl_per_actuator(u), [0.4, 0.45])
    assert peak_ctrl(u) == 0.45
    assert peak_ctrl(np.zeros((0, 2))) == 0.0


def test_saturation_counts_a_step_when_any_actuator_is_at_its_own_bound():
    u = np.array([[1.0, 0.0], [0.0, 0.5], [0.0, 0.2], [-0.3, -0.5]])
    assert saturation_fraction(u, [[-1, 1], [-0.5, 0.5]]) == pytest.approx(3 / 4)
    assert saturation_fraction(u, [[-1, 1], [-np.inf, np.inf]]) == pytest.approx(1 / 4)


def test_track_margin_reads_the_slide_column():
    q = np.zeros((3, 3))
    q[:, 2] = [0.0, 1.2, -0.4]  # a model whose slide is qpos 2
    q[:, 0] = 5.0
    assert track_margin(q, (-1.5, 1.5), slide=2) == pytest.approx(0.3)
    assert track_margin(q, (-1.5, 1.5), slide=None) == np.inf


def _chain_rollout(t, x, nu=1):
    nq = x.shape[1] // 2
    return Rollout(t=t, qpos=x[:, :nq], qvel=x[:, nq:], ctrl=np.zeros((len(t) - 1, nu)))


def test_summarize_takes_the_layout_from_the_model():
    from cartpole.models import build_model
    from cartpole.models import SHIPPED_MJCF

    model = build_model(SHIPPED_MJCF.with_name("cartpole_two_pole.xml"))
    t, x = _chain_run(1, nq=model.nq)
    x[:, 0] *= 10  # the cart goes out to a few metres
    run = _chain_rollout(t, x)
    m = summarize(run, model)
    assert m.settling_time_seed == settling_time_seed(t, x, x_eq=model.x_eq, hinges=model.hinges)
    assert m.settling_time_strict == settling_time_strict(t, x, model.x_eq, hinges=model.hinges)
    lo, hi = model.params.cart_range
    assert m.track_margin == pytest.approx(min(np.min(x[:, 0] - lo), np.min(hi - x[:, 0])))


def test_swingup_metrics_need_every_pole_up_and_still():
    from cartpole.models import SHIPPED_MJCF, read_params

    params = read_params(SHIPPED_MJCF.with_name("cartpole_three_pole.xml"))
    t = np.arange(401) * 0.005
    x = np.zeros((401, 8))
    run = _chain_rollout(t, x)
    assert held_upright(run, hinges=params.hinges, slide=params.slide)
    m = swingup_metrics(run, params)
    assert m["success"] and m["time_to_upright"] == 0.0 and m["cart_clearance"] == pytest.approx(1.5)
    x[:300, 3] = np.pi  # the last link hangs until t = 1.5 s
    run = _chain_rollout(t, x)
    assert not held_upright(run, hold=1.0, hinges=params.hinges) and held_upright(run, hold=0.4)
    assert swingup_metrics(run, params)["time_to_upright"] == pytest.approx(1.5)
    x[:] = 0
    x[:, 7] = 0.2  # upright but the last link still turning
    assert not swingup_metrics(_chain_rollout(t, x), params)["success"]


@pytest.mark.parametrize("n_poles", [1, 2, 3])
def test_dmc_scoring_evaluates_the_objectives_reward_function_over_the_rows(chain_dir, n_poles):
    """The numeric dm_control reward used for scoring is the OCP's symbolic definition (clipped control term)
    mapped over the rows: equal at random states of any batch shape, and the OCP's running cost is its negation
    wherever the ctrl is inside dm_control's ctrlrange (-1, 1)."""
    import casadi as ca

    from cartpole.models import build_model
    from cartpole.ocp import make_objective
    from cartpole.ocp.dmc import SMOOTH_MIN_WIDTH
    from cartpole.ocp.objectives import dmc_swingup_reward as symbolic
    from cartpole.validation.metrics import dmc_swingup_reward

    m = build_model(str(chain_dir / f"dmc_{n_poles}pole{'s' if n_poles > 1 else ''}.xml"))
    rng = np.random.default_rng(10 + n_poles)
    X = rng.uniform(-1, 1, (3, 40, m.nx)) * np.r_[2.5, [7.0] * n_poles, 4.0, [15.0] * n_poles]
    U = rng.uniform(-2.5, 2.5, (3, 40, m.nu))  # past the clip at |u| = 1 and past sqrt(5), where 1 - u^2 < -4
    x, u = ca.SX.sym("x", m.nx), ca.SX.sym("u", m.nu)
    point = ca.Function("point", [x, u], [symbolic(m, x, u, clip_control=True)])
    by_point = np.array([[float(point(xi, ui)) for xi, ui in zip(xr, ur)] for xr, ur in zip(X, U)])
    scored = dmc_swingup_reward(m, X, U)
    assert scored.shape == (3, 40)
    np.testing.assert_allclose(scored, by_point, rtol=1e-15, atol=1e-16)
    assert np.all((scored >= 0) & (scored <= 1))
    assert dmc_swingup_reward(m, X[0, 0], U[0, 0]).shape == () and dmc_swingup_reward(m, X[:0, 0], U[:0, 0]).size == 0
    cost = make_objective(m, "dmc_swingup").running
    inside = np.abs(U[..., 0]) <= 1
    assert inside.any() and (~inside).any()
    ocp = np.array([[float(cost(xi, ui)) for xi, ui in zip(xr, ur)] for xr, ur in zip(X, U)])
    if n_poles == 1:
        np.testing.assert_allclose(-ocp[inside], scored[inside], rtol=1e-15, atol=1e-16)
    else:  # the planner's form smooths the least of the poles' rate tolerances: just below the reward (each
        # smoothed pair at most half the width below its minimum, which enters the reward halved)
        gap = scored[inside] + ocp[inside]
        assert np.all(gap >= -1e-15) and np.all(gap <= (n_poles - 1) * SMOOTH_MIN_WIDTH / 4 + 1e-15)
    assert np.all(-ocp[~inside] < scored[~inside])  # outside the range only the smooth form goes on falling


def test_a_file_built_hanging_is_judged_against_its_true_upright_whatever_names_the_plant():
    """Parameters or a path name the plant as well as its model does: the upright is computed (here half a turn
    from the file's qpos 0), so a cart-pole left hanging at rest is no swing-up."""
    from pathlib import Path

    from cartpole.models import build_model

    path = Path(__file__).parents[1] / "assets" / "corpus" / "cartpole_built_hanging.xml"
    params = read_params(path)
    model = build_model(params)
    hanging = _rollout(np.zeros(201))
    hinge = params.hinges[0]
    up = _rollout(np.full(201, float(model.x_eq[hinge])))
    for source in (params, str(path), model):
        assert not swingup_success(hanging, source)
        assert swingup_success(up, source)
        assert swingup_metrics(up, source)["success"] and uptime_metrics(hanging, source)["uptime"] == 0.0
