"""Disturbances that knock a balanced cart-pole down, as generalized forces on its joints, seeded and logged.

A lab that shows its cart-pole to visitors gets poked: :class:`Knockdown` waits until every pole has been upright
(within :data:`UPRIGHT_BAND` of the upright equilibrium, angle errors wrapped) for ``after`` seconds, then pushes each
hinge with a random torque for ``length`` seconds, strong enough to beat the controller, and waits for the next
time it is upright; :class:`Throw` throws the state at random times whatever the controller is doing (as RealAIGym's
robustness benchmark does), as a one-step impulse giving each hinge a random change of rate. Both are callables
``f(t, x) -> (nv,)`` that :func:`cartpole.sim.rollout.simulate` applies through MuJoCo's ``qfrc_applied`` and logs
every physics step, so the run replays exactly with ``mj_step``.

Strength of a knock, per hinge ``i`` (N m): ``M_ii (4 / length^2 + 2 a_i) * r_i``, with ``M_ii`` the joint-space
inertia at upright, ``4 / length^2`` the angular acceleration that turns a free pole by 2 rad in ``length`` seconds,
``a_i = |(M^-1 B)_i| u_max`` the largest angular acceleration the actuators can give that hinge at upright (so the
knock beats the controller's authority twice over), and ``r_i`` drawn uniformly from [0.5, 1] with a random sign,
held for the knock's length. Slides are not pushed (the cart is what the controller moves).
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleParams, wrap_angle
from cartpole.sim.rollout import ctrl_bounds, make_mujoco

#: Upright band, rad: every pole's wrapped angle error from upright below this counts as upright for a knockdown's
#: trigger and for the uptime metric (:func:`cartpole.validation.metrics.uptime`).
UPRIGHT_BAND = 0.2

#: Longest knock or wait accepted, s.
MAX_DISTURBANCE_SECONDS = 3600.0


class DisturbanceError(CartPoleError):
    """A knockdown or throw whose times, strength or seed are not sensible numbers."""


def _seconds(name: str, value, *, low: float = 0.0) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not (np.isfinite(v) and low < v <= MAX_DISTURBANCE_SECONDS):
        raise DisturbanceError(f"The {name} must be a number of seconds in ({low:g}, "
                               f"{MAX_DISTURBANCE_SECONDS:g}]; got {value!r}.")
    return v


def _seed(value) -> int:
    text = str(value).strip()
    if not text.isdigit():
        raise DisturbanceError(f"The disturbance's seed must be a whole number >= 0; got {value!r}.")
    return int(text)


def joint_inertia_and_authority(plant, x_eq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's joint-space inertia diagonal (nv,) (kg, kg m^2) and the largest acceleration (nv,) (m/s^2, rad/s^2)
    the actuators can give each joint within their ctrl ranges (0 for unlimited ones), at the state ``x_eq`` (nx,)
    at rest, for the MJCF ``source`` (CartPoleParams or path)."""
    m, d = make_mujoco(plant)
    d.qpos[:] = x_eq[:m.nq]
    d.qvel[:] = 0.0
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    lo, hi = ctrl_bounds(m)
    u_max = np.where(np.isfinite(lo) & np.isfinite(hi), np.maximum(np.abs(lo), np.abs(hi)), 0.0)
    # the actuators' moment arms: qfrc per unit ctrl (gain * gear for MuJoCo's joint motors)
    Bq = np.zeros((m.nv, m.nu))
    for a in range(m.nu):
        d.ctrl[:] = 0.0
        d.ctrl[a] = 1.0
        mujoco.mj_forward(m, d)
        f1 = d.qfrc_actuator.copy()
        d.ctrl[a] = 0.0
        mujoco.mj_forward(m, d)
        Bq[:, a] = f1 - d.qfrc_actuator
    authority = np.abs(np.linalg.solve(M, Bq)) @ u_max
    return np.diag(M).copy(), authority


@dataclass(frozen=True)
class Knockdown:
    """Knock the poles down each time they have been upright for ``after`` seconds.

    Parameters
    ----------
    after : float
        Seconds every pole must stay within :data:`UPRIGHT_BAND` of upright before each knock.
    length : float
        Seconds each knock lasts.
    seed : int
        Seed of the knocks' random torques (the same seed, the same knocks on the same run).
    strength : float
        Scale of the torques (1: the module's rule, which beats the actuators twice over).

    Raises
    ------
    DisturbanceError
        Times not in (0, 3600] s, a negative seed or a strength not in (0, 100].
    """

    after: float
    length: float
    seed: int = 0
    strength: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "after", _seconds("knockdown's wait (AFTER)", self.after))
        object.__setattr__(self, "length", _seconds("knockdown's length (LENGTH)", self.length))
        object.__setattr__(self, "seed", _seed(self.seed))
        s = float(self.strength)
        if not (np.isfinite(s) and 0 < s <= 100):
            raise DisturbanceError(f"The knockdown's strength must be in (0, 100]; got {self.strength!r}.")
        object.__setattr__(self, "strength", s)

    @classmethod
    def parse(cls, text: str) -> "Knockdown":
        """``"AFTER:LENGTH[:SEED]"`` (seconds, seconds, whole number), as the command line writes it."""
        parts = str(text).split(":")
        if len(parts) not in (2, 3):
            raise DisturbanceError(f"A knockdown is AFTER:LENGTH[:SEED] (seconds upright before each knock, seconds "
                                   f"it lasts, a seed), e.g. 3:0.3:1; got {text!r}.")
        try:
            after, length = float(parts[0]), float(parts[1])
        except ValueError:
            raise DisturbanceError(f"A knockdown is AFTER:LENGTH[:SEED] with AFTER and LENGTH in seconds, e.g. "
                                   f"3:0.3:1; got {text!r}.") from None
        return cls(after, length, parts[2] if len(parts) == 3 else 0)

    def start(self, source: CartPoleParams, *, x_eq, hinges) -> "KnockdownForce":
        """The stateful force ``f(t, x) -> (nv,)`` for one run on ``source`` (upright at ``x_eq`` (nx,), pole angles
        at qpos indices ``hinges``)."""
        return KnockdownForce(self, source, np.asarray(x_eq, dtype=float), tuple(int(h) for h in hinges))


class KnockdownForce:
    """One run's knockdowns (:meth:`Knockdown.start`): call it as ``f(t, x) -> (nv,)`` once per physics step in time
    order. :attr:`events` lists each knock's ``(start, end)`` times in s.

    Parameters
    ----------
    knock : Knockdown
    source : CartPoleParams or MJCF path
        The model MuJoCo runs.
    x_eq : (nx,) array
        The upright equilibrium ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    hinges : tuple of int
        qpos indices of the pole angles.
    """

    def __init__(self, knock: Knockdown, source, x_eq: np.ndarray, hinges: tuple):
        self.knock = knock
        self.x_eq = x_eq
        self.hinges = hinges
        self.nq = x_eq.size // 2
        inertia, authority = joint_inertia_and_authority(source, x_eq)
        self.scale = knock.strength * inertia * (4.0 / knock.length ** 2 + 2.0 * authority)
        self.rng = np.random.default_rng(knock.seed)
        self.upright_since: float | None = None
        self.knock_until: float | None = None
        self.torque = np.zeros(x_eq.size - self.nq)
        self.events: list[tuple[float, float]] = []

    def upright(self, x) -> bool:
        """Every pole within :data:`UPRIGHT_BAND` of upright (angle errors wrapped)."""
        err = wrap_angle(np.asarray(x, dtype=float)[list(self.hinges)] - self.x_eq[list(self.hinges)])
        return bool(np.all(np.abs(err) < UPRIGHT_BAND))

    def __call__(self, t: float, x) -> np.ndarray:
        if self.knock_until is not None:
            if t < self.knock_until - 1e-12:
                return self.torque.copy()
            self.knock_until, self.upright_since = None, None
        if not self.upright(x):
            self.upright_since = None
            return np.zeros_like(self.torque)
        if self.upright_since is None:
            self.upright_since = t
        if t - self.upright_since < self.knock.after - 1e-12:
            return np.zeros_like(self.torque)
        self.torque = np.zeros_like(self.torque)
        for h in self.hinges:
            self.torque[h] = self.scale[h] * self.rng.uniform(0.5, 1.0) * self.rng.choice((-1.0, 1.0))
        self.knock_until = t + self.knock.length
        self.events.append((float(t), float(t + self.knock.length)))
        return self.torque.copy()


@dataclass(frozen=True)
class Throw:
    """Throw the state at random times, whatever it is doing: every ``every`` seconds on average (each gap uniform in
    [0.5, 1.5] ``every``), a one-step impulse changing each hinge's rate by a random amount in
    [-``max_rate``, ``max_rate``] rad/s.

    Parameters
    ----------
    every : float
        Mean seconds between throws.
    max_rate : float
        Largest change of a hinge's rate, rad/s.
    seed : int
        Seed of the throws.
    """

    every: float
    max_rate: float = 10.0
    seed: int = 0

    def __post_init__(self):
        object.__setattr__(self, "every", _seconds("throw's mean interval (EVERY)", self.every))
        r = float(self.max_rate)
        if not (np.isfinite(r) and 0 < r <= 1000):
            raise DisturbanceError(f"The throw's largest rate change must be in (0, 1000] rad/s; got {self.max_rate!r}.")
        object.__setattr__(self, "max_rate", r)
        object.__setattr__(self, "seed", _seed(self.seed))

    @classmethod
    def parse(cls, text: str) -> "Throw":
        """``"EVERY[:RATE[:SEED]]"`` (seconds, rad/s, whole number), as the command line writes it."""
        parts = str(text).split(":")
        try:
            if not 1 <= len(parts) <= 3:
                raise ValueError
            every = float(parts[0])
            rate = float(parts[1]) if len(parts) > 1 else 10.0
        except ValueError:
            raise DisturbanceError(f"A throw is EVERY[:RATE[:SEED]] (mean seconds between throws, the largest rate "
                                   f"change in rad/s, a seed), e.g. 4:20:1; got {text!r}.") from None
        return cls(every, rate, parts[2] if len(parts) == 3 else 0)

    def start(self, source: CartPoleParams, *, x_eq, hinges, timestep: float) -> "ThrowForce":
        """The stateful force ``f(t, x) -> (nv,)`` for one run on ``source`` at the physics step ``timestep`` (s);
        ``x_eq`` is taken for the same call as :meth:`Knockdown.start` (a throw does not depend on upright)."""
        return ThrowForce(self, source, tuple(int(h) for h in hinges), float(timestep))


class ThrowForce:
    """One run's throws (:meth:`Throw.start`); :attr:`events` lists each throw's ``(start, end)`` times in s.

    Parameters
    ----------
    throw : Throw
    source : CartPoleParams or MJCF path
        The model MuJoCo runs.
    hinges : tuple of int
        qpos indices of the pole angles.
    timestep : float
        The physics step, s: each throw is an impulse over one step.
    """

    def __init__(self, throw: Throw, source, hinges: tuple, timestep: float):
        self.throw, self.hinges, self.h = throw, hinges, timestep
        self.m, self.d = make_mujoco(source)
        self.mujoco = mujoco
        self.rng = np.random.default_rng(throw.seed)
        self.next_at = self._gap()
        self.events: list[tuple[float, float]] = []

    def _gap(self) -> float:
        return float(self.throw.every * self.rng.uniform(0.5, 1.5))

    def __call__(self, t: float, x) -> np.ndarray:
        nv = self.m.nv
        if t < self.next_at - 1e-12:
            return np.zeros(nv)
        self.next_at = t + self._gap()
        dv = np.zeros(nv)
        for h in self.hinges:
            dv[h] = self.rng.uniform(-self.throw.max_rate, self.throw.max_rate)
        x = np.asarray(x, dtype=float)
        self.d.qpos[:] = x[:self.m.nq]
        self.d.qvel[:] = x[self.m.nq:]
        self.mujoco.mj_forward(self.m, self.d)
        M = np.zeros((nv, nv))
        self.mujoco.mj_fullM(self.m, self.d, M)
        self.events.append((float(t), float(t + self.h)))
        return M @ dv / self.h


class Disturbances:
    """Several disturbances at once: ``f(t, x)`` is their sum; :attr:`events` all their ``(start, end)`` times, in
    time order.

    Parameters
    ----------
    parts : tuple of callables
        Each ``f(t [s], x (nx,)) -> (nv,)`` with an ``events`` list (:class:`KnockdownForce`, :class:`ThrowForce`).
    """

    def __init__(self, parts: tuple):
        self.parts = parts

    @property
    def events(self) -> list[tuple[float, float]]:
        """Every part's ``(start, end)`` times in s, sorted."""
        return sorted(e for p in self.parts for e in p.events)

    def __call__(self, t: float, x) -> np.ndarray:
        return sum(np.asarray(p(t, x), dtype=float) for p in self.parts)
