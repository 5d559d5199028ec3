"""The LQR balance lab: K is SciPy's, the five starts settle in MuJoCo on every model and replay exactly,
starts are scaled into a model's joint ranges, and the sign facts docs/lab.md states hold; the PID baseline runs
the same starts (reset for each) and balances them, and the live view logs the run it shows."""
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from cartpole import Q_LAB, R_LAB, build_model, read_params
from cartpole.apps.lab import (LAB_INITIAL_CONDITIONS, LAB_OFFSETS, START_SCALES, LabError, compare_pid,
                          lab_initial_conditions, lab_start_scale, linear_settling_time, run_lab, run_pid_lab,
                          slowest_time_constant, starts_in_band, view_first_run)
from cartpole.riccati import default_weights
from cartpole.models import SHIPPED_MJCF, wrap_angle
from cartpole.sim import SimOptions, replays_exactly, simulate


def test_five_starts_settle_and_replay_exactly(any_mjcf):
    res = run_lab(any_mjcf)
    assert res.x0s.shape == (5, 4) and len(res.rollouts) == 5
    assert all(res.settled), (res.settling_times, [m.track_margin for m in res.metrics])
    for run, x0 in zip(res.rollouts, res.x0s):
        np.testing.assert_array_equal(run.x[0], x0)
        assert replays_exactly(run, res.params)
        # independent of the metrics module: the final state is at the equilibrium
        assert np.abs(run.x[-1] - res.x_eq).max() < 0.01
    assert np.all(np.isfinite(res.settling_times_seed)) and np.all(res.settling_times_seed < res.settling_times)


def test_gains_are_scipys_riccati_gains():
    model = build_model()
    A, B = model.linearize()
    Ad, Bd = model.linearize(discrete=True)
    res = run_lab(duration=0.1)
    S = scipy.linalg.solve_continuous_are(A, B, Q_LAB, R_LAB)
    np.testing.assert_allclose(res.K, B.T @ S / R_LAB[0, 0], rtol=1e-12, atol=1e-12)
    resd = run_lab(discrete=True, duration=0.1)
    Sd = scipy.linalg.solve_discrete_are(Ad, Bd, Q_LAB, R_LAB)
    np.testing.assert_allclose(resd.K, np.linalg.solve(R_LAB + Bd.T @ Sd @ Bd, Bd.T @ Sd @ Ad), rtol=1e-10)
    assert resd.discrete and not res.discrete


def test_discrete_design_settles_too():
    res = run_lab(discrete=True)
    assert all(res.settled)
    assert all(replays_exactly(r, res.params) for r in res.rollouts)


def test_shipped_asset_runs_the_handouts_starts():
    np.testing.assert_array_equal(lab_initial_conditions(read_params()), LAB_INITIAL_CONDITIONS)
    np.testing.assert_allclose(np.rad2deg(LAB_INITIAL_CONDITIONS[:, 1]), [5, -5, 8, 3, -4])


def _variant_with(tmp_path, name, **swap):
    from variants import variant_xml

    xml = variant_xml("rk4_fine_step")
    for old, new in swap.items():
        assert old in xml
        xml = xml.replace(old, new)
    path = tmp_path / f"{name}.xml"
    path.write_text(xml)
    return path


def test_starts_are_scaled_into_short_ranges(tmp_path):
    path = _variant_with(tmp_path, "short",
                         **{'range="-1.5 1.5"': 'range="0.2 0.6"',
                            'type="hinge" axis="0 1 0"': 'type="hinge" axis="0 1 0" limited="true" range="-10 10"'})  # degrees
    p = read_params(path)
    x0s = lab_initial_conditions(p)
    s_mid = 0.4
    assert np.all(np.abs(x0s[:, 0] - s_mid) <= 0.5 * 0.2 + 1e-12)
    room = 0.5 * np.deg2rad(10)
    assert np.all(np.abs(x0s[:, 1]) <= room + 1e-12)
    # one factor per joint: the pattern of the handout's starts is kept
    off = LAB_INITIAL_CONDITIONS
    np.testing.assert_allclose((x0s[:, 0] - s_mid) / 0.1, off[:, 0] / np.abs(off[:, 0]).max(), atol=1e-12)
    np.testing.assert_allclose(x0s[:, 1] / room, off[:, 1] / np.abs(off[:, 1]).max(), atol=1e-12)
    res = run_lab(path)
    assert all(res.settled), res.settling_times


def test_hinge_range_without_upright_is_refused(tmp_path):
    path = _variant_with(tmp_path, "no_upright",
                         **{'type="hinge" axis="0 1 0"': 'type="hinge" axis="0 1 0" limited="true" range="30 180"'})
    with pytest.raises(LabError, match="does not contain the upright angle"):
        run_lab(path)


def test_sign_facts_of_the_shipped_asset():
    """docs/lab.md derives: hinge axis +y, so theta > 0 tilts the pole toward +x, and K[1] < 0 pushes the cart
    toward +x (under the pole) to catch it. Checked here against MuJoCo's kinematics and dynamics."""
    import mujoco

    from cartpole.sim import make_mujoco

    m, d = make_mujoco(None)
    d.qpos[:] = [0.0, 0.1]
    mujoco.mj_forward(m, d)
    pole = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pole")
    assert d.xipos[pole][0] > d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cart")][0]
    assert d.qacc[1] > 0  # gravity tips it further: A[3, 1] > 0
    res = run_lab(duration=0.1)
    assert res.K[0, 1] < 0 and -res.K[0] @ [0, 0.1, 0, 0] > 0
    # pushing the cart +x (ctrl > 0) makes theta accelerate negative: B[3] < 0
    d.qpos[:] = 0.0
    d.ctrl[0] = 1.0
    mujoco.mj_forward(m, d)
    assert d.qacc[1] < 0 and res.B[3, 0] < 0 and d.qacc[1] == pytest.approx(res.B[3, 0], rel=1e-9)


HANDOUT_MJCF = """<mujoco model="cartpole">
<option timestep="0.005" gravity="0 0 -9.81"/>
<worldbody>
<light pos="0 0 3"/>
<geom name="floor" type="plane" size="2 2 0.1" rgba="0.8 0.8 0.8 1"/>
<body name="cart" pos="0 0 0.1">
<joint name="slider" type="slide" axis="1 0 0" limited="true" range="-1.5 1.5" damping="0.1"/>
<geom name="cart_geom" type="box" size="0.1 0.05 0.05" rgba="0.2 0.2 0.8 1" mass="1"/>
<body name="pole" pos="0 0 0.05">
<joint name="hinge" type="hinge" axis="0 1 0" damping="0.01"/>
<geom name="pole_geom" type="capsule" fromto="0 0 0 0 0 0.6" size="0.02" rgba="0.8 0.2 0.2 1" mass="0.1"/>
</body>
</body>
</worldbody>
<actuator>
<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/>
</actuator>
</mujoco>
"""


def test_shipped_asset_has_the_handout_files_dynamics(tmp_path):
    """The shipped MJCF only raises the rail: K and every logged state equal those of the handout's own file
    (up to rounding: the compiled inertias differ in the last bits because the bodies sit at other heights).

    The handout's file is run as written, contacts on: its hanging pole is inside the floor, but the floor is far
    from upright (cartpole.models.contacts), so the lab balances it and its runs never touch: MuJoCo computes the
    same steps."""
    path = tmp_path / "handout_cartpole.xml"
    path.write_text(HANDOUT_MJCF)
    ours, theirs = run_lab(), run_lab(path)
    np.testing.assert_allclose(ours.K, theirs.K, rtol=1e-12)
    np.testing.assert_array_equal(ours.settling_times_seed, theirs.settling_times_seed)
    for a, b in zip(ours.rollouts, theirs.rollouts):
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.ctrl, b.ctrl, rtol=0, atol=1e-9)


def test_lab_weights_for_one_pole_are_the_labs():
    Q, R = default_weights(build_model())
    np.testing.assert_array_equal(Q, Q_LAB)
    np.testing.assert_array_equal(R, R_LAB)
    res = run_lab(duration=0.1)
    np.testing.assert_array_equal(res.Q, Q_LAB)
    np.testing.assert_array_equal(res.R, R_LAB)
    assert res.start_scale == 1.0


def _final_error(run, x_eq, hinges):
    """Largest entry of the wrapped state error at the end of a run, computed here (not by the metrics module)."""
    e = run.x[-1] - x_eq
    e[list(hinges)] = wrap_angle(e[list(hinges)])
    return np.abs(e).max()


@pytest.mark.parametrize("asset", ["cartpole_two_pole.xml", "cartpole_three_pole.xml"])
def test_chain_balances_from_the_labs_five_starts_on_its_first_pole(asset):
    path = SHIPPED_MJCF.with_name(asset)
    model = build_model(path)
    res = run_lab(path)
    nq, (h1, *rest) = model.nq, model.hinges
    assert res.K.shape == (1, 2 * nq) and res.x0s.shape == (5, 2 * nq) and res.start_scale == 1.0
    np.testing.assert_array_equal(res.Q, default_weights(model)[0])
    assert np.all(res.E.real < 0)
    # the handout's offsets on the slide and the first hinge; every other joint at x*, everything at rest
    np.testing.assert_allclose(res.x0s[:, model.slide] - res.x_eq[model.slide], LAB_OFFSETS[:, 0], atol=1e-15)
    np.testing.assert_allclose(res.x0s[:, h1] - res.x_eq[h1], LAB_OFFSETS[:, 1], atol=1e-15)
    np.testing.assert_array_equal(res.x0s[:, rest], np.tile(res.x_eq[rest], (5, 1)))
    np.testing.assert_array_equal(res.x0s[:, nq:], 0)
    assert all(res.settled), res.settling_times
    for run, x0 in zip(res.rollouts, res.x0s):
        assert run.qpos.shape[1] == nq and run.ctrl.shape[1] == model.nu
        np.testing.assert_array_equal(run.x[0], x0)
        assert replays_exactly(run, res.params)
        assert _final_error(run, res.x_eq, model.hinges) < 0.01
    # every pole's angle counts in the handout's settling time: it is no earlier than the first pole's alone
    for run, ts in zip(res.rollouts, res.settling_times_seed):
        first = np.flatnonzero(np.abs(wrap_angle(run.qpos[:, h1] - res.x_eq[h1])) > 0.05)
        assert ts >= (run.t[first[-1] + 1] if first.size else 0.0)


def test_starts_a_chain_cannot_catch_are_scaled_by_the_largest_factor_that_settles(chain_dir):
    """dm_control's triple pole on its 1 m cart is lighter on ctrl than the lab's: the full-size starts tip it."""
    path = chain_dir / "dmc_3poles.xml"
    res = run_lab(path)
    assert res.start_scale < 1.0 and res.start_scale in START_SCALES
    assert all(res.settled) and all(replays_exactly(r, res.params) for r in res.rollouts)
    full = lab_initial_conditions(path)
    np.testing.assert_allclose(res.x0s - res.x_eq, res.start_scale * (full - res.x_eq), atol=1e-15)
    # the next larger factor leaves some start unsettled (checked here from plain final states)
    model = build_model(path)
    ctrl = res.controller()
    bigger = lab_initial_conditions(path, scale=2 * res.start_scale)
    errs = [_final_error(simulate(path, ctrl, x0, res.duration), res.x_eq, model.hinges) for x0 in bigger]
    assert max(errs) > 0.01
    # the factor belongs to the model: other weights or a shorter run use the same starts
    other = run_lab(model, R=1.0, duration=0.5)
    assert other.start_scale == res.start_scale and lab_start_scale(model) == res.start_scale
    np.testing.assert_array_equal(other.x0s, res.x0s)


def test_pendulum_without_a_cart_gets_the_angles_only(chain_dir):
    path = chain_dir / "pendulum.xml"
    res = run_lab(path)
    assert res.x0s.shape == (5, 2)
    np.testing.assert_allclose(res.x0s[:, 0], LAB_OFFSETS[:, 1], atol=1e-15)
    assert all(res.settled) and all(replays_exactly(r, res.params) for r in res.rollouts)
    assert all(m.track_margin == np.inf for m in res.metrics)


# ---- the PID baseline beside the LQR (cartpole lqr --compare-pid) -----------------------------------------------

@pytest.fixture(scope="module")
def shipped_lab():
    return run_lab()


def test_pid_balances_the_labs_five_starts_and_each_run_replays_exactly(shipped_lab):
    from cartpole.control.pid import CascadedPID, tune_pid

    lab = shipped_lab
    model = build_model()
    pid = compare_pid(lab, model)
    np.testing.assert_array_equal(pid.x0s, lab.x0s)
    assert pid.duration == lab.duration and pid.gains.to_dict() == tune_pid(model).to_dict()
    assert all(pid.settled), pid.settling_times
    for run, lqr_run, x0 in zip(pid.rollouts, lab.rollouts, lab.x0s):
        np.testing.assert_array_equal(run.x[0], x0)
        np.testing.assert_array_equal(run.t, lqr_run.t)  # same duration, same physics step
        assert replays_exactly(run, pid.params)
        assert _final_error(run, pid.x_eq, model.hinges) < 0.01
        assert not np.array_equal(run.ctrl, lqr_run.ctrl)  # the PID ran, not the LQR
        # reset for each start: the same as a freshly built PID from this start
        fresh = simulate(SHIPPED_MJCF, CascadedPID.for_model(model), x0, lab.duration)
        np.testing.assert_array_equal(run.ctrl, fresh.ctrl)
    # the two added statistics, computed here from the logs
    for res in (lab, pid):
        np.testing.assert_array_equal(res.peak_ctrl, [np.abs(r.ctrl).max() for r in res.rollouts])
        np.testing.assert_array_equal(res.cart_excursion,
                                      [np.abs(r.qpos[:, 0] - res.x_eq[0]).max() for r in res.rollouts])


def test_pid_regulates_to_the_labs_equilibrium_on_a_rail_off_the_origin(tmp_path):
    """On a rail from -0.5 to 2.5 m the lab balances at its middle, s* = 1 m, and so must the PID."""
    path = _variant_with(tmp_path, "off_origin", **{'range="-1.5 1.5"': 'range="-0.5 2.5"'})
    res = run_pid_lab(path)
    assert res.x_eq[0] == pytest.approx(1.0) and np.all(np.abs(res.x0s[:, 0] - 1.0) <= 0.3 + 1e-12)
    assert all(res.settled), res.settling_times
    for run in res.rollouts:
        assert replays_exactly(run, res.params)
        assert abs(run.qpos[-1, 0] - 1.0) < 0.01
    assert np.all(res.cart_excursion < 0.5)


def test_pid_on_a_two_pole_cart_is_refused_in_one_sentence_before_anything_runs(monkeypatch):
    import cartpole.apps.lab
    from cartpole.control.pid import PIDError

    monkeypatch.setattr(cartpole.apps.lab, "simulate", None)  # a run attempted would fail with a TypeError
    with pytest.raises(PIDError) as err:
        run_pid_lab(SHIPPED_MJCF.with_name("cartpole_two_pole.xml"))
    msg = str(err.value)
    assert "one pole on an actuated cart" in msg and "2 poles" in msg and "\n" not in msg


# ---- the live view (cartpole lqr --view) logs the run it shows --------------------------------------------------

def test_the_run_shown_replaces_the_logged_first_run_and_is_the_same(shipped_lab):
    shown_runs = []

    def watcher(*a, **k):
        shown_runs.append(simulate(*a, **k))
        return shown_runs[-1]

    lab, shown = view_first_run(shipped_lab, watcher)
    assert shown is shown_runs[0] and lab.rollouts[0] is shown
    assert all(a is b for a, b in zip(lab.rollouts[1:], shipped_lab.rollouts[1:], strict=True))
    np.testing.assert_array_equal(shown.x, shipped_lab.rollouts[0].x)
    np.testing.assert_array_equal(lab.settling_times_seed, shipped_lab.settling_times_seed)


def test_a_window_closed_early_keeps_the_full_logged_run(shipped_lab):
    lab, shown = view_first_run(shipped_lab, lambda *a, **k: simulate(
        *a, options=SimOptions(stop=lambda t, x: t >= 1.0), **k))
    assert shown.t[-1] == pytest.approx(1.0) and lab is shipped_lab


def test_a_shown_run_that_differs_from_the_logged_one_is_refused(shipped_lab):
    from cartpole.control.linear import LinearFeedback

    law = shipped_lab.controller()

    def other(source, ctrl, x0, duration):  # another gain than the law it is given
        return simulate(source, LinearFeedback(1.1 * law.K, law.x_eq, law.u_eq, hinges=(1,)), x0, duration)

    with pytest.raises(LabError, match="differs from the logged run"):
        view_first_run(shipped_lab, other)


def test_no_display_leaves_the_lab_untouched(shipped_lab, monkeypatch):
    from cartpole.viz.viewer import ViewerUnavailable, watch

    for var in ("DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(var, raising=False)
    with pytest.raises(ViewerUnavailable, match="DISPLAY is not set"):
        view_first_run(shipped_lab, watch)


def test_delay_margin_is_the_last_delay_that_balances_and_the_next_fails():
    from cartpole.apps.lab import balances, delay_margin, run_lab
    from cartpole.sim import LoopOptions

    loop = LoopOptions(period=0.01, delay_compensation=False)
    found = delay_margin(loop=loop, max_delay=0.06)
    m, f = found["lqr"], found["lqr_first_failure"]
    assert m is not None and f is not None and f == pytest.approx(m + 0.005)
    at_margin, at_failure = run_lab(loop=loop.replace(delay=m)), run_lab(loop=loop.replace(delay=f))
    assert balances(at_margin) and not balances(at_failure)
    assert found["tried"][-1] == pytest.approx(f)
    runs = found["lqr_runs"]
    assert [r["delay"] for r in runs] == found["tried"] and [r["balances"] for r in runs] == [True] * (len(runs) - 1) + [False]
    assert runs[-2]["settling_time_seed_max"] == pytest.approx(max(at_margin.settling_times_seed))
    assert runs[-2]["residual_angle_max"] == pytest.approx(at_margin.residual_error[:, 1].max())


def test_lab_on_a_cart_with_dry_friction_balances_and_the_compensation_cuts_the_residual_cart_error():
    """The shipped cart with 0.5 N on the slider and 0.002 N m on the hinge: the LQR (designed without the dry
    friction) balances the five starts with and without the feedforward cancelling the slider's friction; the hinge's
    friction, which no actuator cancels, leaves a limit cycle in both, and the compensation keeps the cart closer to
    the centre in it."""
    from cartpole.apps.lab import balances, run_lab
    from cartpole.sim import LoopOptions

    mjcf = SHIPPED_MJCF.parent / "examples" / "cartpole_friction.xml"
    on = run_lab(mjcf)
    off = run_lab(mjcf, loop=LoopOptions(friction_compensation=False))
    assert on.friction_compensation and not off.friction_compensation
    np.testing.assert_array_equal(on.K, off.K)
    for res in (on, off):
        assert balances(res)
        assert all(replays_exactly(r) for r in res.rollouts)
    slide = on.params.slide
    assert on.residual_error[:, slide].max() < off.residual_error[:, slide].max()
    assert not any(on.settled)  # the hinge's stiction: never inside the strict 0.01 band


def test_noise_tolerance_is_the_last_noise_that_balances_and_is_measured_through_the_estimator():
    """rig_margin over the sensor noise (the search behind --noise-margin): the PID on the measurements gives up
    between 1 mrad and 0.1 rad of noise, and its margin and first failure are what run_lab + compare_pid say."""
    from cartpole.apps.lab import NOISE_FRACTIONS, balances, compare_pid, rig_margin, run_lab
    from cartpole.sim import LoopOptions

    loop = LoopOptions(period=0.01, encoder_cpr=2048, encoder_resolution=0.001)
    found = rig_margin(loop=loop, setting="sensor_noise", values=[0.001, 0.1], pid=True)
    assert found["setting"] == "sensor_noise" and found["pid"] == 0.001 and found["pid_first_failure"] == 0.1
    assert not balances(compare_pid(run_lab(loop=loop.replace(sensor_noise=0.1)), None))
    assert [r["sensor_noise"] for r in found["pid_runs"]] == [0.001, 0.1]
    assert found["lqr_runs"][0]["balances"] and found["lqr"] is not None
    assert NOISE_FRACTIONS[0] == 0.0 and NOISE_FRACTIONS[-1] == 1.0 and list(NOISE_FRACTIONS) == sorted(NOISE_FRACTIONS)


# ---- an honest lab (issue 38): no vacuous settling time, unsettled starts say why, starts shrink for the ctrl only --

HEAVY_CART = Path(__file__).resolve().parent.parent / "assets" / "heavy_cart.xml"
HEAVY_SLOW_CART = Path(__file__).resolve().parent.parent / "assets" / "heavy_slow_cart.xml"


@pytest.fixture(scope="module")
def heavy_lab():
    return run_lab(HEAVY_CART)


@pytest.fixture(scope="module")
def slow_lab():
    return run_lab(HEAVY_SLOW_CART)


def test_starts_inside_the_band_are_not_counted_in_the_mean():
    """At half size the lab's 5, -5, 3 and -4 degree starts begin inside the 0.05 rad band; only 8 degrees counts."""
    res = run_lab(start_scale=0.5, duration=2.0)
    h = res.params.hinges[0]
    inside = np.abs(res.x0s[:, h] - res.x_eq[h]) <= 0.05
    assert res.in_band == tuple(inside) and res.counted == tuple(~inside) and 0 < sum(res.counted) < 5
    assert res.mean_settling_time_seed == pytest.approx(np.mean(res.settling_times_seed[~inside]))
    assert res.std_settling_time_seed == pytest.approx(np.std(res.settling_times_seed[~inside]))
    assert starts_in_band(res.x0s, res.x_eq, []) == (False,) * 5  # no pole: nothing is inside a pole's band


def test_heavy_cart_starts_shrunk_for_the_ctrl_limit_give_no_vacuous_mean(heavy_lab):
    res = heavy_lab
    assert res.start_scale < 1.0 and "ctrl limit" in res.start_scale_reason
    assert all(res.settled) and all(replays_exactly(r, res.params) for r in res.rollouts)
    # the 20 N cannot catch the 50 kg cart's pole outside the band: every start left is inside it, none counted
    assert res.in_band == (True,) * 5 and not any(res.counted)
    assert np.isnan(res.mean_settling_time_seed) and np.isnan(res.std_settling_time_seed)
    # twice as large, the starts fail for the ctrl limit: the pole falls with the ctrl at its limit
    bigger = run_lab(HEAVY_CART, start_scale=2 * res.start_scale)
    why = [w for w in bigger.not_settled if w is not None]
    assert why and all(w.reason == "ctrl_limit" for w in why)
    assert all(w.final_angle_error > 0.05 and w.saturation_fraction > 0.01 for w in why)


def test_a_slow_heavy_cart_is_not_shrunk_and_says_its_time_constant_and_the_run_it_needs(slow_lab):
    res = slow_lab
    tau = 1.0 / np.min(-res.E.real)
    assert res.slowest_time_constant == pytest.approx(tau, rel=1e-12) and tau > 1.0
    assert res.start_scale == 1.0 and res.start_scale_reason is None and all(res.counted)
    assert not any(res.settled) and np.all(np.isfinite(res.settling_times_seed))
    for w, m in zip(res.not_settled, res.metrics):
        assert w.reason == "slow" and m.saturation_fraction == 0.0
        assert w.final_angle_error < 0.05 < w.final_error  # the pole is up, the cart still on its way back
        assert res.duration < w.linear_settling_time < np.inf
    # the linear loop's prediction is MuJoCo's: a run that long settles the start
    w0 = res.not_settled[0]
    run = simulate(HEAVY_SLOW_CART, res.controller(), res.x0s[0], w0.linear_settling_time + 1.0)
    assert _final_error(run, res.x_eq, res.params.hinges) < 0.01


def test_linear_settling_time_is_the_first_instant_inside_the_box_for_good():
    # e[k] = 0.5**k: inside 0.01 from k = 7 (0.0078), at 0.1 s a step
    assert linear_settling_time(np.array([[0.5]]), [1.0], 0.1, 10.0) == pytest.approx(0.7)
    assert linear_settling_time(np.array([[0.5]]), [0.001], 0.1, 10.0) == 0.0
    assert linear_settling_time(np.array([[0.999]]), [1.0], 0.1, 1.0) == np.inf
    assert slowest_time_constant([-2.0, -0.5 + 1j, -0.5 - 1j]) == pytest.approx(2.0)
    assert slowest_time_constant(np.exp(np.array([-2.0, -0.25]) * 0.01), discrete=True, period=0.01) == \
        pytest.approx(4.0)
    assert slowest_time_constant([0.0, -1.0]) == np.inf


def test_lab_runs_report_progress_within_each_run():
    seen = []
    run_lab(duration=0.5, start_scale=1.0, progress=seen.append)
    assert len(seen) > 5 * 5 and seen[-1] == pytest.approx(1.0)  # about 20 fractions a run, not one per run
    assert all(b >= a - 1e-12 for a, b in zip(seen, seen[1:]))
