"""Compile an export folder with the strict flags and load it through ``ctypes``.

The compiler is :func:`cartpole.codegen.compiler` (``$CC``, else ``gcc``, else ``cc``), the one the toolkit's
generated C already uses; the flags are :data:`STRICT_CFLAGS`: an export that does not build warning-free under
them is never written.
"""
from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import numpy as np

from cartpole.codegen import build_sources, compiler
from cartpole.export.estimators import ExportError

#: What every export must compile under (warnings are errors).
STRICT_CFLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic")
#: Optimisation of the shared library the verification loads and the timing harness: what the toolkit's own
#: generated C uses (:data:`cartpole.codegen.CFLAGS`), for this machine; without ``-march=native`` where the
#: compiler refuses it.
OPT_CFLAGS = ("-O3", "-march=native")
#: The shared library's file name inside a folder.
SHARED_NAME = "libcartpole_controller.so"


def find_compiler() -> str:
    """The C compiler's path, or one :class:`ExportError` sentence when there is none."""
    cc = compiler()
    if cc is None:
        raise ExportError("No C compiler found ($CC, gcc or cc on PATH); install one (e.g. apt-get install gcc) or "
                          "set CC.")
    return cc


def compile_shared(folder: str | Path, *, cc: str | None = None, extra=()) -> Path:
    """Build ``folder``'s ``src/*.c`` into ``folder/libcartpole_controller.so`` with :data:`STRICT_CFLAGS`.

    Parameters
    ----------
    folder : path
        An export folder (``include/``, ``src/``).
    cc : str, optional
        Compiler (default :func:`find_compiler`).
    extra : sequence of str
        More flags (e.g. ``-O3``).

    Returns
    -------
    Path
        The library.

    Raises
    ------
    ExportError
        No compiler, or the sources do not compile (the compiler's first error quoted).
    """
    folder = Path(folder)
    cc = cc or find_compiler()
    srcs = sorted(str(p) for p in (folder / "src").glob("*.c"))
    lib = folder / SHARED_NAME
    cmd = [cc, *STRICT_CFLAGS, *OPT_CFLAGS, *extra, "-fPIC", "-shared", f"-I{folder / 'include'}",
           f"-I{folder / 'src'}", *srcs, "-o", str(lib), "-lm"]
    proc = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0 and "-march=native" in cmd:
        cmd = [c for c in cmd if c != "-march=native"]
        proc = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        lines = [ln for ln in proc.stderr.splitlines() if "error" in ln] or proc.stderr.splitlines() or ["?"]
        raise ExportError(f"The exported C does not compile with {Path(cc).name} {' '.join(STRICT_CFLAGS)}: "
                          f"{lines[0].strip()[:160]}; report this as a bug.")
    return lib


def program_library(files: dict, *, extra=()) -> str:
    """The C files of an export's program (relative path -> text; the ``include/`` and ``src/`` entries are used)
    compiled once into a shared library cached by their content, the compiler and the flags
    (:func:`cartpole.codegen.build_sources` with :data:`STRICT_CFLAGS`, :data:`OPT_CFLAGS` and ``extra``): the one
    compile path of the MuJoCo loop (:mod:`cartpole.export.inloop`) and of the verification's loaded folder
    (:func:`cartpole.export.make.load_design`). Load a copy of it for state of its own (a library loaded twice
    from one file shares its static memory).

    Parameters
    ----------
    files : dict
        Relative path -> text (e.g. :func:`cartpole.export.make.export_files`).
    extra : sequence of str
        More flags.

    Returns
    -------
    str
        The library's path.

    Raises
    ------
    ExportError
        No C compiler, or the C does not compile.
    """
    find_compiler()
    c_files = {rel: text for rel, text in files.items() if rel.startswith(("include/", "src/"))}
    try:
        return build_sources(c_files, "cp_program", cflags=(*STRICT_CFLAGS, *OPT_CFLAGS, *extra))
    except RuntimeError as exc:
        raise ExportError(f"The exported C does not compile ({exc}); report this as a bug.") from None


class CController:
    """An exported controller loaded from its shared library: ``reset()``, ``step(t, y) -> (code, u)``.

    Parameters
    ----------
    lib : path or ctypes.CDLL
        ``libcartpole_controller.so`` of an export, or such a library already loaded (e.g. a private copy:
        :func:`cartpole.codegen.load_private_copy`).
    ny, nu : int
        ``CP_NY``, ``CP_NU`` (from the manifest).
    real : {"double", "float"}
        ``cp_real``.
    """

    def __init__(self, lib, ny: int, nu: int, real: str = "double"):
        loaded = isinstance(lib, ctypes.CDLL)
        self.lib_path = str(lib._name if loaded else lib)
        self._lib = lib if loaded else ctypes.CDLL(self.lib_path)
        self.ny, self.nu = int(ny), int(nu)
        ctype = ctypes.c_float if real == "float" else ctypes.c_double
        self.dtype = np.float32 if real == "float" else np.float64
        self._y = np.zeros(self.ny, dtype=self.dtype)
        self._u = np.zeros(self.nu, dtype=self.dtype)
        ptr = ctypes.POINTER(ctype)
        self._step = self._lib.cp_step
        self._step.argtypes = [ctypes.c_double, ptr, ptr]
        self._step.restype = ctypes.c_int
        self._reset = self._lib.cp_reset
        self._reset.argtypes = []
        self._reset.restype = None
        self._yp = self._y.ctypes.data_as(ptr)
        self._up = self._u.ctypes.data_as(ptr)

    def reset(self) -> None:
        """``cp_reset()``."""
        self._reset()

    def step(self, t: float, y) -> tuple[int, np.ndarray]:
        """``cp_step(t, y, u)``: the return code and a copy of ``u`` (nu,) as float64.

        Parameters
        ----------
        t : float
            Sample time, s.
        y : (ny,) array
            Measurements (rounded to ``cp_real``).
        """
        self._y[:] = np.asarray(y, dtype=float).ravel()
        code = int(self._step(float(t), self._yp, self._up))
        return code, self._u.astype(float)
