"""Disturbances that knock a balanced cart-pole down, as generalized forces on its joints, seeded and logged.

A lab that shows its cart-pole to visitors gets poked: :class:`Knockdown` waits until every pole has been upright
(within :data:`UPRIGHT_BAND` of the upright equilibrium, angle errors wrapped) for ``after`` seconds, then pushes each
hinge with a random torque, strong enough to beat the controller, for at most ``length`` seconds and until it has done
its share of the model's swing-up energy in work, and waits for the next time it is upright; :class:`Throw` throws the state at random times whatever the controller is doing (as RealAIGym's
robustness benchmark resets it), as a one-step impulse giving each hinge a random change of rate (or, ``set_rates``,
a random rate); :class:`Reset` is RealAIGym's own reset, a gravity-compensated PID on every hinge towards a random
pose for 0.2 s with the controller switched off (:meth:`ResetForce.gate`). All are callables
``f(t, x) -> (nv,)`` that :func:`cartpole.sim.rollout.simulate` applies through MuJoCo's ``qfrc_applied`` and logs
every physics step, so the run replays exactly with ``mj_step``.

Size of a knock, stated in energy: each knock may do at most ``W = energy * r_E * E_swing`` of work on the hinges,
``E_swing = E(upright) - E(hanging)`` the model's own swing-up energy (:func:`swingup_energy`, J: 0.59 on the lab's
cart, 39 on dm_control's acrobot), ``energy`` the knock's size in those units (:data:`KNOCK_ENERGY` by default) and
``r_E`` uniform in [0.5, 1], seeded. The work counted is ``sum_i max(tau_i dq_i, 0)`` over the physics steps (each
hinge's positive work only, so no hinge's loss pays for another's gain: the net work is at most that), and the push
stops, early, the moment it reaches ``W`` (its last step scaled down to land on it). So a knock leaves the chain a
bounded fraction of its swing-up energy above upright on every model, light or heavy, instead of a torque held for
``length`` s whatever it did.

Torque of a knock, per hinge ``i`` (N m), while the budget lasts and for at most ``length`` s:
``strength * M_ii (4 / length^2 + 2 a_i) * r_i``, with ``M_ii`` the joint-space inertia at upright, ``4 / length^2``
the angular acceleration that turns a free pole by 2 rad in ``length`` seconds, ``a_i = |(M^-1 B)_i| u_max`` the
largest angular acceleration the actuators can give that hinge at upright (so the knock beats the controller's
authority twice over: the catch cannot hold the poles in the band against it), and ``r_i`` drawn uniformly from
[0.5, 1] with a random sign, held for the knock. Slides are not pushed (the cart is what the controller moves).
Each knock's record (:class:`KnockRecord`: its times, budget, work and whether the poles then left the upright band)
is in :attr:`KnockdownForce.knocks`.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, CartPoleParams, MJCFError, plant_model, wrap_angle
from cartpole.sim.rollout import ctrl_bounds, make_mujoco

#: Upright band, rad: every pole's wrapped angle error from upright below this counts as upright for a knockdown's
#: trigger and for the uptime metric (:func:`cartpole.validation.metrics.uptime`).
UPRIGHT_BAND = 0.2

#: Longest knock or wait accepted, s.
MAX_DISTURBANCE_SECONDS = 3600.0

#: A knock's default size, in units of the model's swing-up energy ``E(upright) - E(hanging)``: each knock's work
#: budget is this times a seeded factor uniform in [0.5, 1], so half a swing-up to one. Enough to bring the poles out
#: of the upright band against the LQR catch on every shipped model, and past the supervisor's catch on the lab's cart
#: (with half this, the smallest knocks, under 0.3 of a swing-up there, were caught back inside the band's
#: neighbourhood); a small fraction of what the acrobot's damping had to take out after the torque rule alone.
KNOCK_ENERGY = 1.0

#: Largest knock size accepted, in swing-up energies.
MAX_KNOCK_ENERGY = 100.0


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


def joint_space_inertia(m, d, qpos) -> np.ndarray:
    """MuJoCo's joint-space inertia matrix ``M(q)`` (armature included) at the joint positions ``qpos``.

    Parameters
    ----------
    m : mujoco.MjModel
    d : mujoco.MjData
        Of ``m``: its ``qpos`` is set to ``qpos``, its kinematics and inertia recomputed (nothing else).
    qpos : (nq,) array or longer
        Joint positions (m, rad); a state ``[qpos, qvel]`` (nx,) is cut to its first ``nq`` entries.

    Returns
    -------
    (nv, nv) array
        kg on slides, kg m^2 on hinges, kg m between them.
    """
    d.qpos[:] = np.asarray(qpos, dtype=float)[:m.nq]
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_makeM(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    return M


def joint_inertia_and_authority(plant, x_eq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's joint-space inertia diagonal (nv,) (kg, kg m^2) and the largest acceleration (nv,) (m/s^2, rad/s^2)
    the actuators can give each joint within their ctrl ranges (0 for unlimited ones), at the state ``x_eq`` (nx,)
    at rest, for the MJCF ``source`` (CartPoleParams or path)."""
    return _inertia_and_authority(*make_mujoco(plant), x_eq)


def _inertia_and_authority(m, d, x_eq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`joint_inertia_and_authority` computed in ``(m, d)`` (its state left at ``x_eq`` at rest, ctrl 0)."""
    M = joint_space_inertia(m, d, x_eq)
    d.qvel[:] = 0.0
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


def swingup_energy(plant) -> float:
    """The model's swing-up energy ``E(x_eq) - E(x_hanging)`` in J (upright rest minus hanging rest, from
    :attr:`cartpole.models.CartPoleModel.energy`), the scale of a knock's size; ``plant`` params, a model (used as it
    is) or a path. A model with no hanging rest (gravity pushing an undriven joint there) gets the most its poles'
    weight can do instead, ``2 |g| m d`` with ``m``, ``d`` the mass the first hinge carries and its centre of mass's
    distance from the hinge's axis (:meth:`cartpole.models.CartPoleParams.carried_by`): the same number for a chain
    straight at ``qpos0``."""
    model = plant_model(plant)
    try:
        hanging = model.x_hanging
    except MJCFError:
        params = model.params
        mass, distance, _ = params.carried_by(model.hinges[0])
        return float(2.0 * params.g * mass * distance)
    return float(model.energy(model.x_eq)) - float(model.energy(hanging))


@dataclass(frozen=True)
class KnockRecord:
    """One knock as it happened (:attr:`KnockdownForce.knocks`).

    Attributes
    ----------
    start, end : float
        s: the push's first step and the time it stopped (budget spent or ``length`` over).
    budget : float
        J: the work it was allowed.
    work : float
        J: the positive work it did on the hinges, ``sum_i max(tau_i dq_i, 0)`` over its steps.
    downed : bool
        True once the poles left the upright band after it began (before the next knock).
    """

    start: float
    end: float
    budget: float
    work: float
    downed: bool


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
    energy : float
        Size of each knock in units of the model's swing-up energy (:func:`swingup_energy`): its work budget is this
        times a seeded factor in [0.5, 1]; default :data:`KNOCK_ENERGY`.

    Raises
    ------
    DisturbanceError
        Times not in (0, 3600] s, a negative seed, a strength not in (0, 100] or an energy not in (0, 100].
    """

    after: float
    length: float
    seed: int = 0
    strength: float = 1.0
    energy: float = KNOCK_ENERGY

    def __post_init__(self):
        object.__setattr__(self, "after", _seconds("knockdown's wait (AFTER)", self.after))
        object.__setattr__(self, "length", _seconds("knockdown's length (LENGTH)", self.length))
        object.__setattr__(self, "seed", _seed(self.seed))
        s = float(self.strength)
        if not (np.isfinite(s) and 0 < s <= 100):
            raise DisturbanceError(f"The knockdown's strength must be in (0, 100]; got {self.strength!r}.")
        object.__setattr__(self, "strength", s)
        try:
            e = float(self.energy)
        except (TypeError, ValueError):
            e = float("nan")
        if not (np.isfinite(e) and 0 < e <= MAX_KNOCK_ENERGY):
            raise DisturbanceError(f"The knockdown's energy (ENERGY) must be a number of swing-up energies in (0, "
                                   f"{MAX_KNOCK_ENERGY:g}]; got {self.energy!r}.")
        object.__setattr__(self, "energy", e)

    @classmethod
    def parse(cls, text: str) -> "Knockdown":
        """``"AFTER:LENGTH[:SEED[:ENERGY]]"`` (seconds, seconds, whole number, swing-up energies), as the command line
        writes it; ENERGY defaults to :data:`KNOCK_ENERGY`."""
        parts = str(text).split(":")
        if len(parts) not in (2, 3, 4):
            raise DisturbanceError(f"A knockdown is AFTER:LENGTH[:SEED[:ENERGY]] (seconds upright before each knock, "
                                   f"seconds it lasts at most, a seed, its size in swing-up energies), e.g. 3:0.3:1; "
                                   f"got {text!r}.")
        try:
            after, length = float(parts[0]), float(parts[1])
        except ValueError:
            raise DisturbanceError(f"A knockdown is AFTER:LENGTH[:SEED[:ENERGY]] with AFTER and LENGTH in seconds, "
                                   f"e.g. 3:0.3:1; got {text!r}.") from None
        energy = parts[3] if len(parts) == 4 else KNOCK_ENERGY
        return cls(after, length, parts[2] if len(parts) >= 3 else 0, energy=energy)

    def start(self, source: CartPoleParams, *, x_eq, hinges, model: CartPoleModel | None = None) -> "KnockdownForce":
        """The stateful force ``f(t, x) -> (nv,)`` for one run on ``source`` (upright at ``x_eq`` (nx,), pole angles
        at qpos indices ``hinges``); ``model``, the symbolic model of ``source`` the caller already has, gives the
        swing-up energy (:func:`swingup_energy`) without building another (default: built from ``source``)."""
        return KnockdownForce(self, source, np.asarray(x_eq, dtype=float), tuple(int(h) for h in hinges),
                              model=model)


class KnockdownForce:
    """One run's knockdowns (:meth:`Knockdown.start`): call it as ``f(t, x) -> (nv,)`` once per physics step in time
    order. :attr:`events` lists each knock's ``(start, end)`` times in s (end: when its push stopped), :attr:`knocks`
    each knock's :class:`KnockRecord`.

    Parameters
    ----------
    knock : Knockdown
    source : CartPoleParams or MJCF path
        The model MuJoCo runs.
    x_eq : (nx,) array
        The upright equilibrium ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    hinges : tuple of int
        qpos indices of the pole angles.
    model : CartPoleModel, optional
        The symbolic model of ``source``, whose swing-up energy (:func:`swingup_energy`) sizes the knocks; default
        built from ``source``.
    """

    def __init__(self, knock: Knockdown, source, x_eq: np.ndarray, hinges: tuple, *,
                 model: CartPoleModel | None = None):
        self.knock = knock
        self.x_eq = x_eq
        self.hinges = hinges
        self.nq = x_eq.size // 2
        self._m, self._d = make_mujoco(source)
        self.inertia, authority = _inertia_and_authority(self._m, self._d, x_eq)
        self.scale = knock.strength * self.inertia * (4.0 / knock.length ** 2 + 2.0 * authority)
        self.swingup_energy = swingup_energy(source if model is None else model)
        self.h = float(self._m.opt.timestep)
        self.rng = np.random.default_rng(knock.seed)
        self.upright_since: float | None = None
        self.knock_until: float | None = None
        self.torque = np.zeros(x_eq.size - self.nq)
        self.events: list[tuple[float, float]] = []
        self._knocks: list[dict] = []
        self._q_last: np.ndarray | None = None
        self._applied = np.zeros_like(self.torque)
        self._spent = False

    def _accel(self, x: np.ndarray) -> np.ndarray:
        """(nv,) the joints' acceleration from the knock's torque alone at state ``x``: ``M(q)^-1 tau``."""
        return np.linalg.solve(joint_space_inertia(self._m, self._d, x), self.torque)

    @property
    def knocks(self) -> tuple[KnockRecord, ...]:
        """Every knock so far, in time order."""
        return tuple(KnockRecord(**k) for k in self._knocks)

    def upright(self, x) -> bool:
        """Every pole within :data:`UPRIGHT_BAND` of upright (angle errors wrapped)."""
        err = wrap_angle(np.asarray(x, dtype=float)[list(self.hinges)] - self.x_eq[list(self.hinges)])
        return bool(np.all(np.abs(err) < UPRIGHT_BAND))

    def __call__(self, t: float, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        up = self.upright(x)
        if self._knocks and not up:
            self._knocks[-1]["downed"] = True
        if self.knock_until is not None:
            torque = self._pushing(t, x)
            if torque is not None:
                return torque
        if not up:
            self.upright_since = None
            return np.zeros_like(self.torque)
        if self.upright_since is None:
            self.upright_since = t
        if t - self.upright_since < self.knock.after - 1e-12:
            return np.zeros_like(self.torque)
        return self._begin(t, x)

    def _begin(self, t: float, x: np.ndarray) -> np.ndarray:
        """A new knock from time ``t`` (s): its torques, held while it lasts, and its work budget (J)."""
        self.torque = np.zeros_like(self.torque)
        for h in self.hinges:
            self.torque[h] = self.scale[h] * self.rng.uniform(0.5, 1.0) * self.rng.choice((-1.0, 1.0))
        budget = self.knock.energy * self.rng.uniform(0.5, 1.0) * self.swingup_energy
        self.knock_until = t + self.knock.length
        self.events.append((float(t), float(t + self.knock.length)))
        self._knocks.append({"start": float(t), "end": float(t + self.knock.length), "budget": float(budget),
                             "work": 0.0, "downed": False})
        self._q_last, self._spent = None, False
        return self._pushing(t, x)

    def _pushing(self, t: float, x: np.ndarray):
        """The knock's torque (nv,) for the step from ``t`` (s), scaled down on the step that would overrun its
        budget; None once it is over (length elapsed or budget spent), its end then recorded."""
        rec = self._knocks[-1]
        q = x[:self.nq]
        if self._q_last is not None:  # the work of the torque applied over the last step: exact, tau constant on it
            rec["work"] += float(np.sum(np.maximum(self._applied * (q - self._q_last)[:self.torque.size], 0.0)))
        left = rec["budget"] - rec["work"]
        if t >= self.knock_until - 1e-12 or self._spent or left <= 1e-12 * max(rec["budget"], 1.0):
            self.knock_until, self.upright_since, self._q_last = None, None, None
            rec["end"] = float(t)
            self.events[-1] = (rec["start"], float(t))
            return None
        v = x[self.nq:self.nq + self.torque.size]
        # the step's work predicted from the rates and the acceleration the torque gives (M(q)^-1 tau), each part's
        # positive side only, so that scaling the torque by s < 1 scales the prediction by s or less
        accel = self._accel(x)
        predicted = float(np.sum(np.maximum(self.torque * v * self.h, 0.0))
                          + np.sum(np.maximum(self.torque * accel * self.h ** 2, 0.0)))
        self._spent = predicted > left  # this step lands on the budget: the knock's last
        applied = self.torque * (left / predicted) if self._spent else self.torque.copy()
        self._q_last, self._applied = q.copy(), applied
        return applied.copy()


@dataclass(frozen=True)
class Throw:
    """Throw the state at random times, whatever it is doing: every ``every`` seconds on average (each gap uniform in
    [0.5, 1.5] ``every``), a one-step impulse changing each hinge's rate by a random amount in
    [-``max_rate``, ``max_rate``] rad/s, or with ``set_rates`` setting each hinge's rate to such a random value
    (about: the impulse is sized from the state at the step's start, over one step).

    Parameters
    ----------
    every : float
        Mean seconds between throws.
    max_rate : float
        Largest change of a hinge's rate (with ``set_rates``: largest rate), rad/s.
    seed : int
        Seed of the throws.
    set_rates : bool
        False (default): each throw adds to the rates the chain has, so throws landing on a chain still spinning from
        the last can leave it ever more energy. True: each throw sets the rates, whatever they were, so the energy a
        throw leaves does not depend on the run before it (as RealAIGym's reset, which drives the chain towards a random
        pose at rest, does not).
    """

    every: float
    max_rate: float = 10.0
    seed: int = 0
    set_rates: bool = False

    def __post_init__(self):
        object.__setattr__(self, "every", _seconds("throw's mean interval (EVERY)", self.every))
        r = float(self.max_rate)
        if not (np.isfinite(r) and 0 < r <= 1000):
            raise DisturbanceError(f"The throw's largest rate change must be in (0, 1000] rad/s; got {self.max_rate!r}.")
        object.__setattr__(self, "max_rate", r)
        object.__setattr__(self, "seed", _seed(self.seed))
        object.__setattr__(self, "set_rates", bool(self.set_rates))

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
        self.rng = np.random.default_rng(throw.seed)
        self.dof_of = {int(self.m.jnt_qposadr[j]): int(self.m.jnt_dofadr[j]) for j in range(self.m.njnt)}
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
            dof = self.dof_of[h]
            dv[dof] = self.rng.uniform(-self.throw.max_rate, self.throw.max_rate)
            if self.throw.set_rates:
                dv[dof] -= float(x[self.m.nq + dof])
        M = joint_space_inertia(self.m, self.d, x)
        self.events.append((float(t), float(t + self.h)))
        return M @ dv / self.h


@dataclass(frozen=True)
class Reset:
    """RealAIGym's reset (dfki-ric-underactuated-lab/double_pendulum,
    src/python/double_pendulum/controller/global_policy_testing_controller.py, ``GlobalPolicyTestingControllerV2``, as
    leaderboard/acrobot/simulation_v3/calculate_leaderboard_score.py builds it): ``count`` times in a run of
    ``duration`` s, at ``linspace(d, duration - d, count)`` with ``d = duration / (count + 1)``, each moved by a
    uniform amount in [-``jitter``, ``jitter``) s, the controller is switched off (its ctrl zero: :meth:`ResetForce.gate`)
    and, for ``length`` s, a PID on EVERY hinge, gravity-compensated, drives the chain towards a random pose at rest:
    each hinge's goal angle uniform in [-pi, pi) about the model's hanging rest, rate zero.

    Each hinge's torque (N m) on a physics step from ``t``, ``e`` its goal angle minus its angle (rad, not wrapped,
    as theirs, ``modulo_angles=False``), ``e_j`` the errors of every reset step so far in the run (theirs keeps one
    list for the whole run) and ``dt = pid_dt``::

        clip(kp e + ki dt sum_j e_j + kd (e - e_prev) / dt + g(q), -max_torque, max_torque)

    the derivative term zero for the run's first two reset steps, ``g(q)`` the torque that holds the chain at rest
    at ``q`` (MuJoCo's ``qfrc_bias`` at zero rate, theirs ``-B G(q)``). Their PID is given ``dt = 0.001`` s (the
    class's default: the leaderboard does not pass its own) while their simulator calls it every 0.002 s, so its
    derivative term is twice ``kd`` times the rate; kept as theirs. The shoulder of an acrobot has no actuator in
    MuJoCo, so the torques go on the hinges as ``qfrc_applied`` (logged by :func:`cartpole.sim.rollout.simulate`:
    the run replays exactly with ``mj_step``). A reset lasts ``length`` rounded to whole physics steps (theirs: until
    its timer, a sum of step lengths, exceeds it: the same or one step more, by rounding).

    Random draws as theirs after ``np.random.seed(seed)``: ``RandomState(seed).uniform(0, 2 pi, (10 count + 1, 4))``
    (the poses, less pi; the i-th reset takes row i), then ``rand(count)`` (the jitters). Their angles turn the other
    way about the hinges than MuJoCo's y axis in ``realaigym_acrobot.xml`` (its comment), so a pose's angles are
    taken with a minus sign: the same poses for that file; for any other chain, still uniform ones.

    Parameters
    ----------
    count : int
        Resets in the run (theirs: 15).
    duration : float
        s, the run's length the times are spread over (theirs: 60).
    length : float
        s each reset lasts (theirs: 0.2).
    seed : int
        Seed of the poses and times.
    jitter : float
        s, largest move of a reset's time (theirs: 1).
    kp, ki, kd : float
        N m/rad, N m/(rad s), N m s/rad: the PID's gains (theirs: 10, 0.1, 1).
    pid_dt : float
        s, the PID's own step for its integral and difference (theirs: 0.001).
    max_torque : float
        N m, each hinge's torque limit (theirs: 6, ``mpar_nolim``).
    """

    count: int = 15
    duration: float = 60.0
    length: float = 0.2
    seed: int = 0
    jitter: float = 1.0
    kp: float = 10.0
    ki: float = 0.1
    kd: float = 1.0
    pid_dt: float = 0.001
    max_torque: float = 6.0

    def __post_init__(self):
        try:
            count = int(self.count)
        except (TypeError, ValueError):
            count = -1
        if not (1 <= count <= 10000 and count == self.count):
            raise DisturbanceError(f"The reset's count must be a whole number in [1, 10000]; got {self.count!r}.")
        object.__setattr__(self, "count", count)
        object.__setattr__(self, "duration", _seconds("reset run's duration", self.duration))
        object.__setattr__(self, "length", _seconds("reset's length", self.length))
        object.__setattr__(self, "seed", _seed(self.seed))
        for name in ("jitter", "kp", "ki", "kd", "pid_dt", "max_torque"):
            try:
                v = float(getattr(self, name))
            except (TypeError, ValueError):
                v = float("nan")
            if not (np.isfinite(v) and v >= 0 and (v > 0 or name in ("jitter", "ki", "kd"))):
                raise DisturbanceError(f"The reset's {name} must be a finite number >= 0 (> 0 for kp, pid_dt and "
                                       f"max_torque); got {getattr(self, name)!r}.")
            object.__setattr__(self, name, v)

    def draws(self) -> tuple[np.ndarray, np.ndarray]:
        """The poses ``(count, 4)`` (rad about the hanging rest, uniform in [-pi, pi): theirs takes the first two
        as the angles and zeroes the other two, its rates; a chain of up to four hinges takes its first as many) and
        the times ``(count,)`` (s), as theirs draws them after ``np.random.seed(seed)``."""
        rng = np.random.RandomState(self.seed)
        states = rng.uniform(0.0, 2 * np.pi, (10 * self.count + 1, 4)) - np.pi
        gap = self.duration / float(self.count + 1)
        times = np.linspace(gap, self.duration - gap, self.count) + self.jitter * 2.0 * (rng.rand(self.count) - 0.5)
        return states[:self.count], times

    def start(self, source, *, x_hanging, hinges, timestep: float, period: float | None = None) -> "ResetForce":
        """The stateful force ``f(t, x) -> (nv,)`` for one run on ``source`` (CartPoleParams or MJCF path) at the
        physics step ``timestep`` (s) and the loop's control ``period`` (s, None: every physics step), the poses
        taken about the hanging rest ``x_hanging`` (nx,) at qpos indices ``hinges``; wrap the run's controller in
        its :meth:`ResetForce.gate`."""
        return ResetForce(self, source, np.asarray(x_hanging, dtype=float), tuple(int(h) for h in hinges),
                          float(timestep), period)


class ResetForce:
    """One run's resets (:meth:`Reset.start`): call it as ``f(t, x) -> (nv,)`` once per physics step in time order,
    and run the controller through :meth:`gate`. :attr:`events` lists each reset's ``(start, end)`` times in s as it
    happens, :attr:`goals` each one's goal angles (qpos of the hinges, rad), :attr:`windows` every reset's planned
    physics steps ``(first, last + 1)``.

    Parameters
    ----------
    reset : Reset
    source : CartPoleParams or MJCF path
        The model MuJoCo runs.
    x_hanging : (nx,) array
        The hanging rest the poses are drawn about.
    hinges : tuple of int
        qpos indices of the pole angles (1-DOF hinges: the same index in qvel).
    timestep : float
        The physics step, s.
    period : float, optional
        The loop's control period, s (None: every physics step): each reset starts at the first control instant at
        or after its time and lasts whole periods (``length`` rounded up to them), so that the controller, asked
        only at control instants, is off for exactly the reset's steps.
    """

    def __init__(self, reset: Reset, source, x_hanging: np.ndarray, hinges: tuple, timestep: float,
                 period: float | None = None):
        self.reset, self.hinges, self.h = reset, hinges, timestep
        self.m, self.d = make_mujoco(source)
        self.dofs = [int(self.m.jnt_dofadr[j]) for j in range(self.m.njnt) if int(self.m.jnt_qposadr[j]) in hinges]
        poses, times = reset.draws()
        if len(hinges) > poses.shape[1]:
            raise DisturbanceError(f"RealAIGym's reset draws at most {poses.shape[1]} angles a pose; the model has "
                                   f"{len(hinges)} hinges.")
        self.poses = x_hanging[list(hinges)] - poses[:, :len(hinges)]
        hold = 1 if period is None else max(1, int(round(period / timestep)))
        steps = hold * int(np.ceil(round(reset.length / timestep) / hold))
        first = hold * np.ceil(np.asarray(times) / (timestep * hold) - 1e-9).astype(int)
        self.windows = [(int(k), int(k) + steps) for k in first]
        self.events: list[tuple[float, float]] = []
        self.goals: list[np.ndarray] = []
        self._errors_sum = np.zeros(len(hinges))
        self._errors_n = 0
        self._last_error: np.ndarray | None = None

    def active(self, t: float) -> int | None:
        """The index of the reset under way at time ``t`` (s), or None."""
        k = int(round(t / self.h))
        for i, (a, b) in enumerate(self.windows):
            if a <= k < b:
                return i
        return None

    def gate(self, controller):
        """``controller`` switched off during the resets: ``f(t, x)`` returns zero ctrl (nu,) then, without asking
        it (as theirs, which does not call the swing-up controller during a reset), else ``controller(t, x)``. For
        :func:`cartpole.sim.rollout.simulate` without a rig, at the control period this force was started with."""
        zero = np.zeros(self.m.nu)

        def gated(t, x):
            return zero.copy() if self.active(t) is not None else controller(t, x)
        return gated

    def holding_torque(self, x) -> np.ndarray:
        """(nv,) the generalized force that holds the chain at rest at ``x``'s joint positions: MuJoCo's
        ``qfrc_bias`` at zero rate (N m on hinges, N on slides)."""
        d = self.d
        d.qpos[:] = np.asarray(x, dtype=float)[:self.m.nq]
        d.qvel[:] = 0.0
        mujoco.mj_forward(self.m, d)
        return d.qfrc_bias.copy()

    def __call__(self, t: float, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        i = self.active(t)
        f = np.zeros(self.m.nv)
        if i is None:
            return f
        if len(self.events) <= i:
            self.events.append((float(t), float(self.windows[i][1] * self.h)))
            self.goals.append(self.poses[i].copy())
        r = self.reset
        e = self.poses[i] - x[list(self.hinges)]
        self._errors_sum += e
        self._errors_n += 1
        u = r.kp * e + r.ki * self._errors_sum * r.pid_dt
        if self._errors_n > 2:
            u += r.kd * (e - self._last_error) / r.pid_dt
        self._last_error = e
        u += self.holding_torque(x)[self.dofs]
        f[self.dofs] = np.clip(u, -r.max_torque, r.max_torque)
        return f


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
