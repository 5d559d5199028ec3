"""Estimate the LQR catch's basin ``{e : e' S e < rho}`` by replaying the catch in MuJoCo from sampled states.

For any model the reader accepts (any number of poles and actuators); ``e = x - x_eq`` is the error from the
catch's equilibrium (the model's computed upright ``x_eq``), hinge-angle entries wrapped. Method (documented in
:class:`BasinEstimate`):

1. draw ``n`` errors spread over the ellipsoid ``e' S e <= level``, which perturbs every state component at once:
   a direction ``d`` uniform on the unit sphere of dimension ``nx``, ``e = r sqrt(level) L^-T d`` with ``S = L L'``
   (so ``e' S e = level r^2``) and ``r`` uniform in ``[0, 1]``, from ``numpy.random.default_rng(seed)``; errors whose
   cart (slide) position is outside 90 % of the half-track are redrawn. The start states are ``x_eq + e``. The level
   set is long and thin (rates and angles mix), so sampling in the metric of ``S`` puts every sample where it
   informs rho, where a fixed box wastes most of them;
2. run the catch ``u = clip(u_eq - K e)`` (``e`` the wrapped error) from each in MuJoCo on the MJCF for
   ``duration`` s, all runs batched (:func:`~cartpole.sim.batch.simulate_batch_linear`);
3. call a run a success when MuJoCo never warned that it blew up (a diverged run, which MuJoCo resets to ``qpos0``
   at rest, is a failure whatever its end state: :class:`~cartpole.sim.batch.BatchRollouts`), the cart never reaches its joint limit (kept ``limit_margin`` inside it) and at the
   end every pole is upright and still: each wrapped hinge-angle error from ``x_eq`` below ``0.05`` rad, each
   hinge rate below ``0.1`` rad/s and each slide rate below ``0.1`` m/s (:mod:`~cartpole.validation.metrics`'
   ``UPRIGHT_TOL``, ``REST_RATE_TOL``, ``REST_SPEED_TOL``);
4. ``rho_sampled`` is the largest level below which every sample succeeded: the smallest cost ``e' S e`` of a
   failed sample. The samples only cover ``e' S e < rho_cover`` (``level``, or less where the track cuts the
   ellipsoid: ``(0.9 half-track)^2 / (S^-1)_ss``, ``s`` the slide's index), so above that they say nothing; the
   estimate is ``rho = safety_factor * min(rho_sampled, rho_cover)``. The safety factor (default 0.75) covers
   directions the finite sample missed; it is a margin, not a proof.

Estimates are cached (:class:`BasinCache`): in memory, and with ``BasinCache.on_disk()`` (what
:func:`cartpole.apps.swingup.run_swingup` and the sweeps use) as ``.npz`` files under the user cache directory
(``$CARTPOLE_CACHE_DIR``, else ``$XDG_CACHE_HOME/cartpole``, else ``~/.cache/cartpole``; subdirectory ``basins``),
named by :func:`basin_key`: a SHA-256 of the MJCF text, the catch (``K``, ``S``, ``x_eq``, ``u_eq``, ``u_limits``,
``hinges``), every sampling setting (``n``, ``seed``, ``level``, ``duration``, ``safety_factor``, ``limit_margin``),
MuJoCo's version, :data:`BASIN_VERSION` and the source of the code that estimates it. So a second ``cartpole
swingup`` does not estimate it again, and an edit to the method never reads a stale estimate.
"""
from __future__ import annotations

import hashlib
import io
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

import cartpole.control.linear
import cartpole.sim.batch
from cartpole._arrays import readonly
from cartpole._files import OutputError
from cartpole.codegen import cache_dir, private_dir, read_verified, write_verified
from cartpole.control.linear import LinearFeedback
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleParams, plant_params, state_error
from cartpole.progress import stage
from cartpole.sim import simulate_batch_linear
from cartpole.validation.metrics import REST_RATE_TOL, REST_SPEED_TOL, UPRIGHT_TOL


#: Version of the estimate's method, part of every cache key: bump it when :func:`estimate_basin` changes.
BASIN_VERSION = 2
#: :func:`estimate_basin`'s sampling settings and defaults (the cache key holds every one of them).
DEFAULTS = {"n": 300, "seed": 0, "level": 1.0, "duration": 4.0, "safety_factor": 0.75, "limit_margin": 0.01}


class BasinError(CartPoleError):
    """Bad sampling settings for a basin estimate."""


@dataclass(frozen=True)
class BasinEstimate:
    """A sampled estimate of the catch basin ``e' S e < rho``, with everything needed to inspect it.

    Attributes
    ----------
    rho : float
        The catch level to use: ``safety_factor * min(rho_sampled, rho_cover)``.
    rho_sampled : float
        Smallest cost of a failed sample (inf when none failed).
    rho_cover : float
        Level up to which the samples cover the set ``e' S e < rho_cover`` (``level``, less if the track cuts it).
    samples : (n, nx) array
        Start states ``x_eq + e``, [m, rad, m/s, rad/s] (for a model built upright ``x_eq = 0`` and these are the
        errors themselves; :attr:`errors` gives ``e``).
    costs : (n,) array
        ``e' S e`` of each sample.
    success : (n,) bool array
        Whether the catch brought that sample to upright rest without touching the cart limit and without diverging.
    S : (nx, nx) array
        Cost-to-go matrix of the catch.
    K : (nu, nx) array
        Gain of the catch.
    n : int
    seed : int
    level : float
        Samples were drawn in ``e' S e <= level``.
    box : (nx,) array
        Half-widths of the box enclosing the sampled errors, ``max |e|`` per state, [m, rad, m/s, rad/s].
    duration : float
        Seconds each sample was simulated.
    safety_factor : float
    limit_margin : float
        m inside the cart joint limit that a run must stay.
    mjcf : str
        MJCF the runs used.
    x_eq : (nx,) array or None
        The catch's equilibrium the errors are measured from (None: the origin).
    diverged : (n,) bool array or None
        Whether MuJoCo warned that the run from that sample blew up (and reset it): each such sample is a failure.
    """

    rho: float
    rho_sampled: float
    rho_cover: float
    samples: np.ndarray
    costs: np.ndarray
    success: np.ndarray
    S: np.ndarray
    K: np.ndarray
    n: int
    seed: int
    level: float
    box: np.ndarray
    duration: float
    safety_factor: float
    limit_margin: float
    mjcf: str = ""
    x_eq: np.ndarray | None = None
    diverged: np.ndarray | None = None

    def __post_init__(self):
        for name in ("samples", "costs", "S", "K", "box"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        object.__setattr__(self, "success", readonly(self.success, bool))
        dv = np.zeros(self.success.shape, bool) if self.diverged is None else self.diverged
        object.__setattr__(self, "diverged", readonly(dv, bool))
        if self.x_eq is not None:
            object.__setattr__(self, "x_eq", readonly(self.x_eq))

    @property
    def errors(self) -> np.ndarray:
        """(n, nx) sampled errors ``samples - x_eq``."""
        return self.samples - (0.0 if self.x_eq is None else self.x_eq)

    @property
    def n_inside(self) -> int:
        """Number of samples with cost below ``rho``."""
        return int(np.sum(self.costs < self.rho))

    def summary(self) -> dict:
        """JSON-ready summary (no sample arrays)."""
        return {"rho": self.rho, "rho_sampled": None if not np.isfinite(self.rho_sampled) else self.rho_sampled,
                "rho_cover": self.rho_cover, "n": self.n, "seed": self.seed, "level": self.level,
                "box": self.box.tolist(),
                "duration": self.duration, "safety_factor": self.safety_factor,
                "successes": int(self.success.sum()), "diverged": int(self.diverged.sum()),
                "n_inside": self.n_inside}


def catch_succeeds(plant, catch: LinearFeedback, starts, duration: float, *, limit_margin: float = 0.01,
                   progress=None) -> np.ndarray:
    """Which runs of the catch from ``starts`` (n, nx) end upright and still: the first output of
    :func:`catch_outcomes` (same arguments: ``duration`` s, ``limit_margin`` m), (n,) bool."""
    return catch_outcomes(plant, catch, starts, duration, limit_margin=limit_margin, progress=progress)[0]


def catch_outcomes(plant, catch: LinearFeedback, starts, duration: float, *, limit_margin: float = 0.01,
                   progress=None) -> tuple[np.ndarray, np.ndarray]:
    """Run the catch in MuJoCo from each start state and say which runs end upright and still, and which diverged.

    All runs advance together (:func:`~cartpole.sim.batch.simulate_batch_linear`: MuJoCo's own
    ``mj_step`` through its threaded rollout, the catch's law evaluated for the batch in numpy), about ten
    times faster than a Python loop of ``mj_step`` per run and the same physics as :func:`simulate`.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    catch : LinearFeedback
        Its law ``u* - K (x - x*)`` (wrapped hinge errors, its ``u_limits``) every physics step; MuJoCo clips
        ctrl to ctrlrange.
    starts : (n, nx) array
        Start states.
    duration : float
        Seconds per run.
    limit_margin : float
        The cart must stay this far (m) inside its joint range the whole run.
    progress : callable, optional
        Called with the fraction done.

    Returns
    -------
    success : (n,) bool array
        The run never diverged, the cart stayed inside its range throughout, and at the end every wrapped hinge
        error from ``catch.x_eq`` is below ``UPRIGHT_TOL``, every hinge rate below ``REST_RATE_TOL`` and every slide
        rate below ``REST_SPEED_TOL``.
    diverged : (n,) bool array
        MuJoCo warned that the run blew up and reset it (:class:`~cartpole.sim.batch.BatchRollouts`).
    """
    params = plant_params(plant)
    nq = params.nq
    starts = np.atleast_2d(np.asarray(starts, dtype=float))
    runs = simulate_batch_linear(params, catch.K, starts, duration, x_eq=catch.x_eq, u_eq=catch.u_eq,
                                 u_limits=catch.u_limits, hinges=catch.hinges, progress=progress)
    states, diverged = runs.states, runs.diverged
    stayed = np.ones(starts.shape[0], dtype=bool)
    if params.slide is not None:
        lo, hi = params.cart_range  # the slide joint's range (infinite when unlimited)
        lo, hi = lo + limit_margin, hi - limit_margin
        s = states[:, 1:, params.slide]  # the cart after every step
        stayed = np.all((lo < s) & (s < hi), axis=1)
    hinges = list(params.hinges)
    e = state_error(states[:, -1], catch.x_eq, hinges)
    still = (np.all(np.abs(e[:, hinges]) < UPRIGHT_TOL, axis=1)
             & np.all(np.abs(e[:, [nq + h for h in hinges]]) < REST_RATE_TOL, axis=1)
             & np.all(np.abs(e[:, [nq + i for i in params.slides]]) < REST_SPEED_TOL, axis=1))
    return stayed & still & ~diverged, diverged


def sample_errors(S, n: int, *, level: float, seed: int, s_max: float = np.inf, slide: int | None = 0) -> np.ndarray:
    """Errors (n, nx) spread over ``e' S e <= level`` (see the module notes), with ``|e[slide]| < s_max`` (m).

    ``slide`` is the state index of the cart position (None: no cart, nothing redrawn).
    """
    S = np.asarray(S, dtype=float)
    nx = S.shape[0]
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(S)
    out = np.empty((0, nx))
    while len(out) < n:
        d = rng.standard_normal((n, nx))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        r = rng.uniform(0.0, 1.0, size=(n, 1))
        e = np.linalg.solve(L.T, (np.sqrt(level) * r * d).T).T
        out = np.vstack([out, e if slide is None else e[np.abs(e[:, slide]) < s_max]])
    return out[:n]


def estimate_basin(plant=None, catch: LinearFeedback | None = None, *, n: int = 300, seed: int = 0,
                   level: float = 1.0, duration: float = 4.0, safety_factor: float = 0.75,
                   limit_margin: float = 0.01, progress=None) -> BasinEstimate:
    """Sample start states around ``x_eq``, replay the catch in MuJoCo from each and return the safe level rho.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The model, any number of poles and actuators (None = shipped asset).
    catch : LinearFeedback, optional
        Catch with ``S``; default the lab LQR about the model's ``x_eq`` on the exact linearisation
        (:meth:`~cartpole.control.linear.LinearFeedback.for_model`).
    n : int
        Number of samples.
    seed : int
        Seed of ``numpy.random.default_rng``.
    level : float
        Samples fill ``e' S e <= level`` (cost units of ``S``); keep it well above the expected rho.
    duration : float
        Seconds each sample is simulated.
    safety_factor : float
        In (0, 1]: rho is this fraction of the sampled level.
    limit_margin : float
        m inside the cart joint range a successful run must stay.
    progress : callable, optional
        Called with the fraction done; the estimate is also a :func:`cartpole.progress.stage` ("basin estimate").

    Returns
    -------
    BasinEstimate
    """
    params = plant_params(plant)
    if catch is None:
        catch = LinearFeedback.for_model(params)
    if catch.S is None:
        raise BasinError("The catch has no cost-to-go matrix S; build it with LinearFeedback(K, S=S).")
    if int(n) < 1 or not (duration > 0) or not (0 < safety_factor <= 1) or not (level > 0):
        raise BasinError(f"Basin sampling needs n >= 1, level > 0, duration > 0 and 0 < safety_factor <= 1 "
                         f"(got n = {n}, level = {level}, duration = {duration}, safety_factor = {safety_factor}).")
    S = np.asarray(catch.S, dtype=float)
    if S.shape != (2 * params.nq, 2 * params.nq):
        raise BasinError(f"The catch's S is {S.shape} but the MJCF has {2 * params.nq} states; design the catch on "
                         "this model.")
    slide = params.slide
    half = 0.5 * (params.cart_range[1] - params.cart_range[0])
    s_max = 0.9 * half if np.isfinite(half) else np.inf
    errors = sample_errors(S, int(n), level=float(level), seed=int(seed), s_max=s_max, slide=slide)
    x_eq = np.asarray(catch.x_eq, dtype=float)
    samples = x_eq + errors
    costs = np.einsum("ni,ij,nj->n", errors, S, errors)
    with stage("basin estimate", size=f"{int(n)} runs", callback=progress) as tick:
        success, diverged = catch_outcomes(params, catch, samples, duration, limit_margin=limit_margin,
                                           progress=tick)
    rho_sampled = float(costs[~success].min()) if np.any(~success) else np.inf
    cut = s_max**2 / np.linalg.inv(S)[slide, slide] if slide is not None else np.inf
    rho_cover = float(min(level, cut))
    rho = float(safety_factor * min(rho_sampled, rho_cover))
    return BasinEstimate(rho=rho, rho_sampled=rho_sampled, rho_cover=rho_cover, samples=samples, costs=costs,
                         success=success, S=S, K=catch.K, n=int(n), seed=int(seed), level=float(level),
                         box=np.abs(errors).max(axis=0), duration=float(duration),
                         safety_factor=float(safety_factor), limit_margin=float(limit_margin), mjcf=params.mjcf,
                         x_eq=x_eq, diverged=diverged)


def basin_key(params: CartPoleParams, catch: LinearFeedback, **settings) -> str:
    """SHA-256 hex digest naming one estimate: the MJCF text, the catch's ``K``, ``S``, ``x_eq``, ``u_eq``,
    ``u_limits`` and ``hinges``, the sampling settings (``n``, ``seed``, ``level``, ``duration``, ``safety_factor``,
    ``limit_margin``; missing ones take :data:`DEFAULTS`), MuJoCo's version, :data:`BASIN_VERSION` and a digest of
    the estimating code's source (this module, :mod:`cartpole.sim.batch`, :mod:`cartpole.control.linear`).

    Raises
    ------
    BasinError
        A setting :func:`estimate_basin` does not take.
    """
    unknown = set(settings) - set(DEFAULTS) - {"progress"}
    if unknown:
        raise BasinError(f"Unknown basin setting(s) {', '.join(sorted(unknown))}; use {', '.join(DEFAULTS)}.")
    opts = {k: float(settings.get(k, v)) for k, v in DEFAULTS.items()}
    h = hashlib.sha256()
    h.update(json.dumps({"version": BASIN_VERSION, "mujoco": mujoco.__version__, "code": _code_digest(), **opts},
                        sort_keys=True).encode())
    h.update(params.xml.encode())
    for a in (catch.K, catch.S, catch.x_eq, catch.u_eq, catch.u_limits):
        arr = np.ascontiguousarray(np.asarray(a, dtype=float))
        h.update(repr(arr.shape).encode() + arr.tobytes())
    h.update(repr(tuple(int(i) for i in (catch.hinges or ()))).encode())
    return h.hexdigest()


def _code_digest() -> str:
    """SHA-256 of the source of the code an estimate runs (this module, the batch rollouts, the linear law), so an
    edit to it never finds a stale estimate on disk."""
    h = hashlib.sha256()
    for mod in (__name__, cartpole.sim.batch.__name__, cartpole.control.linear.__name__):
        try:
            h.update(Path(sys.modules[mod].__file__).read_bytes())
        except (OSError, TypeError, KeyError):
            h.update(mod.encode())
    return h.hexdigest()


def _default_directory() -> Path:
    return cache_dir() / "basins"


_ARRAYS = ("samples", "costs", "success", "S", "K", "box", "x_eq", "diverged")
_SCALARS = ("rho", "rho_sampled", "rho_cover", "n", "seed", "level", "duration", "safety_factor", "limit_margin")


def _save(path: Path, est: BasinEstimate) -> None:
    """Write ``est`` as ``.npz`` with its content hash beside it (:func:`cartpole.codegen.write_verified`, each whole
    or not at all); an unwritable cache is skipped silently (it is a cache)."""
    buf = io.BytesIO()
    arrays = {k: np.asarray(getattr(est, k)) for k in _ARRAYS if getattr(est, k) is not None}
    np.savez(buf, **arrays, scalars=np.array([float(getattr(est, k)) for k in _SCALARS]))
    try:
        private_dir(path.parent)
        write_verified(path, buf.getvalue())
    except OutputError:
        pass


def plausible(est: BasinEstimate) -> bool:
    """Whether a stored estimate holds values an estimate can have: finite arrays of consistent shapes, levels
    ``rho_cover >= rho >= 0`` (``rho_sampled`` > 0 or inf), ``rho`` equal to ``safety_factor * min(rho_sampled,
    rho_cover)``, a safety factor in (0, 1], ``n`` samples. A file failing this (a negative or NaN rho, say) is
    discarded and the basin estimated again."""
    try:
        n = int(est.n)
        arrays_ok = (est.samples.ndim == 2 and est.samples.shape[0] == n and est.costs.shape == (n,)
                     and est.success.shape == (n,) and all(np.all(np.isfinite(np.asarray(a, float))) for a in
                                                             (est.samples, est.costs, est.S, est.K, est.box)))
        levels = (np.isfinite(est.rho) and est.rho >= 0 and np.isfinite(est.rho_cover) and est.rho_cover >= est.rho
                  and not np.isnan(est.rho_sampled) and est.rho_sampled > 0 and 0 < est.safety_factor <= 1)
        consistent = levels and np.isclose(est.rho, est.safety_factor * min(est.rho_sampled, est.rho_cover),
                                           rtol=1e-12, atol=0.0)
        return bool(n > 0 and arrays_ok and consistent)
    except (AttributeError, TypeError, ValueError):
        return False


def _load(path: Path, mjcf: str) -> BasinEstimate | None:
    """The estimate stored at ``path``, or None when absent, unreadable, not the content recorded when it was saved
    (:func:`cartpole.codegen.read_verified`) or not :func:`plausible` (then it is estimated again)."""
    data = read_verified(path)
    if data is None:
        return None
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: np.array(z[k]) for k in _ARRAYS if k in z.files}
            sc = dict(zip(_SCALARS, (float(v) for v in z["scalars"])))
    except (OSError, ValueError, KeyError, EOFError):
        return None
    try:
        est = BasinEstimate(rho=sc["rho"], rho_sampled=sc["rho_sampled"], rho_cover=sc["rho_cover"],
                            samples=arrays["samples"], costs=arrays["costs"], success=arrays["success"],
                            S=arrays["S"], K=arrays["K"], n=int(sc["n"]), seed=int(sc["seed"]), level=sc["level"],
                            box=arrays["box"], duration=sc["duration"], safety_factor=sc["safety_factor"],
                            limit_margin=sc["limit_margin"], mjcf=mjcf, x_eq=arrays.get("x_eq"),
                            diverged=arrays.get("diverged"))
    except (KeyError, ValueError, TypeError):
        return None
    return est if plausible(est) else None


@dataclass
class BasinCache:
    """Cache of basin estimates, keyed by :func:`basin_key` (the MJCF text, the catch, the sampling settings).

    Pass one around explicitly (no module-level state); ``cache.get(source, catch, **kw)`` estimates once and
    returns the same :class:`BasinEstimate` afterwards. With a ``directory`` (:meth:`on_disk`: the user cache
    directory's ``basins``) every estimate is also kept on disk as ``<key>.npz`` and found there by any later
    process; ``hits`` and ``misses`` count lookups that did not / did run the estimate.
    """

    _store: dict = field(default_factory=dict)
    directory: Path | None = None
    hits: int = 0
    misses: int = 0

    @classmethod
    def on_disk(cls, directory: str | Path | None = None) -> "BasinCache":
        """A cache backed by ``directory`` (default ``cache_dir() / "basins"``, which honours
        ``$CARTPOLE_CACHE_DIR``)."""
        return cls(directory=Path(directory) if directory is not None else _default_directory())

    def get(self, plant=None, catch: LinearFeedback | None = None, **kwargs) -> BasinEstimate:
        """:func:`estimate_basin` with the same arguments, computed once per distinct input (and, on disk, once per
        machine)."""
        params = plant_params(plant)
        if catch is None:
            catch = LinearFeedback.for_model(params)
        if catch.S is None:
            raise BasinError("The catch has no cost-to-go matrix S; build it with LinearFeedback(K, S=S).")
        key = basin_key(params, catch, **kwargs)
        if key in self._store:
            self.hits += 1
            return self._store[key]
        est = None
        path = None if self.directory is None else Path(self.directory) / f"{key}.npz"
        if path is not None:
            try:  # a basins directory others may write to is refused (CacheError), never read
                private_dir(path.parent)
            except OSError:  # cannot be created: no disk cache this time
                path = None
        if path is not None and path.is_file():
            est = _load(path, params.mjcf)
        if est is not None:
            self.hits += 1
        else:
            self.misses += 1
            est = estimate_basin(params, catch, **kwargs)
            if path is not None:
                _save(path, est)
        self._store[key] = est
        return est

    def __len__(self) -> int:
        return len(self._store)
