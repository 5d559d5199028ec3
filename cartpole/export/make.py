"""Write an export: its files from an :class:`~cartpole.export.design.ExportDesign`, compiled warning-free in a
staging folder before anything reaches ``--out`` (:func:`write_export`); and a compiled, loaded copy for the
verification (:func:`load_design`).
"""
from __future__ import annotations

import hashlib
import shutil
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

from cartpole.export.build import (
    SHARED_NAME,
    CController,
    compile_shared,
    find_compiler,
    program_library,
)
from cartpole.export.folder import (
    MANIFEST_FORMAT,
    check_target,
    commit_folder,
    discard,
    folder_files,
    stage_folder,
)
from cartpole.export.program import RETURN_CODES, sources


def toolkit_version() -> str:
    """The installed cartpole's version."""
    try:
        from importlib.metadata import version

        return version("cartpole")
    except Exception:  # noqa: BLE001 - an uninstalled checkout
        return "unknown"


def file_sha256(path) -> str:
    """Hex sha256 of a file's bytes ("" for no file)."""
    if not path or not Path(path).is_file():
        return ""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def manifest(design, real: str) -> dict:
    """``manifest.json`` of an export (see the module doc of :mod:`cartpole.export.folder`).

    Parameters
    ----------
    design : ExportDesign
    real : {"double", "float"}

    Returns
    -------
    dict
        ``format``, ``controller``, ``estimator``, ``real``, ``ny``, ``nu``, ``nx``, ``period``, ``delay``,
        ``delay_compensation``, ``physics_step``, ``y`` {``names``, ``units``}, ``u`` {``names``, ``units``,
        ``gear``, ``ctrlrange``}, ``state`` {``names``, ``x_eq``}, ``sensors`` (the spec or None), ``mjcf``
        {``path``, ``sha256``}, ``toolkit_version``, ``return_codes``.
    """
    prog = design.program
    params = design.model.params
    joints = [j.name for j in params.joints]
    pos_units = ["rad" if j.kind == "hinge" else "m" for j in params.joints]
    return {
        "format": MANIFEST_FORMAT,
        "controller": design.method,
        "estimator": design.estimator,
        "real": real,
        "ny": prog.ny, "nu": prog.nu, "nx": prog.nx,
        "period": prog.period, "delay": prog.delay,
        "delay_compensation": prog.predict is not None,
        "physics_step": float(design.model.dt),
        "y": {"names": list(design.y_names), "units": list(design.y_units)},
        "u": {"names": [a.name for a in params.actuators], "units": ["ctrl"] * prog.nu,
              "gear": [float(a.gear) for a in params.actuators],
              "ctrlrange": [[float(lo), float(hi)] for lo, hi in zip(prog.u_low, prog.u_high)]},
        "state": {"names": joints + [f"{j}_vel" for j in joints], "units": pos_units + [f"{u}/s" for u in pos_units],
                  "x_eq": [float(v) for v in design.model.x_eq]},
        "sensors": None if design.spec is None else design.spec.to_dict(),
        "mjcf": {"path": params.mjcf, "sha256": file_sha256(params.mjcf)},
        "toolkit_version": toolkit_version(),
        "return_codes": {str(k): v for k, v in RETURN_CODES.items()},
    }


def c_sources(prog) -> dict:
    """Relative path -> text of the C files (``include/``, ``src/``) of the program ``prog``: what
    :func:`export_files` writes and the MuJoCo loop compiles (:mod:`cartpole.export.inloop`)."""
    return sources(prog, toolkit_version())


def export_files(design, real: str = "double") -> dict:
    """Relative path -> text of every file of the export of ``design`` with ``cp_real`` ``real``."""
    prog = replace(design.program, real=real) if real != design.program.real else design.program
    version = toolkit_version()
    return folder_files(sources(prog, version), manifest(design, real))


@dataclass(frozen=True)
class WrittenExport:
    """An export written to its folder.

    Attributes
    ----------
    folder : Path
    files : tuple of str
        Relative paths, sorted.
    bytes : int
        Their total size.
    """

    folder: Path
    files: tuple
    bytes: int


def write_export(design, out, *, real: str = "double") -> WrittenExport:
    """Write the export of ``design`` to the folder ``out``: staged beside it, compiled with the strict flags (the
    shared library then removed), and renamed into place whole.

    Parameters
    ----------
    design : ExportDesign
    out : path
        Missing, empty, or an earlier export (replaced); anything else is refused.
    real : {"double", "float"}

    Returns
    -------
    WrittenExport

    Raises
    ------
    ExportError
        ``out`` is not an earlier export, there is no C compiler, the C does not compile.
    """
    out = check_target(Path(out))
    cc = find_compiler()
    files = export_files(design, real)
    staged = stage_folder(files, out.resolve().parent)
    try:
        compile_shared(staged, cc=cc)
        (staged / SHARED_NAME).unlink()
        commit_folder(staged, out)
    except BaseException:
        discard(staged)
        raise
    names = tuple(sorted(files))
    return WrittenExport(folder=out, files=names, bytes=sum(len(files[n].encode()) for n in names))


def load_design(design, real: str = "double", *, extra_cflags=()) -> tuple[CController, Path]:
    """The export of ``design`` compiled (:func:`~cartpole.export.build.program_library`, cached by content) and
    loaded from a copy in a temporary folder holding its files: ``(controller, folder)``; remove the folder with
    :func:`cartpole.export.folder.discard` when done.

    Raises
    ------
    ExportError
        No compiler, or the C does not compile.
    """
    files = export_files(design, real)
    staged = stage_folder(files, tempfile.gettempdir())
    try:  # compiled once per content (the loop's path); a copy loaded, so its static memory is its own
        lib = shutil.copyfile(program_library(files, extra=extra_cflags), staged / SHARED_NAME)
        ctl = CController(lib, design.program.ny, design.program.nu, real)
    except BaseException:
        discard(staged)
        raise
    return ctl, staged
