"""Initial guesses for trajectory optimisation that meet both boundary states, for any model shape.

IPOPT started from a poor guess finds poor local minima or crawls. The guesses here, tried in order by
:meth:`DirectCollocation.solve`:

1. for a model with one pole and one input only: an energy-shaping rollout of the symbolic model
   (:func:`cartpole.control.energy.energy_rollout`), bent at the end onto the goal (:func:`energy_shaped_guess`;
   skipped for every other model);
2. a pumping shape (:func:`pump_guess`: every hinge swings back once before it rises, the cart moves out and
   back) and a smooth straight line (:func:`linear_guess`) towards the nearest upright angles;
3. the same two shapes towards a second goal: for a chain, every link after the first looping once more
   relative to its parent the way the first swings up (on the shipped two-pole cart the fastest swing-up);
   for a single hinge, upright one turn the other way.

When every hinge starts within a quarter turn of its goal angle, the straight lines come before the pumping
shapes (nothing needs pumping up). :func:`named_guesses` gives them with names (reported by the multi-start).
"""
from __future__ import annotations

import numpy as np

from cartpole.control.energy import EnergyShapingController, energy_rollout
from cartpole.control.linear import LinearFeedback
from cartpole.control.switching import SwitchingController
from cartpole.models import CartPoleModel, plant_model
from cartpole.ocp.bounds import OCPBounds, OCPError, bounds_from_model
from cartpole.ocp.trajectory import Trajectory


def _traj(model: CartPoleModel | None, t, x, u) -> Trajectory:
    """A Trajectory from knots ``x`` (n, nx), ``u`` (n, nu) or (n,); ``xdot`` from the model when given (else
    finite differences)."""
    t = np.asarray(t, dtype=float)
    u = np.asarray(u, dtype=float).reshape(t.size, -1)
    if model is not None:
        xdot = np.asarray(model.f.map(len(t))(x.T, u.T)).T
    else:
        xdot = np.gradient(x, t, axis=0)
    return Trajectory(t=t, x=x, u=u, xdot=xdot)


def linear_guess(x0, x_goal, t, u=None) -> tuple[np.ndarray, np.ndarray]:
    """Smooth straight line in position from ``x0`` to ``x_goal`` (both (nx,) = ``[qpos, qvel]``) over the times
    ``t`` (n,), with consistent rates.

    Positions follow ``x0 + (3 tau^2 - 2 tau^3) (x_goal - x0)`` (``tau`` from 0 to 1); rates that step's
    derivative plus a linear blend of the start and goal rates. ``u`` (nu,) is held constant (default one zero
    input).

    Returns ``(x (n, nx), u (n, nu))``; the end states are exactly ``x0`` and ``x_goal``.
    """
    x0 = np.asarray(x0, dtype=float)
    x_goal = np.asarray(x_goal, dtype=float)
    t = np.asarray(t, dtype=float)
    nq = x0.size // 2
    u = np.zeros(1) if u is None else np.atleast_1d(np.asarray(u, dtype=float))
    tau = (t - t[0]) / (t[-1] - t[0])
    # positions follow a smooth step (zero rate at both ends, matching rest states); rates its derivative
    sm = 3 * tau**2 - 2 * tau**3
    dsm = (6 * tau - 6 * tau**2) / (t[-1] - t[0])
    dq = x_goal[:nq] - x0[:nq]
    x = np.empty((t.size, x0.size))
    x[:, :nq] = x0[:nq] + np.outer(sm, dq)
    x[:, nq:] = np.outer(dsm, dq) + np.outer(1 - tau, x0[nq:]) + np.outer(tau, x_goal[nq:])
    return x, np.tile(u, (t.size, 1))


def stretched(traj: Trajectory, T: float, t, nq: int) -> tuple[np.ndarray, np.ndarray]:
    """``traj`` replayed over a duration ``T`` s instead of its own, sampled at the times ``t`` (s, on the new clock):
    the same path at another pace, the rates (state entries ``nq`` on) scaled by ``traj.duration / T``; returns
    ``(x (len(t), nx), u (len(t), nu))`` (the inputs as they are). How a plan seeds a problem of another duration."""
    t = np.asarray(t, dtype=float)
    ratio = traj.duration / T
    x, u = traj.state(traj.t[0] + t * ratio), traj.input(traj.t[0] + t * ratio)
    if ratio != 1.0:
        x = x.copy()
        x[:, nq:] *= ratio
        u = u.copy()
    return x, u


def pump_guess(x0, x_goal, t, *, hinges, slide=None, swing: float = 1.0, cart: float = 0.3,
               u=None) -> tuple[np.ndarray, np.ndarray]:
    """A swing-up shape with one back-swing on :func:`linear_guess`: every hinge (qpos indices ``hinges``) first
    swings by ``swing`` rad away from the direction it turns in (positive for a hinge that ends where it
    starts), then rises; the cart (qpos index ``slide``, None for no cart) moves by ``cart`` m the way the first
    hinge turns and back. Ends exactly at ``x0`` and ``x_goal`` (nx,), on the times ``t`` (n,) in s.

    Returns ``(x (n, nx), u (n, nu))``.
    """
    x, u = linear_guess(x0, x_goal, t, u)
    x0 = np.asarray(x0, dtype=float)
    x_goal = np.asarray(x_goal, dtype=float)
    nq = x0.size // 2
    t = np.asarray(t, dtype=float)
    T = t[-1] - t[0]
    tau = (t - t[0]) / T
    bump = np.sin(np.pi * tau) ** 2 * np.sin(np.pi * tau)  # zero value and slope at both ends
    dbump = 3 * np.sin(np.pi * tau) ** 2 * np.cos(np.pi * tau) * np.pi / T
    directions = [np.sign(x_goal[i] - x0[i]) or 1.0 for i in hinges]
    for i, direction in zip(hinges, directions):
        x[:, i] -= direction * swing * bump
        x[:, nq + i] -= direction * swing * dbump
    if slide is not None and directions:
        x[:, slide] += directions[0] * cart * bump
        x[:, nq + slide] += directions[0] * cart * dbump
    return x, u


def _clip_positions(x: np.ndarray, bounds: OCPBounds) -> np.ndarray:
    """``x`` (n, nx) with each bounded joint's position clipped into its bounds (in place; returned)."""
    for i in bounds.bounded_joints:
        x[:, i] = np.clip(x[:, i], bounds.q_low[i], bounds.q_high[i])
    return x


def energy_shaped_guess(model: CartPoleModel, x0, x_goal, T: float, N: int, *,
                        bounds: OCPBounds) -> Trajectory | None:
    """An energy-shaping rollout of the symbolic model over ``T`` s from ``x0`` (nx,), bent onto ``x_goal`` at the end.

    Single pole only: energy shaping pumps one pole with one input, so this returns None for any model without
    exactly one hinge and one actuator (the other guesses of :func:`initial_guesses` cover those).

    The rollout is :func:`~cartpole.control.energy.energy_rollout` under ``EnergyShapingController(model)`` (no
    catch), ctrl clipped to the bounds' ``[u_low, u_high]``, ``round(T / dt)`` steps, resampled on ``N + 1``
    knots (states and ctrl linearly) and bent quadratically in time onto ``x_goal`` (nx,), the goal angle taken
    modulo 2 pi nearest to where the rollout ends; bounded joint positions (the cart) clipped into the bounds.
    Returns None when the controller cannot be built for the model or the rollout fails (NaN/inf).
    """
    if len(model.hinges) != 1 or model.nu != 1:
        return None
    try:
        ctrl = EnergyShapingController(model)
    except Exception:  # a model energy shaping cannot drive (no ctrl range ...)
        return None
    dt = model.dt
    n = max(1, int(round(T / dt)))
    lo, hi = float(bounds.u_low[0]), float(bounds.u_high[0])
    try:
        x, u = energy_rollout(model, ctrl, x0, n, u_limits=(lo, hi))
    except Exception:
        return None
    if not np.all(np.isfinite(x)):
        return None
    u = np.append(u, u[-1])  # the last knot holds the last ctrl
    t_fine = dt * np.arange(n + 1)
    t = np.linspace(0.0, T, N + 1)
    xs = np.column_stack([np.interp(t, t_fine, x[:, i]) for i in range(model.nx)])
    us = np.interp(t, t_fine, u)
    goal = np.array(x_goal, dtype=float)
    h = model.hinges[0]
    goal[h] += 2 * np.pi * np.round((xs[-1, h] - goal[h]) / (2 * np.pi))
    tau = (t / T)[:, None]
    xs = xs + tau**2 * (goal - xs[-1])  # bend onto the goal; zero change at the start
    _clip_positions(xs, bounds)
    return _traj(model, t, xs, np.clip(us, lo, hi))


def _upright_candidates(model: CartPoleModel, x0, x_goal, bounds: OCPBounds) -> list[np.ndarray]:
    """Two goals: every free hinge at the upright angle (``x_goal``'s modulo whole turns) nearest its start, then
    every free hinge one turn the other way (hinges with a joint range keep ``x_goal``'s angle)."""
    base = np.array(x_goal, dtype=float)
    goals = [base.copy(), base.copy()]
    for i in model.hinges:
        if i in bounds.bounded_joints:
            continue
        k = np.round((x0[i] - base[i]) / (2 * np.pi))
        cands = sorted([base[i] + 2 * np.pi * k, base[i] + 2 * np.pi * (k + 1), base[i] + 2 * np.pi * (k - 1)],
                       key=lambda a: abs(a - x0[i]))[:2]
        goals[0][i], goals[1][i] = cands
    return goals


def _co_turn_goal(model: CartPoleModel, x0, nearest: np.ndarray, bounds: OCPBounds) -> np.ndarray | None:
    """``nearest`` with every free hinge after the first turned one more whole turn the way the first hinge turns
    (each link loops once relative to its parent, with the swing); None with fewer than two free hinges."""
    free = [i for i in model.hinges if i not in bounds.bounded_joints]
    if len(free) < 2:
        return None
    first = free[0]
    direction = np.sign(nearest[first] - x0[first]) or 1.0
    goal = nearest.copy()
    for i in free[1:]:
        goal[i] += 2 * np.pi * direction
    return goal


def named_guesses(model: CartPoleModel, x0, x_goal=None, T: float = 2.0, N: int = 100, *,
                  bounds: OCPBounds | None = None, u_max=None, cart_max: float | None = None,
                  count: int = 4, second_goal: bool = True) -> list[tuple[str, Trajectory]]:
    """Up to ``count`` named initial guesses on ``N + 1`` knots over ``T`` s, in the order they are tried.

    A deterministic set (no randomness): for a single pole with one input the energy-shaping rollout
    (``"energy"``) first; then the pumping shape (``"pump"``) and the straight line (``"line"``) to the nearest
    upright angles (the line first when every hinge starts within a quarter turn of upright); then the same two
    shapes to a second goal, ``"... co-turn"`` (every link after the first loops once more relative to its parent,
    the way the first swings up; chains of two or more free hinges) or ``"... other turn"`` (every free hinge one
    turn the other way; a single hinge).

    Parameters
    ----------
    model : CartPoleModel
    x0, x_goal : (nx,) arrays
        Start and goal ``[qpos, qvel]`` (goal default the upright equilibrium ``model.x_eq``).
    T : float
        Duration in s.
    N : int
        Intervals.
    bounds : OCPBounds, optional
        The problem's bounds (the energy-shaped guess clips ctrl and positions into them); default
        :func:`~cartpole.ocp.bounds.bounds_from_model` with ``u_max`` and ``cart_max`` passed on.
    u_max : float or (nu,) array, optional
        ctrl bound (default the MJCF's ctrlranges).
    cart_max : float, optional
        Cart travel bound in m (default the MJCF's rail).
    count : int
        Most guesses returned.
    second_goal : bool
        Include the shapes towards the second goal (False: the energy guess and the two shapes towards the
        nearest upright angles only).

    Returns
    -------
    list of (str, Trajectory)
        Name and guess; each guess meets ``x0`` and ``x_goal`` (hinge angles possibly shifted by whole turns).
    """
    if bounds is None:
        bounds = bounds_from_model(model, u_max=u_max, cart_max=cart_max)
    x0 = np.asarray(x0, dtype=float)
    x_goal = model.x_eq if x_goal is None else x_goal
    t = np.linspace(0.0, T, N + 1)
    out: list[tuple[str, Trajectory]] = []
    eg = energy_shaped_guess(model, x0, x_goal, T, N, bounds=bounds)
    if eg is not None:
        out.append(("energy", eg))
    goals = _upright_candidates(model, x0, x_goal, bounds)
    co = _co_turn_goal(model, x0, goals[0], bounds)
    second = [] if not second_goal else [(" other turn", goals[1])] if co is None else [(" co-turn", co)]
    u_rest = np.clip(model.u_eq, bounds.u_low, bounds.u_high)
    near = all(abs(x0[i] - goals[0][i]) < 0.5 * np.pi for i in model.hinges)
    for tag, g in [("", goals[0]), *second]:
        pump = ("pump" + tag, _traj(model, t, *pump_guess(x0, g, t, hinges=model.hinges, slide=model.slide,
                                                         u=u_rest)))
        line = ("line" + tag, _traj(model, t, *linear_guess(x0, g, t, u=u_rest)))
        out += [line, pump] if near else [pump, line]
    return out[:max(1, count)]


def initial_guesses(model: CartPoleModel, x0, x_goal=None, T: float = 2.0, N: int = 100, *,
                    bounds: OCPBounds | None = None, u_max=None, cart_max: float | None = None,
                    count: int = 3) -> list[Trajectory]:
    """The guesses of :func:`named_guesses` without their names (same arguments: ``x0``, ``x_goal`` (nx,) states,
    ``T`` in s, ``u_max`` ctrl, ``cart_max`` m), best first.

    Returns
    -------
    list of Trajectory
        Each meets ``x0`` and ``x_goal`` (hinge angles possibly shifted by whole turns).
    """
    return [g for _, g in named_guesses(model, x0, x_goal, T, N, bounds=bounds, u_max=u_max, cart_max=cart_max,
                                        count=count)]


def energy_guess(plant=None, x0=None, T: float = 4.0, N: int = 100, *, controller=None,
                 catch=True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A swing-up guess for trajectory optimisation: simulate the symbolic model under energy shaping.

    The symbolic model's exact discrete step (``model.step``, the MJCF's integrator) is run for ``T`` seconds
    under the energy controller (and, with ``catch``, the LQR catch once the state is near upright), and the
    states and inputs are sampled on a uniform grid of ``N`` intervals.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        One pole on a cart (see :func:`cartpole.control.energy.check_single_pole`) unless ``controller`` is given.
    x0 : (nx,) array, optional
        Start state; default the model's hanging rest ``model.x_hanging`` (``[0, pi, 0, 0]`` on the shipped cart).
    T : float
        Horizon in s.
    N : int
        Number of grid intervals.
    controller : callable, optional
        ``(t, x) -> ctrl`` (one input) to use instead of the default energy shaping (+ catch).
    catch : bool
        Switch to the lab LQR once ``e' S e`` is below a conservative level (no MuJoCo basin estimate here).

    Returns
    -------
    t : (N+1,) array, s
    x : (N+1, nx) array
    u : (N, 1) array, ctrl applied from ``t[k]`` (zero-order sample of the simulated input)
    """
    model = plant_model(plant)
    if not (T > 0 and int(N) >= 1):
        raise OCPError(f"energy_guess needs T > 0 and N >= 1 (got T = {T}, N = {N}).")
    N = int(N)
    x0 = model.x_hanging if x0 is None else x0
    if controller is None:
        controller = EnergyShapingController(model)
        if catch:
            c = LinearFeedback.for_model(model)
            # Without a MuJoCo basin estimate use a small, safe level: 10 % of the cost of a 0.2 rad tilt.
            tilt = np.zeros(model.nx)
            tilt[model.hinges[0]] = 0.2
            rho = 0.1 * float(tilt @ c.S @ tilt)
            controller = SwitchingController(controller, c, rho)
    h = model.dt
    n = int(np.ceil(T / h))
    xs, us = energy_rollout(model, controller, x0, n, u_limits=model.params.ctrl_range[0])
    tk = np.arange(n + 1) * h
    tg = np.linspace(0.0, T, N + 1)
    xg = np.column_stack([np.interp(tg, tk, xs[:, i]) for i in range(model.nx)])
    idx = np.minimum((tg[:-1] / h).astype(int), n - 1)
    return tg, xg, us[idx].reshape(-1, 1)
