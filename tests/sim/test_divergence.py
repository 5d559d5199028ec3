"""A run MuJoCo blows up (and resets to qpos0, upright on the shipped cart) is diverged, stopped, never a success."""
import json

import mujoco
import numpy as np
import pytest

from cartpole.cli import main
from cartpole.control import LinearFeedback
from cartpole.models import SHIPPED_MJCF, build_model, mujoco_warnings, read_params
from cartpole.sim import replay, replays_exactly, simulate, simulate_batch_linear
from cartpole.validation.metrics import diverged, diverged_at, summarize, swingup_success

HUGE_RATE = [0.0, 0.1, 0.0, 1e12]  # qvel above MuJoCo's 1e10: it warns BADQVEL and resets on the first step
FAST_RATE = [0.0, 0.1, 0.0, 1e5]  # finite and accepted, but the accelerations blow up within a few steps


def _first_warning_step(x0, ctrl):
    """Independently of the package: the 1-based step of a plain mj_step loop at which a warning count grows."""
    m = mujoco.MjModel.from_xml_path(str(SHIPPED_MJCF))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = x0[:m.nq], x0[m.nq:]
    mujoco.mj_forward(m, d)
    for k, u in enumerate(ctrl):
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        if sum(int(w.number) for w in d.warning) > 0:
            return k + 1
    return None


@pytest.fixture(scope="module")
def catch():
    return LinearFeedback.for_model(build_model(read_params(None)))


@pytest.fixture(autouse=True)
def quiet():
    notes = []
    with mujoco_warnings(notes.append):
        yield notes


@pytest.mark.parametrize("x0, warning", [(HUGE_RATE, "BADQVEL"), (FAST_RATE, "BADQACC")])
def test_a_blown_up_run_stops_at_its_first_warning_and_is_never_a_success(catch, x0, warning):
    run = simulate(None, catch, x0, 2.0)
    k = _first_warning_step(np.array(x0), run.ctrl)
    assert k is not None and len(run.ctrl) == k  # stopped at the step MuJoCo warned in
    assert diverged(run) and diverged_at(run) == pytest.approx(k * run.dt)
    assert run.info["diverged_warning"] == warning
    m = build_model(read_params(None))
    assert not swingup_success(run, m) and not summarize(run, m).settled
    assert replays_exactly(run)  # the log still replays, reset included
    assert replay(None, run.x[0], run.ctrl).info["diverged"] == pytest.approx(k * run.dt)


def test_a_calm_run_has_no_divergence(catch):
    run = simulate(None, catch, [0.0, 0.05, 0.0, 0.0], 0.5)
    assert not diverged(run) and run.info["diverged_warning"] is None and len(run.ctrl) == 100


def test_the_batch_marks_the_runs_that_blew_up_and_blanks_them_after(catch):
    X0 = np.array([[0.0, 0.1, 0.0, 0.0], HUGE_RATE, FAST_RATE])
    runs = simulate_batch_linear(None, catch, X0, 0.5, nthread=0)
    states, ctrl = runs  # still unpacks as before
    for i, x0 in enumerate(X0):
        one = simulate(None, catch, x0, 0.5)
        if not diverged(one):
            assert np.isnan(runs.diverged_at[i])
            np.testing.assert_allclose(states[i], one.x, rtol=0, atol=1e-12)
            continue
        k = len(one.ctrl)
        assert runs.diverged_at[i] == pytest.approx(diverged_at(one))
        np.testing.assert_array_equal(states[i, :k + 1], one.x)  # up to and with MuJoCo's reset state
        assert np.all(np.isnan(states[i, k + 1:])) and np.all(np.isnan(ctrl[i, k:]))
    assert runs.diverged.tolist() == [False, True, True]


def test_a_saved_diverged_run_loads_diverged(catch, tmp_path):
    from cartpole.sim import Rollout

    run = simulate(None, catch, FAST_RATE, 1.0)
    run.save(tmp_path / "r.json")
    back = Rollout.load(tmp_path / "r.json")
    assert diverged_at(back) == diverged_at(run) and back.info["diverged_warning"] == "BADQACC"


def _without_input_limits(monkeypatch):
    """Lift the command line's range checks (issue 24 refuses these inputs up front) so that the run itself blows
    up: what is tested here is that a diverged run is reported as one, whatever let it start."""
    import cartpole.apps.sweep.plan as plan
    import cartpole.apps.swingup as swingup
    import cartpole.sim.options as options

    monkeypatch.setattr(swingup, "MAX_START_RATE", float("inf"))
    monkeypatch.setattr(options, "MAX_PUSH_FORCE", float("inf"))
    monkeypatch.setattr(plan, "MAX_PUSH_FORCE", float("inf"))


@pytest.mark.parametrize("argv", [["--x0", "0", "3", "0", "1e308"], ["--push", "1:1e12"]])
def test_the_command_line_refuses_inputs_that_would_blow_the_run_up(argv, tmp_path, capsys):
    assert main(["swingup", "--json", "--no-video", "--duration", "2", "--out", str(tmp_path / "out"), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and ("limit" in err or "at most" in err)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv", [["--x0", "0", "3", "0", "1e308"], ["--push", "1:1e12"]])
def test_swingup_reports_a_blown_up_run_as_diverged_not_caught(argv, tmp_path, capsys, monkeypatch):
    _without_input_limits(monkeypatch)
    assert main(["swingup", "--json", "--no-video", "--duration", "2", "--out", str(tmp_path), *argv]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["success"] is False and doc["caught_at"] is None and doc["time_to_upright"] is None
    assert doc["diverged"] is True and doc["diverged_at"] > 0
    t = doc["rollout"]["t"]
    assert doc["diverged_at"] == pytest.approx(t[-1])  # the run stopped there
    if "--push" in argv:
        assert doc["diverged_at"] >= 1.0


def test_swingup_json_says_a_good_run_did_not_diverge(tmp_path, capsys):
    assert main(["swingup", "--json", "--no-video", "--duration", "5", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["success"] is True and doc["diverged"] is False and doc["diverged_at"] is None


def test_a_sweep_row_that_blew_up_is_a_diverged_failure_in_the_json_and_the_csv(tmp_path, capsys, monkeypatch):
    import csv

    _without_input_limits(monkeypatch)

    assert main(["sweep", "--json", "--push-force", "0", "1e12", "2", "--duration", "2", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    calm, blown = doc["rows"]
    assert calm["diverged"] is False and calm["diverged_at"] is None
    assert blown["diverged"] is True and blown["success"] is False and blown["failure"] == "diverged"
    assert blown["diverged_at"] == pytest.approx(0.505)  # the push starts at 0.5 s: MuJoCo resets in its first step
    with open(doc["results"], newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["diverged"] for r in rows] == ["False", "True"] and float(rows[1]["diverged_at_s"]) == 0.505
    assert rows[1]["failure"] == "diverged" and rows[1]["success"] == "False"


def test_the_lab_json_says_no_run_diverged(tmp_path, capsys):
    assert main(["lqr", "--json", "--no-video", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["diverged"] == [False] * 5 and doc["diverged_at"] == [None] * 5
