"""The naive MHE a user writes first, for the benchmark: every period the whole window's nonlinear least squares
(:mod:`cartpole.estimation.mhe`'s problem, same cost, constraints and arrival cost) re-solved to convergence by IPOPT
from the previous solution shifted by one node. Built once (one ``nlpsol`` with the window's data as parameters, SX
expanded), so it is what a careful first attempt costs, not a rebuild per period.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from cartpole.estimation.mhe_functions import window_functions


class IpoptWindow:
    """The full window (``N`` intervals) of ``mhe`` as one IPOPT problem in the nodes and the noises.

    Parameters
    ----------
    mhe : MovingHorizonEstimator
        The estimator whose problem is solved (its model maths, ``L``, ``RV``, bounds).
    model : CartPoleModel
    h : casadi.Function
        Its measurement model.
    """

    def __init__(self, mhe, model, h):
        nx, nu, ny, m, N = mhe.nx, mhe.nu, mhe.ny, mhe.steps, mhe.N
        des = mhe.design
        L, RV = des["L"], des["RV"]
        r = L.shape[1]
        fns = window_functions(model, m, h, N, compiled=False)
        X, E = ca.SX.sym("X", nx, N + 1), ca.SX.sym("E", r, N)
        Y, UU, UH = ca.SX.sym("Y", ny, N + 1), ca.SX.sym("UU", nu * m, N), ca.SX.sym("UH", nu, N + 1)
        xbar, R = ca.SX.sym("xbar", nx), ca.SX.sym("R", nx, nx)  # R' R = P^-1
        stage = fns.stage.expand() if fns.stage.is_a("MXFunction") else fns.stage
        F = stage.map(N)(X[:, :N], UU)[0]
        Yh = fns.measurement.map(N + 1)(X, UH)[0]
        a = ca.mtimes(R, X[:, 0] - xbar)
        res = ca.mtimes(ca.DM(RV), Yh - Y)
        cost = ca.sumsqr(a) + ca.sumsqr(res) + ca.sumsqr(E)
        g = ca.vec(X[:, 1:] - F - ca.mtimes(ca.DM(L), E))
        w = ca.vertcat(ca.vec(X), ca.vec(E))
        p = ca.vertcat(ca.vec(Y), ca.vec(UU), ca.vec(UH), xbar, ca.vec(R))
        self.solver = ca.nlpsol("mhe_ipopt", "ipopt", {"x": w, "f": cost, "g": g, "p": p},
                                {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                                 "ipopt.tol": 1e-10})
        lo, hi = np.full((N + 1, nx), -np.inf), np.full((N + 1, nx), np.inf)
        b = des["bounded"]
        lo[:, b], hi[:, b] = des["low"], des["high"]
        self.lbx = np.r_[lo.ravel(), np.full(N * r, -np.inf)]
        self.ubx = np.r_[hi.ravel(), np.full(N * r, np.inf)]
        self.nx, self.r, self.N, self.ng = nx, r, N, N * nx

    def solve(self, Y, UU, UH, xbar, P, guess):
        """The window's solution: ``(X (N+1, nx), w)`` (``w`` the whole primal vector, the next warm start).

        Parameters
        ----------
        Y : (N+1, ny) array
        UU : (N, nu steps) array
        UH : (N+1, nu) array
        xbar : (nx,) array
        P : (nx, nx) array
            The arrival cost's centre and covariance.
        guess : (n_w,) array
            Warm start.

        Returns
        -------
        (array, array)
        """
        R = np.linalg.inv(np.linalg.cholesky(P))
        p = np.r_[Y.ravel(), UU.ravel(), UH.ravel(), xbar, R.ravel(order="F")]
        sol = self.solver(x0=guess, p=p, lbx=self.lbx, ubx=self.ubx, lbg=0, ubg=0)
        w = np.asarray(sol["x"]).ravel()
        return w[:(self.N + 1) * self.nx].reshape(self.N + 1, self.nx), w


def shifted(w, nx: int, r: int, N: int):
    """A warm start one node later: ``w``'s nodes and noises shifted by one, the last repeated."""
    X = w[:(N + 1) * nx].reshape(N + 1, nx)
    E = w[(N + 1) * nx:].reshape(N, r) if r else np.zeros((N, 0))
    X = np.r_[X[1:], X[-1:]]
    E = np.r_[E[1:], np.zeros((1, r))]
    return np.r_[X.ravel(), E.ravel()]


def time_ipopt_window(mhe, model, h, samples) -> dict:
    """Time :class:`IpoptWindow` on ``samples``: the full windows the RTI estimator saw, one re-solve each.

    Parameters
    ----------
    mhe : MovingHorizonEstimator
    model : CartPoleModel
    h : casadi.Function
    samples : list of tuple
        ``(Y (N+1, ny), UU (N, nu steps), UH (N+1, nu), xbar (nx,), P (nx, nx), x_rti (nx,))``, in time order.

    Returns
    -------
    dict
        ``step_ms_median``, ``step_ms_max`` (ms per re-solve), ``n``, ``max_diff_from_rti`` (the largest
        ``|x_ipopt - x_rti|`` of the current node: how far one Gauss-Newton step is from the converged window).
    """
    ip = IpoptWindow(mhe, model, h)
    guess = np.r_[np.tile(samples[0][5], ip.N + 1), np.zeros(ip.N * ip.r)]
    times, diff = [], 0.0
    for Y, UU, UH, xbar, P, x_rti in samples:
        t0 = time.perf_counter()
        X, w = ip.solve(Y, UU, UH, xbar, P, guess)
        times.append(time.perf_counter() - t0)
        diff = max(diff, float(np.abs(X[-1] - x_rti).max()))
        guess = shifted(w, ip.nx, ip.r, ip.N)
    ms = 1e3 * np.array(times)
    return {"step_ms_median": float(np.median(ms)), "step_ms_max": float(ms.max()), "n": len(samples),
            "max_diff_from_rti": diff}
