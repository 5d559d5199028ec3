"""The exported step timed in C itself, without ctypes: a small harness linked with the export replays the
measurements a MuJoCo run gave the controller and times each ``cp_step`` with ``clock_gettime``.

The harness is not part of the export (it needs POSIX clocks, the export only C99); it lives in a temporary folder
beside a compiled copy.
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile

import numpy as np

from cartpole.codegen import CSRC
from cartpole.export.build import OPT_CFLAGS, STRICT_CFLAGS, find_compiler
from cartpole.export.estimators import ExportError
from cartpole.export.folder import stage_folder

#: The harness's C (``cartpole/csrc/cp_bench.c``).
HARNESS = (CSRC / "cp_bench.c").read_text()


def time_steps(files: dict, t, y, *, repeats: int = 5) -> dict:
    """Replay measurements through an export's ``cp_step`` compiled with :data:`~cartpole.export.build.OPT_CFLAGS`
    and time each step in C.

    Parameters
    ----------
    files : dict
        The export's files (:func:`cartpole.export.make.export_files`).
    t : (K,) array
        Sample times, s.
    y : (K, ny) array
        Measurements, in order.
    repeats : int
        Each step's time is its fastest over this many replays of the whole sequence.

    Returns
    -------
    dict
        ``step_us`` (K,) array (microseconds), ``codes`` (K,) and ``u`` (K, nu) of the last replay.

    Raises
    ------
    ExportError
        No C compiler or a harness that does not build.
    """
    cc = find_compiler()
    staged = stage_folder({**files, "bench/harness.c": HARNESS}, tempfile.gettempdir())
    try:
        exe = staged / "harness"
        srcs = [str(p) for p in sorted((staged / "src").glob("*.c"))]
        cmd = [cc, *[f for f in STRICT_CFLAGS if f != "-pedantic"], *OPT_CFLAGS, f"-I{staged / 'include'}",
               f"-I{staged / 'src'}", str(staged / "bench/harness.c"), *srcs, "-o", str(exe), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
        if proc.returncode != 0 and "-march=native" in cmd:
            cmd = [c for c in cmd if c != "-march=native"]
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
        if proc.returncode != 0:
            raise ExportError(f"The timing harness does not build: {proc.stderr.strip().splitlines()[:1]}.")
        rows = np.column_stack([np.asarray(t, float), np.asarray(y, float)])
        text = "\n".join(" ".join(repr(float(v)) for v in row) for row in rows) + "\n"
        out = subprocess.run([str(exe), str(int(repeats))], input=text, capture_output=True, text=True,
                             check=True, timeout=600).stdout
    finally:
        shutil.rmtree(staged, ignore_errors=True)
    vals = np.array([[float(v) for v in line.split()] for line in out.splitlines()])
    return {"step_us": vals[:, 0] * 1e-3, "codes": vals[:, 1].astype(int), "u": vals[:, 2:]}


def measured_inputs(run) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` the C controller received in a :class:`~cartpole.export.loop.LockstepRun`."""
    return np.asarray(run.t, float), np.asarray(run.y, float)

