"""``cartpole swingup``: the JSON contract (exact replay with our own mj_step loop), files, and error paths."""
import json

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF


def _replay_with_mj_step(mjcf, qpos0, qvel0, ctrl):
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(mjcf))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = qpos0, qvel0
    mujoco.mj_forward(m, d)
    qpos, qvel = [d.qpos.copy()], [d.qvel.copy()]
    for u in ctrl:
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
        qvel.append(d.qvel.copy())
    return np.array(qpos), np.array(qvel)


def _check_contract(doc, method, out):
    assert doc["mjcf"] == str(SHIPPED_MJCF) and doc["method"] == method
    ro = doc["rollout"]
    n = len(ro["ctrl"])
    assert len(ro["t"]) == len(ro["qpos"]) == len(ro["qvel"]) == n + 1
    assert np.allclose(ro["qpos"][0], [0, np.pi]) and np.allclose(ro["qvel"][0], [0, 0])
    qpos, qvel = _replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
    assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))
    assert doc["success"] is True
    assert isinstance(doc["caught_at"], float) and 0 < doc["caught_at"] < ro["t"][-1]
    assert 0 < doc["time_to_upright"] < ro["t"][-1]
    assert doc["video"] is None
    fig = out / "figures" / f"swingup_{method}.png"
    assert doc["figure"] == str(fig.resolve()) and fig.stat().st_size > 10_000


def test_energy_json_contract_and_exact_replay(tmp_path, capsys):
    assert main(["swingup", "--json", "--no-video", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    doc = json.loads(out)  # stdout is exactly one JSON document
    _check_contract(doc, "energy", tmp_path)
    assert not (tmp_path / "videos").exists()


def test_trajopt_json_contract_and_exact_replay(tmp_path, capsys):
    pytest.importorskip("cartpole.ocp.pipeline")
    assert main(["swingup", "--method", "trajopt", "--json", "--no-video", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    _check_contract(doc, "trajopt", tmp_path)


def test_prose_summary(tmp_path, capsys):
    assert main(["swingup", "--no-video", "--out", str(tmp_path), "--duration", "6"]) == 0
    out = capsys.readouterr().out
    assert "SUCCESS" in out and "Caught at" in out and "time to upright" in out and "Peak |ctrl|" in out


@pytest.mark.parametrize("argv", [["--x0", "0", "nan", "0", "0"], ["--x0", "0", "3.14", "0"],
                                  ["--x0", "1.6", "3.14", "0", "0"], ["--duration", "-1"],
                                  ["--mjcf", "NOT_A_CARTPOLE"]])
def test_bad_input_is_one_sentence_exit_2_and_no_files(argv, tmp_path, capsys):
    if argv[-1] == "NOT_A_CARTPOLE":
        bad = tmp_path / "pendulum.xml"
        bad.write_text('<mujoco><worldbody><body><joint type="hinge"/><geom size=".1" mass="1"/></body>'
                       '</worldbody></mujoco>')
        argv = ["--mjcf", str(bad)]
    out = tmp_path / "out"
    assert main(["swingup", "--json", "--no-video", "--out", str(out), *argv]) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartpole swingup: ")
    assert not out.exists()
