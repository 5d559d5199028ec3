"""Logged runs for system identification: the toolkit's rollout JSON or a CSV of encoder readings.

The CSV format (what ``cartpole excite`` writes and a rig's own logger can write): a header with ``t`` (s), one
column per joint position named after the MJCF's joint (m on slides, rad on hinges), optional ``<joint>_vel``
columns (m/s, rad/s), one column per actuator named after it (MuJoCo's ``ctrl``), every other column ignored. Rows
at one fixed sample time (any, not necessarily the MJCF's step); row ``k`` holds the positions measured at ``t[k]``
and the ctrl applied from ``t[k]`` to ``t[k+1]`` (held), so the last row's ctrl is not used. A rollout JSON
(``cartpole swingup --json``'s ``rollout``, or :meth:`cartpole.sim.rollout.Rollout.save`) holds the same per physics
step, with the rates.

Every problem with a log is one sentence (:class:`LogError`) naming the file and what to fix.
"""
from __future__ import annotations

import csv
import difflib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cartpole._arrays import readonly
from cartpole._files import short
from cartpole.errors import CartPoleError

#: Relative spread of the sample intervals accepted as one fixed sample time (CSV times printed to 6-9 digits).
UNIFORM_RTOL = 1e-4


class LogError(CartPoleError, ValueError):
    """A logged run that cannot be read, is not at one fixed sample time, or does not match the MJCF."""


@dataclass(frozen=True)
class RunLog:
    """One logged run at a fixed sample time.

    Attributes
    ----------
    name : str
        Where it came from (the file's path).
    t : (N,) array, s
        Sample times, strictly increasing at one step.
    qpos : (N, nq) array
        Measured joint positions, m and rad, in the MJCF's qpos order.
    qvel : (N, nq) array or None
        Measured rates, m/s and rad/s, when the log has them (NaN columns where one joint's rate is missing).
    ctrl : (N, nu) array
        Ctrl applied from ``t[k]`` to ``t[k+1]`` (row ``N-1`` unused).
    """

    name: str
    t: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray | None
    ctrl: np.ndarray

    def __post_init__(self):
        for f in ("t", "qpos", "ctrl"):
            object.__setattr__(self, f, readonly(getattr(self, f)))
        if self.qvel is not None:
            object.__setattr__(self, "qvel", readonly(self.qvel))

    @property
    def sample_time(self) -> float:
        """The fixed sample time in s."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    @property
    def n(self) -> int:
        """Number of samples N."""
        return len(self.t)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` in s."""
        return float(self.t[-1] - self.t[0])

    def to_csv_rows(self, joint_names, actuator_names) -> tuple[list, list]:
        """(header, rows) of this log in the CSV format (positions, rates when known, ctrl)."""
        header = ["t", *joint_names]
        cols = [self.t[:, None], self.qpos]
        if self.qvel is not None:
            header += [f"{j}_vel" for j in joint_names]
            cols.append(self.qvel)
        header += list(actuator_names)
        cols.append(self.ctrl)
        return header, np.hstack(cols).tolist()


def _check_times(t: np.ndarray, name: str) -> None:
    if len(t) < 3:
        raise LogError(f"Log {name} has {len(t)} samples; give at least 3 rows (a run of a few seconds).")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise LogError(f"Log {name} has time going {'backwards' if dt[k] < 0 else 'nowhere'} at row {k + 2} "
                       f"(t = {t[k]:g} then {t[k + 1]:g} s); give strictly increasing times.")
    step = (t[-1] - t[0]) / (len(t) - 1)
    bad = np.abs(dt - step) > UNIFORM_RTOL * step + 1e-12
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise LogError(f"Log {name} is not at one fixed sample time: row {k + 2} comes {dt[k]:g} s after the one "
                       f"before, the mean step is {step:g} s; resample it to a fixed step.")


def _check_finite(a: np.ndarray, name: str, offset: int = 2) -> None:
    bad = ~np.all(np.isfinite(a), axis=1)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise LogError(f"Log {name} has a value that is not a finite number in row {k + offset} "
                       f"({int(bad.sum())} such rows); drop or fill those rows and resample.")


def _suggest(col: str, header) -> str:
    close = difflib.get_close_matches(col, list(header), n=1)
    return f" (is its column '{close[0]}' meant to be it?)" if close else ""


def read_csv_log(path: str | Path, joint_names, actuator_names) -> RunLog:
    """Read a CSV log (module docstring) for a model with these joints and actuators.

    Parameters
    ----------
    path : path
    joint_names : sequence of str
        The MJCF's joint names in qpos order.
    actuator_names : sequence of str
        The MJCF's actuator names in ctrl order.

    Returns
    -------
    RunLog

    Raises
    ------
    LogError
        Unreadable file, a missing column, a value that is not a number, times not strictly increasing or not at
        one step.
    """
    path = Path(path)
    name = str(path)
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise LogError(f"Log {name} cannot be read ({getattr(exc, 'strerror', None) or type(exc).__name__}); "
                       "give the path of a CSV or rollout JSON file.") from None
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise LogError(f"Log {name} is empty; give a CSV with a header t,<joints>,<actuators> and one row per "
                       "sample.")
    header = [c.strip() for c in rows[0]]
    needed = ["t", *joint_names, *actuator_names]
    for col in needed:
        if col not in header:
            what = ("time" if col == "t" else "joint" if col in joint_names else "actuator")
            raise LogError(f"Log {name} has no column '{col}' (the MJCF's {what}){_suggest(col, header)}; its "
                           f"header must name t, every joint ({', '.join(joint_names)}) and every actuator "
                           f"({', '.join(actuator_names)}).")
    body = rows[1:]
    if not body:
        raise LogError(f"Log {name} has a header but no rows; give one row per sample.")
    used = [c for c in dict.fromkeys(header) if c in needed or c in {f"{j}_vel" for j in joint_names}]
    index = [header.index(c) for c in used]
    data = np.empty((len(body), len(used)))
    for k, r in enumerate(body):
        try:
            data[k] = [float(r[i]) if i < len(r) and r[i].strip() else np.nan for i in index]
        except ValueError:
            raise LogError(f"Log {name} has a value that is not a number in row {k + 2}; give numbers only in "
                           "the t, joint and actuator columns.") from None
    col = {c: data[:, i] for i, c in enumerate(used)}
    t = col["t"]
    qpos = np.column_stack([col[j] for j in joint_names])
    ctrl = np.column_stack([col[a] for a in actuator_names])
    vel_names = [f"{j}_vel" for j in joint_names]
    qvel = None
    if any(v in col for v in vel_names):
        qvel = np.column_stack([col[v] if v in col else np.full(len(t), np.nan) for v in vel_names])
    _check_finite(np.column_stack([t, qpos, ctrl] + ([qvel[:, [v in col for v in vel_names]]] if qvel is not None
                                                     else [])), name)
    _check_times(t, name)
    return RunLog(name=name, t=t, qpos=qpos, qvel=qvel, ctrl=ctrl)


def read_json_log(path: str | Path, nq: int, nu: int) -> RunLog:
    """Read a rollout JSON (``t`` (n+1,), ``qpos``, ``qvel`` (n+1, nq), ``ctrl`` (n, nu)), bare or as the ``rollout``
    of a command's JSON document, for a model with ``nq`` joints and ``nu`` actuators.

    Returns
    -------
    RunLog
        With the rates, and the last ctrl row repeated (it is never used).

    Raises
    ------
    LogError
        Not JSON, no rollout in it, or arrays whose sizes do not match the model.
    """
    path = Path(path)
    name = str(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LogError(f"Log {name} cannot be read as JSON ({type(exc).__name__}); give a rollout JSON or a "
                       "CSV file.") from None
    if isinstance(doc, dict) and "rollout" in doc and isinstance(doc["rollout"], dict):
        doc = doc["rollout"]
    if not (isinstance(doc, dict) and all(k in doc for k in ("t", "qpos", "ctrl"))):
        raise LogError(f"Log {name} is JSON without a rollout (t, qpos, ctrl); give a swing-up's JSON "
                       "document (its rollout), a saved rollout, or a CSV.")
    try:
        t = np.asarray(doc["t"], float).ravel()
        qpos = np.asarray(doc["qpos"], float).reshape(len(t), -1)
        qvel = np.asarray(doc["qvel"], float).reshape(len(t), -1) if doc.get("qvel") is not None else None
        ctrl = np.asarray(doc["ctrl"], float).reshape(len(t) - 1, -1)
    except (TypeError, ValueError):
        raise LogError(f"Log {name} has rollout arrays of inconsistent sizes (need t (n+1), qpos and qvel "
                       "(n+1, nq), ctrl (n, nu)); give a rollout the toolkit wrote.") from None
    if qpos.shape[1] != nq or ctrl.shape[1] != nu or (qvel is not None and qvel.shape[1] != nq):
        raise LogError(f"Log {name} is a run of another model: it has {qpos.shape[1]} joint(s) and "
                       f"{ctrl.shape[1]} actuator(s), the MJCF {nq} and {nu}; give the MJCF the run was made on.")
    ctrl = np.vstack([ctrl, ctrl[-1:]]) if len(ctrl) else np.zeros((len(t), nu))
    _check_finite(np.column_stack([t, qpos, ctrl] + ([qvel] if qvel is not None else [])), name, offset=1)
    _check_times(t, name)
    return RunLog(name=name, t=t, qpos=qpos, qvel=qvel, ctrl=ctrl)


def read_log(path: str | Path, params) -> RunLog:
    """Read a log (CSV or rollout JSON, told apart by content) for the model of ``params``
    (:class:`~cartpole.models.CartPoleParams`).

    Parameters
    ----------
    path : path
    params : CartPoleParams
        The nominal model: its joint and actuator names and sizes.

    Returns
    -------
    RunLog

    Raises
    ------
    LogError
        A missing file or any problem :func:`read_csv_log` and :func:`read_json_log` name.
    """
    path = Path(path)
    if not path.is_file():
        raise LogError(f"Log {short(path)} does not exist; give the path of a CSV or rollout JSON file.")
    try:
        head = path.read_bytes()[:64].lstrip()
    except OSError as exc:
        raise LogError(f"Log {short(path)} cannot be read ({exc.strerror}); check the path.") from None
    if head.startswith(b"{"):
        return read_json_log(path, params.nq, params.nu)
    return read_csv_log(path, params.joint_names, tuple(a.name for a in params.actuators))
