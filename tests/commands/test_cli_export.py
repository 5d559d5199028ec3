"""`cartpole export`: the JSON contract, --verify, and bad input as one sentence, exit 2, nothing written."""
import json
import os
import subprocess
import sys

import pytest

from cartpole.cli import main

TWO_POLE = "cartpole/assets/cartpole_two_pole.xml"


def _run(args, capsys):
    code = main(["export", *args])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_export_json_follows_the_contract(tmp_path, capsys):
    out = tmp_path / "ctl"
    code, stdout, _ = _run(["--json", "--out", str(out), "--controller", "lqr", "--estimator", "kf",
                            "--encoder-cpr", "2048", "--period", "0.01", "--delay", "0.01", "--verify",
                            "--duration", "3"], capsys)
    assert code == 0
    doc = json.loads(stdout)
    exp = doc["export"]
    assert {"files", "bytes", "verified", "max_ctrl_diff", "step_us"} <= set(exp)
    assert exp["verified"] is True and exp["max_ctrl_diff"] <= 1e-9
    assert exp["float32"]["success"] and exp["double"]["replays"]
    assert 0 < exp["step_us"]["median"] <= exp["step_us"]["max"]
    assert doc["period"] == 0.01 and doc["delay"] == 0.01 and doc["estimator"] == "kf"
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()) == sorted(exp["files"])
    assert exp["bytes"] == sum((out / f).stat().st_size for f in exp["files"])


@pytest.mark.parametrize("controller", ["lqr", "pid", "tvlqr", "energy"])
def test_export_float32_verifies_on_the_shipped_carts(tmp_path, capsys, controller):
    short = ["--duration", "3"] if controller in ("lqr", "pid") else []  # a swing-up runs as long as in Python
    code, stdout, _ = _run(["--json", "--out", str(tmp_path / "c"), "--controller", controller, "--float32",
                            "--verify", *short], capsys)
    assert code == 0
    doc = json.loads(stdout)
    assert doc["real"] == "float" and doc["export"]["verified"]
    assert "typedef float cp_real;" in (tmp_path / "c/include/cartpole_controller.h").read_text()


def test_two_pole_lqr_export_verifies(tmp_path, capsys):
    code, stdout, _ = _run(["--json", "--mjcf", TWO_POLE, "--out", str(tmp_path / "c"), "--verify",
                            "--duration", "3"], capsys)
    assert code == 0 and json.loads(stdout)["export"]["verified"]


def test_prose_mode_names_the_folder_and_the_build(tmp_path, capsys):
    code, stdout, _ = _run(["--out", str(tmp_path / "c")], capsys)
    assert code == 0 and "make -C" in stdout and str(tmp_path / "c") in stdout


def _nothing_written(tmp_path, before):
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize("args,words", [
    (["--period", "0.0123"], "period"),                # not a whole number of physics steps
    (["--controller", "pid", "--mjcf", TWO_POLE], "one pole"),  # the cascade needs one pole
    (["--x0", "0", "1"], "--x0"),
    (["--controller", "tvlqr", "--x0", "1.45", "3.14", "3", "0"], "no swing-up found"),  # no plan from this start
    (["--controller", "energy", "--mjcf", TWO_POLE], "one pole"),
    (["--controller", "tvlqr", "--estimator", "kf", "--encoder-cpr", "1024"], "not available"),
])
def test_bad_input_is_one_sentence_exit_2_nothing_written(tmp_path, capsys, args, words):
    code, stdout, err = _run(["--out", str(tmp_path / "c"), *args], capsys)
    assert code == 2 and stdout == ""
    assert err.count("\n") == 1 and words.lower() in err.lower() and "Traceback" not in err
    _nothing_written(tmp_path, [])


def test_a_folder_that_is_not_an_export_is_refused(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    code, _, err = _run(["--out", str(tmp_path)], capsys)
    assert code == 2 and "not an earlier export" in err and err.count("\n") == 1
    _nothing_written(tmp_path, ["notes.txt"])


def test_no_c_compiler_is_refused_before_anything_is_written(tmp_path):
    env = {**os.environ, "PATH": str(tmp_path / "nowhere"), "CC": str(tmp_path / "nowhere" / "cc")}
    done = subprocess.run([sys.executable, "-m", "cartpole", "export", "--out", str(tmp_path / "c")], env=env,
                          capture_output=True, text=True, check=False)
    assert done.returncode == 2 and "No C compiler" in done.stderr and done.stderr.count("\n") == 1
    _nothing_written(tmp_path, [])


def test_view_without_verify_is_one_sentence_exit_2(tmp_path, capsys):
    code, stdout, err = _run(["--out", str(tmp_path / "c"), "--view", "web"], capsys)
    assert code == 2 and stdout == "" and err.count("\n") == 1
    assert "--verify" in err and "Traceback" not in err
    _nothing_written(tmp_path, [])


def test_view_without_a_display_says_so_once_and_verifies_as_usual(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    code, stdout, err = _run(["--json", "--out", str(tmp_path / "c"), "--verify", "--duration", "1", "--view",
                              "desktop"], capsys)
    assert code == 0 and json.loads(stdout)["export"]["verified"]
    (line,) = [ln for ln in err.strip().splitlines() if "live view" in ln]
    assert line.startswith("cartpole export: no live view: No display for the live viewer")
