"""Swing-up by direct collocation: Hermite-Simpson transcription in CasADi, built once, solved many times.

Transcription (compressed Hermite-Simpson with a first-order-hold input): knots ``x_k`` (nx,), ``u_k`` (nu,)
at ``t_k = k h``, ``h = T / N``; on each interval

    f_k = f(x_k, u_k),   x_c = (x_k + x_k+1) / 2 + h (f_k - f_k+1) / 8,   u_c = (u_k + u_k+1) / 2,
    x_k+1 - x_k - h (f_k + 4 f(x_c, u_c) + f_k+1) / 6 = 0.

The state between knots is therefore the cubic Hermite polynomial through the knots (``x_c`` is its value at
the midpoint) and the input is piecewise linear; :class:`~cartpole.ocp.trajectory.Trajectory` interpolates
the same way. The effort objective ``integral u'u dt`` is Simpson's rule on that piecewise-linear input
(exact). Bounds come from the MJCF (:mod:`cartpole.ocp.bounds`): each actuator's ctrlrange, the cart inside
its joint range shrunk by a margin, every other limited joint inside its range; the start and the final
(by default the model's upright equilibrium ``x_eq``) states are pinned through variable bounds, so changing
them never rebuilds anything. Any model shape works: the sizes come from the model's ``nx``, ``nu``.

Speed (the usual CasADi traps avoided): the NLP is built once per problem shape and cached; ``f`` is
evaluated at all knots by one ``map`` call and the interval defects by another; the MX graph is expanded to
SX (``expand=True``); variables and constraints are scaled to order one; warm starts reuse the last primal
and dual solution. With IPOPT (compressed) the interval functions (defect, interval cost, their derivatives in
the knots and the interval length, and the interval's Lagrangian Hessian block) are compiled to C once per model
and mapped over the intervals (:mod:`cartpole.ocp.compiled_nlp`), for every objective: fixed-time effort, running
costs, and minimum time, whose free T couples every interval (one dense column in the constraint Jacobian and
in the Hessian). Same NLP, same iterates, several times less time a solve (``cartpole bench`` measures it).

Multi-start: :meth:`DirectCollocation.solve` tries named, deterministic guesses
(:func:`cartpole.ocp.guess.named_guesses`) in turn and keeps the best converged one (``best_of``) or the first;
:meth:`DirectCollocation.multistart` returns all of them; every try is an :class:`Attempt` in
:attr:`SolveInfo.attempts`.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, replace
from typing import ClassVar

import casadi as ca
import numpy as np

from cartpole.models import CartPoleModel
from cartpole.options import StageOptions
from cartpole.ocp import compiled_nlp
from cartpole.ocp.bounds import OCPBounds, OCPError, bounds_from_model, bounds_from_params, scales
from cartpole.ocp.guess import linear_guess, named_guesses, stretched
from cartpole.ocp.hermite_simpson import hs_interval_function, simpson_effort_terms
from cartpole.ocp.objectives import NAMED, Objective, make_objective
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory

OBJECTIVES = NAMED  # plus any function (x, u) -> scalar (see cartpole.ocp.objectives)
SOLVERS = ("ipopt", "fatrop")


__all__ = ["Attempt", "CollocationOptions", "DirectCollocation", "OCPBounds", "OCPError", "OCPInfeasible",
           "OCPNotSolved", "SolveInfo", "bounds_from_model", "bounds_from_params"]


class OCPInfeasible(OCPError):
    """The swing-up problem provably has no solution within the bounds; the message states the proof (e.g. the energy
    ceiling of :mod:`cartpole.planning.energy_ceiling`). Raised only with a proof."""


class OCPNotSolved(OCPError):
    """No start converged: no solution was found, which proves nothing. The message says what was tried and, from a
    relaxed solve, which bound a nearby solution would need (a local figure). ``attempts`` holds every solve."""

    def __init__(self, message: str, attempts: tuple = ()):
        super().__init__(message)
        self.attempts = tuple(attempts)


@dataclasses.dataclass(frozen=True, eq=False)
class CollocationOptions(StageOptions):
    """Solver settings of a :class:`DirectCollocation` (the problem itself, model, grid, objective and bounds, is
    given to its constructor), validated on creation.

    Attributes
    ----------
    solver : {'ipopt', 'fatrop'}
        NLP solver (default ``ipopt``); fatrop needs the casadi fatrop plugin and a fixed final time.
    solver_options : mapping or None
        Passed straight to ``casadi.nlpsol`` (e.g. ``{"ipopt": {"tol": 1e-10}}``), merged over the defaults
        (stored read-only).
    time_effort_weight : float
        Weight (>= 0) of the effort term in the minimum-time objective, per ctrl^2 s (default 1e-3).
    separated : bool
        IPOPT only: make the midpoint states decision variables (separated Hermite-Simpson) instead of
        eliminating them (compressed, default False). Same solution; a cheaper Hessian but a larger KKT system.
    compiled : bool
        IPOPT, compressed, any objective (fixed T or free): evaluate the NLP and its derivatives with the
        Hermite-Simpson interval functions compiled to C (:mod:`cartpole.ocp.compiled_nlp`; the shared library is
        cached in ``~/.cache/cartpole`` under a key of the model, its scaling and running cost, compiled once per
        model, the larger sources unoptimised; one library serves every T, N and both fixed and free time). Same
        NLP, iterates and solution as the SX formulation, and faster a solve. Without a C compiler the SX formulation
        is used (a note on stderr). Default True.

    Raises
    ------
    OCPError
        An unknown solver, a negative weight or a ``solver_options`` that is not a mapping.
    """

    solver: str = "ipopt"
    solver_options: object = None
    time_effort_weight: float = 1e-3
    separated: bool = False
    compiled: bool = True

    error: ClassVar[type] = OCPError
    SCALARS: ClassVar[tuple] = ("time_effort_weight",)

    def __post_init__(self):
        if self.solver not in SOLVERS:
            raise OCPError(f"Solver '{self.solver}' is not supported; choose one of {', '.join(SOLVERS)}.")
        self.number("time_effort_weight", low=0.0, unit="per ctrl^2 s")
        self.freeze_mapping("solver_options")
        self.set_field("separated", bool(self.separated))
        self.set_field("compiled", bool(self.compiled))


@dataclass
class _Built:
    solver: ca.Function
    nw: int
    ng: int
    lbg: np.ndarray
    ubg: np.ndarray
    unpack: ca.Function  # w -> (X (nx, N+1), U (nu, N+1), T, Xc (nx, N), effort, running cost), physical
    relaxed: bool
    warm: bool
    idx: np.ndarray  # entries of the standard (ipopt) variable vector each solver variable holds


@dataclass
class _Transcription:
    """One transcription's symbols (MX): the variables ``w``, parameters ``p``, duration ``T`` and step ``h``, the
    physical knot states ``X`` (nx, N+1), inputs ``U`` (nu, N+1) and midpoint states ``Xc`` (nx, N), the slacks (or
    None), the constraint blocks and their bounds, and ``idx`` (see ``_Built``)."""
    w: ca.MX
    p: ca.MX
    T: ca.MX
    h: ca.MX
    X: ca.MX
    U: ca.MX
    Xc: ca.MX
    slack: ca.MX | None
    g: list
    lbg: list
    ubg: list
    idx: np.ndarray


class DirectCollocation:
    """A Hermite-Simpson OCP for one model and problem shape, built once and solved many times.

    Any model: states ``x`` (nx,) = ``[qpos, qvel]`` and inputs ``u`` (nu,) = MuJoCo ctrl, sizes from the model.

    Parameters
    ----------
    model : CartPoleModel
        The symbolic model to plan with (its ``f``; its params give the default bounds).
    N : int
        Number of intervals.
    T : float or None
        Duration in s; None makes the final time free (then ``objective`` defaults to ``time``). A fixed T
        is a parameter of the NLP: :meth:`solve` accepts another ``T`` without rebuilding.
    objective : {'effort', 'time', 'tracking', 'dmc_swingup'}, callable or Objective, optional
        ``effort`` minimises ``integral u'u dt`` (Simpson quadrature, ctrl^2 s); ``time`` minimises T
        (free final time) plus ``options.time_effort_weight * integral u'u dt`` to make the bang-bang answer unique;
        ``tracking`` a quadratic cost toward ``x*`` (``2 (1 - cos e)`` per hinge error), ``dmc_swingup``
        maximises dm_control's smooth swing-up reward; a function ``(x, u) -> scalar`` of CasADi SX symbols is
        a running cost (minimised), or a running reward (maximised) when wrapped with
        :func:`cartpole.ocp.objectives.reward`. Every objective but ``time`` needs a fixed T. See
        :mod:`cartpole.ocp.objectives`.
    u_max : float or (nu,) array, optional
        Symmetric ctrl bound ``|u| <= u_max`` overriding the MJCF's ctrlranges.
    cart_max : float, optional
        Cart bound ``|s - centre| <= cart_max`` in m overriding the slide range and margin.
    cart_margin : float
        Shrinks the MJCF's slide range on each side, m (default 0.1).
    bounds : OCPBounds, optional
        All bounds at once (e.g. those of another MJCF, :func:`cartpole.ocp.bounds.bounds_from_params`);
        overrides ``u_max``, ``cart_max`` and ``cart_margin``.
    T_range : (float, float)
        Bounds on the free final time in s (default (0.2, 10)).
    options : CollocationOptions, optional
        Solver settings: the NLP solver, options passed straight to ``casadi.nlpsol``, the minimum-time
        objective's effort weight, the separated or compressed transcription, compiled interval functions
        (default ``CollocationOptions()``: IPOPT, compressed, compiled).
    """

    def __init__(self, model: CartPoleModel, N: int = 100, T: float | None = 2.0, *, objective: str | None = None,
                 u_max: float | None = None, cart_max: float | None = None, cart_margin: float = 0.1,
                 T_range: tuple[float, float] = (0.2, 10.0), bounds: OCPBounds | None = None,
                 options: CollocationOptions | None = None):
        options = CollocationOptions() if options is None else options
        if not isinstance(options, CollocationOptions):
            raise OCPError(f"options must be a CollocationOptions; got {type(options).__name__}.")
        solver = options.solver
        obj = make_objective(model, objective, free_time=T is None)
        objective = obj.name
        if obj.free_time and T is not None:
            raise OCPError("A minimum-time objective needs a free final time; pass T=None.")
        if obj.kind == "running" and T is None:
            raise OCPError(f"The objective '{obj.name}' needs a fixed duration; give T (s).")
        if solver == "fatrop" and T is None:
            raise OCPError("The fatrop formulation needs a fixed final time; give T or use "
                           "CollocationOptions(solver='ipopt').")
        if not ca.has_nlpsol(solver):
            raise OCPError(f"This CasADi build has no '{solver}' plugin; use CollocationOptions(solver='ipopt').")
        if int(N) < 2:
            raise OCPError(f"N = {N} intervals is too few; use N >= 2 (100 is typical).")
        if T is not None and not T > 0:
            raise OCPError(f"Duration T = {T} s is not positive; give T > 0 or None for a free final time.")
        self.model = model
        self.N = int(N)
        self.T = None if T is None else float(T)
        self.free_time = T is None
        self.objective = objective
        self.objective_spec: Objective = obj
        self.nx, self.nu = int(model.nx), int(model.nu)
        if bounds is None:
            bounds = bounds_from_model(model, u_max=u_max, cart_max=cart_max, cart_margin=cart_margin)
        if bounds.u_low.size != self.nu or bounds.q_low.size != model.nq:
            raise OCPError(f"The bounds are for {bounds.u_low.size} inputs and {bounds.q_low.size} joints but the "
                           f"model has {self.nu} and {model.nq}; build them from this model's MJCF.")
        self.bounds = bounds
        self.T_range = (float(T_range[0]), float(T_range[1]))
        self.options = options
        self.solver_name = solver
        self.solver_options = dict(options.solver_options or {})
        self.time_effort_weight = options.time_effort_weight
        self.separated = options.separated
        self.compiled = options.compiled
        self.compiled_library: str | None = None  # the shared library in use, once built
        self.scale = scales(model, self.bounds)  # (nx + nu,): states then inputs
        self._interval = hs_interval_function(model.f)
        self._f_knots = model.f.map(self.N + 1)  # f at all N+1 knots: in the NLP and for the returned Trajectory
        self._built: dict[tuple, _Built] = {}
        self._last: dict | None = None  # primal and dual values of the last converged solve

    def set_bounds(self, bounds: OCPBounds) -> None:
        """Solve from now on within ``bounds`` (an :class:`OCPBounds` of the same model), without rebuilding the NLP:
        the bounds are the variables' bounds of each solve, while the scaling stays the one made at construction
        (e.g. a continuation that shrinks the ctrl bound step by step)."""
        if bounds.u_low.size != self.nu or bounds.q_low.size != self.model.nq:
            raise OCPError(f"The bounds are for {bounds.u_low.size} inputs and {bounds.q_low.size} joints but the "
                           f"model has {self.nu} and {self.model.nq}; build them from this model's MJCF.")
        self.bounds = bounds

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
        solver_name = "ipopt" if relaxed else self.solver_name
        n_slk = len(self._slack_names()) if relaxed else 0
        if solver_name == "fatrop":
            tr = self._transcribe_fatrop()
        elif not self.separated:
            tr = self._transcribe_compressed(n_slk)
        else:
            tr = self._transcribe_separated(n_slk)
        J, effort, running, eff_scale = self._objective(tr, relaxed)
        nlp = {"x": tr.w, "f": J, "g": ca.vertcat(*tr.g), "p": tr.p}
        opts = self._options(warm, solver_name)
        lbg_all, ubg_all = np.concatenate(tr.lbg), np.concatenate(tr.ubg)
        if solver_name == "fatrop":
            opts.setdefault("equality", [bool(a == b) for a, b in zip(lbg_all, ubg_all)])
        if self.compiled and solver_name == "ipopt" and not relaxed and not self.separated:
            nlp = self._compiled_nlp(nlp, opts, eff_scale)
        solver = ca.nlpsol(f"hs_swingup_{'relaxed' if relaxed else 'nlp'}", solver_name, nlp, opts)
        unpack = ca.Function("unpack", [tr.w, tr.p], [tr.X, tr.U, tr.T, tr.Xc, effort, running])
        b = _Built(solver=solver, nw=tr.w.numel(), ng=int(sum(a.size for a in tr.lbg)), lbg=np.concatenate(tr.lbg),
                   ubg=np.concatenate(tr.ubg), unpack=unpack, relaxed=relaxed, warm=warm, idx=tr.idx)
        self._built[key] = b
        return b

    # The "standard" vector (what guesses and bounds are packed into, scaled):
    #   [vec(Z) (nz (N+1): x_k, u_k per knot), vec(Xc) (nx N: midpoint states), (T), (slacks)]
    # Each transcription says which entry of it each of its own variables holds (``idx``).

    def _knots(self, Z, ex, n_slk: int):
        """T (s, a variable when free, else the parameter p), p, the slacks, and the unscaled knot states, inputs
        and their derivatives, from the scaled knots Z and the extra variables ex [(T), (slacks)]."""
        nx, sc = self.nx, self.scale
        n_extra = int(self.free_time) + n_slk
        p = ca.MX.sym("p", 0 if self.free_time else 1)
        T = ex[0] if self.free_time else p[0]
        slack = ex[n_extra - n_slk:] if n_slk else None
        X, U = Z[:nx, :] * ca.DM(sc[:nx]), Z[nx:, :] * ca.DM(sc[nx:])
        return T, p, slack, X, U, self._f_knots(X, U)

    def _transcribe_fatrop(self) -> _Transcription:
        """Fatrop needs explicit stage dynamics z_k+1 = F(z_k, w_k). Hermite-Simpson is implicit, so the stage state
        is z_k = (x_k, u_k), the stage control w_k = (x_k+1, u_k+1) a copy of the next knot, the dynamics are the
        copy z_k+1 = w_k, and the (compressed) defect is a path equality."""
        N, sc, nx = self.N, self.scale, self.nx
        nz = nx + self.nu
        sx, su = sc[:nx], sc[nx:]
        w = ca.MX.sym("w", 2 * nz * N + nz)  # [z_0, w_0, z_1, w_1, ..., z_N]
        stages = ca.reshape(w[:2 * nz * N], 2 * nz, N)
        Z = ca.horzcat(stages[:nz, :], w[2 * nz * N:])
        Wn = stages[nz:, :]
        X = Z[:nx, :] * ca.DM(sx)
        U = Z[nx:, :] * ca.DM(su)
        F = self._f_knots(X, U)
        Xn, Un = Wn[:nx, :] * ca.DM(sx), Wn[nx:, :] * ca.DM(su)
        Fn = self.model.f.map(N)(Xn, Un)
        # Boundary states as equality constraints of the first/last stage (fatrop handles a pinned
        # variable, lb = ub, poorly), from parameters p = [T, x0 (nx), x_goal (nx)] (scaled).
        p = ca.MX.sym("p", 1 + 2 * nx)
        T = p[0]
        h = T / N
        D, Xc = self._interval.map(N)(X[:, :-1], U[:, :-1], Xn, Un, F[:, :-1], Fn, h)
        blocks = [Z[:nx, 0] - p[1:1 + nx]]
        blocks += [ca.vertcat(Z[:, k + 1] - Wn[:, k], D[:, k] / ca.DM(sx)) for k in range(N)]
        blocks.append(Z[:nx, N] - p[1 + nx:])
        n_g = (nz + nx) * N + 2 * nx
        # entries of the standard vector each fatrop entry holds: z_k, then z_k+1 (the copy)
        idx = np.concatenate([np.r_[nz * k:nz * k + 2 * nz] for k in range(N)] + [np.r_[nz * N:nz * N + nz]])
        return _Transcription(w=w, p=p, T=T, h=h, X=X, U=U, Xc=Xc, slack=None, g=[ca.vertcat(*blocks)],
                              lbg=[np.zeros(n_g)], ubg=[np.zeros(n_g)], idx=idx)

    def _transcribe_compressed(self, n_slk: int) -> _Transcription:
        """Compressed Hermite-Simpson: the knots are the variables, the midpoint states eliminated."""
        N, nx = self.N, self.nx
        nz = nx + self.nu
        n_extra = int(self.free_time) + n_slk
        w = ca.MX.sym("w", nz * (N + 1) + n_extra)  # [x_0, u_0, x_1, u_1, ..., x_N, u_N, extra]
        Z = ca.reshape(w[:nz * (N + 1)], nz, N + 1)
        T, p, slk, X, U, F = self._knots(Z, w[nz * (N + 1):], n_slk)
        h = T / N
        D, Xc = self._interval.map(N)(X[:, :-1], U[:, :-1], X[:, 1:], U[:, 1:], F[:, :-1], F[:, 1:], h)
        # Defects scaled by the state scales (dimensionless), one block per interval, stage-ordered.
        g = [ca.vec(D / ca.DM(self.scale[:nx]))]
        n_std = (nz + nx) * N + nz  # knots and midpoints of the standard vector
        idx = np.r_[np.arange(nz * (N + 1)), np.arange(n_std, n_std + n_extra)]
        return _Transcription(w=w, p=p, T=T, h=h, X=X, U=U, Xc=Xc, slack=slk, g=g, lbg=[np.zeros(nx * N)],
                              ubg=[np.zeros(nx * N)], idx=idx)

    def _transcribe_separated(self, n_slk: int) -> _Transcription:
        """Separated Hermite-Simpson: midpoint states are variables, so every f call depends on one knot (or
        midpoint) only and the Hessian of the Lagrangian is block-diagonal and cheaper to evaluate; the KKT system is
        larger, though (measured: slower overall at N = 100)."""
        N, nx = self.N, self.nx
        nz = nx + self.nu
        sx = self.scale[:nx]
        n_extra = int(self.free_time) + n_slk
        ns = nz + nx  # one stage: knot and midpoint
        w = ca.MX.sym("w", ns * N + nz + n_extra)  # [x_0, u_0, xc_0, x_1, u_1, xc_1, ..., x_N, u_N, extra]
        stages = ca.reshape(w[:ns * N], ns, N)
        Z = ca.horzcat(stages[:nz, :], w[ns * N:ns * N + nz])
        Xc = stages[nz:, :] * ca.DM(sx)
        T, p, slk, X, U, F = self._knots(Z, w[ns * N + nz:], n_slk)
        h = T / N
        Uc_ = 0.5 * (U[:, :-1] + U[:, 1:])
        Fc = self.model.f.map(N)(Xc, Uc_)
        mid = Xc - (0.5 * (X[:, :-1] + X[:, 1:]) + h / 8 * (F[:, :-1] - F[:, 1:]))
        D = X[:, 1:] - X[:, :-1] - h / 6 * (F[:, :-1] + 4 * Fc + F[:, 1:])
        # both residuals scaled by the state scales (dimensionless), stage-ordered
        g = [ca.vec(ca.vertcat(mid, D) / ca.DM(np.r_[sx, sx]))]
        zc0 = nz * (N + 1)
        idx = np.concatenate([np.r_[nz * k:nz * k + nz, zc0 + nx * k:zc0 + nx * k + nx] for k in range(N)]
                             + [np.r_[nz * N:nz * N + nz], np.arange(ns * N + nz, ns * N + nz + n_extra)])
        return _Transcription(w=w, p=p, T=T, h=h, X=X, U=U, Xc=Xc, slack=slk, g=g, lbg=[np.zeros(2 * nx * N)],
                              ubg=[np.zeros(2 * nx * N)], idx=idx)

    def _objective(self, tr: _Transcription, relaxed: bool):
        """``(J, effort, running, eff_scale)``: the scaled objective of the transcription ``tr`` (with the relaxed
        problem's slack rows appended to ``tr.g``), the effort and running integrals (physical) and the effort's
        scale."""
        N, X, U, Xc, h = self.N, tr.X, tr.U, tr.Xc, tr.h
        su = self.scale[self.nx:]
        effort = h / 6 * ca.sum2(ca.sum1(simpson_effort_terms(U[:, :-1], U[:, 1:])))
        run = self.objective_spec.running
        if run is not None:  # Simpson on each interval: knots and the Hermite / first-order-hold midpoints
            Lk = run.map(N + 1)(X, U)
            Lc = run.map(N)(Xc, 0.5 * (U[:, :-1] + U[:, 1:]))
            running = h / 6 * (ca.sum2(Lk[:, :-1]) + 4 * ca.sum2(Lc) + ca.sum2(Lk[:, 1:]))
        else:
            running = ca.MX(0)
        eff_scale = float(np.sum(su**2)) * (self.T or 1.0)
        if relaxed:
            self._slack_rows(tr)
            J = 1e3 * ca.sum1(tr.slack) + 1e-3 * effort / eff_scale
        elif self.objective_spec.kind == "effort":
            J = effort / eff_scale
        elif self.objective_spec.kind == "running":
            J = running / (self.T or 1.0)  # the mean running cost: order one for the named objectives
        else:
            J = tr.T + self.time_effort_weight * effort
        return J, effort, running, eff_scale

    def _slack_rows(self, tr: _Transcription) -> None:
        """Append to ``tr``'s constraints the slack on each bounded joint and each ctrl (dimensionless, relative to
        the bound's half-width): |q_k - centre| <= half (1 + slack_joint), |u_k - centre| <= half (1 + slack_ctrl)."""
        bd, N, slk = self.bounds, self.N, tr.slack
        rows = [(tr.X[i, :], bd.q_low[i], bd.q_high[i]) for i in bd.bounded_joints]
        rows += [(tr.U[j, :], bd.u_low[j], bd.u_high[j]) for j in range(self.nu)]
        for k, (row, lo, hi) in enumerate(rows):
            c, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
            rel = (row - c) / half if c != 0 else row / half
            tr.g += [ca.vec(rel - 1 - slk[k]), ca.vec(-rel - 1 - slk[k])]
        n_rel = 2 * len(rows) * (N + 1)
        tr.lbg.append(-np.inf * np.ones(n_rel))
        tr.ubg.append(np.zeros(n_rel))

    def _compiled_nlp(self, nlp: dict, opts: dict, eff_scale: float) -> dict:
        """Same NLP on interval functions compiled to C (see cartpole.ocp.compiled_nlp), its solver options merged
        into ``opts``; ``nlp`` itself (the SX path is kept) when there is no C compiler or the build fails."""
        N, sc, nx = self.N, self.scale, self.nx
        sx, su = sc[:nx], sc[nx:]
        kind = self.objective_spec.kind
        if kind == "effort":
            comp = compiled_nlp.compiled_nlp(self.model, N, sx, su, eff_scale)
        elif kind == "running":
            comp = compiled_nlp.compiled_nlp(self.model, N, sx, su, self.T or 1.0, running=self.objective_spec.running)
        else:  # time: T + time_effort_weight * effort, T the last variable
            comp = compiled_nlp.compiled_nlp(self.model, N, sx, su, 1.0 / self.time_effort_weight,
                                             free_time=True, time_weight=1.0)
        if comp is None:
            return nlp
        opts.update(comp.options)
        opts["expand"] = False  # the compiled functions are called, not expanded
        self.compiled_library = comp.library
        return comp.nlp

    # ---- numbers in and out ----------------------------------------------------------------------
    def _slack_names(self) -> list[tuple[str, int]]:
        """The relaxed problem's slacks in order: ``("joint", qpos index)`` per bounded joint, then
        ``("ctrl", actuator index)`` per actuator."""
        return [("joint", i) for i in self.bounds.bounded_joints] + [("ctrl", j) for j in range(self.nu)]

    def _var_bounds(self, x0, x_goal, relaxed: bool, pin: bool = True):
        N, sc, bd, nx = self.N, self.scale, self.bounds, self.nx
        nz = nx + self.nu
        lb = -np.inf * np.ones((nz, N + 1))
        ub = np.inf * np.ones((nz, N + 1))
        lbc = -np.inf * np.ones((nx, N))
        ubc = np.inf * np.ones((nx, N))
        if not relaxed:  # joint bounds hold at the knots and at the midpoints; ctrl at the knots (FOH)
            for i in bd.bounded_joints:
                lb[i, :] = lbc[i, :] = bd.q_low[i] / sc[i]
                ub[i, :] = ubc[i, :] = bd.q_high[i] / sc[i]
            lb[nx:, :] = (bd.u_low / sc[nx:])[:, None]
            ub[nx:, :] = (bd.u_high / sc[nx:])[:, None]
        if pin:
            lb[:nx, 0] = ub[:nx, 0] = x0 / sc[:nx]
            lb[:nx, -1] = ub[:nx, -1] = x_goal / sc[:nx]
        lb = [lb.ravel(order="F"), lbc.ravel(order="F")]
        ub = [ub.ravel(order="F"), ubc.ravel(order="F")]
        if self.free_time:
            lb.append([self.T_range[0]])
            ub.append([self.T_range[1]])
        if relaxed:
            n_slk = len(self._slack_names())
            lb.append(np.zeros(n_slk))
            ub.append(np.full(n_slk, np.inf))
        return np.concatenate(lb), np.concatenate(ub)

    def _pack_guess(self, traj: Trajectory | None, T: float, x0, x_goal, relaxed: bool) -> np.ndarray:
        N, sc, nx, nq = self.N, self.scale, self.nx, self.model.nq
        t = np.linspace(0.0, T, 2 * N + 1)  # knots and midpoints
        if traj is None:
            u_rest = np.clip(self.model.u_eq, self.bounds.u_low, self.bounds.u_high)
            x, u = linear_guess(x0, x_goal, t, u=u_rest)
        else:
            if traj.x.shape[1] != nx or traj.u.shape[1] != self.nu:
                raise OCPError(f"The initial guess has {traj.x.shape[1]} states and {traj.u.shape[1]} inputs but "
                               f"the model has {nx} and {self.nu}; give a guess of this model.")
            x, u = stretched(traj, T, t, nq)  # the guess's path at this duration's pace
        Z = np.vstack([x[::2].T / sc[:nx, None], u[::2].T / sc[nx:, None]])
        parts = [Z.ravel(order="F"), (x[1::2].T / sc[:nx, None]).ravel(order="F")]
        if self.free_time:
            parts.append([T])
        if relaxed:
            parts.append(np.full(len(self._slack_names()), 0.1))
        return np.concatenate(parts)

    def _trajectory(self, b: _Built, w, T_param) -> tuple[Trajectory, float, float, float]:
        X, U, T, Xc, effort, running = b.unpack(w, T_param)
        X, U, Xc = np.asarray(X), np.asarray(U), np.asarray(Xc)
        T = float(T)
        xdot = np.asarray(self._f_knots(X, U))
        t = np.linspace(0.0, T, self.N + 1)
        traj = Trajectory(t=t, x=X.T, u=U.T, xdot=xdot.T, x_mid=Xc.T, u_mid=(0.5 * (U[:, :-1] + U[:, 1:])).T)
        return traj, T, float(effort), float(running)

    def _cost(self, info: SolveInfo) -> float:
        """The minimised quantity of ``info.objective`` (a reward's integral negated)."""
        return -info.objective if self.objective_spec.is_reward else info.objective

    # ---- solving -----------------------------------------------------------------------------------
    def _goal(self, x0, x_goal, guess: Trajectory | None) -> np.ndarray:
        """The goal's hinge angles shifted by whole turns to the ones the guess ends nearest (upright is
        upright); hinges with a joint range are left where they are."""
        x_goal = np.array(x_goal, dtype=float)
        if guess is not None:
            for i in self.model.hinges:
                if i in self.bounds.bounded_joints:
                    continue
                turns = np.round((guess.x[-1, i] - x_goal[i]) / (2 * np.pi))
                x_goal[i] += 2 * np.pi * turns
        return x_goal

    def _check_state(self, name, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (self.nx,) or not np.all(np.isfinite(x)):
            names = ", ".join(self.model.params.joint_names)
            raise OCPError(f"The {name} {x.tolist()} must be {self.nx} finite numbers: the positions of "
                           f"[{names}], then their rates.")
        return x

    def solve_once(self, x0, x_goal=None, *, guess: Trajectory | None = None, T: float | None = None,
                   warm: bool = False, start: int = 0) -> tuple[Trajectory, SolveInfo]:
        """One solver call from one initial guess; never raises on non-convergence (check ``info.success``).

        Parameters
        ----------
        x0, x_goal : (nx,) arrays
            Start and final state ``[qpos, qvel]`` (``x_goal`` default the model's upright equilibrium
            ``x_eq``; its hinge angles are shifted by whole turns to the ones ``guess`` ends nearest).
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
        x_goal = self._check_state("goal state", self.model.x_eq if x_goal is None else x_goal)
        x_goal = self._goal(x0, x_goal, guess)
        T = float(T if T is not None else (self.T if self.T is not None else (guess.duration if guess else 2.0)))
        warm = warm and self.solver_name == "ipopt" and self._last is not None
        b = self._build(warm=warm)
        lbx, ubx = self._var_bounds(x0, x_goal, False)
        p = [] if self.free_time else [T]
        if self.solver_name == "fatrop":  # boundary states are constraints there, not pinned variables
            sx = self.scale[:self.nx]
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
        traj, T_sol, effort, running = self._trajectory(b, w, args["p"])
        kind = self.objective_spec.kind
        objective = T_sol if kind == "time" else effort if kind == "effort" else (
            -running if self.objective_spec.is_reward else running)
        it = stats.get("iter_count", stats.get("iterations", {}).get("iter", [-1])[-1]
                       if isinstance(stats.get("iterations"), dict) else -1)
        info = SolveInfo(status=str(stats.get("return_status", "unknown")), success=success,
                         iterations=int(it), objective=float(objective), solve_time_s=elapsed,
                         solver=self.solver_name, T=T_sol, start=start)
        return traj, info

    def solve(self, x0=None, x_goal=None, *, guess=None, T: float | None = None,
              starts: int = 3, best_of: bool | None = None, stage: str | None = None
              ) -> tuple[Trajectory, SolveInfo]:
        """Solve from one or several initial guesses; return the best converged plan.

        Parameters
        ----------
        x0 : (nx,) array, optional
            Start state ``[qpos, qvel]`` (default the model's hanging rest ``x_hanging``).
        x_goal : (nx,) array, optional
            Final state, default the upright equilibrium ``x_eq`` (hinge angles shifted by whole turns to the
            guess's nearest).
        guess : Trajectory, list of Trajectory or of (name, Trajectory), optional
            Initial guess(es), tried in order; default :func:`cartpole.ocp.guess.named_guesses` (for one pole an
            energy-shaping rollout of the symbolic model, then pumping and straight-line shapes), ``starts``
            of them.
        T : float, optional
            Duration in s (fixed-time problems; default the constructor's).
        starts : int
            How many default guesses to try.
        best_of : bool, optional
            True: solve from every guess and keep the converged solution of least cost (a multi-start);
            False: stop at the first that converges. Default True for the default guesses of a
            minimum-time problem, False otherwise.
        stage : str, optional
            Label of the attempts in :attr:`SolveInfo.attempts` (default the objective's name).

        Returns
        -------
        (Trajectory, SolveInfo)
            ``info.start`` and ``info.guess`` name the guess that won; ``info.attempts`` lists every try.

        Raises
        ------
        OCPNotSolved
            No start converged (the message names the bound a relaxed solve from the first guess had to widen, a
            local figure: no proof that the problem is infeasible).
        """
        x0 = self._check_state("start state", self.model.x_hanging if x0 is None else x0)
        x_goal = self._check_state("goal state", self.model.x_eq if x_goal is None else x_goal)
        T_use = T if T is not None else self.T
        if guess is None:
            guesses = named_guesses(self.model, x0, x_goal, T_use if T_use is not None else 2.0, self.N,
                                    bounds=self.bounds, count=starts)
            if best_of is None:
                best_of = self.objective_spec.kind == "time"
        elif isinstance(guess, Trajectory):
            guesses = [("given", guess)]
        else:
            guesses = [g if isinstance(g, tuple) else (f"given {i}" if len(guess) > 1 else "given", g)
                       for i, g in enumerate(guess)]
        sols, attempts = self.multistart(x0, x_goal, guesses, T=T_use, stage=stage, best_of=bool(best_of))
        if sols:
            return sols[0]
        raise self.diagnose(x0, x_goal, guesses[0][1], T_use, attempts=attempts)

    def multistart(self, x0, x_goal, guesses, *, T: float | None = None, stage: str | None = None,
                   best_of: bool = True) -> tuple[list[tuple[Trajectory, SolveInfo]], list[Attempt]]:
        """Solve from each named guess in turn; never raises on non-convergence.

        Parameters
        ----------
        x0, x_goal : (nx,) arrays
            Start and goal ``[qpos, qvel]`` (the goal's hinge angles shifted by whole turns to each guess's end).
        guesses : list of (str, Trajectory)
            Named initial guesses, tried in order.
        T : float, optional
            Duration (fixed time) or the guess of T (free time), as :meth:`solve_once`.
        stage : str, optional
            Label of the attempts (default the objective's name).
        best_of : bool
            Solve from every guess (True) or stop at the first that converges.

        Returns
        -------
        (solutions, attempts)
            The converged ``(Trajectory, SolveInfo)`` pairs, least cost first (each info's ``attempts`` is every
            attempt, the best one marked ``chosen``), and every attempt in the order made.
        """
        label = stage or self.objective
        found, attempts = [], []
        for i, (name, g) in enumerate(guesses):
            traj, info = self.solve_once(x0, x_goal, guess=g, T=T, start=i)
            attempts.append(Attempt.of(info, label, name, self.N))
            if info.success:
                found.append((traj, replace(info, start=i, guess=name)))
                if not best_of:
                    break
        found.sort(key=lambda ti: (self._cost(ti[1]), ti[1].start))
        if found:
            k = found[0][1].start
            attempts[k] = replace(attempts[k], chosen=True)
        return [(tr, replace(inf, attempts=tuple(attempts))) for tr, inf in found], attempts

    def diagnose(self, x0, x_goal, guess: Trajectory | None, T: float | None, *, attempts=()) -> OCPNotSolved:
        """Solve the problem with slack on every joint and ctrl bound from ``guess`` and name the bounds whose slack
        it needed: what a failed multi-start (its ``attempts``) reports. One relaxed solve from one guess is a local
        result, so the sentence says so and never calls the problem infeasible.

        Returns (does not raise) an :class:`OCPNotSolved` carrying ``attempts``.
        """
        b = self._build(relaxed=True)
        x_goal = self._goal(x0, x_goal, guess)
        T = float(T if T is not None else (guess.duration if guess is not None else 2.0))
        lbx, ubx = self._var_bounds(x0, x_goal, True)
        args = dict(x0=self._pack_guess(guess, T, x0, x_goal, True)[b.idx], lbx=lbx[b.idx], ubx=ubx[b.idx],
                    lbg=b.lbg, ubg=b.ubg,
                    p=[] if self.free_time else [T])
        sol = b.solver(**args)
        names = self._slack_names()
        slack = np.asarray(sol["x"]).ravel()[-len(names):]
        when = f"in T = {T:.3g} s" if not self.free_time else f"within T <= {self.T_range[1]:.3g} s"
        tol = 1e-4
        parts = [self._binding(kind, i, s) for (kind, i), s in zip(names, slack) if s > tol]
        tried = f"after {len(attempts)} attempt{'s' if len(attempts) != 1 else ''}" if attempts else "from its guess"
        if parts:
            return OCPNotSolved(f"No swing-up found {when} {tried}; a relaxed solve from the first guess says "
                                f"{' and '.join(parts)} (local, no proof); give a longer T, other guesses, a longer "
                                "track or more force (in the MJCF, or --cart-max and --u-max where it has none).",
                                attempts)
        return OCPNotSolved(f"No swing-up found {when} {tried}, although a relaxed solve needs no bound widened; "
                            "give another initial guess or more intervals N.", attempts)

    def _binding(self, kind: str, i: int, slack: float) -> str:
        """Words for a bound the relaxed problem had to widen by the relative ``slack``."""
        bd = self.bounds
        if kind == "joint" and i == self.model.slide:
            return (f"the cart bound |s| <= {bd.cart_max:.3g} m binds (the swing-up needs about "
                    f"{bd.cart_max * (1 + slack):.3g} m)")
        if kind == "joint":
            lo, hi = bd.q_low[i], bd.q_high[i]
            c, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * (1 + slack)
            unit = "m" if self.model.params.joints[i].kind == "slide" else "rad"
            return (f"the range [{lo:.3g}, {hi:.3g}] {unit} of joint '{bd.joint_names[i]}' binds (the swing-up "
                    f"needs about [{c - half:.3g}, {c + half:.3g}] {unit})")
        lo, hi = bd.u_low[i], bd.u_high[i]
        which = "" if self.nu == 1 else f" of actuator '{bd.actuator_names[i]}'"
        if lo == -hi:
            return (f"the ctrl bound |u| <= {hi:.3g}{which} binds (the swing-up needs about "
                    f"{hi * (1 + slack):.3g})")
        c, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * (1 + slack)
        return (f"the ctrl bound {lo:.3g} <= u <= {hi:.3g}{which} binds (the swing-up needs about "
                f"[{c - half:.3g}, {c + half:.3g}])")
