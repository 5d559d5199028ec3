"""The MPC problem as one IPOPT NLP: the baseline's solver and the controller's offline fallback.

Same multiple-shooting NLP as :mod:`cartpole.mpc.nmpc` (same stages, cost, terminal weight, ctrl bounds and soft
rail), as one SX graph for ``casadi.nlpsol("ipopt")`` with ``expand=True``.
"""
from __future__ import annotations

import casadi as ca
import numpy as np


class StepFailed(Exception):
    """A solve inside the MPC loop that could not be done (internal: the controller turns it into its safe action)."""


class IpoptNLP:
    """The MPC problem of a controller as one IPOPT NLP (SX, ``expand=True``), built once, solved from any guess.

    Parameters
    ----------
    problem : cartpole.mpc.nmpc.MPCProblem
    step_expr : casadi.Function
        One control period ``(x, u) -> x_next`` as SX (:attr:`StageFunctions.step_expr`).
    options : dict, optional
        Merged into ``{"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "expand": True}``.
    """

    def __init__(self, problem, step_expr: ca.Function, options: dict | None = None):
        p = self.problem = problem
        N, nx, nu = p.N, p.nx, p.nu
        S = ca.SX.sym("S", nx, N + 1)
        U = ca.SX.sym("U", nu, N)
        sigma = ca.SX.sym("sigma")
        x0 = ca.SX.sym("x0", nx)
        goal = ca.SX.sym("goal", nx)
        F = step_expr.map(N)(S[:, :N], U)
        Qs, Rs, P = ca.DM(p.Qs), ca.DM(p.Rs), ca.DM(p.P)
        ug = ca.DM(p.u_goal)
        J = 0
        for k in range(N):
            e = S[:, k] - goal
            v = U[:, k] - ug
            J += 0.5 * (ca.bilin(Qs, e, e) + ca.bilin(Rs, v, v))
        eN = S[:, N] - goal
        J += 0.5 * ca.bilin(P, eN, eN) + p.rho1 * sigma + 0.5 * p.rho2 * sigma**2
        g = [S[:, 0] - x0, ca.vec(F - S[:, 1:])]
        nb = len(p.bounded)
        if nb:
            q = S[list(p.bounded), 1:]  # (nb, N)
            g += [ca.vec(q) - sigma, ca.vec(q) + sigma]
        w = ca.vertcat(ca.vec(S), ca.vec(U), sigma)
        opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "expand": True}
        opts.update(options or {})
        self.nlp = ca.nlpsol("nmpc_ipopt", "ipopt", {"x": w, "p": ca.vertcat(x0, goal), "f": J, "g": ca.vertcat(*g)},
                             opts)
        neq = nx * (N + 1)
        inf = np.inf
        self._lbg = np.r_[np.zeros(neq), np.full(N * nb, -inf), np.tile(p.q_low, N)]
        self._ubg = np.r_[np.zeros(neq), np.tile(p.q_high, N), np.full(N * nb, inf)]
        self._lbw = np.r_[np.full(nx * (N + 1), -inf), np.tile(p.u_low, N), 0.0]
        self._ubw = np.r_[np.full(nx * (N + 1), inf), np.tile(p.u_high, N), inf]
        self.stats: dict = {}

    def solve(self, x, S, U) -> tuple[np.ndarray, np.ndarray]:
        """``(S (N+1, nx), U (N, nu))`` solved from the guess ``S``, ``U`` for the start ``x`` (nx,); IPOPT's
        statistics in :attr:`stats`. Raises :class:`StepFailed` when the result is not finite."""
        p = self.problem
        N, nx, nu = p.N, p.nx, p.nu
        w0 = np.r_[S.ravel(), U.ravel(), 0.0]  # (N+1, nx) row-major = vec of (nx, N+1)
        sol = self.nlp(x0=w0, p=np.r_[x, p.goal_near(S[-1])], lbx=self._lbw, ubx=self._ubw, lbg=self._lbg,
                       ubg=self._ubg)
        self.stats = self.nlp.stats()
        w = np.asarray(sol["x"]).ravel()
        S_new = w[:nx * (N + 1)].reshape(N + 1, nx)
        U_new = w[nx * (N + 1):nx * (N + 1) + N * nu].reshape(N, nu)
        if not (np.all(np.isfinite(S_new)) and np.all(np.isfinite(U_new))):
            raise StepFailed(f"IPOPT returned a non-finite iterate ({self.stats.get('return_status')})")
        return S_new, U_new
