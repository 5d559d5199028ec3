"""What a sweep found and how it is kept: :class:`SweepResult` (one entry per run, its rows and summary), the
sweep's id (:func:`sweep_id`), and the CSV results file: its columns (:func:`header`), one line per run
(:func:`csv_row`), appended and flushed as each run finishes (:class:`ResultsFile`) and read back to resume
(:func:`read_done`).

The results file: a header, then one line per finished run in the order runs finish (rewritten in run order when
the sweep ends); floats written with ``repr`` (the same doubles read back), empty cells for None/NaN. Its
``sweep`` column is the description's id, which a resumed sweep must match.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cartpole._arrays import readonly
from cartpole._files import InputFileError, exclusive_lock, output_error, read_bounded, short
from cartpole.codegen import private_cache_dir
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleParams, read_params
from cartpole.validation.metrics import failure_reason
from cartpole.apps.sweep.plan import Axis, SweepError, SweepRuns, start_index


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
        "energy", "trajopt" or "mpc".
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
    objective : str or None
        The trajopt objective every run planned with (None: the planner's default).
    returns : (n,) array or None
        With a dm_control task as ``objective``: each run's dm_control return (the exact reward summed over the
        task's episode, :func:`cartpole.validation.metrics.dmc_return`; NaN for a run that raised); else None.
    return_steps : (n,) array or None
        The control steps each return sums (the task's 1000; NaN for a run that raised).
    mpc : dict
        mpc: the MPC settings every run had beyond its defaults (``horizon``, ``seed_plan``; empty: none).
    diverged_at : (n,) array or None
        s: when MuJoCo warned that each run blew up and reset it (a diverged run is never a success); NaN for a run
        that did not diverge (None: none did).
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
    diverged_at: np.ndarray | None = None
    objective: str | None = None
    returns: np.ndarray | None = None
    uptime: np.ndarray | None = None
    knockdowns: np.ndarray | None = None
    swingups: np.ndarray | None = None
    return_steps: np.ndarray | None = None
    mpc: dict = field(default_factory=dict)

    def __post_init__(self):
        n = len(self.success)
        if self.diverged_at is None:
            object.__setattr__(self, "diverged_at", np.full(n, np.nan))
        if self.model_errors is None:
            object.__setattr__(self, "model_errors", np.ones(n))
        if not self.pushes:
            object.__setattr__(self, "pushes", ((),) * n)
        if not self.settings:
            object.__setattr__(self, "settings", ({},) * n)
        for name in ("starts", "time_to_upright", "caught_at", "cart_clearance", "peak_ctrl", "half_widths",
                     "model_errors", "diverged_at"):
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
        ``diverged`` (bool), ``diverged_at`` (s or None), ``time_to_upright`` (s or None), ``caught_at`` (s or None), ``cart_clearance`` (m), ``peak_ctrl``,
        ``error`` (the sentence of a run that raised, else None); with returns also ``return`` and ``return_steps``
        (None where the run raised)."""
        extra = [{} if self.returns is None else
                 {"return": _num(self.returns[i]),
                  "return_steps": None if self.return_steps is None or not np.isfinite(self.return_steps[i])
                  else int(self.return_steps[i])} for i in range(self.n)]
        if self.uptime is not None:
            for i in range(self.n):
                extra[i].update({"uptime": _num(self.uptime[i]), "knockdowns": _count(self.knockdowns[i]),
                                 "swingups": _count(self.swingups[i])})
        return [{**extra[i], "run": i, "start": self.starts[i].tolist(), "push": [list(p) for p in self.pushes[i]],
                 "model_error": float(self.model_errors[i]), "settings": dict(self.settings[i]),
                 "success": bool(self.success[i]),
                 "replays": bool(self.replays[i]), "diverged": bool(np.isfinite(self.diverged_at[i])),
                 "diverged_at": _num(self.diverged_at[i]), "time_to_upright": _num(self.time_to_upright[i]),
                 "caught_at": _num(self.caught_at[i]), "cart_clearance": _num(self.cart_clearance[i]),
                 "peak_ctrl": _num(self.peak_ctrl[i]), "error": self.errors[i]} for i in range(self.n)]

    def summary(self) -> dict:
        """JSON-ready summary: ``mjcf``, ``method``, ``n``, ``successes``, ``success_rate``,
        ``time_to_upright_median``, ``time_to_upright_max``, ``caught_at_median``, ``min_cart_clearance``,
        ``max_peak_ctrl``, ``failed`` (start states of the failures), ``seed``, ``duration``, ``half_widths``,
        ``gain_jitter``, ``rho``, ``workers``, ``address``, ``axes``, ``objective``, ``mpc``; with a dm_control task's
        returns also ``mean_return`` (over the runs that have one), ``returns`` (per run, None where a run raised)
        and ``return_runs`` (how many runs the mean is over)."""
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
                "workers": self.workers, "address": self.address, "axes": [a.describe() for a in self.axes],
                "objective": self.objective, "mpc": dict(self.mpc), **self._return_summary(),
                **self._uptime_summary()}

    def _uptime_summary(self) -> dict:
        """A knocked sweep's ``uptime_mean`` (over every run: a run that raised counts 0), ``knockdowns_total`` and
        ``swingups_total``; empty otherwise."""
        if self.uptime is None:
            return {}
        return {"uptime_mean": _num(float(np.mean(self.uptime)) if self.n else np.nan),
                "knockdowns_total": int(np.nansum(self.knockdowns)), "swingups_total": int(np.nansum(self.swingups))}

    def _return_summary(self) -> dict:
        if self.returns is None:
            return {}
        r = np.asarray(self.returns, float)
        ok = np.isfinite(r)
        return {"mean_return": _num(float(np.mean(r[ok])) if ok.any() else np.nan),
                "returns": [_num(v) for v in r], "return_runs": int(ok.sum())}


def _count(v):
    """``v`` as an int, None for NaN."""
    return None if v is None or not np.isfinite(v) else int(v)


def _num(v):
    """A float, or None for NaN/inf (JSON has neither)."""
    return None if v is None or not np.isfinite(v) else float(v)


def _seconds(value) -> str:
    """``'2.810 s'``, or ``'n/a'`` when no run reached upright (the summary holds None)."""
    return "n/a" if value is None else f"{value:.3f} s"


def summary_line(s: dict) -> str:
    """One line of prose for a :meth:`SweepResult.summary` (times in s, clearance in m)."""
    clear = "n/a" if s["min_cart_clearance"] is None else f"{s['min_cart_clearance']:.3f} m"
    peak = "n/a" if s["max_peak_ctrl"] is None else f"{s['max_peak_ctrl']:.3f}"
    return (f"{s['mjcf']}: {s['method']} success {s['successes']}/{s['n']}, time to upright median "
            f"{_seconds(s['time_to_upright_median'])}, max {_seconds(s['time_to_upright_max'])}, "
            f"min clearance {clear}, peak |ctrl| {peak}")


def _bounds_not_the_files(params: CartPoleParams) -> dict:
    """The ctrl ranges and cart range of ``params`` where they are not those of its MJCF file (empty when they are,
    or when there is no file to compare with)."""
    if not params.mjcf:
        return {}
    try:
        file = read_params(params.mjcf)
    except CartPoleError:
        return {}
    out = {}
    if not np.array_equal(np.asarray(file.ctrl_range, float), np.asarray(params.ctrl_range, float)):
        out["ctrl_range"] = np.asarray(params.ctrl_range, float).tolist()
    if not np.array_equal(np.asarray(file.cart_range, float), np.asarray(params.cart_range, float)):
        out["cart_range"] = np.asarray(params.cart_range, float).tolist()
    return out


def sweep_id(params: CartPoleParams, *, method: str, runs: SweepRuns, loop=None, objective: str | None = None,
             mpc: dict | None = None) -> str:
    """12 hex digits naming the sweep description: the ``sweep`` column of every row, which a resumed sweep must
    match.

    Parameters
    ----------
    params : CartPoleParams
        The MJCF (its path and content are in the description).
    method : str
        The swing-up method.
    runs : SweepRuns
        Which runs: ``n``, ``seed``, ``gain_jitter``, ``axes`` and the fixed start ``x0`` (nx,) ``[qpos, qvel]``.
    loop : LoopOptions, optional
        The loop every run has: its ``duration`` (s, None: the method's own) and, when it is not the perfect loop,
        the rest of it (a description without a rig keeps the id it had before rigs existed).
    objective : str, optional
        The plan's or the MPC's objective by name (a sweep without one keeps its id).
    mpc : dict, optional
        The MPC's settings that differ from the defaults (likewise).

    Returns
    -------
    str
        The first 12 hex digits of the SHA-256 of the description. (A description without axes keeps the id it had
        before axes existed.)
    """
    duration = None if loop is None else loop.duration
    loop = None if loop is None else loop.replace(duration=None)
    n, seed, jitter, axes, x0 = runs.n, runs.seed, runs.gain_jitter, runs.axes, runs.x0
    try:
        digest = hashlib.sha256(Path(params.mjcf).read_bytes()).hexdigest()
    except OSError:
        digest = ""
    desc = {"mjcf": str(params.mjcf), "mjcf_sha256": digest, "method": method, "n": int(n), "seed": int(seed),
            "duration": duration, "jitter": float(jitter)}
    if axes:
        desc["axes"] = [a.describe() for a in axes]
    if x0 is not None:
        desc["x0"] = [float(v) for v in x0]
    if loop is not None and loop != type(loop)():
        desc["loop"] = loop.as_dict()
    if objective is not None:  # (a sweep without one keeps its id)
        desc["objective"] = str(objective)
    if mpc:  # likewise one with the MPC's default settings
        desc["mpc"] = {k: mpc[k] for k in sorted(mpc)}
    bounds = _bounds_not_the_files(params)
    if bounds:  # ctrl or cart bounds given or defaulted (cartpole.models.planning_limits); the file's keep the id
        desc["bounds"] = bounds
    return hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:12]


def header(params: CartPoleParams, settings=(), *, returns: bool = False, knocked: bool = False) -> list[str]:
    """The CSV header: ``sweep``, ``run``, the start (columns named by the MJCF's joints), the push
    (``push_time_s``, empty without a push, and ``push_force_N``), ``model_error``, one ``setting_<name>`` per
    swept controller setting, the outcome; with ``returns`` (a dm_control task's sweep) ``return`` and
    ``return_steps``; with ``knocked`` (a sweep with knockdowns or throws) ``uptime``, ``knockdowns`` and ``swingups``
    last."""
    names = [j.name for j in params.joints]
    return (["sweep", "run"] + [f"x0_{n}" for n in names] + [f"x0_{n}_rate" for n in names]
            + ["push_time_s", "push_force_N", "model_error"] + [f"setting_{k}" for k in settings]
            + ["success", "replays", "diverged", "diverged_at_s", "time_to_upright_s", "caught_at_s", "cart_clearance_m", "peak_ctrl", "failure",
               "error"] + (["return", "return_steps"] if returns else [])
            + (["uptime", "knockdowns", "swingups"] if knocked else []))


def failure(row: dict) -> str:
    """Why a run failed, in a few words ('' for a success)."""
    if row["success"]:
        return ""
    if row["error"]:
        return "raised"
    if not row.get("diverged") and not row["replays"]:
        return "log does not replay"
    return failure_reason(row)


def _cell(v):
    return "" if v is None else v


def csv_row(sid: str, i: int, start, row: dict, settings=(), *, returns: bool = False, knocked: bool = False) -> list:
    """The CSV fields (:func:`header`'s columns) of run ``i`` of sweep ``sid``: its ``start`` ((2 nq,)), and
    ``row`` (a runner's row or one of :meth:`SweepResult.rows`, with ``push``, ``model_error`` and ``settings``);
    ``returns`` and ``knocked`` as for :func:`header`."""
    num = {k: (None if row.get(k) is None or not math.isfinite(row[k]) else float(row[k]))
           for k in ("diverged_at", "time_to_upright", "caught_at", "cart_clearance", "peak_ctrl")}
    r = {**row, **num}
    push = list(row.get("push") or ())
    when = repr(float(push[0][0])) if push else ""
    force = repr(float(sum(F for _, F in push)))
    st = row.get("settings") or {}
    return [sid, int(i), *[repr(float(v)) for v in start], when, force, repr(float(row.get("model_error", 1.0))),
            *[repr(float(st[k])) if k in st else "" for k in settings], bool(r["success"]), bool(r["replays"]),
            num["diverged_at"] is not None, _cell(num["diverged_at"]),
            *[_cell(num[k]) for k in ("time_to_upright", "caught_at", "cart_clearance", "peak_ctrl")],
            failure(r), _cell(r["error"])] + ([_cell(_finite(row.get("return"))), _cell(_finite(row.get("return_steps")))]
                                              if returns else []) + (
        [_cell(_finite(row.get(k))) for k in ("uptime", "knockdowns", "swingups")] if knocked else [])


def _finite(v):
    """``v`` as a float, None for None or NaN."""
    return None if v is None or not math.isfinite(float(v)) else float(v)


#: The numeric outcome columns of a results row (empty: None / NaN).
_OUTCOME_NUMBERS = ("time_to_upright_s", "caught_at_s", "cart_clearance_m", "peak_ctrl")


def parse_row(line: dict) -> dict | None:
    """A runner row (the keys :meth:`~cartpole.apps.sweep.executors.Runner.run` returns) from one CSV line read as
    ``{column: text}``, checked field by field; None when any field is not what a finished run writes (then the run
    is not finished and runs again): ``success``, ``replays`` and ``diverged`` ``True`` or ``False`` (a success that
    does not replay, or diverged, is no success), the start, push, model error and settings finite numbers (push time may be empty), the
    outcome numbers finite or empty, and a success with no error."""
    def f(text):
        if text == "":
            return math.nan
        v = float(text)
        if not math.isfinite(v):
            raise ValueError(text)
        return v

    try:
        flags = {k: {"True": True, "False": False}[line[k]] for k in ("success", "replays", "diverged")}
        for k, text in line.items():
            if k.startswith(("x0_", "setting_")) or k in ("push_force_N", "model_error"):
                if text == "" and k.startswith("setting_"):
                    continue
                if not math.isfinite(float(text)):
                    raise ValueError(k)
        if line["push_time_s"] != "":
            f(line["push_time_s"])
        nums = {k: f(line[k]) for k in _OUTCOME_NUMBERS}
        diverged_at = f(line["diverged_at_s"])
    except (KeyError, ValueError, TypeError):
        return None
    if flags["success"] and (not flags["replays"] or flags["diverged"] or line["error"]
                             or math.isnan(nums["time_to_upright_s"])):
        return None
    extra = {}
    if "return" in line:
        try:
            extra = {"return": f(line["return"]), "return_steps": f(line["return_steps"])}
        except (KeyError, ValueError):
            return None
    if "uptime" in line:
        try:
            extra.update({k: f(line[k]) for k in ("uptime", "knockdowns", "swingups")})
        except (KeyError, ValueError):
            return None
    return {**flags, **extra, "diverged_at": diverged_at, "time_to_upright": nums["time_to_upright_s"],
            "caught_at": nums["caught_at_s"], "cart_clearance": nums["cart_clearance_m"], "peak_ctrl": nums["peak_ctrl"], "rho": math.nan,
            "error": line["error"] or None}


#: Largest results file read back to resume, bytes (:data:`~cartpole.apps.sweep.plan.MAX_RUNS` rows of about a
#: kilobyte each fit many times over).
MAX_RESULTS_BYTES = 256 * 2**20
#: Largest run index read back from a results file (the sweep itself keeps only its own runs).
MAX_READ = 10**9


def read_done(path: Path, head: list[str], sid: str, n: int = MAX_READ) -> dict:
    """``{run: row}`` of the runs ``0 <= run < n`` already in the results file ``path`` for the sweep ``sid``
    (none when the file does not exist; a last line a crash cut short is not counted; a row whose fields are not
    what a finished run writes, :func:`parse_row`, is not counted either, and the run is done again).

    Raises
    ------
    SweepError
        The file cannot be read (a FIFO, a device, more than :data:`MAX_RESULTS_BYTES`, not UTF-8), holds
        another sweep's rows (or another header), or a row whose run index is not one of this sweep's
        ``0 .. n - 1``, in one sentence.
    """
    path = Path(path)
    if not os.path.lexists(path):
        return {}
    try:  # by kind and with a bound: a FIFO, /dev/zero or a huge file is refused, not read whole
        data = read_bounded(path, MAX_RESULTS_BYTES, what="Results file", flag="`results`")
    except InputFileError as exc:
        raise SweepError(f"Cannot resume from {short(path)}: it {exc.reason}; move it away or drop `resume`.") \
            from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise SweepError(f"Cannot resume from {short(path)}: it is not a text CSV file (not UTF-8); move it away or "
                         "drop `resume`.") from None
    lines = text.splitlines()
    if not lines:
        return {}
    if not text.endswith("\n"):
        lines = lines[:-1]  # a row cut short by a crash: run it again
    reader = csv.reader(io.StringIO("\n".join(lines) + "\n"))
    first = next(reader, [])
    if first != head:
        raise SweepError(f"Cannot resume from {short(path)}: its columns are not this sweep's; move it away or drop "
                         "`resume`.")
    done = {}
    for fields in reader:
        if len(fields) != len(head):
            continue
        line = dict(zip(head, fields))
        if line["sweep"] != sid:
            raise SweepError(f"Cannot resume from {short(path)}: it holds sweep {line['sweep']}, not this one "
                             f"({sid}: other `method`, `n`, `seed`, `duration`, `gain_jitter` or MJCF); give the "
                             "same settings, another results file (`results`), or drop `resume`.")
        try:
            i = int(line["run"])
        except ValueError:
            i = None
        if i is None or not 0 <= i < n:
            raise SweepError(f"Cannot resume from {short(path)}: it holds a row for run {short(line['run'], 20)!r}, "
                             f"and this sweep has runs 0 to {n - 1}; move the file away or drop `resume`.")
        row = parse_row(line)
        if row is not None:  # a row with a field a finished run never writes: not finished, run again
            done[i] = row
        else:
            done.pop(i, None)
    return done


def results_lock(path: Path):
    """The exclusive lock (:func:`cartpole._files.exclusive_lock`) a sweep holds on its results file ``path`` while it
    reads, appends and rewrites it, so two sweeps into one ``--out`` cannot both write one file: the second is
    refused in one sentence. The lock file is kept in the user cache directory (``locks/``, keyed by the file's
    absolute path), not beside the results, so ``--out`` holds only the sweep's outputs; sweeps of two users into
    one ``--out`` are therefore not serialised."""
    where = str(Path(path).expanduser().resolve())
    key = hashlib.sha256(where.encode()).hexdigest()[:24]
    return exclusive_lock(private_cache_dir() / "locks" / f"sweep-{key}.lock", f"The results file {short(where)}",
                          "wait for that sweep to finish or give another --out")


class ResultsFile:
    """The results file, opened for appending: one CSV line written, flushed and synced as each run finishes, so an
    interrupt or a crash keeps every finished run.

    Parameters
    ----------
    path : Path
        The CSV file (its directory is created).
    head : list of str
        :func:`header`; written first when the file is new, empty or ``fresh``.
    fresh : bool
        Start the file anew (a sweep not resumed); else append, dropping a last line a crash cut short.

    Raises
    ------
    OutputError
        The file cannot be written.
    """

    def __init__(self, path: Path, head: list[str], fresh: bool):
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            new = fresh or not self.path.exists() or self.path.stat().st_size == 0
            if not new and not self.path.read_bytes().endswith(b"\n"):  # drop a row a crash cut short
                data = self.path.read_bytes()
                self.path.write_bytes(data[:data.rfind(b"\n") + 1])
            self.fh = open(self.path, "w" if new else "a", newline="")
        except OSError as exc:
            raise output_error(self.path, exc) from None
        self.writer = csv.writer(self.fh, lineterminator="\n")
        if new:
            self.write(head)

    def write(self, fields) -> None:
        """Append one line and make it durable (flush and fsync) before returning."""
        self.writer.writerow(fields)
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def close(self) -> None:
        """Close the file (again: no effect)."""
        self.fh.close()
