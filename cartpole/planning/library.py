"""A library of swing-up plans: plans made once from a grid of starts, kept in the user cache under the model's hash,
and handed to the planner as warm starts (:func:`cartpole.planning.trajopt.trajopt_swingup`'s ``guess``).

A cold plan searches: a multi-start of named guesses for the minimum time on a coarse mesh, its refinement, then the
effort problem at ``(1 + time_margin) T_min``. From a start near one a plan was made from, that last problem alone,
started from the stored plan (its hinge angles shifted by whole turns onto the new start's), usually converges at
once: the stored plan's duration is kept and the search is skipped. When it does not converge the planner goes on
cold, so a warm start can only cost the one failed solve.

* :class:`PlanLibrary`: the stored plans (:class:`StoredPlan`: the start and the collocation trajectory), the nearest
  to a state by a quadratic metric on the wrapped difference (the catch's cost-to-go matrix ``S``, or the lab's
  weights), :meth:`~PlanLibrary.guess_for` (the nearest plan shifted onto the start), :meth:`~PlanLibrary.with_plan`
  (a new library with one more plan: a supervisor keeps its own plans as warm starts for the next knockdown);
* :func:`library_starts`: the grid (the chain at rest, its first hinge at evenly spaced angles);
* :func:`build_plan_library`: cold plans from every start of the grid (the starts no plan was found from are kept
  in ``failed``, with the planner's sentence);
* :meth:`PlanLibrary.knot_guess`: the rest of a stored plan from its knot nearest a state (mirror images through
  upright too, for a model :func:`mirror_symmetric` finds symmetric: :func:`mirrored`): a plan pumping from hanging
  holds warm starts for every energy it passes through (a knocked, calmed acrobot swings low near one of its knots);
* :func:`cached_library`: the library of given starts, built once and kept on disk;
* :func:`library_path`, :meth:`PlanLibrary.save`, :meth:`PlanLibrary.load`: the file
  ``<cache>/plans/<model hash>.npz`` (:func:`cartpole.codegen.cache_dir`; written with its SHA-256 beside it,
  read only when it matches), never inside the package.
"""
from __future__ import annotations

import hashlib
import io
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cartpole._arrays import readonly
from cartpole.codegen import cache_dir, model_key, private_dir, read_verified, write_verified
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, CartPoleParams, build_model, wrap_angle
from cartpole.ocp.trajectory import Trajectory, step_grid_trajectory
from cartpole.ocp.bounds import bounds_from_params
from cartpole.ocp.dmc import is_sparse_task
from cartpole.planning.box_tail import kept_inside
from cartpole.planning.trajopt import trajopt_swingup

#: Part of the library file's key: bump when what a stored plan means changes.
LIBRARY_VERSION = "plans-v1"
#: Most plans a library keeps (a supervisor adding its own plans drops the oldest it added beyond this).
MAX_PLANS = 200


class PlanLibraryError(CartPoleError):
    """A plan library that does not fit the model (other state or input sizes), or a grid that cannot be made."""


@dataclass(frozen=True)
class StoredPlan:
    """One plan of the library.

    Attributes
    ----------
    x0 : (nx,) array
        The start the plan was made from ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    trajectory : Trajectory
        The collocation plan (time from 0, duration ``T`` s), ending upright.
    plan_s : float
        s, wall time of the plan that made it (nan when unknown).
    """

    x0: np.ndarray
    trajectory: Trajectory
    plan_s: float = float("nan")

    def __post_init__(self):
        object.__setattr__(self, "x0", readonly(np.asarray(self.x0, dtype=float).ravel()))


def shifted_onto(model: CartPoleModel, traj: Trajectory, x0) -> Trajectory:
    """``traj`` with every hinge angle shifted by the whole turns that bring its first state nearest ``x0`` (nx,)
    (a hinge angle and the same angle a turn on are the same pose; the plan's end moves with it, still upright)."""
    x0 = np.asarray(x0, dtype=float).ravel()
    shift = np.zeros(traj.nx)
    for h in model.hinges:
        shift[h] = 2.0 * np.pi * np.round((x0[h] - traj.x[0, h]) / (2.0 * np.pi))
    if not np.any(shift):
        return traj
    return Trajectory(t=traj.t, x=traj.x + shift, u=traj.u, xdot=traj.xdot,
                      x_mid=None if traj.x_mid is None else traj.x_mid + shift, u_mid=traj.u_mid)


def trajectory_tail(traj: Trajectory, tau: float) -> Trajectory:
    """The rest of ``traj`` from ``tau`` s after its start: its knots from the first at or after ``t[0] + tau`` (at
    least the last two intervals kept), time from 0. A re-plan's warm start while the plan is tracked."""
    k = int(np.searchsorted(traj.t, float(traj.t[0]) + float(tau) - 1e-12))
    k = max(0, min(k, len(traj.t) - 3))
    return Trajectory(t=traj.t[k:] - traj.t[k], x=traj.x[k:], u=traj.u[k:], xdot=traj.xdot[k:],
                      x_mid=None if traj.x_mid is None else traj.x_mid[k:],
                      u_mid=None if traj.u_mid is None else traj.u_mid[k:])


@dataclass(frozen=True)
class PlanLibrary:
    """Stored swing-up plans of one model, the nearest handed out as a warm start.

    Attributes
    ----------
    key : str
        The model's hash (:func:`cartpole.codegen.model_key`) the plans belong to.
    nx, nu : int
        State and input sizes.
    hinges : tuple of int
        qpos indices of the hinge angles (wrapped when comparing states).
    plans : tuple of StoredPlan
    failed : tuple of (x0 (nx,) array, str)
        Starts of the grid no plan was found from, with the planner's sentence.
    """

    key: str
    nx: int
    nu: int
    hinges: tuple
    plans: tuple = ()
    failed: tuple = field(default=(), compare=False)

    @classmethod
    def empty(cls, model: CartPoleModel) -> "PlanLibrary":
        """A library of ``model`` with no plans."""
        return cls(key=model_key(model), nx=int(model.nx), nu=int(model.nu), hinges=tuple(int(h) for h in model.hinges))

    def __len__(self) -> int:
        return len(self.plans)

    def check(self, model: CartPoleModel) -> None:
        """Raise :class:`PlanLibraryError` unless the library is ``model``'s (same hash)."""
        if self.key != model_key(model):
            raise PlanLibraryError("The plan library was made for another model (its hash differs); build one for "
                                   "this model with build_plan_library.")

    def distances(self, x, metric=None) -> np.ndarray:
        """``sqrt(d' W d)`` from ``x`` (nx,) to every plan's start, ``d`` the difference with hinge angles wrapped to
        (-pi, pi]; ``metric`` ``W`` (nx, nx) default diag(1 per slide, 10 per hinge, 0.1 per rate), the lab's
        weights. Shape (len,)."""
        x = np.asarray(x, dtype=float).ravel()
        if x.size != self.nx:
            raise PlanLibraryError(f"The state has {x.size} numbers but the plan library's model has {self.nx}.")
        if not self.plans:
            return np.zeros(0)
        W = self._default_metric() if metric is None else np.asarray(metric, dtype=float)
        d = x[None, :] - np.array([p.x0 for p in self.plans])
        hinges = list(self.hinges)
        d[:, hinges] = wrap_angle(d[:, hinges])
        return np.sqrt(np.maximum(np.einsum("ki,ij,kj->k", d, W, d), 0.0))

    def _default_metric(self) -> np.ndarray:
        nq = self.nx // 2
        w = np.ones(self.nx)
        w[list(self.hinges)] = 10.0
        w[nq:] = 0.1
        return np.diag(w)

    def nearest(self, x, metric=None) -> tuple[StoredPlan, float] | None:
        """The plan whose start is nearest ``x`` (nx,) by :meth:`distances` and that distance, or None when empty."""
        dist = self.distances(x, metric)
        if dist.size == 0:
            return None
        k = int(np.argmin(dist))
        return self.plans[k], float(dist[k])

    def guess_for(self, model: CartPoleModel, x, metric=None) -> Trajectory | None:
        """The nearest plan, its hinge angles shifted by whole turns onto ``x`` (:func:`shifted_onto`): the warm
        start for a plan from ``x``; None when the library is empty."""
        found = self.nearest(x, metric)
        return None if found is None else shifted_onto(model, found[0].trajectory, x)

    def knot_guess(self, model: CartPoleModel, x, metric=None, mirror: bool | None = None
                   ) -> tuple[Trajectory, float] | None:
        """The rest of a stored plan from its knot nearest ``x`` (nx,), shifted by whole turns onto ``x``, and that
        distance (:meth:`distances`' metric, default the lab's weights); None when the library is empty.

        Every knot of every plan is a start the plan's tail (:func:`trajectory_tail`) swings up from, so a plan that
        pumps from hanging holds warm starts for every energy it passes through (a knocked and calmed chain swinging
        low is near one of its knots, not near its start). With ``mirror`` (default: when
        :func:`mirror_symmetric` finds ``model`` symmetric) each plan's mirror image through upright
        (:func:`mirrored`) is searched too."""
        found = self.knot_guesses(model, x, count=1, metric=metric, mirror=mirror)
        return found[0] if found else None

    def knot_guesses(self, model: CartPoleModel, x, count: int = 3, metric=None, mirror: bool | None = None,
                     energy_weight: float = 0.0, min_tail: float = 0.0) -> list[tuple[Trajectory, float]]:
        """Up to ``count`` warm starts for a plan from ``x`` (nx,), nearest first: of each stored plan (and each
        mirror image) the tail from its knot nearest ``x``, as :meth:`knot_guess`; with their distances.

        ``energy_weight`` (dimensionless, default 0) adds ``energy_weight * |E_knot - E(x)| / E_up`` to the distance
        in quadrature, ``E`` the model's total energy and ``E_up`` the swing-up's (upright rest over hanging rest,
        J): a knot of the energy ``x`` has is where the rest of the plan fits it (a pumping plan passes near the
        same pose at every energy). ``min_tail`` (s, default 0): only knots at least that long before the plan's end
        (a swing-up from a state that does not match the knot exactly needs some time)."""
        x = np.asarray(x, dtype=float).ravel()
        if x.size != self.nx:
            raise PlanLibraryError(f"The state has {x.size} numbers but the plan library's model has {self.nx}.")
        if not self.plans:
            return []
        self.check(model)
        trajs = [p.trajectory for p in self.plans]
        if mirror is None:
            mirror = mirror_symmetric(model)
        if mirror:
            trajs = trajs + [mirrored(model, tr) for tr in trajs]
        W = self._default_metric() if metric is None else np.asarray(metric, dtype=float)
        hinges = list(self.hinges)
        if energy_weight:
            e_x = float(model.energy(x))
            scale = float(energy_weight) / max(abs(float(model.energy(model.x_eq)) - float(model.energy(
                model.x_hanging))), 1e-12)
        best = []
        for tr in trajs:
            last = int(np.searchsorted(tr.t, float(tr.t[-1]) - float(min_tail), side="right"))
            knots = np.asarray(tr.x[:max(1, min(last, len(tr.t) - 2))], dtype=float)  # a tail keeps two intervals
            d = x[None, :] - knots
            d[:, hinges] = wrap_angle(d[:, hinges])
            d2 = np.einsum("ki,ij,kj->k", d, W, d)
            if energy_weight:
                e = np.asarray(model.energy.map(len(knots))(knots.T), dtype=float).ravel()
                d2 = d2 + (scale * (e - e_x)) ** 2
            dist = np.sqrt(np.maximum(d2, 0.0))
            k = int(np.argmin(dist))
            best.append((float(dist[k]), tr, float(tr.t[k] - tr.t[0])))
        best.sort(key=lambda b: b[0])
        return [(shifted_onto(model, trajectory_tail(tr, tau), x), dist) for dist, tr, tau in best[:int(count)]]

    def with_plan(self, x0, trajectory: Trajectory, plan_s: float = float("nan")) -> "PlanLibrary":
        """A new library with the plan ``trajectory`` from ``x0`` added (the oldest dropped beyond
        :data:`MAX_PLANS`)."""
        if trajectory.nx != self.nx or trajectory.nu != self.nu:
            raise PlanLibraryError(f"The plan has {trajectory.nx} states and {trajectory.nu} inputs but the library's "
                                   f"model has {self.nx} and {self.nu}.")
        t0 = float(trajectory.t[0])
        traj = trajectory if t0 == 0.0 else Trajectory(t=trajectory.t - t0, x=trajectory.x, u=trajectory.u,
                                                         xdot=trajectory.xdot, x_mid=trajectory.x_mid,
                                                         u_mid=trajectory.u_mid)
        plans = (self.plans + (StoredPlan(x0, traj, float(plan_s)),))[-MAX_PLANS:]
        return PlanLibrary(self.key, self.nx, self.nu, self.hinges, plans, self.failed)

    # ---- the file ---------------------------------------------------------------------------------------------
    def to_bytes(self) -> bytes:
        """The library as an ``.npz`` file's bytes (arrays only, no pickle)."""
        arrays = {"key": np.array(self.key), "version": np.array(LIBRARY_VERSION),
                  "sizes": np.array([self.nx, self.nu]), "hinges": np.array(self.hinges, dtype=int),
                  "count": np.array(len(self.plans))}
        for k, p in enumerate(self.plans):
            tr = p.trajectory
            arrays.update({f"x0_{k}": p.x0, f"t_{k}": tr.t, f"x_{k}": tr.x, f"u_{k}": tr.u, f"xdot_{k}": tr.xdot,
                           f"plan_s_{k}": np.array(p.plan_s)})
            if tr.x_mid is not None and tr.u_mid is not None:
                arrays.update({f"xmid_{k}": tr.x_mid, f"umid_{k}": tr.u_mid})
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        return buf.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> "PlanLibrary":
        """The library :meth:`to_bytes` wrote."""
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            if str(z["version"]) != LIBRARY_VERSION:
                raise PlanLibraryError(f"The plan library file is of version {z['version']}, not {LIBRARY_VERSION}; "
                                       "build it again with build_plan_library.")
            nx, nu = (int(v) for v in z["sizes"])
            plans = []
            for k in range(int(z["count"])):
                mid = (z[f"xmid_{k}"], z[f"umid_{k}"]) if f"xmid_{k}" in z.files else (None, None)
                tr = Trajectory(t=z[f"t_{k}"], x=z[f"x_{k}"], u=z[f"u_{k}"], xdot=z[f"xdot_{k}"], x_mid=mid[0],
                                u_mid=mid[1])
                plans.append(StoredPlan(z[f"x0_{k}"], tr, float(z[f"plan_s_{k}"])))
            return cls(str(z["key"]), nx, nu, tuple(int(h) for h in z["hinges"]), tuple(plans))

    def save(self, path: str | Path | None = None, *, objective: str | None = None) -> Path:
        """Write the library to ``path`` (default :func:`library_path` of its key and ``objective``, in the user
        cache), with its SHA-256 beside it; returns the path."""
        path = library_path(self.key, objective) if path is None else Path(path)
        private_dir(path.parent)
        return write_verified(path, self.to_bytes())

    @classmethod
    def load(cls, model: CartPoleModel, path: str | Path | None = None, *, objective: str | None = None
             ) -> "PlanLibrary":
        """``model``'s library from ``path`` (default the user cache's file of its hash and ``objective``, the
        planner's objective the plans optimised: :func:`library_path`); an empty library when there is none, or the
        file is not the one written (its SHA-256 differs) or of another version or model."""
        key = model_key(model)
        path = library_path(key, objective) if path is None else Path(path)
        data = read_verified(path)
        if data is not None:
            try:
                lib = cls.from_bytes(data)
                if lib.key == key and lib.nx == model.nx and lib.nu == model.nu:
                    return lib
            except (PlanLibraryError, KeyError, ValueError, OSError):
                pass
        return cls.empty(model)


def mirror_symmetric(model: CartPoleModel, samples: int = 6, seed: int = 0) -> bool:
    """Whether ``model`` is symmetric through upright: ``f(2 x* - x, 2 u* - u) = -f(x, u)`` at ``samples`` seeded
    random states and inputs (hinges within a turn, rates within 5 rad/s, slides within 0.5 m of ``x*``) and the ctrl
    ranges centred on ``u*``; then a plan's mirror image (:func:`mirrored`) is a plan too (the acrobot, a cart-pole
    on a level rail)."""
    x_eq, u_eq = np.asarray(model.x_eq, dtype=float), np.asarray(model.u_eq, dtype=float).ravel()
    lo, hi = np.asarray(model.u_low, dtype=float), np.asarray(model.u_high, dtype=float)
    if not np.allclose(lo + hi, 2.0 * u_eq, atol=1e-12):
        return False
    rng = np.random.default_rng(seed)
    scale = np.full(model.nx, 5.0)
    scale[: model.nq] = 0.5
    scale[list(model.hinges)] = np.pi
    for _ in range(int(samples)):
        x = x_eq + rng.uniform(-1.0, 1.0, model.nx) * scale
        u = rng.uniform(lo, hi)
        a, b = model.dynamics(x, u), model.dynamics(2.0 * x_eq - x, 2.0 * u_eq - u)
        if not np.allclose(b, -a, rtol=1e-9, atol=1e-9 * (1.0 + np.max(np.abs(a)))):
            return False
    return True


def mirrored(model: CartPoleModel, traj: Trajectory) -> Trajectory:
    """``traj``'s mirror image through upright: states ``2 x* - x``, inputs ``2 u* - u`` (a plan of a
    :func:`mirror_symmetric` model, ending upright as ``traj`` does)."""
    x_eq, u_eq = np.asarray(model.x_eq, dtype=float), np.asarray(model.u_eq, dtype=float).ravel()
    return Trajectory(t=traj.t, x=2.0 * x_eq - traj.x, u=2.0 * u_eq - traj.u, xdot=-np.asarray(traj.xdot),
                      x_mid=None if traj.x_mid is None else 2.0 * x_eq - traj.x_mid,
                      u_mid=None if traj.u_mid is None else 2.0 * u_eq - traj.u_mid)


def cached_library(params: CartPoleParams, model: CartPoleModel | None = None, starts=None, *, options=None,
                   period: float | None = None, path: str | Path | None = None, exact: bool = False) -> PlanLibrary:
    """The library of plans from ``starts`` kept at ``path``: read when it holds a plan from every start, else the
    missing ones planned cold (:func:`build_plan_library`), added and saved. A library built once per model (keyed
    by its hash) and reused, e.g. by a long test or a demonstration.

    Parameters
    ----------
    params, model, starts, options, period, exact
        As :func:`build_plan_library` (``starts`` (k, nx), default :func:`library_starts`).
    path : str or Path, optional
        The file (default :func:`library_path` of the model's hash and ``options.objective``: a library per
        objective, e.g. ``dmc_cartpole_swingup``'s plans beside the effort plans; with ``exact`` the objective's
        name and ``-entry``, a file of its own).

    Returns
    -------
    PlanLibrary
        Its ``failed`` lists the starts no plan was found from (not saved: they are tried again next time).
    """
    model = build_model(params) if model is None else model
    starts = library_starts(model) if starts is None else np.atleast_2d(np.asarray(starts, dtype=float))
    objective = getattr(options, "objective", None)
    if exact and isinstance(objective, str):
        objective = f"{objective}-entry"
    path = library_path(model_key(model), objective) if path is None else path
    lib = PlanLibrary.load(model, path)
    missing = [x for x in starts if not len(lib) or lib.nearest(x)[1] > 1e-12]
    if not missing:
        return lib
    lib = build_plan_library(params, model, np.array(missing), options=options, period=period, library=lib,
                             exact=exact)
    if len(lib):
        saved = PlanLibrary(lib.key, lib.nx, lib.nu, lib.hinges, lib.plans)
        saved.save(path)
    return lib


def library_path(key: str, objective: str | None = None) -> Path:
    """``<cache>/plans/<key>-<version>.npz``: where the library of the model of hash ``key`` is kept
    (:func:`cartpole.codegen.cache_dir`, the user's cache; never inside the package); with ``objective`` (a named
    objective other than ``effort``, e.g. ``dmc_cartpole_swingup``) ``<key>-<objective>-<version>.npz``, that
    objective's plans. An objective that is not a name (a callable) has no file of its own: the effort file."""
    tag = f"-{objective}" if isinstance(objective, str) and objective not in ("", "effort") else ""
    if tag and not all(c.isalnum() or c in "_.:-" for c in objective):
        tag = "-" + hashlib.sha256(objective.encode()).hexdigest()[:16]
    return cache_dir() / "plans" / f"{key[:32]}{tag}-{LIBRARY_VERSION}.npz"


def library_starts(model: CartPoleModel, angles: int = 7) -> np.ndarray:
    """The grid a library is built from: the chain at rest (cart at ``x_eq``'s position, every rate 0), straight
    (every hinge but the first at its upright value), its first hinge at ``angles`` evenly spaced offsets from
    hanging, ``pi (2 (k + 1) / (angles + 1) - 1)`` rad for ``k < angles`` (hanging itself when ``angles`` is odd;
    upright never). Shape (angles, nx)."""
    if int(angles) < 1:
        raise PlanLibraryError(f"A plan library needs at least 1 start angle; got {angles}.")
    if not model.hinges:
        raise PlanLibraryError("The model has no hinge to swing up; a plan library needs one.")
    h0 = int(model.hinges[0])
    hang = float(model.x_hanging[h0])
    up = float(model.x_eq[h0])
    span = wrap_angle(hang - up)
    out = []
    for k in range(int(angles)):
        x = np.array(model.x_eq, dtype=float)
        x[model.nq:] = 0.0
        x[h0] = up + span + np.pi * (2.0 * (k + 1) / (int(angles) + 1) - 1.0)
        out.append(x)
    return np.array(out)


def _kept(params: CartPoleParams, model: CartPoleModel, plan, options) -> Trajectory:
    """What ``build_plan_library(exact=True)`` keeps of ``plan``: its exact discrete plan as a trajectory on the step
    grid (:func:`~cartpole.ocp.trajectory.step_grid_trajectory`; a sparse task's entry plan moved
    :data:`~cartpole.planning.box_tail.STORED_MARGIN` inside its box: :func:`~cartpole.planning.box_tail.kept_inside`),
    else its collocation plan."""
    d = plan.discrete
    if d is None:
        return plan.trajectory
    x, u = d.x, d.u
    objective = getattr(options, "objective", None)
    if d.box_entry is not None and is_sparse_task(objective):
        step = model if abs(float(model.dt) - float(d.dt)) < 1e-15 else model.rebuilt(dt=float(d.dt))
        bounds = bounds_from_params(params, cart_margin=getattr(options, "cart_margin", 0.1))
        x, u = kept_inside(step, objective, x, u, bounds)
    return step_grid_trajectory(model.f, d.dt, x, u)


def build_plan_library(params: CartPoleParams, model: CartPoleModel | None = None, starts=None, *, options=None,
                       period: float | None = None, library: PlanLibrary | None = None, progress=None,
                       exact: bool = False) -> PlanLibrary:
    """Cold plans (:func:`~cartpole.planning.trajopt.trajopt_swingup`) from every start, kept as a library.

    Parameters
    ----------
    params : CartPoleParams
        The cart-pole (its bounds bound the plans).
    model : CartPoleModel, optional
        The planning model (default the MJCF's own); the library is keyed by its hash.
    starts : (k, nx) array, optional
        The starts; default :func:`library_starts`.
    options : PlanOptions, optional
        The planner's settings.
    period : float, optional
        Control period in s (as the planner's).
    library : PlanLibrary, optional
        A library to add to (default an empty one).
    progress : callable, optional
        ``progress(done, total)`` after each start.
    exact : bool
        Keep each plan's exact discrete plan where it has one (``SwingupPlan.discrete``: a sparse task's box-entry
        plan, on the MJCF's step grid, moved inside its box: :func:`_kept`), else its collocation plan (False,
        default: the collocation plan always).

    Returns
    -------
    PlanLibrary
        ``failed`` lists the starts no plan was found from, with the planner's sentence. Not saved: call
        :meth:`PlanLibrary.save`.
    """
    model = build_model(params) if model is None else model
    lib = PlanLibrary.empty(model) if library is None else library
    lib.check(model)
    starts = library_starts(model) if starts is None else np.atleast_2d(np.asarray(starts, dtype=float))
    failed = list(lib.failed)
    for i, x0 in enumerate(starts):
        tic = time.perf_counter()
        try:
            plan = trajopt_swingup(params, x0=tuple(x0), plan_model=model, options=options, period=period)
        except CartPoleError as exc:
            failed.append((readonly(np.array(x0)), str(exc)))
        else:
            lib = lib.with_plan(x0, _kept(params, model, plan, options) if exact else plan.trajectory,
                                time.perf_counter() - tic)
        if progress is not None:
            progress(i + 1, len(starts))
    return PlanLibrary(lib.key, lib.nx, lib.nu, lib.hinges, lib.plans, tuple(failed))
