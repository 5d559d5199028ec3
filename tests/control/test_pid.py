"""Cascaded PID: tuned from the model by pole placement, it balances the shipped cart and carts it was not designed
on in MuJoCo (runs replayed from their logged ctrl), its integrator cannot wind up, its linear closed loop has its
poles where the rule put them, and it refuses models a cascade cannot drive."""
import numpy as np
import pytest

from cartpole.control.pid import CascadedPID, PIDError, PIDGains, tune_pid
from cartpole.apps.lab import LAB_INITIAL_CONDITIONS
from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.sim import SimOptions, replays_exactly, simulate

from variants import variant_xml

DURATION = 10.0


@pytest.fixture(scope="module")
def shipped():
    model = build_model(SHIPPED_MJCF)
    return model, tune_pid(model)


def _balances(source, model, gains, x0, *, duration=DURATION, **sim):
    """Run the PID in MuJoCo from x0; check it ends upright near the cart's rest position within the ctrl range,
    and that the log replays exactly. Returns the rollout and the final wrapped error."""
    controller = CascadedPID(gains, model)
    run = simulate(source, controller, x0, duration, **sim)
    err = model.state_error(run.x)
    assert run.t[-1] == pytest.approx(duration)
    assert np.all(run.ctrl >= model.u_low) and np.all(run.ctrl <= model.u_high)
    assert np.all(np.abs(err[:, model.hinges[0]]) < np.pi / 2)  # never fell over on the way
    assert abs(err[-1, model.hinges[0]]) < 1e-3  # rad
    assert abs(err[-1, model.slide]) < 1e-2  # m
    assert np.all(np.abs(err[-1, model.nq:]) < 1e-2)  # m/s, rad/s
    assert replays_exactly(run)
    return run, err


def _starts(model):
    """The lab's five starts as offsets from the model's computed upright equilibrium."""
    return model.x_eq + np.asarray(LAB_INITIAL_CONDITIONS)


# ---- (1) the shipped cart ---------------------------------------------------------------------------------

@pytest.mark.parametrize("i", range(len(LAB_INITIAL_CONDITIONS)))
def test_pid_balances_the_shipped_cart_from_each_lab_start(shipped, i):
    model, gains = shipped
    _balances(SHIPPED_MJCF, model, gains, _starts(model)[i])


def test_pid_balances_with_the_ctrl_held_over_several_physics_steps(shipped):
    """dt comes from successive t: holding each ctrl for 4 physics steps (20 ms) still balances."""
    model, gains = shipped
    run, _ = _balances(SHIPPED_MJCF, model, gains, _starts(model)[2],
                       options=SimOptions(control_period=4 * model.dt))
    assert np.all(run.ctrl[0:4] == run.ctrl[0])


# ---- (2) the same rule on carts it was not designed on, and gains used off their model -------------------------

@pytest.mark.parametrize("name", ["heavy_pole", "flipped_offset_armature", "implicit_damped"])
def test_the_tuning_rule_balances_variants_it_was_not_designed_on(name, variant_dir):
    path = variant_dir / f"cartpole_{name}.xml"
    model = build_model(path)
    gains = tune_pid(model)
    for x0 in _starts(model):
        _balances(path, model, gains, x0)


def test_the_tuning_rule_balances_a_cart_whose_upright_is_not_qpos_zero(chain_dir):
    """Gymnasium's single pendulum is built 1 mm off vertical: x* has a nonzero angle the PID must regulate to."""
    path = chain_dir / "gym_single_off_vertical.xml"
    model = build_model(path)
    assert abs(model.x_eq[model.hinges[0]]) > 1e-4
    gains = tune_pid(model)
    for x0 in _starts(model)[[2, 4]]:
        _balances(path, model, gains, x0)


def test_gains_tuned_on_the_shipped_cart_still_balance_a_heavier_pole(shipped, variant_dir):
    """Model error: gains derived on the shipped cart, run on the heavy-pole cart (3x the pole mass, 0.8 m long,
    1.5 kg cart, gear 30); the heavy cart's linearised loop under those gains is stable and MuJoCo agrees."""
    model, gains = shipped
    path = variant_dir / "cartpole_heavy_pole.xml"
    heavy = build_model(path)
    A, B = heavy.linearize()
    assert np.max(np.linalg.eigvals(_closed_loop(A, B, gains)).real) < 0
    for x0 in _starts(heavy)[[2, 4]]:
        _balances(path, heavy, gains, x0)


# ---- (3) anti-windup ------------------------------------------------------------------------------------------

def _integral_log(model, gains, source, x0, *, anti_windup):
    controller = CascadedPID(gains, model, anti_windup=anti_windup)
    log = []

    def logged(t, x):
        u = controller(t, x)
        log.append(controller.integral)
        return u

    run = simulate(source, logged, x0, DURATION)
    return run, np.abs(gains.ki * np.asarray(log))


def test_integrator_stays_bounded_from_a_start_that_saturates_the_ctrl(shipped):
    model, gains = shipped
    x0 = model.x_eq + np.array([0.0, 0.5, 0.0, 0.0])
    run, ki_z = _integral_log(model, gains, SHIPPED_MJCF, x0, anti_windup=True)
    saturated = np.isclose(run.ctrl, model.u_low) | np.isclose(run.ctrl, model.u_high)
    assert saturated.sum() >= 5
    assert replays_exactly(run)
    err = model.state_error(run.x)
    assert abs(err[-1, 1]) < 1e-3 and abs(err[-1, 0]) < 1e-2
    half_span = 0.5 * float(model.u_high[0] - model.u_low[0])
    assert ki_z.max() <= half_span
    _, ki_z_free = _integral_log(model, gains, SHIPPED_MJCF, x0, anti_windup=False)
    assert ki_z.max() < ki_z_free.max()  # the same run without anti-windup integrates through the saturation


def test_integrator_freezes_while_the_ctrl_is_saturated(shipped):
    """A pole held at a tilt the ctrl cannot correct: the integrator stops once the ctrl saturates (and never
    holds more than half the ctrl span), while without anti-windup it grows with time."""
    model, gains = shipped
    x = model.x_eq + np.array([0.0, 0.6, 0.0, 0.0])
    held, free = CascadedPID(gains, model), CascadedPID(gains, model, anti_windup=False)
    for k in range(2000):
        u_held, _ = held(k * model.dt, x), free(k * model.dt, x)
        assert u_held[0] in (model.u_low[0], model.u_high[0])
    assert abs(gains.ki * held.integral) <= 0.5 * float(model.u_high[0] - model.u_low[0])
    assert abs(held.integral) <= model.dt * (0.6 + gains.tilt_limit)
    assert abs(free.integral) == pytest.approx(1999 * model.dt * 0.6, rel=1e-9)


def test_pid_takes_dt_from_successive_times_and_reset_forgets_its_state(shipped):
    model, gains = shipped
    c = CascadedPID(gains, model)
    x = model.x_eq + np.array([0.1, 0.05, 0.0, 0.3])
    u0 = c(0.0, x)
    assert u0.shape == (model.nu,) and c.integral == 0.0 and c.rate_filtered == pytest.approx(0.3)
    u1 = c(0.01, x)
    z1 = c.integral
    assert z1 != 0.0
    np.testing.assert_array_equal(c(0.01, x), u1)  # the same t again: same ctrl, no state change
    assert c.integral == z1
    with pytest.raises(PIDError, match="reset"):
        c(0.005, x)
    c.reset()
    np.testing.assert_array_equal(c(0.0, x), u0)


# ---- (4) refusal ----------------------------------------------------------------------------------------------

def _one_sentence(msg: str) -> bool:
    return "\n" not in msg and msg.endswith(".") and msg.count(". ") == 0


def test_pid_refuses_a_two_pole_cart_in_one_sentence():
    with pytest.raises(PIDError) as exc:
        tune_pid(SHIPPED_MJCF.with_name("cartpole_two_pole.xml"))
    msg = str(exc.value)
    assert "2 poles" in msg and "LQR" in msg and _one_sentence(msg)


def test_pid_refuses_a_cart_whose_motor_drives_the_hinge(tmp_path):
    path = tmp_path / "hinge_motor.xml"
    path.write_text(variant_xml("heavy_pole").replace('joint="slider" gear', 'joint="hinge" gear'))
    with pytest.raises(PIDError) as exc:
        tune_pid(path)
    msg = str(exc.value)
    assert "not on the cart's slide" in msg and "LQR" in msg and _one_sentence(msg)
    with pytest.raises(PIDError):
        CascadedPID(tune_pid(SHIPPED_MJCF), build_model(path))


def test_pid_refuses_a_pendulum_without_a_cart(chain_dir):
    with pytest.raises(PIDError, match="no slide joint"):
        tune_pid(chain_dir / "pendulum.xml")


def test_a_bandwidth_too_high_for_the_derivative_filter_is_refused(shipped):
    model, _ = shipped
    with pytest.raises(PIDError, match="does not stabilise") as exc:
        tune_pid(model, bandwidth_factor=2.0)
    assert _one_sentence(str(exc.value))


# ---- (5) the linear closed loop -------------------------------------------------------------------------------

def _closed_loop(A, B, g: PIDGains) -> np.ndarray:
    """The cascade's linear closed loop on [s, theta, s_dot, theta_dot, z, y], written out from its equations:
    theta_ref = -(kp_cart s + kd_cart s_dot), e_i = theta - theta_ref, z' = e_i, tau y' = theta_dot - y,
    u = -(kp e_i + ki z + kd y)."""
    b = np.asarray(B).ravel()
    e_i = np.array([g.kp_cart, 1.0, g.kd_cart, 0.0])
    top = np.column_stack([A - g.kp * np.outer(b, e_i), -g.ki * b, -g.kd * b])
    z_row = np.concatenate([e_i, [0.0, 0.0]])
    y_row = np.array([0.0, 0.0, 0.0, 1.0, 0.0, -1.0]) / g.filter_tau
    return np.vstack([top, z_row, y_row])


def _sorted(p):
    p = np.asarray(p, complex)
    return p[np.lexsort((np.round(p.imag, 9), np.round(p.real, 9)))]


@pytest.mark.parametrize("name", ["shipped", "heavy_pole", "flipped_offset_armature"])
def test_tuned_linear_closed_loop_has_its_poles_where_the_rule_put_them(name, variant_dir):
    model = build_model(SHIPPED_MJCF if name == "shipped" else variant_dir / f"cartpole_{name}.xml")
    factor = 1.3
    g = tune_pid(model, bandwidth_factor=factor)
    A, B = model.linearize()
    # the rule: a 4th-order Butterworth pattern of radius factor * (unstable eigenvalue of A)
    lam = np.max(np.linalg.eigvals(A).real)
    assert g.bandwidth == pytest.approx(factor * lam, rel=1e-12)
    np.testing.assert_allclose(np.abs(g.poles), g.bandwidth, rtol=1e-12)
    np.testing.assert_allclose(np.sort(np.degrees(np.angle(g.poles)) % 360), [112.5, 157.5, 202.5, 247.5],
                               atol=1e-9)
    # the equivalent state feedback K = [kp kp_cart, kp, kp kd_cart, kd] puts eig(A - B K) there
    K = np.array([[g.kp * g.kp_cart, g.kp, g.kp * g.kd_cart, g.kd]])
    np.testing.assert_allclose(g.K, K)
    np.testing.assert_allclose(_sorted(np.linalg.eigvals(A - B @ K)), _sorted(g.poles), rtol=1e-6, atol=1e-8)
    # with the integrator and the filter the loop is stable and its eigenvalues are the ones reported
    cl = np.linalg.eigvals(_closed_loop(A, B, g))
    assert np.max(cl.real) < 0
    np.testing.assert_allclose(_sorted(cl), _sorted(g.closed_loop_poles), rtol=1e-8, atol=1e-8)
    # the integral and filter follow the bandwidth: ki = kp omega / 10, tau = 1 / (10 omega)
    assert g.ki == pytest.approx(g.kp * g.bandwidth / 10)
    assert g.filter_tau == pytest.approx(1 / (10 * g.bandwidth))


def test_pid_gains_are_frozen_with_read_only_poles(shipped):
    _, g = shipped
    with pytest.raises(AttributeError):
        g.kp = 1.0
    with pytest.raises(ValueError):
        g.poles[0] = 0.0
    d = g.to_dict()
    assert set(d) >= {"kp", "ki", "kd", "kp_cart", "kd_cart", "filter_tau", "tilt_limit", "poles"}


def test_pid_designed_for_a_period_is_the_sampled_loop_mujoco_runs():
    """Tuned at a 20 ms period, the placed poles are those of the sampled loop on the held model, and that linear
    sampled loop (integrator, filter) predicts the PID's MuJoCo run from a small start."""
    from cartpole.control.pid import CascadedPID, sampled_closed_loop_matrix, tune_pid
    from cartpole.models import build_model
    from cartpole.sim import simulate

    model = build_model()
    period = 0.02
    steps = round(period / model.dt)
    g = tune_pid(model, period=period)
    assert np.abs(g.closed_loop_poles).max() < 1
    Ad, Bd = model.hold(steps).linearize()
    M = sampled_closed_loop_matrix(Ad, Bd, g, period, model.slide, model.hinges[0])
    x0 = model.x_eq.copy()
    x0[model.hinges[0]] += 1e-4
    ro = simulate(model.params, CascadedPID(g, model), x0, 1.0, options=SimOptions(control_period=period))
    e0 = model.state_error(x0)
    c = np.zeros(model.nx)  # the first call starts the integrator at 0 (it does not integrate): z_{-1} = -T e_i
    c[model.hinges[0]], c[model.slide], c[model.nq + model.slide] = 1.0, g.kp_cart, g.kd_cart
    xi = np.concatenate([e0, [-period * c @ e0, 0.0]])
    pred = []
    for _ in range(int(round(1.0 / period))):
        pred.append(xi[:model.nx].copy())
        xi = M @ xi
    got = model.state_error(ro.x[::steps][:len(pred)])
    assert np.abs(got - np.array(pred)).max() < 1e-3 * np.abs(got).max()
