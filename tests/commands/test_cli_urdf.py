"""The command line on URDF cart-poles: `--mjcf file.urdf` linearizes and balances (the LQR runs replayed by plain
MuJoCo on the URDF with the reported motor added), the added motor is said in prose and in the JSON (`model`), and
`--actuated-joint` chooses the driven joint where the file does not say, or is refused where it means nothing."""
import io
import json
from contextlib import redirect_stdout

import mujoco
import numpy as np
import pytest

from cartpole.cli import main
from urdf_layouts import BULLET, LAYOUTS, write_layout

LINEARIZE_KEYS = {"mjcf", "dt", "integrator", "x_eq", "u_eq", "A", "B", "Ad", "Bd", "period", "steps"}


def run_json(argv):
    buf = io.StringIO()
    with redirect_stdout(buf):
        code = main(argv)
    return code, (json.loads(buf.getvalue()) if code == 0 else None)


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_linearize_json_reports_the_motor_added(name, tmp_path, capsys):
    path = write_layout(name, tmp_path)
    code, doc = run_json(["linearize", "--mjcf", str(path), "--json"])
    assert code == 0 and LINEARIZE_KEYS <= set(doc) and doc["mjcf"] == str(path)
    (added,) = doc["model"]["actuators_added"]
    _, joint, effort, source = LAYOUTS[name]
    assert added["joint"] == joint and added["source"] == source and added["file"] == str(path)
    assert added["ctrlrange"] == [-effort, effort] and added["gear"] == 1.0 and added["unit"] == "N"
    assert np.shape(doc["B"]) == (4, 1) and np.abs(doc["B"]).max() > 0
    assert f"added motor '{added['actuator']}' on prismatic joint '{joint}'" in capsys.readouterr().err


def test_an_mjcf_json_document_adds_no_urdf_keys(capsys):
    code, doc = run_json(["linearize", "--json"])
    assert code == 0 and set(doc) == LINEARIZE_KEYS | {"smoothed_friction", "model"}
    assert set(doc["model"]) == {"contacts"}  # no actuators_added, urdf_changes or mjcf_ran for an MJCF


def independent_replay(urdf, added, x0, ctrl):
    """Plain MuJoCo: the URDF as MuJoCo reads it, the reported motor added, ctrl applied step by step."""
    spec = mujoco.MjSpec.from_file(str(urdf))
    act = spec.add_actuator(name="m", target=added["joint"], trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.ctrllimited, act.ctrlrange = mujoco.mjtLimited.mjLIMITED_TRUE, added["ctrlrange"]
    for j in spec.joints:
        j.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
    m = spec.compile()
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = x0[:m.nq], x0[m.nq:]
    xs = [np.concatenate([d.qpos, d.qvel])]
    for u in ctrl:
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        xs.append(np.concatenate([d.qpos, d.qvel]))
    return np.array(xs)


@pytest.mark.slow
def test_lqr_balances_the_bullet_layout_and_its_runs_replay(tmp_path, capsys):
    path = write_layout("bullet", tmp_path)
    code, doc = run_json(["lqr", "--mjcf", str(path), "--no-video", "--json", "--out", str(tmp_path / "out")])
    assert code == 0 and not any(doc["diverged"])
    assert all(t is not None for t in doc["settling_times_seed"])  # every start back inside 0.05 rad
    (added,) = doc["model"]["actuators_added"]
    for run in doc["rollouts"]:
        x = np.column_stack([run["qpos"], run["qvel"]])
        assert np.abs(x[-1, 1]) < 0.05  # upright at the end (the pole is up at qpos = 0 in this file)
        replay = independent_replay(path, added, x[0], np.asarray(run["ctrl"]))
        np.testing.assert_allclose(replay, x, atol=1e-9)


def write_two_prismatic(tmp_path):
    path = tmp_path / "two.urdf"
    path.write_text(BULLET.replace("</robot>", """<link name="cart2">
      <inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
      <joint name="rail2" type="prismatic"><parent link="cart"/><child link="cart2"/><axis xyz="0 1 0"/>
      <limit effort="10" lower="-1" upper="1" velocity="1"/></joint></robot>"""))
    return path


def test_two_prismatic_joints_without_transmission_exit_2_naming_the_option(tmp_path, capsys):
    path = write_two_prismatic(tmp_path)
    assert main(["linearize", "--mjcf", str(path)]) == 2
    err = capsys.readouterr().err
    assert "--actuated-joint NAME" in err and "'slider_to_cart', 'rail2'" in err and err.count("\n") == 1
    code, doc = run_json(["linearize", "--mjcf", str(path), "--json", "--actuated-joint", "slider_to_cart",
                          "--actuated-joint", "rail2"])
    assert code == 0 and [a["joint"] for a in doc["model"]["actuators_added"]] == ["slider_to_cart", "rail2"]
    assert {a["source"] for a in doc["model"]["actuators_added"]} == {"actuated_joints"}
    assert np.shape(doc["B"]) == (6, 2)


def test_actuated_joint_with_an_mjcf_exits_2(tmp_path, capsys):
    assert main(["linearize", "--actuated-joint", "slider"]) == 2
    err = capsys.readouterr().err
    assert "--actuated-joint" in err and "URDF" in err and err.count("\n") == 1


def test_an_unknown_actuated_joint_exits_2_naming_the_option(tmp_path, capsys):
    path = write_layout("bullet", tmp_path)
    assert main(["linearize", "--mjcf", str(path), "--actuated-joint", "nope"]) == 2
    err = capsys.readouterr().err
    assert "'nope'" in err and "--actuated-joint NAME" in err and "'slider_to_cart', 'cart_to_pole'" in err
