"""The export folder: the files the contract names, a Makefile that builds with nothing but cc and libm, an example
on stdin/stdout, whole-or-nothing writes, and a folder that is not an earlier export refused."""
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cartpole.export import ExportError, design_export, write_export
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions


@pytest.fixture(scope="module")
def design():
    return design_export(build_model(None), "lqr", LoopOptions(period=0.01, estimator="kf", encoder_cpr=2048))


def test_export_writes_the_contract_files_and_manifest(tmp_path, design):
    out = tmp_path / "ctl"
    w = write_export(design, out)
    assert set(w.files) == {"include/cartpole_controller.h", "src/cartpole_controller.c", "src/cp_generated.c",
                            "src/cp_generated.h", "src/cp_common.c", "src/cp_common.h", "src/cp_parts.h",
                            "src/cp_linalg.c", "src/cp_linalg.h", "src/cp_kf.c", "src/cp_lqr.c", "src/cp_config.h",
                            "src/cp_data.c",
                            "example/main.c", "Makefile", "manifest.json", "README.md"}
    from cartpole.codegen import CSRC

    for rel, name in {"src/cartpole_controller.c": "cp_rig.c", "src/cp_kf.c": "cp_kf.c"}.items():
        assert (out / rel).read_text() == (CSRC / name).read_text()  # the package's C, copied as it is
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()) == sorted(w.files)
    assert w.bytes == sum((out / f).stat().st_size for f in w.files)
    man = json.loads((out / "manifest.json").read_text())
    assert man["ny"] == 2 and man["nu"] == 1 and man["period"] == 0.01 and man["real"] == "double"
    assert man["y"]["units"] == ["m", "rad"] and len(man["u"]["names"]) == 1
    import hashlib

    assert man["mjcf"]["sha256"] == hashlib.sha256(Path(man["mjcf"]["path"]).read_bytes()).hexdigest()
    assert set(man["return_codes"]) >= {"0", "1", "2"}
    header = (out / "include/cartpole_controller.h").read_text()
    for name in ("CP_NY 2", "CP_NU 1", "CP_PERIOD 0.01", "typedef double cp_real;", "void cp_reset(void);",
                 "int cp_step(double t, const cp_real y[CP_NY], cp_real u[CP_NU]);"):
        assert name in header
    src = "".join((out / f).read_text() for f in w.files if f.endswith(".c"))
    assert "malloc" not in src and "calloc" not in src


@pytest.mark.skipif(shutil.which("make") is None, reason="no make on this machine")
def test_make_builds_the_library_and_an_example_that_matches_the_controller(tmp_path, design):
    out = tmp_path / "ctl"
    write_export(design, out)
    subprocess.run(["make", "-s", "-C", str(out), "CFLAGS=-std=c99 -O2 -Wall -Wextra -Werror -pedantic"],
                   check=True, capture_output=True)
    subprocess.run(["make", "-s", "-C", str(out), "shared"], check=True, capture_output=True)
    assert (out / "libcartpole_controller.a").is_file() and (out / "libcartpole_controller.so").is_file()
    lines = "".join(f"{0.01 * k} 0.0 {0.05 * (-1) ** k}\n" for k in range(5))
    done = subprocess.run([str(out / "example/cartpole_example")], input=lines, capture_output=True, text=True,
                          check=True)
    rows = [list(map(float, r.split())) for r in done.stdout.splitlines()]
    assert len(rows) == 5 and all(r[0] == 0 and -1 <= r[1] <= 1 for r in rows)
    # the same measurements through the Python estimator and controller
    kf, fb = design.rig.make_estimator(), design.make_controller()
    u = np.zeros(1)
    for k, row in enumerate(rows):
        y = np.array([0.0, 0.05 * (-1) ** k])
        x = kf.reset(y) if k == 0 else kf.update(y, np.tile(u, (design.program.steps, 1)).T)
        u = np.clip(fb(0.01 * k, x), -1, 1)
        assert abs(row[1] - u[0]) < 1e-12


def test_an_earlier_export_is_replaced_and_an_empty_folder_used(tmp_path, design):
    out = tmp_path / "ctl"
    out.mkdir()
    write_export(design, out)
    (out / "README.md").write_text("old")
    write_export(design, out, real="float")
    assert "typedef float cp_real;" in (out / "include/cartpole_controller.h").read_text()
    assert (out / "README.md").read_text() != "old"
    assert [p.name for p in tmp_path.iterdir()] == ["ctl"]  # no staging folder left beside it


def test_a_folder_that_is_not_an_export_is_refused_untouched(tmp_path, design):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep")
    with pytest.raises(ExportError, match="not an earlier export"):
        write_export(design, out)
    assert [p.name for p in out.iterdir()] == ["notes.txt"] and (out / "notes.txt").read_text() == "keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]


def test_no_compiler_is_one_sentence_and_nothing_written(tmp_path, design, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "nowhere"))
    monkeypatch.setenv("CC", str(tmp_path / "nowhere" / "cc"))
    with pytest.raises(ExportError, match="No C compiler"):
        write_export(design, tmp_path / "ctl")
    assert list(tmp_path.iterdir()) == []
