"""Sample configurations for the hand-written C of ``cartpole/csrc``, and each ``.c`` file compiled alone against one.

A file of ``cartpole/csrc`` is copied as it is into every export that uses it; what it includes from the export
(``cartpole_controller.h``, ``cp_config.h``, ``cp_plan.h`` for a swing-up's plan, ``cp_generated.h``) is rendered per
model and design. To read, compile or lint one file on its own, this writes sample folders rendered by the exporter
itself from designs on the shipped one-pole cart (so they never go stale), one per set of parts (:data:`SAMPLES`),
and compiles every ``.c`` file of ``cartpole/csrc`` alone (``-c``, one translation unit) with the export's strict
flags (:data:`cartpole.export.build.STRICT_CFLAGS`: ``-std=c99 -Wall -Wextra -Werror -pedantic``) against the sample
of a design that carries it (the others against the first sample). ``qp_dual.c`` is not a translation unit but the body
that ``qp_dual.c.jinja`` includes after its sizes: it is compiled in the unit ``cartpole.codegen.qp_source``
renders, with its state fields and a caller.

Run: ``python tools/csrc_sample.py [DIR]`` (``make csrc-lint``): writes ``DIR/<sample>/{include,src}`` (default
``build/csrc-sample``), prints each file's compile command and its result, exits 1 when one fails. Then, e.g.::

    cc -std=c99 -Wall -Wextra -Werror -pedantic -c cartpole/csrc/cp_kf.c \\
       -I build/csrc-sample/lqr-kf/include -I build/csrc-sample/lqr-kf/src -o /dev/null
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: Sample designs on the shipped one-pole cart: ``name -> (controller, estimator)``; together their exports carry
#: every part of ``cartpole/csrc``.
SAMPLES = {"lqr-kf": ("lqr", "kf"), "pid-ekf": ("pid", "ekf"), "tvlqr": ("tvlqr", "none"),
           "energy": ("energy", "none")}
#: The unit ``qp_dual.c`` is compiled in (the solver's sizes for 4 variables and 2 general rows).
QP_SIZES = (4, 2)


def _loop(estimator: str):
    from cartpole.sim.options import LoopOptions

    if estimator == "none":
        return None
    return LoopOptions(period=0.01, delay=0.01, estimator=estimator, encoder_cpr=2048)


def write_samples(out) -> dict[str, Path]:
    """Render each sample of :data:`SAMPLES` into ``out/<name>`` (an export's ``include/`` and ``src/``, its C files
    as the exporter writes them); returns ``name -> folder``."""
    import numpy as np

    from cartpole.export import design_export
    from cartpole.export.make import export_files
    from cartpole.models import build_model

    model = build_model(None)
    folders = {}
    for name, (method, estimator) in SAMPLES.items():
        x0 = np.array(model.x_hanging if method in ("tvlqr", "energy") else model.x_eq, dtype=float)
        design = design_export(model, method, _loop(estimator), x0=x0, rho=1.0 if method == "energy" else None)
        folder = Path(out) / name
        for rel, text in export_files(design).items():
            if rel.endswith((".c", ".h")):
                path = folder / rel
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text)
        folders[name] = folder
    return folders


def qp_dual_unit(out) -> Path:
    """The translation unit ``qp_dual.c`` is compiled in: ``cp_real``, the state struct with the solver's fields,
    the solver rendered for :data:`QP_SIZES` and a function that calls it; written to ``out/qp_dual_unit.c``."""
    from cartpole.codegen import qp_fields, qp_source

    nz, nr = QP_SIZES
    fields = "\n".join(f"    {f}" for f in qp_fields(nz, nr))
    text = (f"#include <math.h>\ntypedef double cp_real;\n#define CP_REAL_IS_FLOAT 0\n"
            f"static struct {{\n{fields}\n}} S;\n"
            f"{qp_source(nz, nr)}\n"
            "int qp_sample(cp_real* H, const cp_real* h, const cp_real* A, const cp_real* lba, const cp_real* uba,\n"
            "              const cp_real* lbx, const cp_real* ubx, cp_real* z);\n"
            "int qp_sample(cp_real* H, const cp_real* h, const cp_real* A, const cp_real* lba, const cp_real* uba,\n"
            "              const cp_real* lbx, const cp_real* ubx, cp_real* z)\n"
            "{\n    return qp_solve(H, h, A, lba, uba, lbx, ubx, z);\n}\n")
    path = Path(out) / "qp_dual_unit.c"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def compile_commands(out, cc: str) -> dict[str, list[str]]:
    """``file name -> compiler command`` for every ``.c`` file of ``cartpole/csrc``, compiled alone (``-c``) with the
    strict flags against the sample (written to ``out``) of a design that carries it."""
    from cartpole.codegen import CSRC
    from cartpole.export.build import STRICT_CFLAGS

    folders = write_samples(out)
    carried = {}
    for name, folder in folders.items():
        for path in (folder / "src").glob("*.c"):
            carried.setdefault(path.name, name)
    first = next(iter(folders.values()))
    cmds = {}
    for src in sorted(CSRC.glob("*.c")):
        if src.name == "qp_dual.c":
            unit, incs = qp_dual_unit(out), [f"-I{CSRC}"]
        else:
            folder = folders[carried[src.name]] if src.name in carried else first
            unit, incs = src, [f"-I{folder / 'include'}", f"-I{folder / 'src'}"]
        cmds[src.name] = [cc, *STRICT_CFLAGS, "-c", str(unit), *incs, "-o", str(Path(out) / (src.stem + ".o"))]
    return cmds


def compile_alone(out, cc: str) -> dict[str, tuple[bool, str]]:
    """Every ``.c`` file of ``cartpole/csrc`` compiled alone (:func:`compile_commands`): ``name -> (ok, compiler
    output)``."""
    results = {}
    for name, cmd in compile_commands(out, cc).items():
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
        results[name] = (proc.returncode == 0, (proc.stdout + proc.stderr).strip())
    return results


def main(argv=None) -> int:
    """Write the samples and compile each file alone; 0 when all compile warning-free, else 1."""
    from cartpole.codegen import compiler

    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0] if args else REPO / "build" / "csrc-sample")
    cc = compiler()
    if cc is None:
        print("No C compiler (gcc or cc) on PATH: nothing compiled.", file=sys.stderr)
        return 1
    failed = 0
    for name, cmd in compile_commands(out, cc).items():
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
        print(("ok    " if proc.returncode == 0 else "FAIL  ") + " ".join(cmd))
        if proc.returncode != 0:
            failed += 1
            print(proc.stderr.strip())
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
