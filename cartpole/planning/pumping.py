"""Swing-ups that pump: guesses at the chain's slowest hanging mode, continuation in T and in the ctrl bound, seeded
restarts.

A weak actuator swings a chain up only by pumping energy in over many swings (dm_control's pendulum: 7 pumps in
6.5 s; the shipped cart at 5 N: about 7 s). A single solve from a straight-line guess finds none. Here:

1. :func:`hanging_mode`: the linearisation at the hanging equilibrium; its slowest oscillatory eigenvalue
   ``lambda = sigma + i omega`` is the mode to pump (any chain, any actuated joint: cart or hinge), with its left
   eigenvector ``l`` (``eta = l' (x - x_hanging)`` the mode's coordinate).
2. :func:`pump_rollout`: the exact discrete model (``model.step``) from the start under the law that grows the mode's
   amplitude fastest, ``u = u_mid + u_half sign(Re(conj(eta) l' B))`` per actuator (hinge errors from hanging wrapped),
   in proportion to the energy deficit (less the cart's momentum part, :func:`pump_energy`) until it reaches
   upright's, then held there (or, ``full``, with the whole ctrl range below upright's energy: the proportional
   push can stall short of upright against the damping); cart
   positions clipped into the bounds. A dynamically consistent shape of a pumping swing-up, seeded by the sign of the
   first push and a relaxed ctrl bound.
3. :func:`pumping_search`: for durations ``T`` from the first pumping rollout that reaches upright energy, growing by
   a fraction of a mode period up to ``T_max``, each guess bent onto the goal at the end, solved as the fixed-time
   effort problem with the ctrl bound relaxed (``RELAX``: 1.6, 1.3, 1.1 times the half ranges) and shrunk to the
   file's, each stage warm-started from the last; the first plan within the file's bound is kept. Where the
   whole-range law under the file's bound reaches upright energy sooner than the gentle one (which stalls when
   the damping takes out what its small pushes put in: the pendulum started near upright), the shorter durations
   it opens are tried first from its rollouts. Every solve is an :class:`~cartpole.ocp.records.Attempt`.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import casadi as ca
import numpy as np

from cartpole.models import CartPoleModel, wrap_angle
from cartpole.ocp.bounds import OCPBounds, OCPError
from cartpole.ocp.collocation import CollocationOptions, DirectCollocation
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory

#: Relaxed ctrl bounds of the continuation, as multiples of each actuator's half range, then the file's (1).
RELAX = (1.6, 1.3, 1.1, 1.0)
#: Collocation intervals per period of the pumped mode (at least :data:`MIN_N` in all).
N_PER_PERIOD = 24
MIN_N = 60
#: Longest plan in s the search tries by default.
T_MAX = 40.0
#: IPOPT iterations per solve of the search.
MAX_ITER = 400


def hanging_mode(model: CartPoleModel) -> tuple[float, float, np.ndarray, np.ndarray]:
    """The slowest oscillatory mode of the linearisation at hanging rest.

    Returns
    -------
    omega : float
        rad/s, its frequency (``Im lambda``).
    sigma : float
        1/s, its decay rate (``Re lambda``, negative with damping).
    left : (nx,) complex array
        Its left eigenvector ``l`` (``eta = l' (x - x_hanging)``).
    gain : (nu,) complex array
        ``l' B``: how each actuator drives it.

    Raises
    ------
    OCPError
        The hanging linearisation has no oscillatory mode (nothing swings).
    """
    A, B = model.linearize(model.x_hanging, model.u_hanging)
    lam, vl = _left_eig(A)
    osc = np.nonzero(lam.imag > 1e-9)[0]
    if osc.size == 0:
        raise OCPError("The hanging chain has no oscillating mode to pump; a pumping swing-up does not apply.")
    k = osc[np.argmin(lam.imag[osc])]
    left = vl[:, k]
    gain = left @ B
    if np.max(np.abs(gain)) < 1e-12 * max(1.0, np.abs(left).max()):
        raise OCPError("The actuators cannot drive the chain's slowest hanging mode; a pumping swing-up does not "
                       "apply.")
    return float(lam[k].imag), float(lam[k].real), left, gain


def _left_eig(A):
    lam, vr = np.linalg.eig(A)
    vl = np.linalg.inv(vr).T  # rows of inv(vr) are the left eigenvectors: l_k' A = lambda_k l_k'
    return lam, vl


def pump_energy(model: CartPoleModel, x: np.ndarray) -> np.ndarray:
    """The chain's energy (J, zero at upright rest) less the part the cart's momentum carries, ``p^2 / (2 M_ss)``
    (nothing without a cart), for states ``x`` (n, nx): (n,), the energy a swing-up must raise from hanging to
    zero."""
    x = np.atleast_2d(np.asarray(x, float))
    return np.asarray(_energy_function(model).map(x.shape[0])(x.T), float).ravel()


def _energy_function(model: CartPoleModel):
    """:func:`pump_energy` of one state as a CasADi Function ``x -> E`` (SX)."""
    x = ca.SX.sym("x", model.nx)
    E = model.energy(x)
    if model.slide is not None:
        M = model.mass_matrix(x)
        p = ca.mtimes(M[model.slide, :], x[model.nq:])
        E = E - 0.5 * p * p / M[model.slide, model.slide]
    return ca.Function("pump_energy", [x], [E])


def pump_rollout(model: CartPoleModel, x0, duration: float, bounds: OCPBounds, *, relax: float = 1.0,
                 first: float = 1.0, mode=None, full: bool = False) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Run the mode-pumping law (module notes) on ``model.step`` from ``x0`` for ``duration`` s.

    Parameters
    ----------
    model : CartPoleModel
    x0 : (nx,) array
    duration : float
        s.
    bounds : OCPBounds
        Its ctrl range is the law's (``relax`` times each half range about its middle); positions clipped into it.
    relax : float
        Scale of the half ranges (>= 1 relaxes).
    first : float
        +1 or -1: the sign of the first push (from rest the mode's amplitude is zero).
    mode : tuple, optional
        :func:`hanging_mode` (computed when not given).
    full : bool
        Below upright's energy push with the whole range; default in proportion to the energy deficit (four times
        the deficit relative to hanging's, clipped to the range), which can stall short of upright against the
        damping.

    Returns
    -------
    x : (n+1, nx) array
    u : (n, nu) array
    t_up : float or None
        s: when :func:`pump_energy` first reached upright's (zero), None if it did not.
    """
    _, _, left, gain = hanging_mode(model) if mode is None else mode
    mid = 0.5 * (bounds.u_low + bounds.u_high)
    half = 0.5 * (bounds.u_high - bounds.u_low) * relax
    n = max(1, round(duration / model.dt))
    energy = _energy_function(model)
    x = np.empty((n + 1, model.nx))
    u = np.empty((n, model.nu))
    x[0] = np.asarray(x0, float)
    hang = np.asarray(model.x_hanging, float)
    hinges = list(model.hinges)
    t_up = None
    E_h = float(energy(hang))
    for k in range(n):
        e = x[k] - hang
        e[hinges] = wrap_angle(e[hinges])
        eta = left @ e
        drive = np.real(np.conj(eta) * gain)
        sign = np.where(np.abs(drive) > 1e-12 * (1 + np.abs(gain)), np.sign(drive), first)
        Ek = float(energy(x[k]))
        if t_up is None and Ek >= 0.0:
            t_up = k * model.dt
        # below upright's energy: pump in proportion to the deficit (gentle near the top: the shape a plan can
        # follow), or with the whole range (``full``: a proportional push stalls where it balances the
        # damping's loss, short of upright); above: brake in proportion to the excess
        level = float(np.clip(-Ek / max(1e-12, -E_h) * 4.0, -1.0, 1.0))
        if full and Ek < 0.0:
            level = 1.0
        u[k] = mid + half * sign * level
        x[k + 1] = np.asarray(model.step_np(x[k], u[k]), float).ravel()
        if not np.all(np.isfinite(x[k + 1])):
            x[k + 1:] = x[k]
            u[k + 1:] = mid
            break
    for i in bounds.bounded_joints:
        x[:, i] = np.clip(x[:, i], bounds.q_low[i], bounds.q_high[i])
    return x, u, t_up


def bent_guess(model: CartPoleModel, x, u, x_goal, T: float, N: int, bounds: OCPBounds) -> Trajectory:
    """A rollout (``x`` (n+1, nx), ``u`` (n, nu) on ``model.dt``) resampled on ``N + 1`` knots over ``T`` s and bent
    onto ``x_goal`` ((nx,) ``[qpos, qvel]``) by ``(t / T)^4`` times the gap at the end (hinge angles shifted by whole
    turns to the nearest; the pumping early on untouched), positions clipped into the bounds."""
    n = u.shape[0]
    t_fine = model.dt * np.arange(n + 1)
    t = np.linspace(0.0, T, N + 1)
    xs = np.column_stack([np.interp(t, t_fine, x[:, i]) for i in range(model.nx)])
    uf = np.vstack([u, u[-1:]])
    us = np.column_stack([np.interp(t, t_fine, uf[:, i]) for i in range(model.nu)])
    goal = np.array(x_goal, float)
    for h in model.hinges:
        goal[h] += 2 * np.pi * np.round((xs[-1, h] - goal[h]) / (2 * np.pi))
    tau = (t / T)[:, None]
    xs = xs + tau**4 * (goal - xs[-1])
    for i in bounds.bounded_joints:
        xs[:, i] = np.clip(xs[:, i], bounds.q_low[i], bounds.q_high[i])
    us = np.clip(us, bounds.u_low, bounds.u_high)
    xdot = np.asarray(model.f.map(N + 1)(xs.T, us.T)).T
    return Trajectory(t=t, x=xs, u=us, xdot=xdot)


def relaxed(bounds: OCPBounds, c: float) -> OCPBounds:
    """``bounds`` with each actuator's half ctrl range scaled by ``c`` about its middle."""
    mid = 0.5 * (bounds.u_low + bounds.u_high)
    half = 0.5 * (bounds.u_high - bounds.u_low) * c
    return replace(bounds, u_low=mid - half, u_high=mid + half)


def pumping_search(model: CartPoleModel, x0, x_goal, bounds: OCPBounds, *, T_max: float = T_MAX,
                   seeds: int = 2, seed: int = 0, solver_options: dict | None = None, deadline_s: float | None = None
                   ) -> tuple[Trajectory | None, SolveInfo | None, list[Attempt]]:
    """Search for a pumping swing-up from ``x0`` to ``x_goal`` within the bounds (module notes).

    Parameters
    ----------
    model : CartPoleModel
    x0, x_goal : (nx,) arrays
        Start and goal (the goal's hinge angles shifted by whole turns to where each guess ends).
    bounds : OCPBounds
        The file's bounds (ctrl, joints).
    T_max : float
        s: the longest plan tried.
    seeds : int
        Restarts per duration: the pumping rollout with the first push one way, the other way, (3) one under the
        most relaxed bound, and from 4 on rollouts with a random first push and relaxation in [1, 1.6].
    seed : int
        Seed of ``numpy.random.default_rng`` for those random restarts.
    solver_options : dict, optional
        Passed to :class:`~cartpole.ocp.collocation.DirectCollocation`.
    deadline_s : float, optional
        Wall-time budget in s; the search stops (unsuccessful) when it is spent.

    Returns
    -------
    (Trajectory or None, SolveInfo or None, attempts)
        The first plan within the file's bounds (fixed-time effort at its T) and its info, or None; every solve.
    """
    tic = time.perf_counter()
    mode = hanging_mode(model)
    omega = mode[0]
    period = 2 * np.pi / omega
    x0 = np.asarray(x0, float)
    attempts: list[Attempt] = []
    opts = {"ipopt": {"max_iter": MAX_ITER}}
    if solver_options:
        opts.update(solver_options)
    # how long pumping takes under the file's bound (and under a relaxed one)
    probes = []
    rng = np.random.default_rng(seed)
    for i in range(max(1, seeds)):
        if i < 3:  # deterministic: the first push either way, then one under the most relaxed bound
            first, c0 = ((1.0, 1.0), (-1.0, 1.0), (1.0, RELAX[0]))[i]
        else:  # seeded: a random first push and relaxation
            first, c0 = float(rng.choice((-1.0, 1.0))), float(rng.uniform(1.0, RELAX[0]))
        x, u, t_up = pump_rollout(model, x0, T_max, relaxed(bounds, c0), first=first, mode=mode)
        probes.append((first, c0, False, x, u, t_up))
    reach = [p[5] for p in probes if p[5] is not None]
    T0 = (min(reach) if reach else T_max / 4) + 0.5 * period
    # the whole-range law under the file's bound: where it reaches upright energy before T0 (the gentle law stalls
    # against the damping, e.g. a pendulum started near upright), the short durations it opens are tried first
    # (run only up to T0: its rollouts serve durations below it)
    full = []
    for first in (1.0, -1.0):
        x, u, t_up = pump_rollout(model, x0, T0, bounds, first=first, mode=mode, full=True)
        if t_up is not None and t_up + 0.5 * period < T0 - 1e-9:
            full.append((first, 1.0, True, x, u, t_up))
    schedule = []
    if full:
        schedule += [(float(T), full) for T in np.arange(min(p[5] for p in full) + 0.5 * period, T0 - 1e-9,
                                                          0.5 * period)]
    schedule += [(float(T), probes) for T in np.arange(T0, T_max + 1e-9, 0.5 * period)]
    built: dict[int, DirectCollocation] = {}
    for T, tried in schedule:
        N = max(MIN_N, 20 * math.ceil(N_PER_PERIOD * T / period / 20))  # nearby T share an NLP
        for first, c0, whole, x, u, _ in tried:
            if deadline_s is not None and time.perf_counter() - tic > deadline_s:
                return None, None, attempts
            name = (f"pump{' full' if whole else ''} {'+' if first > 0 else '-'}"
                    f"{'' if c0 == 1.0 else f' relaxed {c0:.3g}'} T={T:.2f}")
            guess = bent_guess(model, x, u, x_goal, T, N, relaxed(bounds, RELAX[0]))
            traj, info = None, None
            if N not in built:  # one NLP per mesh, scaled for the widest bound; the continuation moves its bounds
                built[N] = DirectCollocation(model, N=N, T=T, bounds=relaxed(bounds, RELAX[0]),
                                              options=CollocationOptions(solver_options=opts))
            ocp = built[N]
            for c in RELAX:
                ocp.set_bounds(relaxed(bounds, c))
                traj, info = ocp.solve_once(x0, x_goal, guess=guess, T=T)
                attempts.append(Attempt.of(info, f"pump effort |u| x{c:g}", name, N, chosen=False))
                if not info.success:
                    break
                guess = traj
            if info is not None and info.success and traj is not None:
                attempts[-1] = replace(attempts[-1], chosen=True)
                return traj, replace(info, guess=name, attempts=tuple(attempts)), attempts
    return None, None, attempts
