"""`cartpole swingup --knockdown`: knocked down, the supervisor swings up again; the log (with its generalized
forces) replays exactly with plain mj_step; bad knockdowns are one sentence."""
import json
import subprocess
import sys

import numpy as np
import pytest

from mj_replay import replay_with_mj_step


def _swingup(*args, tmp_path):
    return subprocess.run([sys.executable, "-m", "cartpole", "swingup", "--no-video", "--json", "--out",
                           str(tmp_path / "out"), *args], capture_output=True, text=True, timeout=600)


def test_knocked_down_the_one_pole_cart_swings_up_again_and_the_log_replays(tmp_path):
    proc = _swingup("--knockdown", "1.5:0.3:3", "--duration", "14", tmp_path=tmp_path)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["method"] == "supervisor"  # the default with a knockdown
    assert doc["knockdowns"] >= 2 and doc["recoveries"] >= doc["knockdowns"] - 1
    assert all(t > 14 - 4.0 for t in doc["unrecovered_at"])  # only the last knock may lack the time to swing up
    assert 0.0 < doc["uptime"] < 1.0 and doc["upright_band"] == pytest.approx(0.2)
    r = doc["rollout"]
    assert len(r["qfrc_applied"]) == len(r["ctrl"]) and np.abs(r["qfrc_applied"]).max() > 0
    qpos, qvel = replay_with_mj_step(doc["mjcf"], r["qpos"][0], r["qvel"][0], r["ctrl"], r["push"], r["qfrc_applied"])
    assert np.array_equal(qpos, np.array(r["qpos"])) and np.array_equal(qvel, np.array(r["qvel"]))
    kinds = [d["kind"] for d in doc["supervisor"]["decisions"]]
    assert kinds.count("catch") >= doc["recoveries"] + 1


@pytest.mark.parametrize("flag, text, words", [("--knockdown", "3", "AFTER:LENGTH"),
                                               ("--knockdown", "3:-1", "length"),
                                               ("--throw", "fast", "EVERY")])
def test_a_bad_knockdown_or_throw_is_one_sentence(flag, text, words, tmp_path):
    proc = _swingup(flag, text, tmp_path=tmp_path)
    assert proc.returncode == 2 and proc.stdout == ""
    line = proc.stderr.strip()
    assert "\n" not in line and words in line and "Traceback" not in line and line.endswith(".")
    assert not (tmp_path / "out").exists()
