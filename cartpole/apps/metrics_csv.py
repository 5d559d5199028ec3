"""The lab's metrics row: one line per ``cartpole lqr`` run appended to ``metrics/metrics.csv`` (the lab's
deliverable), with the date, the commit of this checkout and the mean settling time."""
from __future__ import annotations

import datetime
import subprocess
from pathlib import Path

from cartpole._files import append_csv_row
from cartpole.apps.lab import METRICS_DAY, METRICS_RUN_ID

#: The columns of ``metrics.csv``, in order.
METRICS_HEADER = "run_id,date,day,task,commit,seed,env,method,steps,runs,metric,value,notes"


def git_short_sha() -> str:
    """Short commit hash of the repository holding this package, or ``'nogit'``."""
    try:
        r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).resolve().parent,
                           capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "nogit"
    sha = r.stdout.strip()
    return sha if r.returncode == 0 and sha else "nogit"


def metrics_row(result, *, date: str | None = None, commit: str | None = None) -> list:
    """The lab's ``metrics.csv`` row for a :class:`~cartpole.apps.lab.LabResult`, one field per ``METRICS_HEADER`` column.

    ``steps`` is the number of physics steps of one run; ``value`` the mean of the lab's settling time (s);
    ``notes`` is ``5_ICs``, with ``_<k>_poles`` for a chain, ``_scaled_<f>`` when the starts were scaled and
    ``_<n>_counted`` when only n starts began outside the settling band (the value is then their mean, ``nan`` for
    none).
    """
    date = date or datetime.date.today().isoformat()
    commit = commit or git_short_sha()
    notes = f"{len(result.rollouts)}_ICs"
    if len(result.params.hinges) != 1:
        notes += f"_{len(result.params.hinges)}_poles"
    if result.start_scale != 1.0:
        notes += f"_scaled_{result.start_scale:g}"
    counted = sum(getattr(result, "counted", (True,) * len(result.rollouts)))
    if counted != len(result.rollouts):  # starts inside the settling band are not in the mean
        notes += f"_{counted}_counted"
    return [METRICS_RUN_ID, date, METRICS_DAY, "cartpole_lqr", commit, 0, "cartpole", "lqr", result.steps, 1,
            "settling_time_sec", f"{result.mean_settling_time_seed:.4f}", notes]


def append_metrics(path: Path, row: list) -> Path:
    """Append ``row`` to the CSV at ``path`` (header first when creating it), whole or not at all, through the csv
    module (:func:`~cartpole._files.append_csv_row`)."""
    return append_csv_row(path, METRICS_HEADER.split(","), row)
