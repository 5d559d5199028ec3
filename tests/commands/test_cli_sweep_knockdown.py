"""`cartpole sweep --knockdown`: every run knocked down, the supervisor by default, the table and JSON with each run's
uptime, knockdowns and swing-ups, the CSV with their columns (and read back on --resume)."""
import csv
import json

from cartpole.cli import main


def test_a_knocked_sweep_runs_the_supervisor_and_reports_uptime(tmp_path, capsys):
    out = tmp_path / "out"
    args = ["sweep", "--knockdown", "1.5:0.3:2", "--n", "2", "--duration", "8", "--seed", "1", "--out", str(out)]
    assert main([*args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["method"] == "supervisor" and doc["n"] == 2
    for r in doc["rows"]:
        assert 0.0 <= r["uptime"] <= 1.0 and r["knockdowns"] >= 1 and r["swingups"] >= 1
    assert doc["uptime_mean"] == sum(r["uptime"] for r in doc["rows"]) / 2
    assert doc["knockdowns_total"] == sum(r["knockdowns"] for r in doc["rows"])
    with open(doc["results"]) as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["uptime"]) for r in rows] == [r["uptime"] for r in doc["rows"]]
    assert main([*args, "--resume"]) == 0  # the finished runs are read back, uptime columns and all
    text = capsys.readouterr().out
    assert "Resumed: 2 of 2 runs" in text and "uptime" in text and "knockdown(s)" in text


def test_a_bad_knockdown_on_a_sweep_is_one_sentence(tmp_path, capsys):
    assert main(["sweep", "--knockdown", "3", "--n", "1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "AFTER:LENGTH" in err and "\n" not in err and "Traceback" not in err
