"""`cartpole linearize`: the JSON contract of DESIGN.md, prose mode, and clean failures."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF, build_model


def test_linearize_json_follows_the_contract(capsys):
    assert main(["linearize", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc) == {"mjcf", "dt", "integrator", "x_eq", "u_eq", "A", "B", "Ad", "Bd", "period", "steps",
                        "smoothed_friction", "model"}
    assert doc["smoothed_friction"] == []
    assert doc["model"]["contacts"]["enabled"] is False and doc["model"]["contacts"]["pairs"] == []
    assert doc["period"] == doc["dt"] and doc["steps"] == 1
    assert Path(doc["mjcf"]).is_absolute() and Path(doc["mjcf"]) == SHIPPED_MJCF
    assert doc["dt"] == 0.005 and doc["integrator"] == "Euler"
    A, B, Ad, Bd = (np.array(doc[k]) for k in ("A", "B", "Ad", "Bd"))
    assert A.shape == (4, 4) and Ad.shape == (4, 4) and B.shape == (4, 1) and Bd.shape == (4, 1)
    model = build_model()
    A_ref, B_ref = model.linearize()
    np.testing.assert_array_equal(A, A_ref)
    np.testing.assert_array_equal(Bd, model.linearize(discrete=True)[1])
    assert doc["x_eq"] == [0, 0, 0, 0] and doc["u_eq"] == [0]
    # structure of a cart-pole at upright: positions integrate velocities, gravity destabilises the pole
    np.testing.assert_array_equal(A[:2], [[0, 0, 1, 0], [0, 0, 0, 1]])
    assert A[3, 1] > 0 and B[2, 0] > 0


def test_linearize_follows_the_given_mjcf(tmp_path, capsys):
    from variants import write_variant

    path = write_variant(tmp_path, "rk4_fine_step")
    assert main(["linearize", "--json", "--mjcf", str(path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["integrator"] == "RK4" and doc["dt"] == 0.002 and doc["mjcf"] == str(path.resolve())


def test_linearize_prose_prints_the_matrices(capsys):
    assert main(["linearize"]) == 0
    out = capsys.readouterr().out
    for word in ("A =", "B =", "Ad =", "Bd =", "Euler"):
        assert word in out


def test_linearize_stdout_is_pure_json_through_python_m(tmp_path):
    r = subprocess.run([sys.executable, "-m", "cartpole", "linearize", "--json"], capture_output=True, text=True,
                       check=True)
    json.loads(r.stdout)
    assert r.stderr == ""


def test_linearize_writes_nothing_and_refuses_the_removed_out_in_one_sentence(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["linearize", "--json", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err.splitlines() == ["cartpole linearize: --out was removed from linearize: linearize writes no "
                                    "files; drop the option."]
    assert not out.exists() and list(tmp_path.iterdir()) == []
    assert main(["linearize", "--json"]) == 0
    assert set(json.loads(capsys.readouterr().out)) >= {"A", "B", "Ad", "Bd"}
    assert main(["linearize", "--help"]) == 0
    assert "--out" not in capsys.readouterr().out


def test_bad_mjcf_gives_one_sentence_and_exit_2(tmp_path):
    bad = tmp_path / "ball_joint.xml"
    from variants import variant_xml

    bad.write_text(variant_xml("rk4_fine_step").replace('type="slide" axis="1 0 0"', 'type="ball"'))
    r = subprocess.run([sys.executable, "-m", "cartpole", "linearize", "--json", "--mjcf", str(bad)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "ball" in lines[0] and "Traceback" not in r.stderr


def _linearize_json(path, capsys):
    assert main(["linearize", "--json", "--mjcf", str(path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    return doc, {k: np.array(doc[k]) for k in ("x_eq", "u_eq", "A", "B", "Ad", "Bd")}


def test_linearize_json_shapes_on_the_two_pole_asset(capsys):
    path = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
    doc, a = _linearize_json(path, capsys)
    model = build_model(path)
    assert (model.nq, model.nu) == (3, 1)
    assert a["x_eq"].shape == (6,) and a["u_eq"].shape == (1,)
    assert a["A"].shape == a["Ad"].shape == (6, 6) and a["B"].shape == a["Bd"].shape == (6, 1)
    np.testing.assert_array_equal(a["x_eq"], model.x_eq)
    A, B = model.linearize()
    np.testing.assert_array_equal(a["A"], A)
    np.testing.assert_array_equal(a["B"], B)
    # positions integrate velocities; the motor pushes only through the rates
    np.testing.assert_array_equal(a["A"][:3], np.hstack([np.zeros((3, 3)), np.eye(3)]))
    np.testing.assert_array_equal(a["B"][:3], 0)
    # the linearisation is at a rest point: the model's dynamics vanish there
    assert np.abs(model.dynamics(a["x_eq"], a["u_eq"])).max() < 1e-9


def test_linearize_json_shapes_with_two_motors(chain_dir, capsys):
    path = chain_dir / "two_motors.xml"
    doc, a = _linearize_json(path, capsys)
    model = build_model(path)
    assert (model.nq, model.nu) == (3, 2)
    assert a["x_eq"].shape == (6,) and a["u_eq"].shape == (2,)
    assert a["A"].shape == a["Ad"].shape == (6, 6) and a["B"].shape == a["Bd"].shape == (6, 2)
    np.testing.assert_array_equal(a["Bd"], model.linearize(discrete=True)[1])
    # each motor's column: the cart motor and the wrist motor drive different joints, so the columns differ
    assert np.linalg.matrix_rank(a["B"][3:]) == 2
    assert doc["integrator"] == "implicitfast"


def test_linearize_prose_names_the_joints_and_the_equilibrium(capsys):
    assert main(["linearize", "--mjcf", str(SHIPPED_MJCF.with_name("cartpole_three_pole.xml"))]) == 0
    out = capsys.readouterr().out
    assert "x_eq =" in out and "u_eq =" in out and "hinge3 rate (rad/s)" in out
    A = out.split("A =")[1].split("B =")[0]
    assert len([line for line in A.splitlines() if line.strip()]) == 8


def test_a_damping_that_is_not_a_number_is_one_sentence_not_a_matrix_of_nulls(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a private cwd: MUJOCO_LOG.TXT from other tests' processes cannot show up here
    path = tmp_path / "nan_damping.xml"
    path.write_text(SHIPPED_MJCF.read_text().replace('damping="0.01"', 'damping="nan"'))
    assert main(["linearize", "--json", "--mjcf", str(path)]) == 2
    cap = capsys.readouterr()
    (line,) = cap.err.strip().splitlines()  # MuJoCo's own NaN warning is not printed on a failure
    # the reader refuses the number itself before anything is derived from it
    assert cap.out == "" and line.startswith("cartpole linearize: MJCF") and "not finite in dof_damping" in line
    assert not (Path.cwd() / "MUJOCO_LOG.TXT").exists()


def test_linearize_period_gives_the_held_discrete_model_and_refuses_a_fraction_of_a_step(capsys):
    assert main(["linearize", "--json", "--period", "0.02"]) == 0
    doc = json.loads(capsys.readouterr().out)
    model = build_model()
    assert doc["steps"] == 4 and doc["period"] == 0.02
    Ad, Bd = model.hold(4).linearize()
    np.testing.assert_array_equal(np.array(doc["Ad"]), Ad)
    np.testing.assert_array_equal(np.array(doc["Bd"]), Bd)
    assert main(["linearize", "--json", "--period", "0.012"]) == 2
    err = capsys.readouterr().err
    assert "whole number" in err and err.count("\n") == 1


def test_linearize_says_which_joints_dry_friction_it_smoothed(tmp_path, capsys):
    """frictionloss on the unactuated hinge: A holds the smooth model's slope at rest as a damping, and says so."""
    from cartpole.models import DEFAULT_FRICTION_WIDTH

    text = SHIPPED_MJCF.read_text()
    old = 'type="hinge" axis="0 1 0" damping="0.01"'
    assert old in text
    mjcf = tmp_path / "hinge_friction.xml"
    mjcf.write_text(text.replace(old, old + ' frictionloss="0.004"'))
    assert main(["linearize", "--json", "--mjcf", str(mjcf)]) == 0
    doc = json.loads(capsys.readouterr().out)
    (entry,) = doc["smoothed_friction"]
    assert entry["joint"] == "hinge" and entry["design"] == "smooth" and entry["frictionloss"] == 0.004
    assert entry["width"] == DEFAULT_FRICTION_WIDTH
    assert entry["damping_at_rest"] == 0.004 / DEFAULT_FRICTION_WIDTH
    # the smoothing is in A: the pole's rate row differs from the frictionless model's
    model = build_model(str(mjcf))
    np.testing.assert_allclose(doc["A"], model.linearize()[0])
    assert not np.allclose(doc["A"], model.without_friction().linearize()[0])
    assert main(["linearize", "--mjcf", str(mjcf)]) == 0
    out = capsys.readouterr().out
    assert "in this linearisation: hinge 0.004 N m as the smooth -0.004 tanh(qvel/0.01)" in out
