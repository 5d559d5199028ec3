"""Bounds and variable scales of a trajectory-optimisation problem, read from the model's MJCF.

Bounds: each actuator's ``ctrl`` inside its own ``ctrlrange`` (asymmetric ranges kept); the cart's slide inside
its joint range shrunk by a margin on each side; every other limited joint inside its joint range. Scales: the
typical magnitude of each state and input (slides in m, hinges in rad, their rates, ctrl), so the NLP's
variables are of order one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole._arrays import readonly
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, CartPoleParams


class OCPError(CartPoleError):
    """A trajectory-optimisation problem that is badly posed or did not converge."""


@dataclass(frozen=True)
class OCPBounds:
    """Bounds of a trajectory-optimisation problem in physical units.

    Attributes
    ----------
    u_low, u_high : (nu,) arrays
        ``u_low <= ctrl <= u_high`` per actuator (MuJoCo ctrl, finite).
    q_low, q_high : (nq,) arrays
        Joint position bounds in qpos order (m for slides, rad for hinges), held at the knots and the
        collocation midpoints; ``-inf``/``inf`` where a joint is free.
    cart_max : float or None
        Half-width in m of the cart's allowed interval ``|s - cart_center| <= cart_max`` (the slide's range
        shrunk by the margin); None for a model without a cart.
    cart_center : float
        Centre of the cart's slide range in m (0 when unlimited).
    actuator_names, joint_names : tuples of str
        For messages naming the bound that binds.
    """

    u_low: np.ndarray
    u_high: np.ndarray
    q_low: np.ndarray
    q_high: np.ndarray
    cart_max: float | None
    cart_center: float = 0.0
    actuator_names: tuple = ()
    joint_names: tuple = ()

    def __post_init__(self):
        for name in ("u_low", "u_high", "q_low", "q_high"):
            object.__setattr__(self, name, readonly(np.atleast_1d(getattr(self, name))))

    @property
    def nu(self) -> int:
        """Number of inputs."""
        return self.u_low.size

    @property
    def bounded_joints(self) -> tuple:
        """qpos indices of the joints whose position is bounded on both sides."""
        return tuple(int(i) for i in np.nonzero(np.isfinite(self.q_low) & np.isfinite(self.q_high))[0])


def bounds_from_params(params: CartPoleParams, *, u_max=None, cart_max: float | None = None,
                       cart_margin: float = 0.1) -> OCPBounds:
    """OCP bounds from the MJCF: each ctrlrange, the cart's slide range shrunk by ``cart_margin`` (m) on each
    side, and every other limited joint's range.

    Parameters
    ----------
    params : CartPoleParams
    u_max : float or (nu,) array, optional
        Symmetric ``|ctrl| <= u_max`` overriding the ctrlranges (the benchmark's standard problem uses 1).
    cart_max : float, optional
        ``|s - centre| <= cart_max`` in m overriding the cart's range and margin (the benchmark uses 1.4).
    cart_margin : float
        m kept from each end of the cart's slide range (default 0.1).

    Raises
    ------
    OCPError
        An actuator without a ctrlrange (and no ``u_max``), an unlimited cart slide (and no ``cart_max``), or
        bounds that leave nothing to move in.
    """
    names = tuple(a.name or f"#{i}" for i, a in enumerate(params.actuators))
    if u_max is None:
        rng = np.asarray(params.ctrl_range, float).reshape(params.nu, 2)
        free = [names[i] for i in range(params.nu) if not np.all(np.isfinite(rng[i]))]
        if free:
            raise OCPError(f"The MJCF's actuator '{free[0]}' has no ctrlrange; give `u_max` (or plan on "
                           "cartpole.models.planning_limits(params), which states a default) for the trajectory "
                           "optimisation.")
        u_low, u_high = rng[:, 0].copy(), rng[:, 1].copy()
    else:
        u_high = np.broadcast_to(np.asarray(u_max, float), (params.nu,)).copy()
        u_low = -u_high
    if not np.all(u_high > u_low):
        raise OCPError(f"The ctrl bounds [{u_low.tolist()}, {u_high.tolist()}] leave no room; give each "
                       "actuator a ctrlrange with low < high.")
    q_low = np.array(params.joint_ranges[:, 0], float)
    q_high = np.array(params.joint_ranges[:, 1], float)
    center = 0.0
    if params.slide is not None:
        lo, hi = params.cart_range
        limited = np.isfinite(lo) and np.isfinite(hi)
        center = 0.5 * (lo + hi) if limited else 0.0
        if cart_max is None:
            if not limited:
                raise OCPError("The MJCF's slide joint is unlimited; give `cart_max` (or plan on "
                               "cartpole.models.planning_limits(params), which states a default) for the "
                               "trajectory optimisation.")
            cart_max = 0.5 * (hi - lo) - cart_margin
        if not cart_max > 0:
            raise OCPError(f"The OCP bound cart_max = {cart_max} m must be positive; use a longer track or a "
                           "smaller cart margin.")
        cart_max = float(cart_max)
        q_low[params.slide] = center - cart_max
        q_high[params.slide] = center + cart_max
    else:
        cart_max = None
    return OCPBounds(u_low=u_low, u_high=u_high, q_low=q_low, q_high=q_high, cart_max=cart_max,
                     cart_center=float(center), actuator_names=names, joint_names=params.joint_names)


def bounds_from_model(model: CartPoleModel, **overrides) -> OCPBounds:
    """:func:`bounds_from_params` of ``model.params`` (``u_max``, ``cart_max``, ``cart_margin`` pass through)."""
    return bounds_from_params(model.params, **overrides)


def shooting_bounds(bounds: OCPBounds, nx: int, n: int, x0, x_goal, u_low=None, u_high=None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Bounds ``(lw, hw)`` of a multiple-shooting problem's variables ``[vec(X), vec(U)]`` (CasADi's column-major
    ``X`` (nx, n+1) then ``U`` (nu, n)): the position bounds of ``bounds`` on every state, ``X[:, 0] = x0`` and
    ``X[:, n] = x_goal`` pinned, the ctrl inside ``[u_low, u_high]`` (default the bounds' own)."""
    nq = np.asarray(bounds.q_low).size
    lx = np.full((nx, n + 1), -np.inf)
    hx = np.full((nx, n + 1), np.inf)
    lx[:nq] = np.asarray(bounds.q_low, float)[:, None]
    hx[:nq] = np.asarray(bounds.q_high, float)[:, None]
    lx[:, 0] = hx[:, 0] = np.asarray(x0, float)
    lx[:, -1] = hx[:, -1] = np.asarray(x_goal, float)
    u_lo = bounds.u_low if u_low is None else u_low
    u_hi = bounds.u_high if u_high is None else u_high
    return (np.r_[lx.ravel(order="F"), np.tile(u_lo, n)], np.r_[hx.ravel(order="F"), np.tile(u_hi, n)])


def scales(model: CartPoleModel, bounds: OCPBounds) -> np.ndarray:
    """Typical magnitudes (nx + nu,) of ``[qpos, qvel, ctrl]``, to scale the NLP to order one.

    * the cart's slide: ``cart_max`` m; other slides half their range (1 m when unlimited); hinges pi rad;
    * a hinge's rate: ``sqrt(4 m g l / J)`` rad/s, reached by what it carries (mass ``m``, COM distance ``l``,
      inertia ``J`` about its axis plus armature, as one rigid body) falling from upright to hanging
      (pi rad/s without gravity);
    * a slide's rate: ``min(sqrt(a s), a / 2)`` m/s with ``s`` its position scale and ``a`` the acceleration its
      actuators' full ctrl gives the mass it moves (its position scale per second when it is unactuated);
    * ctrl: ``max(|low|, |high|)`` of each actuator's bounds.
    """
    p = model.params
    nq = model.nq
    su = np.maximum(np.abs(bounds.u_low), np.abs(bounds.u_high))
    pos = np.empty(nq)
    rate = np.empty(nq)
    for i, joint in enumerate(p.joints):
        if joint.kind == "hinge":
            pos[i] = np.pi
            m, l, J = p.carried_by(i)
            J = J + p.armature[i]
            rate[i] = np.sqrt(4 * m * p.g * l / J) if m * p.g * l > 0 and J > 0 else np.pi
            continue
        if i == p.slide:
            pos[i] = bounds.cart_max
        else:
            lo, hi = joint.range
            pos[i] = 0.5 * (hi - lo) if np.isfinite(lo) and np.isfinite(hi) and hi > lo else 1.0
        force = sum(a.gear * su[k] for k, a in enumerate(p.actuators) if a.joint == i)
        moved = sum(p.bodies[b].mass for b in p.subtree(joint.body))
        acc = abs(force) / moved if moved > 0 else 0.0
        rate[i] = min(np.sqrt(acc * pos[i]), 0.5 * acc) if acc > 0 else pos[i]
    return np.concatenate([pos, rate, su])
