"""Initial guesses for the swing-up OCP that meet both boundary states.

IPOPT started from a poor guess finds poor local minima or crawls. The guesses here, tried in order by
:meth:`DirectCollocation.solve`: an energy-shaping rollout of the symbolic model
(:func:`cartpole.control.energy.energy_rollout`), bent at the end onto the goal; then straight lines from start
to goal turning the pole either way; then a pumping shape (one back-swing before the rise).
"""
from __future__ import annotations

import numpy as np

from cartpole.control.energy import EnergyShapingController, energy_rollout
from cartpole.models import CartPoleModel
from cartpole.ocp.trajectory import Trajectory


def _traj(model: CartPoleModel | None, t, x, u) -> Trajectory:
    """A Trajectory from knots; ``xdot`` from the model when given (else finite differences)."""
    u = np.asarray(u, dtype=float).reshape(-1, 1)
    if model is not None:
        xdot = np.asarray(model.f.map(len(t))(x.T, u.T)).T
    else:
        xdot = np.gradient(x, t, axis=0)
    return Trajectory(t=t, x=x, u=u, xdot=xdot)


def linear_guess(x0, x_goal, t) -> tuple[np.ndarray, np.ndarray]:
    """Straight line in position from ``x0`` to ``x_goal`` over the times ``t`` (n,), with consistent rates.

    Returns ``(x (n, 4), u (n, 1))`` with zero input; the end states are exactly ``x0`` and ``x_goal``.
    """
    x0 = np.asarray(x0, dtype=float)
    x_goal = np.asarray(x_goal, dtype=float)
    t = np.asarray(t, dtype=float)
    tau = (t - t[0]) / (t[-1] - t[0])
    # positions follow a smooth step (zero rate at both ends, matching rest states); rates its derivative
    sm = 3 * tau**2 - 2 * tau**3
    dsm = (6 * tau - 6 * tau**2) / (t[-1] - t[0])
    x = np.empty((t.size, 4))
    x[:, :2] = x0[:2] + np.outer(sm, x_goal[:2] - x0[:2])
    x[:, 2:] = np.outer(dsm, x_goal[:2] - x0[:2]) + np.outer(1 - tau, x0[2:]) + np.outer(tau, x_goal[2:])
    return x, np.zeros((t.size, 1))


def pump_guess(x0, x_goal, t, *, swing: float = 1.0, cart: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """A swing-up shape with one back-swing: the pole first swings by ``-swing`` rad away from its final
    direction, then rises; the cart moves by ``cart`` m and back. Ends exactly at ``x0`` and ``x_goal``.

    Returns ``(x (n, 4), u (n, 1))``.
    """
    x, u = linear_guess(x0, x_goal, t)
    t = np.asarray(t, dtype=float)
    T = t[-1] - t[0]
    tau = (t - t[0]) / T
    direction = np.sign(x_goal[1] - x0[1]) or 1.0
    bump = np.sin(np.pi * tau) ** 2 * np.sin(np.pi * tau)  # zero value and slope at both ends
    dbump = 3 * np.sin(np.pi * tau) ** 2 * np.cos(np.pi * tau) * np.pi / T
    x[:, 1] -= direction * swing * bump
    x[:, 3] -= direction * swing * dbump
    x[:, 0] += direction * cart * bump
    x[:, 2] += direction * cart * dbump
    return x, u


def energy_shaped_guess(model: CartPoleModel, x0, x_goal, T: float, N: int, *, u_max: float,
                        cart_max: float) -> Trajectory | None:
    """An energy-shaping rollout of the symbolic model over ``T`` s, bent onto ``x_goal`` at the end.

    The rollout is :func:`~cartpole.control.energy.energy_rollout` under ``EnergyShapingController(model)`` (no
    catch), ctrl clipped to ``|u| <= u_max``, ``round(T / dt)`` steps, resampled on ``N + 1`` knots (states and
    ctrl linearly) and bent quadratically in time onto ``x_goal``, the goal angle taken modulo 2 pi nearest to
    where the rollout ends; cart positions clipped to ``|s| <= cart_max`` m. Returns None when the controller
    cannot be built for the model or the rollout fails (NaN/inf).
    """
    try:
        ctrl = EnergyShapingController(model)
    except Exception:  # a model energy shaping cannot drive (no ctrl range ...)
        return None
    dt = model.dt
    n = max(1, int(round(T / dt)))
    try:
        x, u = energy_rollout(model, ctrl, x0, n, u_limits=(-u_max, u_max))
    except Exception:
        return None
    if not np.all(np.isfinite(x)):
        return None
    u = np.append(u, u[-1])  # the last knot holds the last ctrl
    t_fine = dt * np.arange(n + 1)
    t = np.linspace(0.0, T, N + 1)
    xs = np.column_stack([np.interp(t, t_fine, x[:, i]) for i in range(4)])
    us = np.interp(t, t_fine, u)
    goal = np.array(x_goal, dtype=float)
    goal[1] += 2 * np.pi * np.round((xs[-1, 1] - goal[1]) / (2 * np.pi))
    tau = (t / T)[:, None]
    xs = xs + tau**2 * (goal - xs[-1])  # bend onto the goal; zero change at the start
    xs[:, 0] = np.clip(xs[:, 0], -cart_max, cart_max)
    return _traj(model, t, xs, np.clip(us, -u_max, u_max))


def initial_guesses(model: CartPoleModel, x0, x_goal, T: float, N: int, *, u_max: float, cart_max: float,
                    count: int = 3) -> list[Trajectory]:
    """Up to ``count`` initial guesses on ``N + 1`` knots over ``T`` s, best first (see the module docstring).

    Each meets ``x0`` and ``x_goal`` (the goal angle possibly shifted by whole turns).
    """
    x0 = np.asarray(x0, dtype=float)
    t = np.linspace(0.0, T, N + 1)
    out: list[Trajectory] = []
    eg = energy_shaped_guess(model, x0, x_goal, T, N, u_max=u_max, cart_max=cart_max)
    if eg is not None:
        out.append(eg)
    # the two upright angles nearest the start, nearest first
    base = np.array(x_goal, dtype=float)
    k = np.round((x0[1] - base[1]) / (2 * np.pi))
    cands = sorted([base[1] + 2 * np.pi * k, base[1] + 2 * np.pi * (k + 1), base[1] + 2 * np.pi * (k - 1)],
                   key=lambda a: abs(a - x0[1]))[:2]
    for th in cands:
        g = base.copy()
        g[1] = th
        x, u = pump_guess(x0, g, t)
        out.append(_traj(model, t, x, u))
    for th in cands:
        g = base.copy()
        g[1] = th
        x, u = linear_guess(x0, g, t)
        out.append(_traj(model, t, x, u))
    return out[:max(1, count)]
