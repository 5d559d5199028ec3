"""`cartpole library`: a plan library built on disk from a grid of starts, stored with the model's hash, read back as
the planner's warm starts; bad input is one sentence, exit 2, nothing written."""
import json
import subprocess
import sys

import numpy as np

from cartpole.codegen import model_key
from cartpole.models import build_model, read_params
from cartpole.planning.library import PlanLibrary


def _library(*args):
    return subprocess.run([sys.executable, "-m", "cartpole", "library", "--json", *args], capture_output=True,
                          text=True, timeout=900)


def test_a_library_built_on_disk_is_the_models_and_warm_starts_a_plan(tmp_path):
    path = tmp_path / "plans.npz"
    proc = _library("--build", "1", "--file", str(path))
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    model = build_model(read_params(doc["mjcf"]))
    assert doc["key"] == model_key(model) and doc["file"] == str(path) and path.is_file()
    assert doc["built"] == doc["plans"] == 1 and not doc["failed"] and doc["starts"][0]["T"] > 0
    lib = PlanLibrary.load(model, path)  # read back: the same plan, keyed by the model's hash
    assert len(lib) == 1 and np.allclose(lib.plans[0].x0, doc["starts"][0]["x0"])
    assert lib.guess_for(model, model.x_hanging) is not None
    listed = json.loads(_library("--file", str(path)).stdout)  # without --build: what is stored, nothing planned
    assert listed["plans"] == 1 and listed["built"] == 0


def test_a_library_of_another_model_is_not_used(tmp_path):
    path = tmp_path / "plans.npz"
    two = build_model(read_params("cartpole/assets/cartpole_two_pole.xml"))
    PlanLibrary.empty(two).save(path)
    doc = json.loads(_library("--file", str(path)).stdout)  # the one-pole cart: the file is not its library
    assert doc["plans"] == 0 and doc["key"] != model_key(two)


def test_bad_library_input_is_one_sentence(tmp_path):
    for args in (("--build", "0"), ("--search-s", "-1"), ("--file", str(tmp_path / "missing" / "plans.npz"))):
        proc = _library(*args)
        line = proc.stderr.strip()
        assert proc.returncode == 2 and proc.stdout == "", args
        assert "\n" not in line and "Traceback" not in line and line.endswith(".") and args[0] in line
    assert not (tmp_path / "missing").exists()


def test_a_search_budget_that_is_not_a_positive_number_says_that_inf_means_none():
    proc = _library("--build", "1", "--search-s", "nan")
    line = proc.stderr.strip()
    assert proc.returncode == 2 and proc.stdout == "" and "\n" not in line
    assert "--search-s nan" in line and "inf: no budget" in line
