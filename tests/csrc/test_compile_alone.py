"""Each C file of cartpole/csrc compiles on its own (one translation unit, the export's strict flags
-std=c99 -Wall -Wextra -Werror -pedantic) against a sample configuration the exporter renders
(tools/csrc_sample.py, `make csrc-lint`), so a person can compile, lint and read it without an export."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from cartpole.codegen import CSRC, compiler

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler")


def _tool():
    spec = importlib.util.spec_from_file_location("csrc_sample", REPO / "tools" / "csrc_sample.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return _tool().compile_alone(tmp_path_factory.mktemp("csrc-sample"), compiler())


def test_every_c_file_under_csrc_compiles_alone_warning_free_against_the_sample(results):
    assert set(results) == {p.name for p in CSRC.glob("*.c")}
    failed = {name: out for name, (ok, out) in results.items() if not ok}
    assert not failed, failed


def test_the_samples_carry_every_part_of_csrc_an_export_uses(tmp_path):
    tool = _tool()
    folders = tool.write_samples(tmp_path)
    carried = {p.name for f in folders.values() for p in (f / "src").glob("*.c")}
    for part in ("cp_lqr.c", "cp_pid.c", "cp_tvlqr.c", "cp_energy.c", "cp_state.c", "cp_kf.c", "cp_ekf.c"):
        assert part in carried
    for folder in folders.values():
        assert (folder / "src" / "cp_config.h").is_file() and (folder / "include" / "cartpole_controller.h").is_file()


def test_a_file_that_does_not_compile_is_reported_with_the_compilers_message(tmp_path, monkeypatch):
    tool = _tool()
    bad = tmp_path / "csrc"
    bad.mkdir()
    (bad / "broken.c").write_text("int f(void) { int unused; return 0; }\n")
    monkeypatch.setattr("cartpole.codegen.CSRC", bad)
    out = tool.compile_alone(tmp_path / "out", compiler())
    ok, message = out["broken.c"]
    assert not ok and "unused" in message
