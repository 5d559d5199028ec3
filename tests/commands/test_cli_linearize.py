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
    assert set(doc) == {"mjcf", "dt", "integrator", "A", "B", "Ad", "Bd"}
    assert Path(doc["mjcf"]).is_absolute() and Path(doc["mjcf"]) == SHIPPED_MJCF
    assert doc["dt"] == 0.005 and doc["integrator"] == "Euler"
    A, B, Ad, Bd = (np.array(doc[k]) for k in ("A", "B", "Ad", "Bd"))
    assert A.shape == (4, 4) and Ad.shape == (4, 4) and B.shape == (4, 1) and Bd.shape == (4, 1)
    model = build_model()
    A_ref, B_ref = model.linearize()
    np.testing.assert_array_equal(A, A_ref)
    np.testing.assert_array_equal(Bd, model.linearize(discrete=True)[1])
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
    r = subprocess.run([sys.executable, "-m", "cartpole", "linearize", "--json", "--out", str(tmp_path)],
                       capture_output=True, text=True, check=True)
    json.loads(r.stdout)


def test_bad_mjcf_gives_one_sentence_and_exit_2(tmp_path):
    bad = tmp_path / "two_hinges.xml"
    from variants import variant_xml

    bad.write_text(variant_xml("rk4_fine_step").replace('type="slide" axis="1 0 0"', 'type="hinge" axis="0 0 1"'))
    r = subprocess.run([sys.executable, "-m", "cartpole", "linearize", "--json", "--mjcf", str(bad)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "hinge" in lines[0] and "Traceback" not in r.stderr
