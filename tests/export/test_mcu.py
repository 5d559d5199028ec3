"""The Cortex-M4F float32 build: compiles under the strict flags with arm-none-eabi-gcc, sizes and the worst stack
from the tools' own output; the worst-stack sum on a call graph written by hand."""
import os
import shutil
import subprocess
import sys

import pytest

from cartpole.export import design_export, export_files
from cartpole.export.mcu import cross_build, mcu_tools, worst_stack
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions

needs_arm = pytest.mark.skipif(mcu_tools() is None, reason="arm-none-eabi-gcc / arm-none-eabi-size not installed "
                               "(Debian gcc-arm-none-eabi, libnewlib-arm-none-eabi; .ci/run installs them)")


def test_worst_stack_is_the_deepest_chain_of_frames():
    ci = """graph: { title: "a.c"
node: { title: "a.c:cp_step" label: "cp_step\\na.c:1:1\\n100 bytes (static)" }
node: { title: "a.c:f" label: "f\\na.c:2:1\\n40 bytes (static)" }
node: { title: "g" label: "g\\nb.c:3:1\\n70 bytes (static)" }
node: { title: "sinf" label: "sinf\\nmath.h:1:1" shape : ellipse }
edge: { sourcename: "a.c:cp_step" targetname: "a.c:f" }
edge: { sourcename: "a.c:cp_step" targetname: "sinf" }
edge: { sourcename: "a.c:f" targetname: "g" }
edge: { sourcename: "a.c:f" targetname: "a.c:f" }
}"""
    assert worst_stack([ci]) == (210, ["cp_step", "f", "g"])


@needs_arm
@pytest.mark.parametrize("method,loop", [
    ("lqr", LoopOptions(period=0.01, estimator="kf", encoder_cpr=2048)),
    ("tvlqr", LoopOptions(period=0.01, estimator="ekf", encoder_cpr=2048)),
])
def test_float32_export_cross_compiles_for_a_cortex_m4f(method, loop):
    design = design_export(build_model(None), method, loop, real="float")
    files = export_files(design, "float")
    r = cross_build(files)
    assert "-mfpu=fpv4-sp-d16" in r["command"] and "-Werror" in r["command"]
    assert r["flash"] == r["text"] + r["data"] and r["ram"] == r["data"] + r["bss"]
    assert 0 < r["stack"] < 8192 and r["stack_chain"][0] == "cp_step"
    # the plan and the gains are in flash: a larger controller, a larger image
    assert r["flash"] > sum(len(v) for k, v in files.items() if k.endswith(".c")) / 100


@needs_arm
def test_cli_reports_the_mcu_build(tmp_path, capsys):
    import json

    from cartpole.cli import main

    assert main(["export", "--json", "--mcu", "--out", str(tmp_path / "c")]) == 0
    m = json.loads(capsys.readouterr().out)["export"]["mcu"]
    assert m["target"] == "cortex-m4f" and m["flash"] > 0 and m["stack"] > 0


def test_mcu_without_the_arm_toolchain_is_one_sentence_and_nothing_written(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    os.symlink(shutil.which("gcc") or shutil.which("cc"), bin_dir / "gcc")
    env = {**os.environ, "PATH": str(bin_dir)}
    env.pop("CC", None)
    done = subprocess.run([sys.executable, "-m", "cartpole", "export", "--mcu", "--out", str(tmp_path / "c")],
                          env=env, capture_output=True, text=True, check=False)
    assert done.returncode == 2 and "arm-none-eabi-gcc" in done.stderr and done.stderr.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bin"]
