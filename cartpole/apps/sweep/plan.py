"""Sweep descriptions and run planning: the axes (:class:`Axis`, :func:`axis`), their checks, the start box, and
every run's inputs drawn before any run starts (:func:`plan_runs`).

Every run's inputs are drawn in this process from ``numpy.random.default_rng(seed)`` in a fixed order (the start
box, then each sampled axis by name, then the gain jitter), so a description and a seed give the same runs in any
order and on any number of workers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cartpole._arrays import readonly
from cartpole.control.energy import DEFAULT_SCALING
from cartpole.mpc.options import MPCOptions, mpc_grid
from cartpole.planning.options import PlanOptions
from cartpole.errors import CartPoleError, first_line
from cartpole.models import MAX_PERIOD, CartPoleParams
from cartpole.apps.swingup import check_model_error, check_start
from cartpole.sim.options import MAX_PUSH_FORCE, MAX_PUSH_TIME, LoopOptions
from cartpole.sim.rig import MAX_DELAY

#: Default start box for one pole: centre (hanging at rest) and half-widths [m, rad, m/s, rad/s].
HANGING = (0.0, np.pi, 0.0, 0.0)
HALF_WIDTHS = (0.3, 0.3, 0.3, 1.0)
#: Half-widths per joint kind for any model: (position, rate) for a slide [m, m/s] and a hinge [rad, rad/s].
SLIDE_HALF_WIDTHS = (0.3, 0.3)
HINGE_HALF_WIDTHS = (0.3, 1.0)
#: Dimensionless energy-shaping settings that ``gain_jitter`` perturbs.
JITTERED = ("energy_gain", "overshoot", "energy_accel", "centring_frequency", "centring_damping",
            "damping_softening", "centring_band")
METHODS = ("energy", "trajopt", "mpc", "supervisor")
#: The options value each method's swept settings are fields of (energy: a dict of its dimensionless scalings).
OPTIONS = {"trajopt": PlanOptions, "mpc": MPCOptions}
#: Controller settings an axis may sweep, per method: the energy shaping's dimensionless scalings, the planner's and
#: the NMPC's numeric option fields by name (:meth:`cartpole.options.StageOptions.scalar_names`).
#: The closed loop's fields a sweep may vary for every method (:class:`~cartpole.sim.options.LoopOptions`): the rig's
#: period and delay (rounded to whole physics steps per run), sensor noise, encoder resolution, process noise.
LOOP_SETTINGS = ("period", "delay", "sensor_noise", "encoder_cpr", "encoder_resolution", "process_noise")
SETTINGS = {"energy": tuple(DEFAULT_SCALING) + LOOP_SETTINGS, "trajopt": PlanOptions.scalar_names() + LOOP_SETTINGS,
            "mpc": tuple(k for k in MPCOptions.scalar_names() if k != "period") + LOOP_SETTINGS}
#: Push time (s) of a sweep that sweeps the push force but gives no push time.
DEFAULT_PUSH_TIME = 0.5
#: Most runs in one sweep (their rows are held in memory and printed as one JSON document).
MAX_RUNS = 100_000
#: Most distinct planning models whose basins the sweep estimates before its runs (more: each run its own).
MAX_SHARED_BASINS = 32
#: Most worker processes.
MAX_WORKERS = 256


class SweepError(CartPoleError):
    """Bad sweep settings (no runs, negative widths, jitter outside [0, 1), an unknown method, bad workers or axes)."""


@dataclass(frozen=True)
class SweepRuns:
    """Which runs a sweep makes (its description; :func:`plan_runs` draws them): a classic start box of ``n`` seeded
    starts, or the grid and samples of ``axes``.

    Attributes
    ----------
    n : int
        Runs without axes (1 to :data:`MAX_RUNS`); with axes, the draws per grid cell when any axis is sampled
        (ignored for a pure grid, whose size is the product of the counts).
    seed : int
        Seed of ``numpy.random.default_rng`` for the starts, the sampled axes and the gain jitter.
    axes : tuple of Axis
        Grids and seeded samples over start components, the push, the model error and controller settings
        (:class:`Axis`, :func:`axis`).
    x0 : (2 nq,) array or None
        With axes: the start of every run where no start axis sets a component (default the hanging rest).
    center : (2 nq,) array or None
        Centre of the start box [m, rad, m/s, rad/s], default the model's hanging rest ``x_hanging``.
    half_widths : (2 nq,) array or None
        Half-widths of the start box [m, rad, m/s, rad/s]; default :func:`default_half_widths`.
    gain_jitter : float
        In [0, 1): relative jitter of the settings in :data:`JITTERED`; energy only.
    """

    n: int = 20
    seed: int = 0
    axes: tuple = ()
    x0: object = None
    center: object = None
    half_widths: object = None
    gain_jitter: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "axes", tuple(self.axes or ()))
        for name in ("x0", "center", "half_widths"):
            value = getattr(self, name)
            if value is not None:
                try:
                    object.__setattr__(self, name, readonly(np.asarray(value, float).ravel()))
                except (TypeError, ValueError):
                    raise SweepError(f"SweepRuns.{name} must be numbers [m, rad, m/s, rad/s]; got {value!r}.") \
                        from None


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
        Not one, two or three finite numbers, ``K`` not a whole number from 1 to :data:`MAX_RUNS`, or
        ``LO > HI``.
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
    if v[2] > MAX_RUNS:
        raise SweepError(f"The sweep axis {name} has {v[2]:g} grid points, more than a sweep's {MAX_RUNS} runs; "
                         "give fewer points.")
    return Axis(name, v[0], v[1], int(v[2]))


def check_settings(method: str, n, workers, gain_jitter: float, half_widths=None, energy_options=None, *,
                   seed=0) -> None:
    """Refuse sweep settings that no run could use, before anything runs.

    Parameters
    ----------
    method : str
        One of :data:`METHODS` (``mpc`` only where :mod:`cartpole.mpc.nmpc` is installed).
    n : int
        Runs (or draws per grid cell), 1 to :data:`MAX_RUNS`.
    workers : int
        Processes of this machine, 1 to :data:`MAX_WORKERS`.
    gain_jitter : float
        Relative jitter in [0, 1); energy only.
    half_widths : (2 nq,) array, optional
        Start-box half-widths [m, rad, m/s, rad/s], each >= 0.
    energy_options : dict, optional
        Energy-shaping settings; energy only.
    seed : int
        Seed of the starts, 0 to 2**63 - 1 (numpy's ``default_rng`` takes no negative seed).

    Raises
    ------
    SweepError
        The first setting out of range, in one sentence.
    """
    if method not in METHODS:
        raise SweepError(f"Unknown sweep method '{method}'; choose one of {', '.join(METHODS)}.")
    if not (isinstance(n, (int, np.integer)) and 1 <= n <= MAX_RUNS):
        raise SweepError(f"A sweep needs 1 to {MAX_RUNS} runs (got n = {n}).")
    if not (isinstance(workers, (int, np.integer)) and 1 <= workers <= MAX_WORKERS):
        raise SweepError(f"`workers` must be 1 to {MAX_WORKERS} processes on this machine (got {workers}).")
    if not (isinstance(seed, (int, np.integer)) and 0 <= seed < 2**63):
        raise SweepError(f"The `seed` must be a whole number from 0 to 2**63 - 1 (got {seed}).")
    if not (0 <= gain_jitter < 1):
        raise SweepError(f"A sweep needs 0 <= gain_jitter < 1 (got {gain_jitter}).")
    if half_widths is not None and not np.all(np.asarray(half_widths, float) >= 0):
        raise SweepError(f"A sweep needs half-widths >= 0 (got {half_widths}).")
    if method != "energy" and (gain_jitter > 0 or energy_options):
        raise SweepError("Gain jitter and energy options perturb energy shaping; drop them or use `method='energy'`.")


def _draw_starts(rng, n: int, center, half_widths) -> np.ndarray:
    c = np.asarray(center, float)
    return c + rng.uniform(-1, 1, (int(n), c.size)) * np.asarray(half_widths, float)


def sweep_starts(n: int, *, seed: int = 0, center=HANGING, half_widths=HALF_WIDTHS) -> np.ndarray:
    """Seeded start states (n, len(center)): ``center + U(-half_widths, half_widths)`` (the starts
    :func:`~cartpole.apps.sweep.swingup_sweep` draws first from the same seed, before keeping the cart inside its
    rail)."""
    return _draw_starts(np.random.default_rng(seed), n, center, half_widths)


def default_half_widths(params: CartPoleParams) -> np.ndarray:
    """(2 nq,) start half-widths for a model: :data:`SLIDE_HALF_WIDTHS` / :data:`HINGE_HALF_WIDTHS` per joint,
    positions first, then rates (one pole on a cart: :data:`HALF_WIDTHS`)."""
    kinds = [SLIDE_HALF_WIDTHS if j.kind == "slide" else HINGE_HALF_WIDTHS for j in params.joints]
    return np.array([k[0] for k in kinds] + [k[1] for k in kinds], float)


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


def _check_component(x, i: int, params: CartPoleParams, name: str) -> None:
    """Refuse start component ``i`` of ``x`` as :func:`cartpole.apps.swingup.check_start` would (the others are
    taken inside their ranges)."""
    x = np.array(x, float)
    for k, j in enumerate(params.joints):  # the other positions at a valid point of their range
        if k != i:
            lo, hi = (float(v) for v in j.range)
            x[k] = min(max(0.0, lo), hi)
            if not lo < x[k] < hi:
                x[k] = 0.5 * (lo + hi)
    try:
        check_start(x, params)
    except CartPoleError as exc:
        raise SweepError(f"The sweep axis {name} reaches {x[i]:g}: {first_line(exc)}.") from None


def check_axes(axes, params: CartPoleParams, method: str, duration: float | None = None) -> tuple:
    """Validate a sweep description for this model and method; returns the axes as a tuple.

    Raises
    ------
    SweepError
        An unknown axis name, a start component of no joint or outside what ``cartpole swingup`` accepts (a cart
        beyond its rail), a setting the method does not have, a repeated axis, a push time without a push force,
        a model error outside [0.1, 10], a push time after the run ends (``duration``, s, when given) or a push
        force beyond :data:`~cartpole.sim.options.MAX_PUSH_FORCE`.
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
            i = start_index(a.name, params)
            for v in (a.low, a.high):  # each end as swingup would check it: a start is refused, never clamped
                x = np.zeros(2 * params.nq)
                x[i] = v
                _check_component(x, i, params, a.name)
        elif a.name.startswith("setting:"):
            key = a.name[len("setting:"):]
            if key not in SETTINGS[method]:
                have = ", ".join(SETTINGS[method]) or "none"
                raise SweepError(f"The {method} method has no setting '{key}' to sweep (it has: {have}).")
            if key in LOOP_SETTINGS:
                h = float(params.timestep)
                limits = {"period": (0.5 * h, MAX_PERIOD), "delay": (0.0, MAX_DELAY)}
                if key in limits:  # rounded to whole steps: each end must round to what it says, within limits
                    lo, hi = limits[key]
                    for v in (a.low, a.high):
                        if not (math.isfinite(v) and lo <= v <= hi):
                            raise SweepError(f"The sweep axis {a.name} reaches {v:g}: give {key}s from "
                                             f"{max(lo, h if key == 'period' else 0.0):g} to {hi:g} s (whole "
                                             f"{h:g} s MJCF steps).")
                for v in (a.low, a.high):
                    try:
                        LoopOptions().replace(**{key: round(v) if key == "encoder_cpr" else v})
                    except CartPoleError as exc:
                        raise SweepError(f"The sweep axis {a.name} reaches {v:g}: {first_line(exc)}.") from None
            elif method in OPTIONS:
                for v in (a.low, a.high):  # both ends of the axis must make a valid options value
                    try:
                        opts = OPTIONS[method]().replace(**{key: v})
                        if method == "mpc":
                            mpc_grid(opts, params.timestep)
                    except CartPoleError as exc:
                        raise SweepError(f"The sweep axis {a.name} reaches {v:g}: {first_line(exc)}.") from None
        elif a.name == "model_error":
            for v in (a.low, a.high):
                try:
                    check_model_error(v)
                except CartPoleError as exc:
                    raise SweepError(first_line(exc) + ".") from None
        elif a.name == "push_time":
            if a.low < 0:
                raise SweepError(f"The push time starts at {a.low:g} s; give times >= 0 s.")
            end = MAX_PUSH_TIME if duration is None else float(duration)
            if not (a.high < end or (duration is None and a.high <= end)):
                raise SweepError(f"The push time reaches {a.high:g} s, "
                                 + (f"after the runs end at {end:g} s, so it would never act; give times before the "
                                    "end or a longer duration." if duration is not None else
                                    f"beyond the {end:g} s limit; give earlier times."))
        elif a.name == "push_force":
            if max(abs(a.low), abs(a.high)) > MAX_PUSH_FORCE:
                raise SweepError(f"The push force reaches {max(abs(a.low), abs(a.high)):g} N, beyond the "
                                 f"{MAX_PUSH_FORCE:g} N limit; give smaller forces.")
        else:
            raise SweepError(f"Unknown sweep axis '{a.name}'; sweep push_force, push_time, model_error, "
                             "start:<joint>[_rate] or setting:<name>.")
    if "push_time" in seen and "push_force" not in seen:
        raise SweepError("A push time without a push force pushes nothing; add a push_force axis.")
    if ("push_force" in seen or "push_time" in seen) and params.slide is None:
        raise SweepError("This MJCF has no slide joint, so there is no cart to push; drop the push axes.")
    return axes


def total_runs(axes, n: int) -> int:
    """Runs of a description: ``n`` without axes; with axes the grid's cells, times ``n`` when any axis is
    sampled."""
    axes = tuple(axes or ())
    if not axes:
        return int(n)
    cells = 1
    for a in axes:
        if not a.random:
            cells *= a.count
    return cells * (int(n) if any(a.random for a in axes) else 1)


@dataclass(frozen=True)
class PlannedRuns:
    """Every run's inputs, drawn before any run starts, one entry per run in run order.

    Attributes
    ----------
    starts : (n, 2 nq) array
        Start states ``[qpos, qvel]`` [m, rad, m/s, rad/s].
    options : tuple of dict
        Energy-shaping keywords of each run (the base options, jittered).
    pushes : tuple of tuple
        Each run's pushes ``((T [s], F [N]),)`` or ``()``.
    model_errors : (n,) array
        Each run's planning-model scale (1: the MJCF's own).
    settings : tuple of dict
        Each run's swept controller settings.
    """

    starts: np.ndarray
    options: tuple
    pushes: tuple
    model_errors: np.ndarray
    settings: tuple

    def __post_init__(self):
        object.__setattr__(self, "starts", readonly(self.starts))
        object.__setattr__(self, "model_errors", readonly(self.model_errors))

    def job(self, i: int) -> tuple:
        """Run ``i``'s inputs ``(x0, options, push, model_error, settings)``, as
        :meth:`~cartpole.apps.sweep.executors.Runner.run` takes them."""
        return (self.starts[i], self.options[i], self.pushes[i], float(self.model_errors[i]), self.settings[i])


def plan_runs(params: CartPoleParams, x0, axes: tuple, n: int, seed: int, *, center, half_widths,
              gain_jitter: float = 0.0, base_options: dict | None = None) -> PlannedRuns:
    """The runs of a sweep description, in run order (deterministic in ``seed``; see the module notes).

    Without axes: ``n`` starts ``center + U(-half_widths, half_widths)`` ((2 nq,) each, [m, rad, m/s, rad/s]).
    With axes: the grid axes' product (first axis slowest), times ``n`` when any axis is sampled; starts default
    to ``x0`` ((2 nq,)). Cart positions are kept 1 mm inside the rail, hinge angles inside their finite ranges (a
    start box centred on a range's edge, hanging on a hinge limited to +-3.14159, is cut by the range).

    Raises
    ------
    SweepError
        More than :data:`MAX_RUNS` runs.
    """
    if total_runs(axes, n) > MAX_RUNS:  # before any array of that size is made
        raise SweepError(f"This sweep description has {total_runs(axes, n)} runs, more than {MAX_RUNS}; use fewer "
                         "grid points.")
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
    for i, j in enumerate(params.joints):  # a hinge start MuJoCo's limit would push back at once: on the range
        if j.kind == "hinge":
            starts[:, i] = np.clip(starts[:, i], *(float(v) for v in j.range))
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
    return PlannedRuns(starts=starts, options=tuple(opts), pushes=pushes, model_errors=model_errors,
                       settings=tuple(settings))
