"""The sweep's results (cartpole.apps.sweep.results): the CSV line of a run and back, the id, the results file
appended line by line and read back to resume."""
import csv
import math

import pytest

from cartpole.apps.sweep import (ResultsFile, SweepError, axis, csv_row, failure, header, read_done, sweep_id)
from cartpole.apps.sweep.results import parse_row
from cartpole.models import read_params

ROW = {"success": True, "replays": True, "time_to_upright": 2.8101234567890123, "caught_at": 2.5,
       "cart_clearance": 0.61, "peak_ctrl": 1.0, "rho": 3.0, "error": None, "push": ((0.5, -20.0),),
       "model_error": 1.1, "settings": {"energy_gain": 12.5}}
FAILED = {"success": False, "replays": False, "time_to_upright": math.nan, "caught_at": math.nan,
          "cart_clearance": math.nan, "peak_ctrl": math.nan, "rho": math.nan, "error": "No plan from here.",
          "push": (), "model_error": 1.0, "settings": {}}


def _line(head, fields):
    return dict(zip(head, [str(f) for f in fields]))


def test_a_csv_line_reads_back_as_the_same_row():
    params = read_params()
    head = header(params, ("energy_gain",))
    start = [0.1, 3.0000000000000004, -0.2, 0.7]
    fields = csv_row("abc", 3, start, ROW, ("energy_gain",))
    assert len(fields) == len(head)
    line = _line(head, fields)
    assert [float(line[k]) for k in ("x0_slider", "x0_hinge", "x0_slider_rate", "x0_hinge_rate")] == start
    assert line["push_time_s"] == "0.5" and line["push_force_N"] == "-20.0" and line["setting_energy_gain"] == "12.5"
    back = parse_row(line)
    for k in ("success", "replays", "time_to_upright", "caught_at", "cart_clearance", "peak_ctrl", "error"):
        assert back[k] == ROW[k], k  # repr: the same doubles
    bad = parse_row(_line(head, csv_row("abc", 4, start, FAILED, ("energy_gain",))))
    assert bad["error"] == "No plan from here." and math.isnan(bad["time_to_upright"]) and not bad["success"]
    assert failure(FAILED) == "raised" and failure(ROW) == ""


def test_the_id_changes_with_each_part_of_the_description():
    params = read_params()
    base = dict(method="energy", n=4, seed=0, duration=None, jitter=0.0)
    sid = sweep_id(params, **base)
    assert len(sid) == 12 and int(sid, 16) >= 0 and sweep_id(params, **base) == sid
    others = [sweep_id(params, **{**base, k: v}) for k, v in
              [("method", "trajopt"), ("n", 5), ("seed", 1), ("duration", 4.0), ("jitter", 0.1)]]
    others += [sweep_id(params, **base, axes=(axis("push_force", 1.0),)), sweep_id(params, **base, x0=[0, 3, 0, 0])]
    assert len({sid, *others}) == len(others) + 1


def test_the_results_file_keeps_every_finished_run_and_resume_reads_them_back(tmp_path):
    params = read_params()
    head = header(params)
    path = tmp_path / "sweeps" / "s.csv"
    assert read_done(path, head, "abc") == {}  # no file yet: nothing done
    f = ResultsFile(path, head, fresh=True)
    f.write(csv_row("abc", 2, [0, 3, 0, 0], ROW))
    f.write(csv_row("abc", 0, [0, 3, 0, 0], FAILED))
    f.close()
    with open(path, newline="") as fh:
        assert [r["run"] for r in csv.DictReader(fh)] == ["2", "0"]
    done = read_done(path, head, "abc")
    assert sorted(done) == [0, 2] and done[2]["time_to_upright"] == ROW["time_to_upright"]
    assert sorted(read_done(path, head, "abc", n=1)) == [0]
    # a line a crash cut short is run again, and dropped when the file is appended to
    path.write_bytes(path.read_bytes() + b"abc,1,0.0,3.0")
    assert sorted(read_done(path, head, "abc")) == [0, 2]
    f = ResultsFile(path, head, fresh=False)
    f.write(csv_row("abc", 1, [0, 3, 0, 0], ROW))
    f.close()
    assert sorted(read_done(path, head, "abc")) == [0, 1, 2]
    with pytest.raises(SweepError, match="holds sweep abc, not this one"):
        read_done(path, head, "def")
    with pytest.raises(SweepError, match="columns are not this sweep's"):
        read_done(path, header(params, ("energy_gain",)), "abc")
