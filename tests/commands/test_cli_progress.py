"""Progress: one line per finished stage on a stderr that is not a terminal, a live bar on one, nothing with --json,
never anything on stdout (cartpole.progress and the commands that use it)."""
import io
import json
import re

import numpy as np

from cartpole.cli import main
from cartpole.progress import Reporter, reporting, stage

LINE = re.compile(r"^(\w+): \S.* in \d+\.\d s$")


def _stage_lines(err: str, command: str) -> list[str]:
    assert "\r" not in err, "carriage returns on a stderr that is not a terminal"
    lines = err.splitlines()
    for line in lines:
        m = LINE.match(line)
        assert m and m.group(1) == command, f"not one clean stage line: {line!r}"
    return lines


def test_swingup_prints_one_line_per_stage_and_json_mode_prints_none(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))  # an empty cache: the basin is estimated here
    assert main(["swingup", "--no-video", "--duration", "3", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    lines = _stage_lines(cap.err, "swingup")
    assert [line.rsplit(" in ", 1)[0] for line in lines] == ["swingup: basin estimate 300 runs",
                                                             "swingup: MuJoCo rollout 3 s"]
    assert "basin estimate" not in cap.out and ("SUCCESS" in cap.out or "FAILED" in cap.out)

    assert main(["swingup", "--no-video", "--duration", "3", "--out", str(tmp_path)]) == 0   # the basin from disk
    assert [line.rsplit(" in ", 1)[0] for line in _stage_lines(capsys.readouterr().err, "swingup")] == [
        "swingup: MuJoCo rollout 3 s"]

    assert main(["swingup", "--json", "--no-video", "--duration", "3", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)  # stdout: exactly one JSON document
    assert doc["method"] == "energy" and len(doc["rollout"]["ctrl"]) == 600
    assert cap.err == ""


def test_sweep_reports_the_basin_and_the_runs_as_two_lines(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))  # an empty cache: the basin is estimated here
    assert main(["sweep", "--n", "2", "--duration", "3", "--out", str(tmp_path)]) == 0
    lines = _stage_lines(capsys.readouterr().err, "sweep")
    assert [line.rsplit(" in ", 1)[0] for line in lines] == ["sweep: basin estimate 300 runs",
                                                             "sweep: energy swing-ups 2 runs"]


def test_a_live_bar_on_a_terminal_ends_as_the_same_line():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    with reporting("demo", stream=tty):
        with stage("work", size="4 runs") as tick:
            for k in range(4):
                tick((k + 1) / 4)
    text = tty.getvalue()
    assert "\r" in text and "%|" in text and "00:00<" in text  # tqdm drew a bar: percentage, elapsed<remaining
    last = text.split("\r")[-1].strip().splitlines()[-1]
    assert LINE.match(last) and last.startswith("demo: work 4 runs in ")


def test_a_failed_or_nested_stage_prints_nothing_and_callbacks_still_get_fractions():
    err = io.StringIO()
    seen, inner_seen = [], []
    try:
        with Reporter("x", stream=err):
            with stage("outer", callback=seen.append) as outer:
                with stage("inner", callback=outer) as inner:  # nested: silent, forwards to the outer stage
                    inner(0.5)
                    inner_seen.append(inner.shown)
                    inner(1.0)
                outer(1.0)
            with stage("broken"):
                raise RuntimeError("boom")
    except RuntimeError:
        pass
    assert inner_seen == [False] and seen == [0.5, 1.0, 1.0]
    assert err.getvalue().splitlines()[0].startswith("x: outer in ") and len(err.getvalue().splitlines()) == 1


def test_without_a_reporter_or_when_disabled_stages_are_silent(capsys):
    seen = []
    with stage("alone", callback=seen.append) as tick:
        tick(np.float64(1.0))
    with reporting("off", enabled=False):
        with stage("quiet"):
            pass
    cap = capsys.readouterr()
    assert seen == [1.0] and cap.out == "" and cap.err == ""
