"""Standalone C of the toolkit's controllers and estimators, and its proof in the MuJoCo loop.

``design_export`` (what the export reproduces) -> ``write_export`` (the folder: C99, static memory, Makefile,
example, manifest) and ``load_design`` + ``run_lockstep`` (the compiled C driving MuJoCo beside the Python
controller, step for step).
"""
from cartpole.export.build import (
    STRICT_CFLAGS,
    CController,
    compile_shared,
    find_compiler,
)
from cartpole.export.design import (
    CONTROLLERS,
    SUPPORTED_ESTIMATORS,
    ExportDesign,
    design_export,
)
from cartpole.export.estimators import ExportError
from cartpole.export.folder import MANIFEST_FORMAT, check_target
from cartpole.export.loop import LockstepRun, run_lockstep
from cartpole.export.make import (
    WrittenExport,
    export_files,
    load_design,
    manifest,
    write_export,
)

__all__ = [
    "CONTROLLERS",
    "MANIFEST_FORMAT",
    "STRICT_CFLAGS",
    "SUPPORTED_ESTIMATORS",
    "CController",
    "ExportDesign",
    "ExportError",
    "LockstepRun",
    "WrittenExport",
    "check_target",
    "compile_shared",
    "design_export",
    "export_files",
    "find_compiler",
    "load_design",
    "manifest",
    "run_lockstep",
    "write_export",
]
