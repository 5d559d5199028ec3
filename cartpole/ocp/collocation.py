"""Swing-up by direct collocation: Hermite-Simpson transcription in CasADi, built once, solved many times.

Transcription (compressed Hermite-Simpson with a first-order-hold input): knots ``x_k`` (4,), ``u_k`` (1,)
at ``t_k = k h``, ``h = T / N``; on each interval

    f_k = f(x_k, u_k),   x_c = (x_k + x_k+1) / 2 + h (f_k - f_k+1) / 8,   u_c = (u_k + u_k+1) / 2,
    x_k+1 - x_k - h (f_k + 4 f(x_c, u_c) + f_k+1) / 6 = 0.

The state between knots is therefore the cubic Hermite polynomial through the knots (``x_c`` is its value at
the midpoint) and the input is piecewise linear; :class:`~cartpole.ocp.trajectory.Trajectory` interpolates
the same way. The effort objective ``integral u^2 dt`` is Simpson's rule on that piecewise-linear input
(exact). Bounds come from the MJCF: ``|u| <= u_max`` (ctrlrange) and the cart inside its joint range
shrunk by a margin; the start and the final (upright rest) states are pinned through variable bounds, so
changing them never rebuilds anything.

Speed (the usual CasADi traps avoided): the NLP is built once per problem shape and cached; ``f`` is
evaluated at all knots by one ``map`` call and the interval defects by another; the MX graph is expanded to
SX (``expand=True``); variables and constraints are scaled to order one; warm starts reuse the last primal
and dual solution. For the fixed-time effort problem the interval functions (defect, effort, their
derivatives and the interval's Lagrangian Hessian block) are compiled to C once per model and mapped over the
intervals (:mod:`cartpole.ocp.compiled`): the same NLP in 2 to 3x less time a solve (2.2x to 2.7x measured).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel
from cartpole.ocp import compiled
from cartpole.ocp.guess import linear_guess
from cartpole.ocp.hermite_simpson import hs_interval_function, simpson_effort_terms
from cartpole.ocp.trajectory import Trajectory

OBJECTIVES = ("effort", "time")
SOLVERS = ("ipopt", "fatrop")


class OCPError(CartPoleError):
    """A trajectory-optimisation problem that is badly posed or did not converge."""


class OCPInfeasible(OCPError):
    """The swing-up problem has no solution within the bounds; the message names the bound that binds."""


@dataclass(frozen=True)
class SolveInfo:
    """What the NLP solver reported.

    Attributes
    ----------
    status : str
        The solver's return status (e.g. IPOPT's ``Solve_Succeeded``).
    success : bool
    iterations : int
    objective : float
        In physical units: ``integral u^2 dt`` (ctrl^2 s) for ``effort``, the final time T (s) for ``time``.
    solve_time_s : float
        Wall time of the solver call in s.
    solver : str
        ``ipopt`` or ``fatrop``.
    T : float
        Duration of the plan in s.
    start : int
        Index of the initial guess (start) the returned solution came from.
    """

    status: str
    success: bool
    iterations: int
    objective: float
    solve_time_s: float
    solver: str
    T: float
    start: int = 0


@dataclass(frozen=True)
class OCPBounds:
    """Bounds of the swing-up OCP in physical units.

    Attributes
    ----------
    u_max : float
        ``|ctrl| <= u_max``.
    cart_max : float
        ``|s| <= cart_max`` in m (after the margin); the cart's joint range centre is assumed at 0.
    cart_center : float
        Centre of the cart's range in m.
    """

    u_max: float
    cart_max: float
    cart_center: float = 0.0


def bounds_from_model(model: CartPoleModel, *, u_max: float | None = None, cart_max: float | None = None,
                      cart_margin: float = 0.1) -> OCPBounds:
    """OCP bounds from the MJCF behind ``model``: ctrlrange and the slide range shrunk by ``cart_margin`` (m).

    ``u_max``/``cart_max`` override the MJCF (the benchmark's standard problem uses 1 and 1.4 m).
    """
    p = model.params
    if u_max is None:
        u_max = p.u_max
        if not np.isfinite(u_max):
            raise OCPError("The MJCF's actuator has no ctrlrange; give u_max explicitly for the trajectory "
                           "optimisation.")
    lo, hi = p.cart_range
    center = 0.0 if not (np.isfinite(lo) and np.isfinite(hi)) else 0.5 * (lo + hi)
    if cart_max is None:
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise OCPError("The MJCF's slide joint is unlimited; give cart_max explicitly for the trajectory "
                           "optimisation.")
        cart_max = 0.5 * (hi - lo) - cart_margin
    if not (u_max > 0 and cart_max > 0):
        raise OCPError(f"The OCP bounds u_max = {u_max} and cart_max = {cart_max} m must be positive; "
                       "use a longer track or a smaller cart margin.")
    return OCPBounds(float(u_max), float(cart_max), float(center))


def _scales(model: CartPoleModel, bounds: OCPBounds) -> np.ndarray:
    """Typical magnitudes (5,) of [s, theta, s_dot, theta_dot, u], to scale the NLP to order one."""
    p = model.params
    m, l, g = p.pole_mass, p.pole_com_distance, p.g
    J = p.pole_inertia_about_hinge + p.armature[1]
    rate = np.sqrt(4 * m * g * l / J)  # pole rate reached by falling from upright to hanging
    acc = p.gear * bounds.u_max / (p.cart_mass + p.pole_mass)
    vel = min(np.sqrt(acc * bounds.cart_max), 0.5 * acc)
    return np.array([bounds.cart_max, np.pi, vel, rate, bounds.u_max])


@dataclass
class _Built:
    solver: ca.Function
    nw: int
    ng: int
    lbg: np.ndarray
    ubg: np.ndarray
    unpack: ca.Function  # w -> (X (4, N+1), U (1, N+1), T, Xc (4, N)), physical units
    relaxed: bool
    warm: bool
    idx: np.ndarray  # entries of the standard (ipopt) variable vector each solver variable holds


class DirectCollocation:
    """A Hermite-Simpson swing-up OCP for one model and problem shape, built once and solved many times.

    Parameters
    ----------
    model : CartPoleModel
        The symbolic model to plan with (its ``f``; its params give the default bounds).
    N : int
        Number of intervals.
    T : float or None
        Duration in s; None makes the final time free (then ``objective`` defaults to ``time``). A fixed T
        is a parameter of the NLP: :meth:`solve` accepts another ``T`` without rebuilding.
    objective : {'effort', 'time'}, optional
        ``effort`` minimises ``integral u^2 dt`` (Simpson quadrature, ctrl^2 s); ``time`` minimises T
        (free final time) plus ``time_effort_weight * integral u^2 dt`` to make the bang-bang answer unique.
    u_max, cart_max : float, optional
        Bounds overriding the MJCF's (ctrl; m).
    cart_margin : float
        Shrinks the MJCF's slide range on each side, m (default 0.1).
    T_range : (float, float)
        Bounds on the free final time in s.
    solver : {'ipopt', 'fatrop'}
        NLP solver; fatrop needs the casadi fatrop plugin.
    solver_options : dict, optional
        Passed straight to ``casadi.nlpsol`` (e.g. ``{"ipopt": {"tol": 1e-10}}``), merged over the defaults.
    time_effort_weight : float
        Weight of the effort term in the minimum-time objective (1/s per ctrl^2 s).
    separated : bool
        IPOPT only: make the midpoint states decision variables (separated Hermite-Simpson) instead of
        eliminating them (compressed, default). Same solution; a cheaper Hessian but a larger KKT system.
    compiled : bool
        IPOPT, fixed T, effort objective, compressed: evaluate the NLP and its derivatives with the
        Hermite-Simpson interval functions compiled to C (:mod:`cartpole.ocp.compiled`; the shared library is
        cached in ``~/.cache/cartpole``, compiled once per model in about a second). Same NLP, iterates and
        solution as the SX formulation, 2 to 3x faster a solve. Without a C compiler the SX formulation is
        used (a note on stderr). Default True.
    """

    def __init__(self, model: CartPoleModel, N: int = 100, T: float | None = 2.0, *, objective: str | None = None,
                 u_max: float | None = None, cart_max: float | None = None, cart_margin: float = 0.1,
                 T_range: tuple[float, float] = (0.2, 10.0), solver: str = "ipopt",
                 solver_options: dict | None = None, time_effort_weight: float = 1e-3,
                 separated: bool = False, compiled: bool = True):
        if objective is None:
            objective = "time" if T is None else "effort"
        if objective not in OBJECTIVES:
            raise OCPError(f"Objective '{objective}' is not known; choose one of {', '.join(OBJECTIVES)}.")
        if objective == "time" and T is not None:
            raise OCPError("A minimum-time objective needs a free final time; pass T=None.")
        if solver not in SOLVERS:
            raise OCPError(f"Solver '{solver}' is not supported; choose one of {', '.join(SOLVERS)}.")
        if solver == "fatrop" and T is None:
            raise OCPError("The fatrop formulation needs a fixed final time; give T or use solver='ipopt'.")
        if not ca.has_nlpsol(solver):
            raise OCPError(f"This CasADi build has no '{solver}' plugin; use solver='ipopt'.")
        if int(N) < 2:
            raise OCPError(f"N = {N} intervals is too few; use N >= 2 (100 is typical).")
        if T is not None and not T > 0:
            raise OCPError(f"Duration T = {T} s is not positive; give T > 0 or None for a free final time.")
        self.model = model
        self.N = int(N)
        self.T = None if T is None else float(T)
        self.free_time = T is None
        self.objective = objective
        self.bounds = bounds_from_model(model, u_max=u_max, cart_max=cart_max, cart_margin=cart_margin)
        self.T_range = (float(T_range[0]), float(T_range[1]))
        self.solver_name = solver
        self.solver_options = dict(solver_options or {})
        self.time_effort_weight = float(time_effort_weight)
        self.separated = bool(separated)
        self.compiled = bool(compiled)
        self.compiled_library: str | None = None  # the shared library in use, once built
        self.scale = _scales(model, self.bounds)
        self._interval = hs_interval_function(model.f)
        self._f_knots = model.f.map(self.N + 1)  # f at all N+1 knots: in the NLP and for the returned Trajectory
        self._built: dict[tuple, _Built] = {}
        self._last: dict | None = None  # primal and dual values of the last converged solve

    # ---- building --------------------------------------------------------------------------------
    def _options(self, warm: bool, solver_name: str) -> dict:
        opts: dict = {"expand": True, "print_time": False}
        if solver_name == "ipopt":
            ip = {"print_level": 0, "sb": "yes", "max_iter": 500, "tol": 1e-8}
            if warm:
                ip.update({"warm_start_init_point": "yes", "warm_start_bound_push": 1e-9,
                           "warm_start_mult_bound_push": 1e-9, "mu_init": 1e-6})
            opts["ipopt"] = ip
        else:
            opts.update({"structure_detection": "auto", "debug": False,
                         "fatrop": {"print_level": 0, "max_iter": 500, "tol": 1e-6}})
        user = dict(self.solver_options)
        for key in ("ipopt", "fatrop"):
            if key in user and key in opts:
                opts[key] = {**opts[key], **user.pop(key)}
        if solver_name != self.solver_name:  # options meant for another solver (relaxed problem uses IPOPT)
            user = {k: v for k, v in user.items() if k in ("expand", "print_time")}
        opts.update(user)
        return opts

    def _build(self, *, relaxed: bool = False, warm: bool = False) -> _Built:
        key = (relaxed, warm)
        if key in self._built:
            return self._built[key]
        N, sc = self.N, self.scale
        sx, su = sc[:4], sc[4]
        solver_name = "ipopt" if relaxed else self.solver_name
        n_extra = int(self.free_time) + 2 * int(relaxed)
        # "standard" vector (what guesses and bounds are packed into, scaled):
        #   [vec(Z) (5 (N+1): x_k, u_k per knot), vec(Xc) (4 N: midpoint states), (T), (slack_cart, slack_u)]
        if solver_name == "fatrop":
            # Fatrop needs explicit stage dynamics z_k+1 = F(z_k, w_k). Hermite-Simpson is implicit, so the
            # stage state is z_k = (x_k, u_k), the stage control w_k = (x_k+1, u_k+1) a copy of the next
            # knot, the dynamics are the copy z_k+1 = w_k, and the (compressed) defect is a path equality.
            w = ca.MX.sym("w", 10 * N + 5)  # [z_0, w_0, z_1, w_1, ..., z_N]
            stages = ca.reshape(w[:10 * N], 10, N)
            Z = ca.horzcat(stages[:5, :], w[10 * N:])
            Wn = stages[5:, :]
            X = Z[:4, :] * ca.DM(sx)
            U = Z[4:, :] * su
            F = self._f_knots(X, U)
            Xn, Un = Wn[:4, :] * ca.DM(sx), Wn[4:, :] * su
            Fn = self.model.f.map(N)(Xn, Un)
            # Boundary states as equality constraints of the first/last stage (fatrop handles a pinned
            # variable, lb = ub, poorly), from parameters p = [T, x0 (4), x_goal (4)] (scaled).
            p = ca.MX.sym("p", 9)
            T = p[0]
            h = T / N
            D, Xc = self._interval.map(N)(X[:, :-1], U[:, :-1], Xn, Un, F[:, :-1], Fn, h)
            blocks = [Z[:4, 0] - p[1:5]]
            blocks += [ca.vertcat(Z[:, k + 1] - Wn[:, k], D[:, k] / ca.DM(sx)) for k in range(N)]
            blocks.append(Z[:4, N] - p[5:9])
            g = [ca.vertcat(*blocks)]
            lbg = [np.zeros(9 * N + 8)]
            ubg = [np.zeros(9 * N + 8)]
            # entries of the standard vector each fatrop entry holds: z_k, then z_k+1 (the copy)
            idx = np.concatenate([np.r_[5 * k:5 * k + 10] for k in range(N)] + [np.r_[5 * N:5 * N + 5]])
        elif not self.separated:
            w = ca.MX.sym("w", 5 * (N + 1) + n_extra)  # [x_0, u_0, x_1, u_1, ..., x_N, u_N, extra]
            Z = ca.reshape(w[:5 * (N + 1)], 5, N + 1)
            ex = w[5 * (N + 1):]
            if self.free_time:
                T = ex[0]
                p = ca.MX.sym("p", 0)
            else:
                p = ca.MX.sym("p", 1)
                T = p[0]
            if relaxed:
                slk = ex[n_extra - 2:]
            X = Z[:4, :] * ca.DM(sx)
            U = Z[4:, :] * su
            h = T / N
            F = self._f_knots(X, U)
            D, Xc = self._interval.map(N)(X[:, :-1], U[:, :-1], X[:, 1:], U[:, 1:], F[:, :-1], F[:, 1:], h)
            # Defects scaled by the state scales (dimensionless), one block per interval, stage-ordered.
            g = [ca.vec(D / ca.DM(sx))]
            lbg = [np.zeros(4 * N)]
            ubg = [np.zeros(4 * N)]
            idx = np.r_[np.arange(5 * (N + 1)), np.arange(9 * N + 5, 9 * N + 5 + n_extra)]
        else:
            # Separated Hermite-Simpson: midpoint states are variables, so every f call depends on one
            # knot (or midpoint) only and the Hessian of the Lagrangian is block-diagonal and cheaper to
            # evaluate; the KKT system is larger, though (measured: slower overall at N = 100).
            w = ca.MX.sym("w", 9 * N + 5 + n_extra)  # [x_0, u_0, xc_0, x_1, u_1, xc_1, ..., x_N, u_N, extra]
            stages = ca.reshape(w[:9 * N], 9, N)
            Z = ca.horzcat(stages[:5, :], w[9 * N:9 * N + 5])
            Xc = stages[5:, :] * ca.DM(sx)
            ex = w[9 * N + 5:]
            if self.free_time:
                T = ex[0]
                p = ca.MX.sym("p", 0)
            else:
                p = ca.MX.sym("p", 1)
                T = p[0]
            if relaxed:
                slk = ex[n_extra - 2:]
            X = Z[:4, :] * ca.DM(sx)
            U = Z[4:, :] * su
            h = T / N
            F = self._f_knots(X, U)
            Uc_ = 0.5 * (U[:, :-1] + U[:, 1:])
            Fc = self.model.f.map(N)(Xc, Uc_)
            mid = Xc - (0.5 * (X[:, :-1] + X[:, 1:]) + h / 8 * (F[:, :-1] - F[:, 1:]))
            D = X[:, 1:] - X[:, :-1] - h / 6 * (F[:, :-1] + 4 * Fc + F[:, 1:])
            # both residuals scaled by the state scales (dimensionless), stage-ordered
            g = [ca.vec(ca.vertcat(mid, D) / ca.DM(np.r_[sx, sx]))]
            lbg = [np.zeros(8 * N)]
            ubg = [np.zeros(8 * N)]
            zc0 = 5 * (N + 1)
            idx = np.concatenate([np.r_[5 * k:5 * k + 5, zc0 + 4 * k:zc0 + 4 * k + 4] for k in range(N)]
                                 + [np.r_[5 * N:5 * N + 5], np.arange(9 * N + 5, 9 * N + 5 + n_extra)])
        effort = h / 6 * ca.sum2(simpson_effort_terms(U[:, :-1], U[:, 1:]))
        eff_scale = su**2 * (self.T or 1.0)
        if relaxed:
            # Slack on the cart and ctrl bounds (dimensionless): |s_k| <= cart_max (1 + slack_cart), etc.
            c = self.bounds.cart_center
            s_rel = (X[0, :] - c) / self.bounds.cart_max
            u_rel = U / self.bounds.u_max
            g += [ca.vec(s_rel - 1 - slk[0]), ca.vec(-s_rel - 1 - slk[0]),
                  ca.vec(u_rel - 1 - slk[1]), ca.vec(-u_rel - 1 - slk[1])]
            n4 = 4 * (N + 1)
            lbg.append(-np.inf * np.ones(n4))
            ubg.append(np.zeros(n4))
            J = 1e3 * ca.sum1(slk) + 1e-3 * effort / eff_scale
        elif self.objective == "effort":
            J = effort / eff_scale
        else:
            J = T + self.time_effort_weight * effort
        nlp = {"x": w, "f": J, "g": ca.vertcat(*g), "p": p}
        opts = self._options(warm, solver_name)
        lbg_all, ubg_all = np.concatenate(lbg), np.concatenate(ubg)
        if solver_name == "fatrop":
            opts.setdefault("equality", [bool(a == b) for a, b in zip(lbg_all, ubg_all)])
        if (self.compiled and solver_name == "ipopt" and not relaxed and not self.separated
                and not self.free_time and self.objective == "effort"):
            # Same NLP on interval functions compiled to C (see cartpole.ocp.compiled); None (the SX path
            # is kept) when there is no C compiler or the build fails.
            comp = compiled.compiled_nlp(self.model.f, N, sx, su, eff_scale)
            if comp is not None:
                nlp = comp.nlp
                opts.update(comp.options)
                opts["expand"] = False  # the compiled functions are called, not expanded
                self.compiled_library = comp.library
        solver = ca.nlpsol(f"hs_swingup_{'relaxed' if relaxed else 'nlp'}", solver_name, nlp, opts)
        unpack = ca.Function("unpack", [w, p], [X, U, T, Xc, effort])
        b = _Built(solver=solver, nw=w.numel(), ng=int(sum(a.size for a in lbg)), lbg=np.concatenate(lbg),
                   ubg=np.concatenate(ubg), unpack=unpack, relaxed=relaxed, warm=warm, idx=idx)
        self._built[key] = b
        return b

    # ---- numbers in and out ----------------------------------------------------------------------
    def _var_bounds(self, x0, x_goal, relaxed: bool, pin: bool = True):
        N, sc, bd = self.N, self.scale, self.bounds
        lb = -np.inf * np.ones((5, N + 1))
        ub = np.inf * np.ones((5, N + 1))
        if not relaxed:
            lb[0, :] = (bd.cart_center - bd.cart_max) / sc[0]
            ub[0, :] = (bd.cart_center + bd.cart_max) / sc[0]
            lb[4, :] = -bd.u_max / sc[4]
            ub[4, :] = bd.u_max / sc[4]
        if pin:
            lb[:4, 0] = ub[:4, 0] = x0 / sc[:4]
            lb[:4, -1] = ub[:4, -1] = x_goal / sc[:4]
        lbc = -np.inf * np.ones((4, N))
        ubc = np.inf * np.ones((4, N))
        if not relaxed:  # the cart bound holds at the midpoints too
            lbc[0, :] = (bd.cart_center - bd.cart_max) / sc[0]
            ubc[0, :] = (bd.cart_center + bd.cart_max) / sc[0]
        lb = [lb.ravel(order="F"), lbc.ravel(order="F")]
        ub = [ub.ravel(order="F"), ubc.ravel(order="F")]
        if self.free_time:
            lb.append([self.T_range[0]])
            ub.append([self.T_range[1]])
        if relaxed:
            lb.append([0.0, 0.0])
            ub.append([np.inf, np.inf])
        return np.concatenate(lb), np.concatenate(ub)

    def _pack_guess(self, traj: Trajectory | None, T: float, x0, x_goal, relaxed: bool) -> np.ndarray:
        N, sc = self.N, self.scale
        t = np.linspace(0.0, T, 2 * N + 1)  # knots and midpoints
        if traj is None:
            x, u = linear_guess(x0, x_goal, t)
        else:
            tt = traj.t[0] + t * (traj.duration / T)  # stretch the guess onto this duration
            x, u = traj.state(tt), traj.input(tt)
            if traj.duration != T:
                x = x.copy()
                x[:, 2:] *= traj.duration / T
                u = u.copy()
        Z = np.vstack([x[::2].T / sc[:4, None], u[::2].T / sc[4]])
        parts = [Z.ravel(order="F"), (x[1::2].T / sc[:4, None]).ravel(order="F")]
        if self.free_time:
            parts.append([T])
        if relaxed:
            parts.append([0.1, 0.1])
        return np.concatenate(parts)

    def _trajectory(self, b: _Built, w, T_param) -> tuple[Trajectory, float, float]:
        X, U, T, Xc, effort = b.unpack(w, T_param)
        X, U, Xc = np.asarray(X), np.asarray(U), np.asarray(Xc)
        T = float(T)
        xdot = np.asarray(self._f_knots(X, U))
        t = np.linspace(0.0, T, self.N + 1)
        traj = Trajectory(t=t, x=X.T, u=U.T, xdot=xdot.T, x_mid=Xc.T, u_mid=(0.5 * (U[:, :-1] + U[:, 1:])).T)
        return traj, T, float(effort)

    # ---- solving -----------------------------------------------------------------------------------
    def _goal(self, x0, x_goal, guess: Trajectory | None) -> np.ndarray:
        """The goal angle shifted by whole turns to the one the guess ends nearest (upright is upright)."""
        x_goal = np.array(x_goal, dtype=float)
        if guess is not None:
            turns = np.round((guess.x[-1, 1] - x_goal[1]) / (2 * np.pi))
            x_goal[1] += 2 * np.pi * turns
        return x_goal

    def _check_state(self, name, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (4,) or not np.all(np.isfinite(x)):
            raise OCPError(f"The {name} {x.tolist()} must be 4 finite numbers [s, theta, s_dot, theta_dot].")
        return x

    def solve_once(self, x0, x_goal=None, *, guess: Trajectory | None = None, T: float | None = None,
                   warm: bool = False, start: int = 0) -> tuple[Trajectory, SolveInfo]:
        """One solver call from one initial guess; never raises on non-convergence (check ``info.success``).

        Parameters
        ----------
        x0, x_goal : (4,) arrays
            Start and final state (``x_goal`` default upright rest; its angle is shifted by whole turns to
            the one ``guess`` ends nearest).
        guess : Trajectory, optional
            Initial guess (stretched onto ``T``); default a straight line that meets both boundary states.
        T : float, optional
            Duration in s for a fixed-time problem (default the one given at construction); for a
            free-time problem, the guess of T.
        warm : bool
            Start IPOPT from the previous solution's primal and dual values (same problem shape, e.g. a
            re-solve from a nearby start); ignores ``guess``.
        """
        x0 = self._check_state("start state", x0)
        x_goal = self._check_state("goal state", np.zeros(4) if x_goal is None else x_goal)
        x_goal = self._goal(x0, x_goal, guess)
        T = float(T if T is not None else (self.T if self.T is not None else (guess.duration if guess else 2.0)))
        warm = warm and self.solver_name == "ipopt" and self._last is not None
        b = self._build(warm=warm)
        lbx, ubx = self._var_bounds(x0, x_goal, False)
        p = [] if self.free_time else [T]
        if self.solver_name == "fatrop":  # boundary states are constraints there, not pinned variables
            sx = self.scale[:4]
            p = np.concatenate([[T], x0 / sx, x_goal / sx])
            lbx, ubx = self._var_bounds(x0, x_goal, False, pin=False)
        args = dict(lbx=lbx[b.idx], ubx=ubx[b.idx], lbg=b.lbg, ubg=b.ubg, p=p)
        if warm:
            last = self._last
            args.update(x0=last["x"], lam_x0=last["lam_x"], lam_g0=last["lam_g"])
        else:
            args["x0"] = self._pack_guess(guess, T, x0, x_goal, False)[b.idx]
        return self._run(b, args, T, start)

    def _run(self, b: _Built, args: dict, T: float, start: int) -> tuple[Trajectory, SolveInfo]:
        tic = time.perf_counter()
        try:
            sol = b.solver(**args)
        except RuntimeError as exc:  # e.g. NaN in a function evaluation
            raise OCPError(f"The NLP solver stopped with an error ({str(exc).splitlines()[-1]}); "
                           "give another initial guess or a longer T.") from None
        elapsed = time.perf_counter() - tic
        stats = b.solver.stats()
        w = np.asarray(sol["x"]).ravel()
        success = bool(stats.get("success", False))
        if success and not b.relaxed:
            # any solver of this shape may warm-start from here
            self._last = {"x": w, "lam_x": np.asarray(sol["lam_x"]).ravel(),
                          "lam_g": np.asarray(sol["lam_g"]).ravel()}
        traj, T_sol, effort = self._trajectory(b, w, args["p"])
        objective = T_sol if self.objective == "time" else effort
        it = stats.get("iter_count", stats.get("iterations", {}).get("iter", [-1])[-1]
                       if isinstance(stats.get("iterations"), dict) else -1)
        info = SolveInfo(status=str(stats.get("return_status", "unknown")), success=success,
                         iterations=int(it), objective=float(objective), solve_time_s=elapsed,
                         solver=self.solver_name, T=T_sol, start=start)
        return traj, info

    def solve(self, x0=(0.0, np.pi, 0.0, 0.0), x_goal=None, *, guess=None, T: float | None = None,
              starts: int = 3) -> tuple[Trajectory, SolveInfo]:
        """Solve from one or several initial guesses; return the best converged plan.

        Parameters
        ----------
        x0 : (4,) array
            Start state (default hanging at rest).
        x_goal : (4,) array, optional
            Final state, default upright rest (angle shifted by whole turns to the guess's nearest).
        guess : Trajectory or list of Trajectory, optional
            Initial guess(es); default :func:`cartpole.ocp.guess.initial_guesses` (an energy-shaping rollout
            of the symbolic model when available, then straight lines), ``starts`` of them.
        T : float, optional
            Duration in s (fixed-time problems; default the constructor's).
        starts : int
            How many default guesses to try before giving up.

        Returns
        -------
        (Trajectory, SolveInfo)

        Raises
        ------
        OCPInfeasible
            No start converged and a relaxed problem shows a bound must be violated (the message names it).
        OCPError
            No start converged but no bound is to blame (try another guess or a longer T).
        """
        from cartpole.ocp.guess import initial_guesses

        x0 = self._check_state("start state", x0)
        x_goal = self._check_state("goal state", np.zeros(4) if x_goal is None else x_goal)
        T_use = T if T is not None else self.T
        if guess is None:
            guesses = initial_guesses(self.model, x0, x_goal, T_use if T_use is not None else 2.0, self.N,
                                      u_max=self.bounds.u_max, cart_max=self.bounds.cart_max, count=starts)
        elif isinstance(guess, Trajectory):
            guesses = [guess]
        else:
            guesses = list(guess)
        best = None
        for i, g in enumerate(guesses):
            traj, info = self.solve_once(x0, x_goal, guess=g, T=T_use, start=i)
            if info.success and (best is None or info.objective < best[1].objective - 1e-9):
                best = (traj, info)
                if self.objective == "effort" or i == 0:
                    break  # one converged local optimum is enough; more starts only when asked by failure
        if best is not None:
            return best
        raise self.diagnose(x0, x_goal, guesses[0], T_use)

    def diagnose(self, x0, x_goal, guess: Trajectory | None, T: float | None) -> OCPError:
        """Solve the problem with slack on the cart and ctrl bounds and name the bound whose slack is needed.

        Returns (does not raise) an :class:`OCPInfeasible` or, when no slack is needed, an :class:`OCPError`.
        """
        b = self._build(relaxed=True)
        x_goal = self._goal(x0, x_goal, guess)
        T = float(T if T is not None else (guess.duration if guess is not None else 2.0))
        lbx, ubx = self._var_bounds(x0, x_goal, True)
        args = dict(x0=self._pack_guess(guess, T, x0, x_goal, True)[b.idx], lbx=lbx[b.idx], ubx=ubx[b.idx],
                    lbg=b.lbg, ubg=b.ubg,
                    p=[] if self.free_time else [T])
        sol = b.solver(**args)
        w = np.asarray(sol["x"]).ravel()
        s_cart, s_u = w[-2], w[-1]
        bd = self.bounds
        when = f"in T = {T:.3g} s" if not self.free_time else f"within T <= {self.T_range[1]:.3g} s"
        tol = 1e-4
        if s_cart > tol or s_u > tol:
            parts = []
            if s_cart > tol:
                parts.append(f"the cart bound |s| <= {bd.cart_max:.3g} m binds (the swing-up needs about "
                             f"{bd.cart_max * (1 + s_cart):.3g} m)")
            if s_u > tol:
                parts.append(f"the ctrl bound |u| <= {bd.u_max:.3g} binds (the swing-up needs about "
                             f"{bd.u_max * (1 + s_u):.3g})")
            return OCPInfeasible(f"The swing-up OCP is infeasible {when}: {' and '.join(parts)}; "
                                 "give a longer T, a longer track or more actuator force.")
        return OCPError(f"The swing-up OCP did not converge {when} although no bound needs relaxing; "
                        "give another initial guess or more intervals N.")
