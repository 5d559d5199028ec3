"""`cartpole lqr --margins`: the JSON `margins` per design, the figures, and the refusal of a loop that is not
linear."""
import json
from pathlib import Path

from cartpole.cli import main


def test_margins_json_has_one_object_per_design_and_writes_the_figures(tmp_path, capsys):
    code = main(["lqr", "--margins", "--json", "--compare-pid", "--period", "0.01", "--delay", "0.005",
                 "--estimator", "kf", "--encoder-cpr", "2048", "--encoder-resolution", "0.001",
                 "--out", str(tmp_path)])
    doc = json.loads(capsys.readouterr().out)
    assert code in (0, None)
    assert set(doc["margins"]) == {"lqr", "lqg", "pid"}
    for m in doc["margins"].values():
        assert {"gain_margin", "phase_margin_deg", "delay_margin_s", "ms", "mt", "gain_crossover_rad_s"} <= set(m)
        assert m["gain_margin"][0] < 1 < m["gain_margin"][1]
    assert doc["margins"]["lqg"]["phase_margin_deg"] < doc["margins"]["lqr"]["phase_margin_deg"]
    for path in doc["figures"].values():
        assert Path(path).is_file() and Path(path).parent == (tmp_path / "figures").resolve()


def test_margins_of_a_nonlinear_estimator_are_refused_in_one_sentence(tmp_path, capsys):
    code = main(["lqr", "--margins", "--estimator", "ekf", "--encoder-cpr", "2048", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "linear loop" in err and "--estimator kf" in err and "Traceback" not in err
    assert not (tmp_path / "figures").exists()


def test_ctrl_noise_without_sensors_is_refused_before_the_lab_runs(tmp_path, capsys):
    code = main(["lqr", "--ctrl-noise", "0.1", "--no-video", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "needs sensors" in err and "--estimator kf" in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())
