"""The sweep's results (cartpole.apps.sweep.results): the CSV line of a run and back, the id, the results file
appended line by line and read back to resume."""
import csv
import dataclasses
import math

import pytest

from cartpole.apps.sweep import (ResultsFile, SweepError, SweepRuns, axis, csv_row, failure, header, read_done,
                                 sweep_id)
from cartpole.apps.sweep.results import parse_row
from cartpole.models import read_params
from cartpole.sim import LoopOptions

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
    runs = SweepRuns(n=4, seed=0)
    sid = sweep_id(params, method="energy", runs=runs, loop=LoopOptions())
    assert len(sid) == 12 and int(sid, 16) >= 0 and sweep_id(params, method="energy", runs=runs) == sid
    others = [sweep_id(params, method="trajopt", runs=runs),
              sweep_id(params, method="energy", runs=runs, loop=LoopOptions(duration=4.0)),
              sweep_id(params, method="energy", runs=runs, loop=LoopOptions(period=0.02))]
    others += [sweep_id(params, method="energy", runs=dataclasses.replace(runs, **{k: v})) for k, v in
               [("n", 5), ("seed", 1), ("gain_jitter", 0.1), ("axes", (axis("push_force", 1.0),)),
                ("x0", [0, 3, 0, 0])]]
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
    with pytest.raises(SweepError, match="a row for run '2', and this sweep has runs 0 to 0"):
        read_done(path, head, "abc", n=1)  # a run this sweep does not have: refused, not silently dropped
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


@pytest.mark.parametrize("column, value", [("success", "banana"), ("replays", "maybe"), ("time_to_upright_s", "nan"),
                                           ("peak_ctrl", "inf"), ("x0_hinge", "zero"), ("model_error", ""),
                                           ("replays", "False")])
def test_a_row_with_a_field_no_finished_run_writes_is_not_finished(tmp_path, column, value):
    params = read_params()
    head = header(params)
    path = tmp_path / "s.csv"
    f = ResultsFile(path, head, fresh=True)
    f.write(csv_row("abc", 0, [0, 3, 0, 0], ROW))
    f.write(csv_row("abc", 1, [0, 3, 0, 0], ROW))
    f.close()
    lines = path.read_text().splitlines()
    row = next(csv.DictReader(lines[:1] + lines[2:]))
    row[column] = value  # run 1 tampered with: a success that does not replay is no success either
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(head)
        w.writerow(lines[1].split(","))
        w.writerow([row[k] for k in head])
    assert sorted(read_done(path, head, "abc", n=2)) == [0]


@pytest.mark.parametrize("run", ["999", "-1", "one"])
def test_a_row_for_a_run_the_sweep_does_not_have_is_refused(tmp_path, run):
    params = read_params()
    head = header(params)
    path = tmp_path / "s.csv"
    f = ResultsFile(path, head, fresh=True)
    f.write(csv_row("abc", 0, [0, 3, 0, 0], ROW))
    f.close()
    path.write_text(path.read_text().replace("abc,0,", f"abc,{run},"))
    with pytest.raises(SweepError, match="holds a row for run"):
        read_done(path, head, "abc", n=3)


def test_two_sweeps_cannot_hold_one_results_file(tmp_path, monkeypatch):
    from cartpole._files import LockedError
    from cartpole.apps.sweep.results import results_lock

    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    path = tmp_path / "out" / "sweeps" / "sweep_energy.csv"
    with results_lock(path):
        with pytest.raises(LockedError, match="is in use by process"):
            with results_lock(tmp_path / "out" / "." / "sweeps" / "sweep_energy.csv"):
                pass
        with results_lock(tmp_path / "out" / "sweeps" / "sweep_trajopt.csv"):  # another file: its own lock
            pass
    with results_lock(path):  # released when the first sweep ended
        pass
    assert not (tmp_path / "out").exists()  # the lock lives in the cache, --out holds only outputs
