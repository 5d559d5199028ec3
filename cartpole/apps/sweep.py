"""Robustness sweeps of the swing-up: one description, many runs, one row per run, one summary.

A sweep is described by axes (:class:`Axis`), each a grid (``linspace(low, high, count)``) or a seeded uniform
sample (``U(low, high)`` per run) of one input: a start-state component (any joint's position or rate, ``start:<joint>``
or ``start:<joint>_rate``), a push (``push_force`` N and ``push_time`` s: one push of :data:`~cartpole.apps.swingup.
PUSH_SECONDS`), the planning model's error ``model_error`` (pole masses and lengths scaled,
:meth:`~cartpole.models.CartPoleParams.scaled_pole`) or a controller setting (``setting:<name>``: an energy-shaping
scaling of :data:`~cartpole.control.energy.DEFAULT_SCALING` for ``energy``, ``period`` or ``horizon`` for ``mpc``).
The runs are the Cartesian product of the grid axes (the first axis varies slowest), repeated ``n`` times with fresh
draws when any axis is sampled; every input not on an axis is fixed (the start at the model's hanging rest, no push,
no model error, the controller's own settings). Without axes a sweep is the classic start box below.

Each run is :func:`cartpole.apps.swingup.run_swingup` (``method="energy"``: energy shaping + LQR catch,
``"trajopt"``: collocation + TVLQR, or ``"mpc"``: nonlinear MPC), in MuJoCo on the MJCF, so a sweep measures exactly what ``cartpole swingup``
does. A run counts as a success when :func:`~cartpole.validation.metrics.swingup_success` holds (upright and at
rest over the last second, cart never at its limit, every ctrl in range) *and* its log replays exactly with
``mj_step`` (:func:`~cartpole.sim.rollout.replays_exactly`). A run that raises a :class:`CartPoleError` (an
infeasible plan from that start, say) is a failure whose row carries the sentence as ``error``. The catch basin is
estimated once per planning model, before the runs, found on disk when an earlier run estimated it
(:meth:`~cartpole.validation.basin.BasinCache.on_disk`), and handed to every run.

Starts: ``center + U(-half_widths, half_widths)`` per state from ``numpy.random.default_rng(seed)``, default
around the model's hanging rest ``x_hanging`` with half-widths 0.3 m per slide, 0.3 rad per hinge, 0.3 m/s per
slide rate and 1 rad/s per hinge rate (one pole: ``(0.3 m, 0.3 rad, 0.3 m/s, 1 rad/s)``); cart positions are kept
1 mm inside the rail. Gain jitter (``gain_jitter = j``, energy only) multiplies each dimensionless setting in
:data:`JITTERED` by an independent ``U(1 - j, 1 + j)`` factor per run (``energy_accel`` is capped at 1), drawn from
the same generator after the starts.

Every run's inputs are drawn in this process before any run starts, from ``numpy.random.default_rng(seed)``
in a fixed order (the start box, then each sampled axis by name, then the gain jitter), so a description and a
seed give the same runs in any order and on any number of workers.

Parallel runs (``workers > 1``): a :class:`concurrent.futures.ProcessPoolExecutor` (``spawn`` start method) whose
initializer builds the model once per worker process (and each planning model once, on its first run there);
every run depends only on the model and its inputs, so the rows are the same, bit for bit, for any number of
workers, and they come back in run order.
On a cluster (``address``): the same runs as Dask distributed tasks on an existing scheduler; each worker process
builds the model on its first run of the sweep and keeps it (:func:`_run_on_dask`). Runs already finished
(``done``) are skipped, and ``on_row`` sees each row as it finishes (the command appends it to its results file).

Examples (the README's numbers)::

    cartpole sweep --n 20 --seed 0 --workers 2          # or: python -m cartpole.apps.sweep --n 20
    cartpole sweep --method trajopt --push-force -20 20 5 --model-error 0.8 1.2 5 --push-time 0.5
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from cartpole._arrays import readonly
from cartpole.control.energy import DEFAULT_SCALING
from cartpole.errors import CartPoleError, first_line
from cartpole.models import CartPoleModel, CartPoleParams, build_model, read_params
from cartpole.progress import stage
from cartpole.sim import replays_exactly
from cartpole.apps.swingup import ENERGY_DURATION, MPC_DURATION, check_model_error, planning_model, run_swingup
from cartpole.validation.basin import BasinCache

#: Default start box for one pole: centre (hanging at rest) and half-widths [m, rad, m/s, rad/s].
HANGING = (0.0, np.pi, 0.0, 0.0)
HALF_WIDTHS = (0.3, 0.3, 0.3, 1.0)
#: Half-widths per joint kind for any model: (position, rate) for a slide [m, m/s] and a hinge [rad, rad/s].
SLIDE_HALF_WIDTHS = (0.3, 0.3)
HINGE_HALF_WIDTHS = (0.3, 1.0)
#: Dimensionless energy-shaping settings that ``gain_jitter`` perturbs.
JITTERED = ("energy_gain", "overshoot", "energy_accel", "centring_frequency", "centring_damping",
            "damping_softening", "centring_band")
METHODS = ("energy", "trajopt", "mpc")
#: Controller settings an axis may sweep, per method (energy: its dimensionless scalings).
SETTINGS = {"energy": tuple(DEFAULT_SCALING), "trajopt": (), "mpc": ("period", "horizon")}
#: Push time (s) of a sweep that sweeps the push force but gives no push time.
DEFAULT_PUSH_TIME = 0.5
#: Most runs in one sweep (their rows are held in memory and printed as one JSON document).
MAX_RUNS = 100_000
#: Most distinct planning models whose basins the sweep estimates before its runs (more: each run its own).
MAX_SHARED_BASINS = 32
#: Most worker processes.
MAX_WORKERS = 256
#: Seconds to wait for a Dask scheduler given by ``address`` before giving up.
CONNECT_TIMEOUT = 10.0


class SweepError(CartPoleError):
    """Bad sweep settings (no runs, negative widths, jitter outside [0, 1), an unknown method, bad workers or axes)."""


@dataclass(frozen=True)
class Axis:
    """One swept input of a sweep description.

    Attributes
    ----------
    name : str
        ``"push_force"`` (N), ``"push_time"`` (s), ``"model_error"`` (scale), ``"start:<joint>"`` (m or rad) or
        ``"start:<joint>_rate"`` (m/s or rad/s) for a joint of the MJCF, or ``"setting:<name>"`` (a controller
        setting, :data:`SETTINGS`).
    low, high : float
        The range (``low == high`` with ``count == 1``: a fixed value).
    count : int or None
        ``count`` grid points ``linspace(low, high, count)``; None: a seeded uniform sample in ``[low, high]`` per
        run.
    """

    name: str
    low: float
    high: float
    count: int | None = None

    @property
    def random(self) -> bool:
        """True for a sampled axis, False for a grid (or a fixed value)."""
        return self.count is None

    def values(self) -> np.ndarray:
        """The grid (``count`` values); a sampled axis has none."""
        return np.linspace(self.low, self.high, int(self.count)) if self.count else np.empty(0)

    def describe(self) -> dict:
        """JSON-ready: ``name``, ``low``, ``high``, ``count`` (None: sampled)."""
        return {"name": self.name, "low": float(self.low), "high": float(self.high), "count": self.count}

    @property
    def label(self) -> str:
        """Axis label with its unit, for figures and prose."""
        if self.name == "push_force":
            return "push force [N]"
        if self.name == "push_time":
            return "push time [s]"
        if self.name == "model_error":
            return "planning model's pole mass and length scale"
        if self.name.startswith("setting:"):
            return self.name[len("setting:"):]
        return f"start {self.name[len('start:'):]}"


def axis(name: str, *values) -> Axis:
    """An :class:`Axis` from the command line's numbers: ``V`` (fixed), ``LO HI`` (seeded uniform sample) or
    ``LO HI K`` (grid of K points).

    Raises
    ------
    SweepError
        Not one, two or three finite numbers, ``K`` not a whole number >= 1, or ``LO > HI``.
    """
    try:
        v = [float(x) for x in values]
    except (TypeError, ValueError):
        raise SweepError(f"The sweep axis {name} needs numbers (V, LO HI or LO HI K); got {list(values)}.") from None
    if len(v) not in (1, 2, 3) or not all(math.isfinite(x) for x in v):
        raise SweepError(f"The sweep axis {name} takes V (fixed), LO HI (random) or LO HI K (grid) finite numbers; "
                         f"got {list(values)}.")
    if len(v) == 1:
        return Axis(name, v[0], v[0], 1)
    if v[0] > v[1]:
        raise SweepError(f"The sweep axis {name} runs from LO to HI; got LO {v[0]:g} > HI {v[1]:g}.")
    if len(v) == 2:
        return Axis(name, v[0], v[1], None)
    if not (v[2] >= 1 and v[2] == int(v[2])):
        raise SweepError(f"The sweep axis {name} needs a whole number K >= 1 of grid points; got {v[2]:g}.")
    return Axis(name, v[0], v[1], int(v[2]))


@dataclass(frozen=True)
class SweepResult:
    """What a robustness sweep found; arrays are read-only, one entry per run, in run order.

    Attributes
    ----------
    mjcf : str
        The MJCF every run used.
    starts : (n, 2 nq) array
        Start states ``[qpos, qvel]`` [m, rad, m/s, rad/s].
    success : (n,) bool array
        ``swingup_success`` of the MuJoCo rollout and the rollout replays exactly.
    time_to_upright : (n,) array
        s (``time_to_upright`` of :func:`~cartpole.validation.metrics.swingup_metrics`); NaN where the run failed.
    caught_at : (n,) array
        s, when the LQR catch took over for good; NaN if it never did.
    cart_clearance : (n,) array
        m, smallest distance to a cart limit over each run (NaN for a run that raised).
    peak_ctrl : (n,) array
        Largest |ctrl| of each run (NaN for a run that raised).
    options : tuple of dict
        The energy-shaping keyword arguments of each run (jittered settings), as passed to the controller.
    rho : float
        Catch level of the nominal planning model (the basin estimate's; NaN for mpc, which has no catch).
    seed : int
    duration : float or None
        Simulated seconds per run (energy default 10 s; None for trajopt's default, each plan + 3 s).
    half_widths : (2 nq,) array
    gain_jitter : float
    base_options : dict
    method : str
        "energy" or "trajopt".
    replays : (n,) bool array
        The run's log replays exactly with ``mj_step``.
    errors : tuple of (str or None)
        The sentence of a run that raised, else None.
    workers : int
        Processes of this machine the runs were spread over (1 when they ran on a Dask cluster, see ``address``).
    address : str or None
        The Dask scheduler the runs went to, or None.
    pushes : tuple of tuple
        Each run's pushes ``((T [s], F [N]),)`` or ``()``.
    model_errors : (n,) array
        Each run's planning-model scale (1: the MJCF's own).
    settings : tuple of dict
        Each run's swept controller settings (``{}`` when none is swept).
    axes : tuple of Axis
        The sweep description (empty: the classic start box).
    """

    mjcf: str
    starts: np.ndarray
    success: np.ndarray
    time_to_upright: np.ndarray
    caught_at: np.ndarray
    cart_clearance: np.ndarray
    peak_ctrl: np.ndarray
    options: tuple
    rho: float
    seed: int
    duration: float | None
    half_widths: np.ndarray
    gain_jitter: float
    base_options: dict = field(default_factory=dict)
    method: str = "energy"
    replays: np.ndarray | None = None
    errors: tuple = ()
    workers: int = 1
    address: str | None = None
    pushes: tuple = ()
    model_errors: np.ndarray | None = None
    settings: tuple = ()
    axes: tuple = ()

    def __post_init__(self):
        n = len(self.success)
        if self.model_errors is None:
            object.__setattr__(self, "model_errors", np.ones(n))
        if not self.pushes:
            object.__setattr__(self, "pushes", ((),) * n)
        if not self.settings:
            object.__setattr__(self, "settings", ({},) * n)
        for name in ("starts", "time_to_upright", "caught_at", "cart_clearance", "peak_ctrl", "half_widths",
                     "model_errors"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        object.__setattr__(self, "success", readonly(self.success, bool))
        rep = self.success if self.replays is None else self.replays
        object.__setattr__(self, "replays", readonly(rep, bool))
        if not self.errors:
            object.__setattr__(self, "errors", (None,) * self.n)

    @property
    def n(self) -> int:
        """Number of runs."""
        return int(len(self.success))

    @property
    def success_rate(self) -> float:
        """Fraction of runs that succeeded."""
        return float(np.mean(self.success)) if self.n else 0.0

    def _t(self):
        return self.time_to_upright[self.success]

    @property
    def t_median(self) -> float:
        """Median time to upright (s) over the successful runs (NaN if none)."""
        t = self._t()
        return float(np.median(t)) if t.size else float("nan")

    @property
    def t_max(self) -> float:
        """Largest time to upright (s) over the successful runs (NaN if none)."""
        t = self._t()
        return float(np.max(t)) if t.size else float("nan")

    def axis_values(self, ax: Axis | str, params: CartPoleParams) -> np.ndarray:
        """(n,) value of one swept input per run (``ax`` an :class:`Axis` or its name), e.g. for a figure."""
        name = ax.name if isinstance(ax, Axis) else str(ax)
        if name == "push_force":
            return np.array([sum(F for _, F in p) for p in self.pushes], float)
        if name == "push_time":
            return np.array([p[0][0] if p else np.nan for p in self.pushes], float)
        if name == "model_error":
            return np.asarray(self.model_errors, float)
        if name.startswith("setting:"):
            key = name[len("setting:"):]
            return np.array([st.get(key, np.nan) for st in self.settings], float)
        return np.asarray(self.starts, float)[:, start_index(name, params)]

    def rows(self) -> list[dict]:
        """One JSON-ready dict per run, in run order: ``run`` (index), ``start`` (2 nq numbers), ``push`` (list of
        ``[T s, F N]``), ``model_error``, ``settings`` (swept controller settings), ``success``, ``replays``,
        ``time_to_upright`` (s or None), ``caught_at`` (s or None), ``cart_clearance`` (m), ``peak_ctrl``,
        ``error`` (the sentence of a run that raised, else None)."""
        return [{"run": i, "start": self.starts[i].tolist(), "push": [list(p) for p in self.pushes[i]],
                 "model_error": float(self.model_errors[i]), "settings": dict(self.settings[i]),
                 "success": bool(self.success[i]),
                 "replays": bool(self.replays[i]), "time_to_upright": _num(self.time_to_upright[i]),
                 "caught_at": _num(self.caught_at[i]), "cart_clearance": _num(self.cart_clearance[i]),
                 "peak_ctrl": _num(self.peak_ctrl[i]), "error": self.errors[i]} for i in range(self.n)]

    def summary(self) -> dict:
        """JSON-ready summary: ``mjcf``, ``method``, ``n``, ``successes``, ``success_rate``,
        ``time_to_upright_median``, ``time_to_upright_max``, ``caught_at_median``, ``min_cart_clearance``,
        ``max_peak_ctrl``, ``failed`` (start states of the failures), ``seed``, ``duration``, ``half_widths``,
        ``gain_jitter``, ``rho``, ``workers``, ``address``."""
        ca_ok = self.caught_at[self.success]
        return {"mjcf": self.mjcf, "method": self.method, "n": self.n, "successes": int(self.success.sum()),
                "success_rate": self.success_rate, "time_to_upright_median": _num(self.t_median),
                "time_to_upright_max": _num(self.t_max),
                "caught_at_median": _num(float(np.median(ca_ok)) if ca_ok.size else np.nan),
                "min_cart_clearance": _num(np.nanmin(self.cart_clearance) if np.any(np.isfinite(
                    self.cart_clearance)) else np.nan),
                "max_peak_ctrl": _num(np.nanmax(self.peak_ctrl) if np.any(np.isfinite(self.peak_ctrl)) else np.nan),
                "failed": self.starts[~self.success].tolist(), "seed": self.seed, "duration": self.duration,
                "half_widths": self.half_widths.tolist(), "gain_jitter": self.gain_jitter, "rho": _num(self.rho),
                "workers": self.workers, "address": self.address, "axes": [a.describe() for a in self.axes]}


def _num(v):
    """A float, or None for NaN/inf (JSON has neither)."""
    return None if v is None or not np.isfinite(v) else float(v)


def _draw_starts(rng, n: int, center, half_widths) -> np.ndarray:
    c = np.asarray(center, float)
    return c + rng.uniform(-1, 1, (int(n), c.size)) * np.asarray(half_widths, float)


def sweep_starts(n: int, *, seed: int = 0, center=HANGING, half_widths=HALF_WIDTHS) -> np.ndarray:
    """Seeded start states (n, len(center)): ``center + U(-half_widths, half_widths)`` (the starts
    :func:`swingup_sweep` draws first from the same seed, before keeping the cart inside its rail)."""
    return _draw_starts(np.random.default_rng(seed), n, center, half_widths)


def start_index(name: str, params: CartPoleParams) -> int:
    """State index of a start axis ``start:<joint>`` (its position) or ``start:<joint>_rate`` (its rate).

    Raises
    ------
    SweepError
        No joint of that name in the MJCF (the sentence lists them).
    """
    key = name[len("start:"):] if name.startswith("start:") else name
    names = [j.name for j in params.joints]
    for i, j in enumerate(names):
        if key == j:
            return i
        if key == f"{j}_rate":
            return params.nq + i
    raise SweepError(f"No joint '{key}' to sweep the start of; this MJCF's are {', '.join(names)} (add _rate for "
                     "a rate).")


def check_axes(axes, params: CartPoleParams, method: str) -> tuple:
    """Validate a sweep description for this model and method; returns the axes as a tuple.

    Raises
    ------
    SweepError
        An unknown axis name, a start component of no joint, a setting the method does not have, a repeated axis, a
        push time without a push force, a model error outside (0, 10] or a bad push time.
    """
    axes = tuple(axes or ())
    seen = set()
    for a in axes:
        if not isinstance(a, Axis):
            raise SweepError(f"A sweep axis must be an Axis (cartpole.apps.sweep.axis(name, ...)); got {a!r}.")
        if a.name in seen:
            raise SweepError(f"The sweep axis {a.name} is given twice; give each input once.")
        seen.add(a.name)
        if a.name.startswith("start:"):
            start_index(a.name, params)
        elif a.name.startswith("setting:"):
            key = a.name[len("setting:"):]
            if key not in SETTINGS[method]:
                have = ", ".join(SETTINGS[method]) or "none"
                raise SweepError(f"The {method} method has no setting '{key}' to sweep (it has: {have}).")
        elif a.name == "model_error":
            for v in (a.low, a.high):
                try:
                    check_model_error(v)
                except CartPoleError as exc:
                    raise SweepError(first_line(exc) + ".") from None
        elif a.name == "push_time":
            if a.low < 0:
                raise SweepError(f"The push time starts at {a.low:g} s; give times >= 0 s.")
        elif a.name != "push_force":
            raise SweepError(f"Unknown sweep axis '{a.name}'; sweep push_force, push_time, model_error, "
                             "start:<joint>[_rate] or setting:<name>.")
    if "push_time" in seen and "push_force" not in seen:
        raise SweepError("A push time without a push force pushes nothing; add --push-force.")
    if ("push_force" in seen or "push_time" in seen) and params.slide is None:
        raise SweepError("This MJCF has no slide joint, so there is no cart to push; drop the push axes.")
    return axes


@dataclass(frozen=True)
class _Runs:
    """Every run's inputs, drawn before any run starts (see the module notes)."""

    starts: np.ndarray
    options: tuple
    pushes: tuple
    model_errors: np.ndarray
    settings: tuple


def plan_runs(params: CartPoleParams, x0, axes: tuple, n: int, seed: int, *, center, half_widths,
              gain_jitter: float = 0.0, base_options: dict | None = None) -> _Runs:
    """The runs of a sweep description, in run order (deterministic in ``seed``; see the module notes).

    Without axes: ``n`` starts ``center + U(-half_widths, half_widths)``. With axes: the grid axes' product
    (first axis slowest), times ``n`` when any axis is sampled; starts default to ``x0``."""
    rng = np.random.default_rng(seed)
    base = dict(base_options or {})
    nx = 2 * params.nq
    if not axes:
        starts = _draw_starts(rng, n, center, half_widths)
        total = int(n)
        grid_vals = {}
        random_vals = {}
    else:
        grid = [a for a in axes if not a.random]
        sampled = sorted((a for a in axes if a.random), key=lambda a: a.name)
        reps = int(n) if sampled else 1
        mesh = np.meshgrid(*[a.values() for a in grid], indexing="ij") if grid else []
        cells = int(np.prod([a.count for a in grid])) if grid else 1
        total = cells * reps
        grid_vals = {a.name: np.repeat(m.ravel(), reps) for a, m in zip(grid, mesh)}
        random_vals = {a.name: rng.uniform(a.low, a.high, total) for a in sampled}
        starts = np.tile(np.asarray(x0, float), (total, 1))
    if total > MAX_RUNS:
        raise SweepError(f"This sweep description has {total} runs, more than {MAX_RUNS}; use fewer grid points.")
    vals = {**grid_vals, **random_vals}
    for name, v in vals.items():
        if name.startswith("start:"):
            starts[:, start_index(name, params)] = v
    if params.slide is not None:
        lo, hi = params.cart_range
        starts[:, params.slide] = np.clip(starts[:, params.slide], lo + 1e-3, hi - 1e-3)
    opts, settings = [], []
    for i in range(total):
        o = dict(base)
        st = {}
        for name, v in vals.items():
            if name.startswith("setting:"):
                st[name[len("setting:"):]] = float(v[i])
        if gain_jitter > 0:
            f = rng.uniform(1 - gain_jitter, 1 + gain_jitter, len(JITTERED))
            for k, fk in zip(JITTERED, f):
                val = float(o.get(k, DEFAULT_SCALING[k])) * fk
                o[k] = min(val, 1.0) if k == "energy_accel" else val
        opts.append(o)
        settings.append(st)
    force = vals.get("push_force")
    when = vals.get("push_time")
    pushes = tuple(() if force is None or force[i] == 0 else
                   ((float(DEFAULT_PUSH_TIME if when is None else when[i]), float(force[i])),) for i in range(total))
    model_errors = np.asarray(vals.get("model_error", np.ones(total)), float)
    assert starts.shape == (total, nx)
    return _Runs(starts=starts, options=tuple(opts), pushes=pushes, model_errors=model_errors,
                 settings=tuple(settings))


def default_half_widths(params: CartPoleParams) -> np.ndarray:
    """(2 nq,) start half-widths for a model: :data:`SLIDE_HALF_WIDTHS` / :data:`HINGE_HALF_WIDTHS` per joint,
    positions first, then rates (one pole on a cart: :data:`HALF_WIDTHS`)."""
    kinds = [SLIDE_HALF_WIDTHS if j.kind == "slide" else HINGE_HALF_WIDTHS for j in params.joints]
    return np.array([k[0] for k in kinds] + [k[1] for k in kinds], float)


class _Runner:
    """One process's share of a sweep: the model (built once), each planning model (built once, on first use), the
    basin cache, and the settings every run shares.

    The same object serves the in-process loop (``workers = 1``) and each worker process (through
    :func:`_init_worker`), so a run computes the same thing wherever it runs.
    """

    def __init__(self, params: CartPoleParams, method: str, duration, catch_weights, cache: BasinCache,
                 model: CartPoleModel | None = None):
        self.params = params
        self.model = build_model(params) if model is None else model
        self.method = method
        self.duration = duration
        self.catch_weights = catch_weights
        self.cache = cache
        self.plans = {1.0: self.model}

    def plan_model(self, model_error: float) -> CartPoleModel:
        """The planning model of scale ``model_error`` (:func:`~cartpole.apps.swingup.planning_model`), built once."""
        S = float(model_error)
        if S not in self.plans:
            self.plans[S] = planning_model(self.model, S)
        return self.plans[S]

    def basin(self, model_error: float = 1.0):
        """The catch basin the runs of this planning model use (estimated once, then found in the cache): the
        energy method's LQR catch, or for trajopt the hand-over LQR that takes over when the plan ends; None for
        mpc (no catch)."""
        pm = self.plan_model(model_error)
        if self.method == "mpc":
            return None
        if self.method == "trajopt":
            from cartpole.planning.trajopt import handover_catch

            return self.cache.get(self.params, handover_catch(self.params, pm))
        from cartpole.control.switching import swingup_catch

        catch = swingup_catch(pm) if self.catch_weights is None else swingup_catch(pm, *self.catch_weights)
        return self.cache.get(self.params, catch)

    def run(self, x0, options: dict, push=(), model_error: float = 1.0, settings: dict | None = None) -> dict:
        """One swing-up from ``x0`` with its push, model error and settings: its row's numbers (``success``,
        ``replays``, ``time_to_upright``, ...)."""
        settings = dict(settings or {})
        energy = {**options, **settings} if self.method == "energy" else None
        mpc = {k: settings.get(k) for k in ("period", "horizon")} if self.method == "mpc" else {}
        try:
            res = run_swingup(self.model, method=self.method, x0=x0, duration=self.duration,
                              basin_cache=self.cache, energy_options=energy, catch_weights=self.catch_weights,
                              push=push or None, model_error=model_error, plan_model=self.plan_model(model_error),
                              **mpc)
        except CartPoleError as exc:
            return {"success": False, "replays": False, "time_to_upright": math.nan, "caught_at": math.nan,
                    "cart_clearance": math.nan, "peak_ctrl": math.nan, "rho": math.nan,
                    "error": first_line(exc) + "."}
        m = res.metrics
        replays = bool(replays_exactly(res.rollout, self.params))
        ok = bool(res.success and replays)
        tu = m["time_to_upright"]
        return {"success": ok, "replays": replays,
                "time_to_upright": float(tu) if (ok and tu is not None) else math.nan,
                "caught_at": math.nan if res.caught_at is None else float(res.caught_at),
                "cart_clearance": float(m["cart_clearance"]), "peak_ctrl": float(m["peak_ctrl"]),
                "rho": float(res.basin.rho) if res.basin is not None else math.nan, "error": None}


_WORKER: _Runner | None = None  # set in each worker process by _init_worker


def _init_worker(params, method, duration, catch_weights, cache) -> None:
    """ProcessPoolExecutor initializer: build this worker's model (once) and keep the shared settings.

    MuJoCo's warnings are dropped here (the parent loaded the same MJCF first and reported them), so a worker
    neither prints them nor writes MUJOCO_LOG.TXT into the current directory. Ctrl-C is left to the parent (which
    keeps the finished rows and stops the pool), so a worker does not die of it mid-run."""
    import signal

    import mujoco

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    global _WORKER
    mujoco.set_mju_user_warning(lambda msg: None)
    _WORKER = _Runner(params, method, duration, catch_weights, cache)


def _run_in_worker(x0, options, push=(), model_error=1.0, settings=None) -> dict:
    row = _WORKER.run(x0, options, push, model_error, settings)
    row["basins"] = len(_WORKER.cache)  # 1: the parent's estimate was reused, not redone here
    return row


def _check(method, n, workers, gain_jitter, half_widths, energy_options) -> None:
    if method not in METHODS:
        raise SweepError(f"Unknown sweep method '{method}'; choose one of {', '.join(METHODS)}.")
    if method == "mpc":
        import importlib.util

        if importlib.util.find_spec("cartpole.mpc.nmpc") is None:
            raise SweepError("The mpc method needs cartpole.mpc.nmpc (nonlinear MPC), which this installation does "
                             "not have yet; use --method trajopt or energy.")
    if not (isinstance(n, (int, np.integer)) and 1 <= n <= MAX_RUNS):
        raise SweepError(f"A sweep needs 1 to {MAX_RUNS} runs (got n = {n}).")
    if not (isinstance(workers, (int, np.integer)) and 1 <= workers <= MAX_WORKERS):
        raise SweepError(f"--workers must be 1 to {MAX_WORKERS} processes on this machine (got {workers}).")
    if not (0 <= gain_jitter < 1):
        raise SweepError(f"A sweep needs 0 <= gain_jitter < 1 (got {gain_jitter}).")
    if half_widths is not None and not np.all(np.asarray(half_widths, float) >= 0):
        raise SweepError(f"A sweep needs half-widths >= 0 (got {half_widths}).")
    if method != "energy" and (gain_jitter > 0 or energy_options):
        raise SweepError("Gain jitter and energy options perturb energy shaping; drop them or use --method energy.")


def swingup_sweep(mjcf=None, *, method: str = "energy", n: int = 20, seed: int = 0, center=None,
                  half_widths=None, gain_jitter: float = 0.0, energy_options: dict | None = None,
                  duration: float | None = None, catch_weights: tuple | None = None, basin_cache=None,
                  progress=None, workers: int = 1, address: str | None = None, done: dict | None = None,
                  on_row=None, axes=(), x0=None) -> SweepResult:
    """Run the swing-up over a sweep description (``axes``; without: ``n`` seeded starts in a box, optionally with
    jittered gains) and summarise.

    Parameters
    ----------
    mjcf : path or CartPoleParams or None
        The cart-pole (None = shipped asset).
    method : {"energy", "trajopt", "mpc"}
        Swing-up of every run (:func:`~cartpole.apps.swingup.run_swingup`).
    n : int
        Number of runs (1 to :data:`MAX_RUNS`) without axes; with axes, the number of draws per grid cell when
        any axis is sampled (ignored for a pure grid, whose size is the product of the counts).
    axes : sequence of Axis
        The sweep description (:class:`Axis`, :func:`axis`): grids and seeded samples over start components,
        the push, the model error and controller settings.
    x0 : (2 nq,) array, optional
        With axes: the start of every run where no start axis sets a component (default the hanging rest).
    seed : int
        Seed of ``numpy.random.default_rng`` for the starts (and the gain jitter).
    center : (2 nq,) array, optional
        Centre of the start box, default the model's hanging rest ``x_hanging``.
    half_widths : (2 nq,) array, optional
        Half-widths of the start box [m, rad, m/s, rad/s]; default :func:`default_half_widths` (one pole:
        ``(0.3, 0.3, 0.3, 1.0)``).
    gain_jitter : float
        In [0, 1): relative jitter of the settings in :data:`JITTERED` (0 = the gains as given); energy only.
    energy_options : dict, optional
        Energy-shaping settings (``EnergyShapingController`` keywords / ``default_gains`` scalings) every run
        starts from; default the package defaults.
    duration : float, optional
        Simulated seconds per run (default that of :func:`~cartpole.apps.swingup.run_swingup`).
    catch_weights : (Q, R), optional
        LQR weights of the catch (default :func:`~cartpole.control.switching.swingup_catch`'s), passed to
        :func:`~cartpole.apps.swingup.run_swingup`.
    basin_cache : BasinCache, optional
        Reuse basin estimates across sweeps.
    progress : callable, optional
        ``progress(fraction)`` after each run (the sweep is also a :func:`cartpole.progress.stage`).
    workers : int
        Processes to spread the runs over (1 = this process; results identical for any number).
    address : str, optional
        A running Dask distributed scheduler (``tcp://host:port``): the runs go to its workers instead (one model
        per worker process, built on its first run there); ``workers`` is then ignored. Same rows, bit for bit.
    done : dict, optional
        ``{run index: row}`` of runs already finished (a resumed sweep): they are not run again, their rows (the
        keys :meth:`_Runner.run` returns) are used as given.
    on_row : callable, optional
        ``on_row(index, start, row)`` as each run finishes, in the order they finish (the command appends it to the
        results file); ``row`` also carries the run's ``push``, ``model_error`` and ``settings``. An exception it raises (KeyboardInterrupt, say) stops the sweep; finished rows stay reported.

    Returns
    -------
    SweepResult

    Raises
    ------
    SweepError
        Bad settings. Errors of the model (an MJCF that is not a cart-pole, energy on a chain) are raised before
        any run; a run that raises on its own start is a failed row instead.
    """
    _check(method, n, workers, gain_jitter, half_widths, energy_options)
    n, workers = int(n), int(workers)
    params = mjcf if isinstance(mjcf, CartPoleParams) else read_params(mjcf)
    model = build_model(params)
    nx = 2 * params.nq
    axes = check_axes(axes, params, method)
    center = model.x_hanging if center is None else np.asarray(center, float)
    half_widths = default_half_widths(params) if half_widths is None else np.asarray(half_widths, float)
    if center.shape != (nx,) or half_widths.shape != (nx,):
        raise SweepError(f"The start box needs {nx} centre values and {nx} half-widths for this model (got "
                         f"{center.size} and {half_widths.size}).")
    if x0 is not None and not axes:
        raise SweepError("A fixed start x0 is for a sweep over axes; without axes the starts fill the start box.")
    if x0 is not None:
        from cartpole.apps.swingup import check_start
        try:
            x0 = check_start(x0, params)
        except CartPoleError as exc:
            raise SweepError(first_line(exc) + ".") from None
    base = dict(energy_options or {})
    if method == "energy":  # refuse a model energy shaping cannot drive before anything runs
        from cartpole.control.energy import EnergyShapingController
        EnergyShapingController(model, **base)
    runs = plan_runs(params, model.x_hanging if x0 is None else x0, axes, n, seed, center=center,
                     half_widths=half_widths, gain_jitter=gain_jitter, base_options=base)
    starts, opts = runs.starts, list(runs.options)
    n = len(starts)
    cache = BasinCache.on_disk() if basin_cache is None else basin_cache
    runner = _Runner(params, method, duration, catch_weights, cache, model=model)
    # each planning model's basin once, here, before the runs (and shipped to the workers in the cache); a sampled
    # model error has a planning model per run: those runs estimate their own basin where they run (in parallel)
    scales = sorted(set(runs.model_errors.tolist()))
    rhos = {}
    for S in (scales if len(scales) <= MAX_SHARED_BASINS else [1.0]):
        b = runner.basin(S)
        rhos[S] = math.nan if b is None else float(b.rho)
    rho = rhos.get(1.0, rhos[scales[0]] if scales[0] in rhos else math.nan)
    jobs = [(starts[i], opts[i], runs.pushes[i], float(runs.model_errors[i]), runs.settings[i]) for i in range(n)]
    out: list = [None] * n
    for i, row in (done or {}).items():
        if 0 <= int(i) < n:
            out[int(i)] = row
    todo = [i for i in range(n) if out[i] is None]
    workers = min(workers, max(len(todo), 1))
    where = f" on {address}" if address else (f" on {workers} workers" if workers > 1 else "")
    size = f"{len(todo)} runs" + (f" of {n}" if len(todo) < n else "") + where
    with stage(f"{method} swing-ups", size=size, callback=progress) as tick:
        counter = [0]

        def finished(i, row):
            out[i] = row
            counter[0] += 1
            if on_row is not None:
                on_row(i, starts[i], {**row, "push": runs.pushes[i], "model_error": float(runs.model_errors[i]),
                                      "settings": dict(runs.settings[i])})
            tick(counter[0] / len(todo))

        if not todo:
            pass
        elif address:
            _run_dask(address, runner, jobs, todo, finished)
        elif workers == 1:
            for i in todo:
                finished(i, runner.run(*jobs[i]))
        else:
            _run_parallel(runner, jobs, workers, todo, finished)
    return SweepResult(mjcf=params.mjcf, starts=starts, success=np.array([r["success"] for r in out], bool),
                       time_to_upright=np.array([r["time_to_upright"] for r in out], float),
                       caught_at=np.array([r["caught_at"] for r in out], float),
                       cart_clearance=np.array([r["cart_clearance"] for r in out], float),
                       peak_ctrl=np.array([r["peak_ctrl"] for r in out], float), options=tuple(opts), rho=rho,
                       seed=int(seed), duration=float(duration) if duration is not None else (
                           {"energy": ENERGY_DURATION, "mpc": MPC_DURATION}.get(method)),
                       half_widths=half_widths, gain_jitter=float(gain_jitter), base_options=base, method=method,
                       replays=np.array([r["replays"] for r in out], bool),
                       errors=tuple(r["error"] for r in out), workers=1 if address else workers,
                       address=address or None, pushes=runs.pushes, model_errors=runs.model_errors,
                       settings=runs.settings, axes=axes)


def _run_parallel(runner: _Runner, jobs, workers: int, todo, finished) -> None:
    """The runs ``todo`` on a process pool (one model per worker, built by the initializer); ``finished(i, row)``
    as each one comes back."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    ctx = multiprocessing.get_context("spawn")  # no fork of a process holding MuJoCo and CasADi threads
    init = (runner.params, runner.method, runner.duration, runner.catch_weights, runner.cache)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker, initargs=init)
    try:
        # workers start while submitting: they inherit the ignored Ctrl-C and one BLAS/OpenMP thread from birth
        with _sigint_ignored(), _one_blas_thread():
            futures = {pool.submit(_run_in_worker, *jobs[i]): i for i in todo}
        for fut in as_completed(futures):
            finished(futures[fut], fut.result())
    except BrokenProcessPool:
        raise SweepError(f"A sweep worker process died (out of memory, or killed); try fewer --workers than "
                         f"{workers}.") from None
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


#: Environment of a pool worker: one BLAS / OpenMP thread (what Dask's nanny gives its workers too). OpenBLAS's
#: threads spin after each call; two workers with two each on two cores take turns instead of running (measured:
#: a 2-worker energy sweep 10-40 % slower with the default).
_WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@contextmanager
def _one_blas_thread():
    """Processes spawned inside get :data:`_WORKER_ENV` (unless the user set those variables); this process's own
    environment is restored after the block."""
    import os

    added = {k: v for k, v in _WORKER_ENV.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for k in added:
            os.environ.pop(k, None)


@contextmanager
def _sigint_ignored():
    """Ignore Ctrl-C (SIGINT) inside the block, in the main thread (elsewhere: no change). Processes spawned inside
    inherit the ignored signal, so a Ctrl-C that reaches the whole process group cannot kill a worker while it is
    still importing (a traceback on stderr); the parent alone handles it and keeps the finished rows."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


#: Per-process cache of runners on Dask workers, keyed by the sweep's token (models built once per worker).
_RUNNERS: dict = {}
#: How many runners this process has built for Dask tasks (a test checks: once per worker, not once per run).
_BUILT = [0]


def _run_on_dask(token: str, init: tuple, x0, options, push=(), model_error=1.0, settings=None) -> dict:
    """One run on a Dask worker: the runner for ``token`` is built on this worker process's first run of the
    sweep (MuJoCo's warnings dropped, as in a pool worker) and reused by every later one."""
    runner = _RUNNERS.get(token)
    if runner is None:
        import mujoco

        mujoco.set_mju_user_warning(lambda msg: None)
        _RUNNERS.clear()  # one sweep's model per worker at a time
        runner = _RUNNERS[token] = _Runner(*init)
        _BUILT[0] += 1
    row = runner.run(x0, options, push, model_error, settings)
    row["basins"] = len(runner.cache)
    return row


def _run_dask(address: str, runner: _Runner, jobs, todo, finished) -> None:
    """The runs ``todo`` on the Dask scheduler at ``address``; ``finished(i, row)`` as each one comes back."""
    import uuid

    try:
        from distributed import Client, as_completed
    except ImportError:
        raise SweepError("--address needs Dask distributed; install it with `pip install 'dask[distributed]'`.") \
            from None
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise SweepError(f"Cannot reach a Dask scheduler at {address} ({type(exc).__name__}); start one "
                         "(`dask scheduler`, then `dask worker ADDRESS`) or give its tcp://host:port.") from None
    futures = []
    try:
        init = (runner.params, runner.method, runner.duration, runner.catch_weights, runner.cache)
        [init_f] = client.scatter([init], broadcast=True)
        token = uuid.uuid4().hex
        index = {}
        for i in todo:
            x0, options, push, model_error, settings = jobs[i]
            f = client.submit(_run_on_dask, token, init_f, np.asarray(x0), options, push, model_error, settings,
                              pure=False)
            index[f.key] = i
            futures.append(f)
        for fut in as_completed(futures, loop=client.loop):
            try:
                row = fut.result()
            except CartPoleError:
                raise
            except Exception as exc:  # a worker died (KilledWorker), or a run failed outside CartPoleError
                raise SweepError(f"A run failed on the Dask cluster at {address}: {type(exc).__name__}: "
                                 f"{first_line(exc)}.") from None
            finished(index[fut.key], row)
    finally:
        pending = [f for f in futures if not f.done()]
        if pending:
            client.cancel(pending)
        client.close()


def _seconds(value) -> str:
    """``'2.810 s'``, or ``'n/a'`` when no run reached upright (the summary holds None)."""
    return "n/a" if value is None else f"{value:.3f} s"


def summary_line(s: dict) -> str:
    """One line of prose for a :meth:`SweepResult.summary`."""
    clear = "n/a" if s["min_cart_clearance"] is None else f"{s['min_cart_clearance']:.3f} m"
    peak = "n/a" if s["max_peak_ctrl"] is None else f"{s['max_peak_ctrl']:.3f}"
    return (f"{s['mjcf']}: {s['method']} success {s['successes']}/{s['n']}, time to upright median "
            f"{_seconds(s['time_to_upright_median'])}, max {_seconds(s['time_to_upright_max'])}, "
            f"min clearance {clear}, peak |ctrl| {peak}")


def main(argv=None) -> int:
    """``python -m cartpole.apps.sweep [--mjcf P ...] [--method M] [--n N] [--seed S] [--workers W] [--address ADDR]
    [--duration S] [--jitter J] [--options JSON] [--json]``: one summary line (or a JSON list of summaries) per model.
    ``cartpole sweep`` is the command-line contract (one model, axes, rows and a CSV results file); this entry point
    is kept for scripts."""
    import argparse
    import json
    import sys

    from cartpole.progress import reporting

    ap = argparse.ArgumentParser(prog="python -m cartpole.apps.sweep", description=main.__doc__)
    ap.add_argument("--mjcf", nargs="*", default=[None], help="MJCF files (default: the shipped asset)")
    ap.add_argument("--method", choices=METHODS, default="energy")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--address", default=None, help="a Dask distributed scheduler (tcp://host:port) to run on")
    ap.add_argument("--duration", type=float, default=None, help="simulated seconds per run")
    ap.add_argument("--jitter", type=float, default=0.0, help="relative gain jitter (0 = none)")
    ap.add_argument("--options", default="{}", help="JSON dict of energy-shaping settings")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    out = []
    try:
        try:
            opts = json.loads(a.options)
        except ValueError:
            raise SweepError(f"--options {a.options!r} is not a JSON object; give e.g. '{{\"energy_gain\": 12}}'.") \
                from None
        if not isinstance(opts, dict):
            raise SweepError(f"--options {a.options!r} is not a JSON object; give e.g. '{{\"energy_gain\": 12}}'.")
        with reporting("sweep", enabled=not a.json):
            for path in a.mjcf:
                r = swingup_sweep(path, method=a.method, n=a.n, seed=a.seed, gain_jitter=a.jitter,
                                  energy_options=opts, workers=a.workers, address=a.address, duration=a.duration)
                s = r.summary()
                out.append(s)
                if not a.json:
                    print(summary_line(s))
    except CartPoleError as exc:
        print(f"python -m cartpole.apps.sweep: {first_line(exc)}.", file=sys.stderr)
        return 2
    if a.json:
        print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
