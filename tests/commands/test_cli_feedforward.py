"""``cartpole feedforward``: the JSON contract (every rollout replays exactly with our own mj_step loop), the prose
table, the figure, and the error paths (one sentence, exit 2, no files)."""
import json

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.apps.feedforward import RUNS
from cartpole.planning.options import PlanOptions
from cartpole.models import SHIPPED_MJCF
from mj_replay import replay_with_mj_step

ROLLOUT_KEYS = {"t", "qpos", "qvel", "ctrl", "push"}


def test_json_contract_every_run_replays_exactly_and_the_figure_is_written(tmp_path, capsys):
    assert main(["feedforward", "--json", "--no-video", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)          # stdout is exactly one JSON document
    assert doc["mjcf"] == str(SHIPPED_MJCF) and doc["mass_error"] == 0.1
    assert doc["wrong_plan"]["pole_mass_factor"] == pytest.approx(1.1)
    assert doc["options"] == {"plan": PlanOptions(exact_discrete=False).as_dict()}  # both plans' settings
    assert list(doc["runs"]) == list(RUNS)
    for name, run in doc["runs"].items():
        assert {"success", "time_to_upright", "final_angle_error", "max_angle_tracking_error",
                "max_cart_tracking_error", "peak_ctrl", "rollout"} <= set(run)
        ro = run["rollout"]
        assert set(ro) == ROLLOUT_KEYS
        n = len(ro["ctrl"])
        assert len(ro["t"]) == len(ro["qpos"]) == len(ro["qvel"]) == n + 1 and len(ro["push"]) == n
        assert not any(ro["push"])
        assert np.allclose(ro["qpos"][0], [0, np.pi]) and np.allclose(ro["qvel"][0], [0, 0])
        qpos, qvel = replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
        assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))
        assert run["replays_exactly"] is True
        assert run["peak_ctrl"] == np.abs(np.array(ro["ctrl"])).max()
    runs = doc["runs"]
    assert runs["feedforward"]["success"] is False and runs["feedforward"]["time_to_upright"] is None
    assert runs["feedforward_tvlqr"]["success"] is True and 0 < runs["feedforward_tvlqr"]["time_to_upright"]
    assert isinstance(runs["wrong_mass_tvlqr"]["success"], bool)
    fig = tmp_path / "figures" / "feedforward.png"
    assert doc["figure"] == str(fig.resolve()) and fig.stat().st_size > 10_000
    assert doc["videos"] is None and not (tmp_path / "videos").exists()
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["feedforward.png"]


def test_prose_prints_one_row_per_run_and_the_replay_check(tmp_path, capsys):
    assert main(["feedforward", "--no-video", "--out", str(tmp_path), "--mass-error", "-0.1"]) == 0
    out = capsys.readouterr().out
    rows = [ln for ln in out.splitlines() if ln.startswith("feedforward ")]
    assert len(rows) == 4 and sum("-10 %" in r for r in rows) == 2
    assert "NO" in rows[0] and "yes" in rows[1]           # open loop fails, feedforward + TVLQR holds
    assert "Every rollout replays exactly from its logged ctrl: True" in out
    assert "Figure:" in out and (tmp_path / "figures" / "feedforward.png").is_file()


@pytest.mark.parametrize("value", ["-2", "nan", "inf", "ten"])
def test_bad_mass_error_is_one_sentence_exit_2_and_no_files(value, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["feedforward", "--json", "--out", str(out), f"--mass-error={value}"]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and lines[0].startswith("cartpole feedforward: ")
    assert "mass error" in lines[0] and "Traceback" not in cap.err
    assert not out.exists()


def test_a_swingup_the_optimiser_cannot_plan_ends_with_its_one_sentence(tmp_path, capsys):
    weak = tmp_path / "weak_motor.xml"
    xml = SHIPPED_MJCF.read_text()
    assert 'ctrlrange="-1 1"' in xml
    weak.write_text(xml.replace('ctrlrange="-1 1"', 'ctrlrange="-0.02 0.02"'))   # 0.4 N cannot swing the pole up
    out = tmp_path / "out"
    assert main(["feedforward", "--json", "--no-video", "--mjcf", str(weak), "--out", str(out)]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and lines[0].startswith("cartpole feedforward: ")
    assert "infeasible" in lines[0] and "Traceback" not in cap.err
    assert not out.exists()


def test_view_without_a_display_says_so_once_and_runs_as_usual(tmp_path, monkeypatch, capsys):
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "XDG_SESSION_TYPE"):
        monkeypatch.delenv(var, raising=False)
    assert main(["feedforward", "--view", "desktop", "--json", "--no-video", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert set(doc["runs"]) == set(RUNS)
    (line,) = [ln for ln in cap.err.strip().splitlines() if "live view" in ln]
    assert line.startswith("cartpole feedforward: no live view: No display for the live viewer")
    assert (tmp_path / "figures" / "feedforward.png").exists()
