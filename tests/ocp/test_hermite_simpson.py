"""The one definition of a Hermite-Simpson interval: exact on cubic states, Simpson's rule exact for the effort."""
import casadi as ca
import numpy as np
import pytest

from cartpole.ocp.hermite_simpson import hs_interval_function, simpson_effort_terms


def _double_integrator():
    x, u = ca.SX.sym("x", 4), ca.SX.sym("u", 1)
    return ca.Function("f", [x, u], [ca.vertcat(x[2], x[3], u, -u)])


def test_defect_vanishes_on_the_exact_solution_under_a_first_order_hold_input():
    """Linear u makes the positions cubic and the velocities quadratic: Hermite-Simpson is exact there."""
    f = _double_integrator()
    uk, uk1, h = 0.3, -0.7, 0.25
    x0 = np.array([0.1, -0.2, 0.5, 1.0])
    a = (uk1 - uk) / h  # u(t) = uk + a t

    def exact(t):
        v = x0[2:] + np.array([1, -1]) * (uk * t + a * t**2 / 2)
        p = x0[:2] + x0[2:] * t + np.array([1, -1]) * (uk * t**2 / 2 + a * t**3 / 6)
        return np.r_[p, v]

    x1 = exact(h)
    defect, xc = hs_interval_function(f)(x0, uk, x1, uk1, f(x0, uk), f(x1, uk1), h)
    np.testing.assert_allclose(np.asarray(defect).ravel(), 0.0, atol=1e-15)
    np.testing.assert_allclose(np.asarray(xc).ravel(), exact(h / 2), atol=1e-15)


@pytest.mark.parametrize("uk, uk1", [(0.0, 1.0), (-0.4, 0.9), (1.0, 1.0)])
def test_simpson_effort_is_the_exact_integral_of_the_linear_input_squared(uk, uk1):
    h = 0.4
    exact = h * (uk**2 + uk * uk1 + uk1**2) / 3
    assert h / 6 * simpson_effort_terms(uk, uk1) == pytest.approx(exact, rel=1e-14)
    sym = simpson_effort_terms(ca.SX.sym("a"), ca.SX.sym("b"))  # the same expression builds CasADi graphs
    assert isinstance(sym, ca.SX)


def test_interval_takes_its_sizes_from_f():
    """Three double integrators driven by two inputs (nx = 6, nu = 2): still exact under a first-order hold."""
    x, u = ca.SX.sym("x", 6), ca.SX.sym("u", 2)
    G = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, -0.5]])  # qacc = G u
    f = ca.Function("f", [x, u], [ca.vertcat(x[3:], ca.mtimes(ca.DM(G), u))])
    uk, uk1, h = np.array([0.3, -0.2]), np.array([-0.7, 0.4]), 0.25
    x0 = np.array([0.1, -0.2, 0.3, 0.5, 1.0, -0.4])
    a = (uk1 - uk) / h

    def exact(t):
        acc_int = G @ (uk * t + a * t**2 / 2)
        pos_int = G @ (uk * t**2 / 2 + a * t**3 / 6)
        return np.r_[x0[:3] + x0[3:] * t + pos_int, x0[3:] + acc_int]

    x1 = exact(h)
    defect, xc = hs_interval_function(f)(x0, uk, x1, uk1, f(x0, uk), f(x1, uk1), h)
    assert defect.shape == (6, 1) and xc.shape == (6, 1)
    np.testing.assert_allclose(np.asarray(defect).ravel(), 0.0, atol=1e-15)
    np.testing.assert_allclose(np.asarray(xc).ravel(), exact(h / 2), atol=1e-15)
