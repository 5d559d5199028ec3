"""The MHE's period in C (cartpole/csrc/mhe.c.jinja, the loop's and the export's one source) against the Python
step (the same Riccati recursion in numpy; the reference and the path without a compiler), on the same inputs:
a swinging cart inside its rail, a window that slides, and readings past the rail's end (the bounded QP)."""
import casadi as ca
import numpy as np
import pytest

from cartpole.codegen import compiler
from cartpole.estimation.mhe import MHEOptions, MovingHorizonEstimator
from cartpole.estimation.mhe_functions import condensed_qp, riccati_window_step
from cartpole.models import SHIPPED_MJCF, build_model

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler")


@pytest.fixture(scope="module")
def model():
    return build_model(SHIPPED_MJCF)


def _encoders(model):
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    return ca.Function("h", [x, u], [x[:model.nq]])


def _pair(model, **kw):
    args = (model, 2, _encoders(model), np.diag([1e-6, 1e-6]))
    c = MovingHorizonEstimator(*args, accel_std=1.0, options=MHEOptions(**kw))
    py = MovingHorizonEstimator(*args, accel_std=1.0, options=MHEOptions(c_step=False, **kw))
    assert c.c is not None and py.c is None
    return c, py


def test_the_c_step_and_the_python_step_give_the_same_estimates_on_a_swinging_cart(model):
    c, py = _pair(model, horizon=8)
    hold = model.hold(2)
    x = np.array(model.x_hanging, dtype=float)
    rng = np.random.default_rng(3)
    U = np.zeros((model.nu, 2))
    y = x[:model.nq] + 1e-3 * rng.standard_normal(model.nq)
    np.testing.assert_array_equal(c.reset(y), py.reset(y))
    for k in range(30):  # past the window's length: the slide and its arrival update too
        U[:] = 0.6 * np.sin(0.3 * k) - 0.5 * x[model.slide]
        x = np.asarray(hold.step_inputs(x, U)).ravel()
        y = x[:model.nq] + 1e-3 * rng.standard_normal(model.nq)
        np.testing.assert_allclose(c.update(y, U), py.update(y, U), rtol=0, atol=1e-10)
    np.testing.assert_allclose(c.window, py.window, rtol=0, atol=1e-10)
    for a, b in zip(c.arrival, py.arrival):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-14)
    assert c.failures == py.failures == []


def test_past_the_rail_both_steps_take_the_bounded_qp_and_keep_the_estimate_on_the_rail(model):
    c, py = _pair(model, horizon=6)
    lo, hi = model.params.joint_ranges[model.slide]
    y = np.array(model.x_hanging[:model.nq], dtype=float)
    y[model.slide] = hi + 0.1
    c.reset(y), py.reset(y)
    U = np.zeros((model.nu, 2))
    for k in range(15):
        y[model.slide] = hi + 0.1 + 0.02 * np.sin(0.4 * k)
        xc, xp = c.update(y, U), py.update(y, U)
        assert lo <= xc[model.slide] <= hi
        np.testing.assert_allclose(xc, xp, rtol=0, atol=1e-8)
    assert xc[model.slide] == pytest.approx(hi, abs=1e-9)


def test_the_riccati_step_is_the_condensed_normal_equations_solution():
    rng = np.random.default_rng(1)
    n, nx, ny, r = 7, 4, 2, 2
    A = np.eye(nx) + 0.1 * rng.standard_normal((n, nx, nx))
    d = 0.01 * rng.standard_normal((n, nx))
    C = rng.standard_normal((n + 1, ny, nx))
    rm = 0.01 * rng.standard_normal((n + 1, ny))
    RV = np.diag([30.0, 20.0])
    L = rng.standard_normal((nx, r))
    P_inv = np.diag([4.0, 3.0, 2.0, 1.0])
    gap, e = 0.01 * rng.standard_normal(nx), 0.1 * rng.standard_normal((n, r))
    dX, dE = riccati_window_step(A, d, C, rm, RV, L, P_inv, gap, e)
    H, g, S, c = condensed_qp(A, d, C, rm, RV, L, P_inv, gap, e)
    z = np.linalg.solve(H, -g)
    np.testing.assert_allclose(dX, c + S @ z, rtol=0, atol=1e-11)
    np.testing.assert_allclose(dE, z[nx:].reshape(n, r), rtol=0, atol=1e-11)


def test_without_a_compiler_the_estimator_runs_its_python_step(model, monkeypatch):
    monkeypatch.setenv("CARTPOLE_NO_COMPILE", "1")
    est = MovingHorizonEstimator(model, 2, _encoders(model), np.diag([1e-6, 1e-6]), options=MHEOptions(horizon=4))
    assert est.c is None and est.library is None
    x0 = est.reset(np.zeros(model.nq))
    assert np.all(np.isfinite(est.update(np.zeros(model.nq), np.zeros((model.nu, 2))))) and x0.shape == (model.nx,)


def test_the_bench_times_the_c_step_beside_the_python_step_and_the_ipopt_window():
    from cartpole.estimation.mhe import bench_mhe

    out = bench_mhe(n=40, horizon=0.1, period=0.01, repeats=2, python=15, baseline=3)
    assert out["c_step"] and out["repeats"] == 2 and len(out["step_ms_medians"]) == 2
    assert out["python"]["n"] == 15 and out["python"]["max_diff"] < 1e-9  # the same estimates
    assert out["ipopt"]["n"] == 3 and out["ipopt"]["step_ms_median"] > 0
    assert out["ipopt"]["max_diff_from_rti"] < 1e-2  # one Gauss-Newton step near the converged window
    assert out["speedup"] == pytest.approx(out["ipopt"]["step_ms_median"] / out["step_ms_median"])
