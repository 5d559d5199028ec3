"""The optimal policy of a pendulum driven at its hinge, computed globally by value iteration.

One pole on one driven hinge (dm_control's pendulum, a Gymnasium-style or a user's pendulum; no cart) has a
two-dimensional state: its angle and its rate. Its optimal policy for a return (dm_control's, or "within the upright
band" for the supervisor) need not be searched for locally, as a trajectory optimisation does from one start: dynamic
programming over a grid of the whole state space gives the optimal value and policy from every state at once.

* **Grid** (:class:`ValueIterationOptions`): the hinge's angle error from the upright ``x*`` wrapped to
  ``(-pi, pi]`` (``angles`` nodes, periodic) or, on a hinge with a limited range, that range (not wrapped);
  the rate within ``[-rate_max, rate_max]`` (``rates`` nodes), ``rate_max`` derived from the model's energy: the
  speed at hanging with the upright's energy (the most a swing-up needs there), times ``rate_margin``.
* **Actions**: ``levels`` ctrl values evenly over the ctrl range (bang-bang included) and zero (``u*``'s side of the
  range) when inside it; ties go to the smallest effort.
* **Transitions**: every node under every action, one control period (``hold`` physics steps) of MuJoCo's own
  ``mj_step`` on the model's MJCF (damping, gear, ctrl clamping and joint limits as MuJoCo applies them), computed
  once as a table by ``mujoco.rollout`` (:class:`HoldStep`). The successor's value is interpolated bilinearly between
  nodes (the angle periodic, the rate clamped to the grid), so each action is one sparse matrix with four entries a
  row and one Bellman backup is one sparse product: ``V <- max_a (r_a + discount P_a V)``.
* **Reward** (a function of the state reached and the ctrl held, evaluated exactly at each successor, never
  interpolated): :class:`DMCReward` (dm_control's, :func:`cartpole.ocp.dmc.rewards`) or :class:`BandReward` (1 with
  the pole within a band of upright).
* **Horizon**: ``horizon`` steps to go (dm_control's pendulum: 1000) with ``discount`` (default 1, the episode's
  plain sum). When every node's value grows by the same amount ``gain`` in one backup (the span of the increment
  below ``tol``), every later backup adds exactly that again (the interpolation's rows sum to 1), so the rest of the
  horizon is added in one step: the optimal return over the whole episode, not an estimate of it.

The result is a frozen :class:`HingeValues` (the value and policy tables and their grid); :class:`ValuePolicy` is
the controller ``u = policy(t, x)``: from the state it is given, the action whose MuJoCo step earns most (the reward
of the state reached, plus that state's interpolated value), which is the policy table refined off the nodes.
:func:`policy_returns` runs it from many starts at once (MuJoCo's ``rollout`` over the batch each step), exactly as
the single runs do. :func:`cached_hinge_values` keeps tables on disk under the model's hash and the settings, as
:mod:`cartpole.planning.library` keeps plans.

It sits in :mod:`cartpole.planning` because it needs what lies below: the dm_control rewards of :mod:`cartpole.ocp`,
MuJoCo's batched steps beside :mod:`cartpole.sim`; and the supervisor (:mod:`cartpole.supervise`) above uses it.
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ClassVar

import mujoco
import mujoco.rollout
import numpy as np
import scipy.sparse as sp

from cartpole._arrays import readonly
from cartpole.codegen import cache_dir, model_key, private_dir, read_verified, write_verified
from cartpole.errors import CartPoleError
from cartpole.models import (CartPoleModel, Plant, mujoco_model, plant_model, plant_params, steps_per_period,
                             wrap_angle)
from cartpole.ocp.dmc import rewards as dmc_rewards
from cartpole.ocp.dmc import task as dmc_task
from cartpole.options import StageOptions
from cartpole.sim import UPRIGHT_BAND

#: Bump when the stored tables' layout or meaning changes (old cache files are then not read).
VALUE_VERSION = 2
#: States a single ``mujoco.rollout`` call steps (the transition table is made in chunks of this many).
ROLLOUT_CHUNK = 65536
#: Q values within this of the best count as equal; the first of them (the smallest effort) is taken.
TIE = 1e-9


class ValueIterationError(CartPoleError):
    """A model that is not one pendulum driven at its hinge, bad grid settings, or a reward without a key where one
    is needed."""


def pendulum_driven_at_hinge(model: CartPoleModel) -> bool:
    """Whether ``model`` is one pole on one driven hinge, no cart (what value iteration and the hinge pump handle)."""
    actuated = [int(j) for j in model.params.actuated]
    return model.nq == 1 and len(model.hinges) == 1 and actuated == [int(model.hinges[0])]


@dataclass(frozen=True, eq=False)
class ValueIterationOptions(StageOptions):
    """The grid, actions and horizon of :func:`hinge_values`.

    Attributes
    ----------
    angles : int
        Angle nodes (>= 8): over a full turn (spacing ``2 pi / angles`` rad), or over a limited hinge's range
        (spacing ``range / (angles - 1)`` rad, shifted to put a node at upright: one node fewer, or the ends within a
        spacing of the range's).
    rates : int
        Rate nodes (>= 5) over ``[-rate_max, rate_max]``; odd puts a node at rest.
    levels : int
        ctrl levels evenly over the ctrl range, its ends included (>= 2); zero is added when inside the range.
    rate_margin : float
        ``rate_max`` is this times the speed at hanging with the upright's energy (> 1).
    rate_max : float or None
        rad/s: the rate bound itself instead (> 0).
    horizon : int
        Steps to go (control periods, >= 1): dm_control's pendulum episode is 1000.
    discount : float
        Per step, in (0, 1]; 1 sums the rewards as the episode does.
    tol : float
        The span of one backup's increment below which the rest of the horizon is extrapolated (> 0).
    every_step : bool
        Pay the reward after every physics step of a period, summed (an action-repeat wrapper's return, e.g.
        TD-MPC2's over dm_control), instead of once for the state at the period's end (dm_control's own control step,
        Gymnasium's frame skip).
    """

    angles: int = 200
    rates: int = 201
    levels: int = 5
    rate_margin: float = 1.25
    rate_max: float | None = None
    horizon: int = 1000
    discount: float = 1.0
    tol: float = 1e-9
    every_step: bool = False

    error: ClassVar[type] = ValueIterationError
    SCALARS: ClassVar[tuple] = ("angles", "rates", "levels", "rate_margin", "rate_max", "horizon", "discount", "tol")

    def __post_init__(self):
        self.number("angles", low=8, integer=True, hint="give e.g. `angles=200`")
        self.number("rates", low=5, integer=True, hint="give e.g. `rates=201`")
        self.number("levels", low=2, integer=True, hint="give e.g. `levels=5` (bang-bang and three between)")
        self.number("rate_margin", low=1.0, low_open=True, hint="give e.g. `rate_margin=1.25`")
        self.number("rate_max", low=0.0, low_open=True, unit="rad/s", optional=True)
        self.number("horizon", low=1, integer=True, hint="give the episode's steps, e.g. `horizon=1000`")
        self.number("discount", low=0.0, high=1.0, low_open=True)
        self.number("tol", low=0.0, low_open=True)
        if not isinstance(self.every_step, (bool, np.bool_)):
            raise ValueIterationError(f"ValueIterationOptions.every_step must be True or False; got {self.every_step!r}.")


class DMCReward:
    """dm_control's exact reward of task ``objective`` (:func:`cartpole.ocp.dmc.rewards`) as ``r(x, u)``.

    Parameters
    ----------
    model : CartPoleModel
    objective : str
        A ``dmc_*`` objective (e.g. ``"dmc_pendulum_swingup"``).
    """

    def __init__(self, model: CartPoleModel, objective: str = "dmc_pendulum_swingup"):
        self.model, self.objective = model, dmc_task(objective).name
        self.key = f"dmc:{self.objective}"

    def __call__(self, x, u) -> np.ndarray:
        """Rewards (M,) of the states reached ``x`` (M, nx) with the ctrl held ``u`` (M, nu)."""
        return dmc_rewards(self.model, self.objective, x, u)


class BandReward:
    """1 where the hinge is within ``band`` rad of upright (angle error wrapped), else 0: the supervisor's "up".

    Parameters
    ----------
    model : CartPoleModel
    band : float
        rad (default :data:`cartpole.sim.UPRIGHT_BAND`, the uptime metric's band).
    """

    def __init__(self, model: CartPoleModel, band: float = UPRIGHT_BAND):
        if not (np.isfinite(band) and 0 < band < np.pi):
            raise ValueIterationError(f"band = {band!r} must be an angle in (0, pi) rad.")
        self.hinge, self.x_eq, self.band = int(model.hinges[0]), float(model.x_eq[model.hinges[0]]), float(band)
        self.key = f"band:{self.band:.12g}"

    def __call__(self, x, u) -> np.ndarray:
        """Rewards (M,) of the states reached ``x`` (M, nx) (``u`` (M, nu) unused)."""
        err = wrap_angle(np.asarray(x, float)[..., self.hinge] - self.x_eq)
        return (np.abs(err) <= self.band).astype(float)


class HoldStep:
    """One control period of MuJoCo's own ``mj_step`` (``hold`` physics steps, the ctrl held) from many states at
    once, by ``mujoco.rollout`` (one thread).

    Parameters
    ----------
    plant : path, CartPoleParams or CartPoleModel
        The MJCF MuJoCo runs.
    hold : int
        Physics steps per control period (>= 1; each of the MJCF's timestep, s).
    """

    def __init__(self, plant: Plant, hold: int = 1):
        self.m = mujoco_model(plant_params(plant))
        self.d = mujoco.MjData(self.m)
        self.hold = int(hold)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.spec = spec
        self.template = np.empty(mujoco.mj_stateSize(self.m, spec))
        mujoco.mj_getState(self.m, self.d, self.template, spec)
        self.q0 = mujoco.mj_stateSize(self.m, mujoco.mjtState.mjSTATE_TIME)  # qpos follows the time
        self.nq, self.nv = self.m.nq, self.m.nv

    def __call__(self, X, U) -> tuple[np.ndarray, np.ndarray]:
        """The states (M, nx) one control period after ``X`` (M, nx) under ctrl ``U`` (M, nu), and (M,) bool: MuJoCo
        reset the run as blown up (its state is then not a successor)."""
        states, bad = self.states(X, U)
        return states[:, -1, :], bad

    def states(self, X, U) -> tuple[np.ndarray, np.ndarray]:
        """The state (M, hold, nx) after each physics step of the period from ``X`` (M, nx) under ctrl ``U`` (M, nu),
        and (M,) bool: blown up (as :meth:`__call__`)."""
        X = np.atleast_2d(np.asarray(X, float))
        U = np.atleast_2d(np.asarray(U, float))
        out, bad = np.empty((X.shape[0], self.hold, X.shape[1])), np.zeros(X.shape[0], bool)
        q0, nq, nv = self.q0, self.nq, self.nv
        for a in range(0, X.shape[0], ROLLOUT_CHUNK):
            b = min(a + ROLLOUT_CHUNK, X.shape[0])
            S0 = np.tile(self.template, (b - a, 1))
            S0[:, 0] = 1.0  # a clock away from 0: MuJoCo's divergence reset sets it to 0
            S0[:, q0:q0 + nq], S0[:, q0 + nq:q0 + nq + nv] = X[a:b, :nq], X[a:b, nq:]
            ctrl = np.repeat(U[a:b, None, :], self.hold, axis=1)
            S, _ = mujoco.rollout.rollout(self.m, self.d, S0, ctrl, nstep=self.hold)
            out[a:b, :, :nq], out[a:b, :, nq:] = S[:, :, q0:q0 + nq], S[:, :, q0 + nq:q0 + nq + nv]
            bad[a:b] = np.abs(S[:, -1, 0] - (1.0 + self.hold * self.m.opt.timestep)) > 1e-9
        return out, bad

    def pay(self, X, U, reward: Callable, every_step: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One period from ``X`` (M, nx) under ``U`` (M, nu): the states reached (M, nx), blown up (M,) bool, and the
        reward paid (M,): ``reward`` of the state reached, or with ``every_step`` summed over each physics step's state
        (an action-repeat wrapper's sum)."""
        states, bad = self.states(X, U)
        if not every_step:
            return states[:, -1, :], bad, np.asarray(reward(states[:, -1, :], U), float)
        M, h, nx = states.shape
        paid = np.asarray(reward(states.reshape(M * h, nx), np.repeat(U, h, axis=0)), float).reshape(M, h).sum(axis=1)
        return states[:, -1, :], bad, paid


@dataclass(frozen=True)
class HingeValues:
    """The optimal value and policy of a hinge-driven pendulum on a grid (:func:`hinge_values`).

    Attributes
    ----------
    angles : (na,) array
        rad: the nodes' hinge angle error from upright ``x_eq`` (periodic: ``2 pi (i - na // 2) / na``, from ``-pi``
        for an even ``na``; else evenly spaced over the hinge's range), a node at 0 either way.
    rates : (nr,) array
        rad/s: the nodes' rates.
    periodic : bool
        The angle wraps (an unlimited hinge); else the nodes span the hinge's limited range.
    actions : (na_u, nu) array
        The ctrl values, smallest effort first.
    value : (na, nr) array
        The optimal return from each node over ``horizon`` steps (the reward's units, e.g. dm_control's 0-1 a step).
    policy : (na, nr) int array
        Index into ``actions`` of the optimal first action at each node.
    horizon : int
        Steps to go the value counts (control periods of ``period`` s each).
    discount : float
    period : float
        s: the control period each action is held.
    hold : int
        Physics steps per period (each of the MJCF's timestep, s).
    iterations : int
        Bellman backups computed (the rest of the horizon extrapolated by ``gain`` a step).
    gain : float
        The last backup's increment (the same at every node once extrapolated): the reward a step the optimal
        policy earns in the long run (1 for dm_control's pendulum: held up).
    reward : str
        The reward's key.
    model : str
        The model's hash (:func:`cartpole.codegen.model_key`).
    hinge : int
        qpos index of the hinge.
    x_eq : (nx,) array
        The upright the angles are measured from.
    solve_s : float
        s of wall time to build the tables (0 when read from the cache).
    every_step : bool
        The reward was paid after every physics step of a period, summed (:class:`ValueIterationOptions`).
    """

    angles: np.ndarray
    rates: np.ndarray
    periodic: bool
    actions: np.ndarray
    value: np.ndarray
    policy: np.ndarray
    horizon: int
    discount: float
    period: float
    hold: int
    iterations: int
    gain: float
    reward: str
    model: str
    hinge: int
    x_eq: np.ndarray
    solve_s: float = 0.0
    every_step: bool = False

    @property
    def rate_max(self) -> float:
        """rad/s: the grid's rate bound."""
        return float(self.rates[-1])

    @property
    def spacing(self) -> tuple[float, float]:
        """(rad, rad/s): the grid's node spacing in angle and rate."""
        return float(self.angles[1] - self.angles[0]), float(self.rates[1] - self.rates[0])

    def coordinates(self, X) -> tuple[np.ndarray, np.ndarray]:
        """The grid coordinates (angle error, rate), each (M,), of states ``X`` (M, nx)."""
        X = np.atleast_2d(np.asarray(X, float))
        nq = X.shape[1] // 2
        err = X[:, self.hinge] - self.x_eq[self.hinge]
        return (wrap_angle(err) if self.periodic else err), X[:, nq + self.hinge]

    def weights(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear interpolation of states ``X`` (M, nx): flat node indices (M, 4) and weights (M, 4) summing to 1
        (the angle periodic or clamped to the range, the rate clamped to the grid)."""
        a, r = self.coordinates(X)
        na, nr = len(self.angles), len(self.rates)
        da, dr = self.spacing
        sa = (a - self.angles[0]) / da
        if self.periodic:
            fa = np.floor(sa)
            wa = sa - fa
            i0 = fa.astype(np.int64) % na
            i1 = (i0 + 1) % na
        else:
            sa = np.clip(sa, 0.0, na - 1)
            i0 = np.minimum(np.floor(sa).astype(np.int64), na - 2)
            wa, i1 = sa - i0, i0 + 1
        sr = np.clip((r - self.rates[0]) / dr, 0.0, nr - 1)
        j0 = np.minimum(np.floor(sr).astype(np.int64), nr - 2)
        wr, j1 = sr - j0, j0 + 1
        idx = np.stack([i0 * nr + j0, i0 * nr + j1, i1 * nr + j0, i1 * nr + j1], axis=1)
        w = np.stack([(1 - wa) * (1 - wr), (1 - wa) * wr, wa * (1 - wr), wa * wr], axis=1)
        return idx, w

    def value_at(self, X) -> np.ndarray:
        """The interpolated optimal return (M,) from states ``X`` (M, nx)."""
        idx, w = self.weights(X)
        return np.sum(self.value.ravel()[idx] * w, axis=1)

    def node_states(self) -> np.ndarray:
        """The nodes as states (na * nr, nx), angle-major (row ``i * nr + j``: angle ``i``, rate ``j``)."""
        nq = len(self.x_eq) // 2
        A, R = np.meshgrid(self.angles, self.rates, indexing="ij")
        X = np.tile(self.x_eq, (A.size, 1))
        X[:, self.hinge] = self.x_eq[self.hinge] + A.ravel()
        X[:, nq + self.hinge] = R.ravel()
        return X

    def to_bytes(self) -> bytes:
        """The tables as an ``.npz`` (no pickles)."""
        meta = {k: getattr(self, k) for k in ("periodic", "horizon", "discount", "period", "hold", "iterations",
                                              "gain", "reward", "model", "hinge", "every_step")}
        buf = io.BytesIO()
        np.savez(buf, angles=self.angles, rates=self.rates, actions=self.actions, value=self.value,
                 policy=self.policy, x_eq=self.x_eq, meta=np.array(json.dumps(meta)))
        return buf.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> "HingeValues":
        """The tables :meth:`to_bytes` wrote."""
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            arrays = {k: readonly(z[k]) for k in ("angles", "rates", "actions", "value", "x_eq")}
            return cls(policy=readonly(z["policy"], dtype=np.int64), **arrays, **meta)


def action_set(lo: float, hi: float, levels: int) -> np.ndarray:
    """ctrl values (n, 1): ``levels`` evenly over ``[lo, hi]`` and zero when inside, sorted by effort ``|u|``
    (ties: the lower first), so that an argmax's first of equals is the gentlest."""
    u = np.linspace(lo, hi, int(levels))
    if lo < 0.0 < hi and not np.any(np.isclose(u, 0.0, atol=1e-12)):
        u = np.append(u, 0.0)
    u = np.array(sorted(set(np.round(u, 12).tolist()), key=lambda v: (abs(v), v)))
    return u[:, None]


def energy_rate_bound(model: CartPoleModel, margin: float = 1.25) -> float:
    """rad/s: ``margin`` times the hinge's speed at hanging rest's pose with the upright's energy,
    ``sqrt(2 (E(x*) - E(hanging)) / J)`` (``J`` the hinge's inertia there, armature included).

    Raises
    ------
    ValueIterationError
        No energy to gain from hanging to upright (no gravity along the pole's swing).
    """
    hang = np.asarray(model.x_hanging, float)
    deficit = float(model.energy(np.asarray(model.x_eq, float))) - float(model.energy(hang))
    h = int(model.hinges[0])
    J = float(np.asarray(model.mass_matrix(hang))[h, h])
    if not (deficit > 0 and J > 0):
        raise ValueIterationError("The pendulum gains no energy from hanging to upright (no gravity along its swing), "
                                  "so no rate bound follows from it; give ValueIterationOptions(rate_max=...).")
    return float(margin) * float(np.sqrt(2.0 * deficit / J))


def _grid(model: CartPoleModel, opts: ValueIterationOptions) -> tuple[np.ndarray, np.ndarray, bool]:
    """Angle nodes, rate nodes and whether the angle wraps."""
    h = int(model.hinges[0])
    lo, hi = (float(v) for v in model.params.joints[h].range)
    x_eq = float(model.x_eq[h])
    periodic = not (np.isfinite(lo) and np.isfinite(hi))  # a limited hinge's angle never wraps, even over a turn
    if periodic:
        angles = 2 * np.pi * (np.arange(opts.angles) - opts.angles // 2) / opts.angles  # a node at upright
    else:  # evenly spaced with a node at upright itself (a fixed point the interpolation keeps), within the range
        d = (hi - lo) / (opts.angles - 1)
        k = np.arange(np.ceil((lo - x_eq) / d - 1e-9), np.floor((hi - x_eq) / d + 1e-9) + 1)
        angles = k * d
    rmax = opts.rate_max if opts.rate_max is not None else energy_rate_bound(model, opts.rate_margin)
    return angles, np.linspace(-rmax, rmax, opts.rates), periodic


def _limits(model: CartPoleModel, u_limits) -> tuple[float, float]:
    lim = (np.c_[model.u_low, model.u_high] if u_limits is None else np.asarray(u_limits, float)).reshape(-1)
    lo, hi = float(lim[0]), float(lim[1])
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueIterationError(f"The pendulum's ctrl range [{lo}, {hi}] is not a finite interval; set ctrlrange on "
                                  "its motor or give u_limits=[[low, high]].")
    return lo, hi


def check_pendulum(model: CartPoleModel) -> None:
    """Raise :class:`ValueIterationError` unless ``model`` is one pole driven at its hinge."""
    if not pendulum_driven_at_hinge(model):
        raise ValueIterationError("Value iteration here solves one pole driven at its hinge (no cart); this model has "
                                  f"{model.nq} joints and drives {list(model.params.actuated)}.")


def _backups(P, R: np.ndarray, opts: ValueIterationOptions) -> tuple[np.ndarray, np.ndarray, int, float]:
    """``horizon`` Bellman backups of ``V <- max_a (R_a + discount P_a V)`` from ``V = 0`` (R (nA, N), P
    (nA N, N)), the tail extrapolated once the increment's span is below ``tol``: (V, policy, backups, gain)."""
    nA, N = R.shape
    V, gain, k = np.zeros(N), 0.0, 0
    Q = R
    while k < opts.horizon:
        Q = R + opts.discount * (P @ V).reshape(nA, N)
        V_new = Q.max(axis=0)
        k += 1
        d = V_new - V
        V = V_new
        span = float(d.max() - d.min())
        if opts.discount == 1.0 and span < opts.tol:
            gain = float(d.mean())
            V = V + (opts.horizon - k) * gain
            break
        if opts.discount < 1.0 and float(np.abs(d).max()) < opts.tol * (1 - opts.discount):
            gain = float(d.mean())
            break
        gain = float(d.mean())
    best = Q.max(axis=0)
    policy = np.argmax(Q >= best - TIE, axis=0)
    return V, policy, k, gain


def hinge_values(plant: Plant, reward: Callable, *, period: float | None = None, u_limits=None,
                 options: ValueIterationOptions | None = None) -> HingeValues:
    """The optimal value and policy of a pendulum driven at its hinge, by value iteration on a grid (module notes).

    Parameters
    ----------
    plant : path, CartPoleParams or CartPoleModel
        One pole on one driven hinge (MuJoCo runs its MJCF; shapes and limits come from it).
    reward : callable
        ``reward(x (M, nx), u (M, nu)) -> (M,)``: paid for the state reached after each control period and the ctrl
        held (:class:`DMCReward`, :class:`BandReward`); a ``key`` attribute names it in the result.
    period : float, optional
        s: the control period (a whole number of physics steps; default one).
    u_limits : (1, 2) array, optional
        ctrl range of the actions (default the motor's ctrlrange).
    options : ValueIterationOptions, optional

    Returns
    -------
    HingeValues

    Raises
    ------
    ValueIterationError
        Not a pendulum driven at its hinge, no finite ctrl range, bad options.
    """
    tic = time.perf_counter()
    model = plant_model(plant)
    check_pendulum(model)
    opts = ValueIterationOptions() if options is None else options
    hold = steps_per_period(period, float(model.dt))
    lo, hi = _limits(model, u_limits)
    angles, rates, periodic = _grid(model, opts)
    actions = action_set(lo, hi, opts.levels)
    shell = HingeValues(readonly(angles), readonly(rates), periodic, readonly(actions), None, None, opts.horizon,
                        opts.discount, hold * float(model.dt), hold, 0, 0.0, getattr(reward, "key", repr(reward)),
                        model_key(model), int(model.hinges[0]), readonly(np.asarray(model.x_eq, float)),
                        every_step=bool(opts.every_step))
    X = shell.node_states()
    N, nA = X.shape[0], actions.shape[0]
    XA = np.tile(X, (nA, 1))
    UA = np.repeat(actions, N, axis=0)
    Xn, bad, paid = HoldStep(model, hold).pay(XA, UA, reward, opts.every_step)
    R = paid.reshape(nA, N)
    R[bad.reshape(nA, N)] = -np.inf  # a blown-up step is never chosen
    idx, w = shell.weights(np.where(bad[:, None], XA, Xn))
    P = sp.csr_matrix((w.ravel(), idx.ravel(), np.arange(0, 4 * nA * N + 1, 4)), shape=(nA * N, N))
    V, policy, k, gain = _backups(P, R, opts)
    shape = (len(angles), len(rates))
    return dataclasses.replace(shell, value=readonly(V.reshape(shape)), iterations=k, gain=gain,
                               policy=readonly(policy.reshape(shape), dtype=np.int64),
                               solve_s=time.perf_counter() - tic)


class ValuePolicy:
    """``u = policy(t, x)``: the optimal policy of :class:`HingeValues` at any state, off the nodes too.

    From the state given, each action's control period is run in MuJoCo (:class:`HoldStep`) and scored with the reward
    of the state reached plus that state's interpolated value (``discount`` applied); the best action is held (the
    first of equals, the gentlest). With ``lookahead=False`` the policy table's action at the nearest node instead.

    Parameters
    ----------
    values : HingeValues
    plant : path, CartPoleParams or CartPoleModel
        The model the tables were made for (its hash is checked).
    reward : callable
        The reward the tables were made with (its ``key`` is checked when it has one).
    lookahead : bool
        One MuJoCo period per action from the state (default) or the table's nearest node.
    depth : int
        Periods looked ahead (>= 1): every sequence of ``depth`` actions is run (``n_actions ** depth`` steps a call),
        the value read after the last; deeper looks past more of the grid's interpolation error.
    outside : callable, optional
        ``(t, x) -> ctrl`` for a state faster than the grid's rates (e.g. the hinge pump, which takes energy out);
        default the lookahead with the rate clamped to the grid.

    Raises
    ------
    ValueIterationError
        Tables made for another model or reward.
    """

    def __init__(self, values: HingeValues, plant: Plant, reward: Callable, *, lookahead: bool = True,
                 depth: int = 1, outside: Callable | None = None):
        model = plant_model(plant)
        if model_key(model) != values.model:
            raise ValueIterationError("The value tables were made for another model (its hash differs); make them "
                                      "for this one with hinge_values(plant, reward).")
        key = getattr(reward, "key", None)
        if key is not None and key != values.reward:
            raise ValueIterationError(f"The value tables were made for the reward '{values.reward}', not '{key}'; "
                                      "give the same reward or make tables for this one.")
        if isinstance(depth, bool) or not isinstance(depth, (int, np.integer)) or not 1 <= depth <= 4:
            raise ValueIterationError(f"depth = {depth!r} must be a whole number of periods from 1 to 4.")
        self.values, self.reward, self.lookahead, self.outside = values, reward, bool(lookahead), outside
        self.depth = int(depth)
        self.step = HoldStep(model, values.hold)
        self.rate = model.nq + values.hinge

    def actions(self, X) -> np.ndarray:
        """ctrl (B, nu) for states ``X`` (B, nx), all at once."""
        X = np.atleast_2d(np.asarray(X, float))
        v = self.values
        if not self.lookahead:
            idx, w = v.weights(X)
            near = idx[np.arange(X.shape[0]), np.argmax(w, axis=1)]
            return np.asarray(v.actions)[v.policy.ravel()[near]]
        Q = self._q(X, self.depth)
        best = np.argmax(Q >= Q.max(axis=0) - TIE, axis=0)
        return np.asarray(v.actions)[best]

    def _q(self, X: np.ndarray, depth: int) -> np.ndarray:
        """(nA, B): each first action's reward plus the best of the ``depth - 1`` further periods' and the value."""
        v = self.values
        nA, B = v.actions.shape[0], X.shape[0]
        XA = np.tile(X, (nA, 1))
        UA = np.repeat(np.asarray(v.actions), B, axis=0)
        Xn, bad, paid = self.step.pay(XA, UA, self.reward, v.every_step)
        later = v.value_at(Xn) if depth <= 1 else self._q(Xn, depth - 1).max(axis=0)
        Q = paid + v.discount * later
        return np.where(bad, -np.inf, Q).reshape(nA, B)

    def summary(self) -> dict:
        """JSON-ready: ``controller`` (``"value_iteration"``), ``reward``, ``angles``, ``rates`` (node counts),
        ``rate_max`` (rad/s), ``actions`` (the ctrl levels), ``period`` (s), ``horizon`` (steps), ``iterations``
        (Bellman backups computed), ``gain`` (the reward a step in the long run), ``solve_s`` (s; 0 when read from the
        cache), ``depth``."""
        v = self.values
        return {"controller": "value_iteration", "reward": v.reward, "angles": len(v.angles), "rates": len(v.rates),
                "rate_max": v.rate_max, "actions": [float(a) for a in np.asarray(v.actions).ravel()],
                "period": v.period, "horizon": v.horizon, "iterations": v.iterations, "gain": v.gain,
                "solve_s": round(v.solve_s, 3), "depth": self.depth}

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at state ``x`` (nx,) (``t`` in s, unused: the policy is stationary)."""
        x = np.asarray(x, float)
        if self.outside is not None and abs(x[self.rate]) > self.values.rate_max:
            return np.asarray(self.outside(t, x), float)
        return self.actions(x[None, :])[0]


def policy_returns(policy: ValuePolicy, X0, steps: int, reward: Callable | None = None) -> np.ndarray:
    """The return (B,) ``policy`` earns from each start ``X0`` (B, nx) over ``steps`` control periods in MuJoCo (the
    reward of each state reached and ctrl held, summed, after every physics step where the tables were made with
    ``every_step``; default the policy's reward), all starts stepped together:
    each run is the one :func:`cartpole.sim.simulate` makes with ``policy`` (a stationary law of the state)."""
    X = np.atleast_2d(np.asarray(X0, float)).copy()
    reward = policy.reward if reward is None else reward
    total = np.zeros(X.shape[0])
    for _ in range(int(steps)):
        U = policy.actions(X)
        X, bad, paid = policy.step.pay(X, U, reward, policy.values.every_step)
        if np.any(bad):
            raise ValueIterationError("MuJoCo reset a run as blown up under the value policy; the model's step is "
                                      "unstable at these rates (a smaller timestep in the MJCF).")
        total += paid
    return total


def value_path(model: CartPoleModel, reward: Callable, period: float | None, u_limits,
               options: ValueIterationOptions) -> Path:
    """``<cache>/value/<hash>-<version>.npz``: where :func:`cached_hinge_values` keeps the tables of this model,
    reward (its ``key``), period, ctrl range and options."""
    key = getattr(reward, "key", None)
    if key is None:
        raise ValueIterationError("Only a reward with a key (DMCReward, BandReward, or your own with a `key` string) "
                                  "can be cached; call hinge_values instead.")
    lo, hi = _limits(model, u_limits)
    what = json.dumps({"model": model_key(model), "reward": key, "period": period, "u": [lo, hi],
                       "options": options.as_dict()}, sort_keys=True)
    return cache_dir() / "value" / f"{hashlib.sha256(what.encode()).hexdigest()[:32]}-{VALUE_VERSION}.npz"


def cached_hinge_values(plant: Plant, reward: Callable, *, period: float | None = None, u_limits=None,
                        options: ValueIterationOptions | None = None) -> HingeValues:
    """:func:`hinge_values`, kept in the user cache (:func:`value_path`, with its SHA-256 beside it) and read from
    there next time: the same model, reward, period, ctrl range and options give the same tables. Without a usable
    cache directory the tables are made and not kept. Parameters, returns and errors as :func:`hinge_values`."""
    model = plant_model(plant)
    check_pendulum(model)
    opts = ValueIterationOptions() if options is None else options
    path = value_path(model, reward, period, u_limits, opts)
    data = read_verified(path)
    if data is not None:
        return HingeValues.from_bytes(data)
    values = hinge_values(model, reward, period=period, u_limits=u_limits, options=opts)
    try:
        private_dir(path.parent)
        write_verified(path, values.to_bytes())
    except (CartPoleError, OSError):
        pass  # no cache: the tables were made, only not kept
    return values
