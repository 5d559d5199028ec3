"""``cartpole swingup``: the JSON contract (exact replay with our own mj_step loop), files, and error paths."""
import json

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.control.energy import EnergyOptions
from cartpole.models import SHIPPED_MJCF
from cartpole.mpc.options import MPCOptions
from cartpole.planning.options import PlanOptions
from cartpole.sim.options import LoopOptions
from mj_replay import replay_with_mj_step


def _check_contract(doc, method, out):
    assert doc["mjcf"] == str(SHIPPED_MJCF) and doc["method"] == method
    ro = doc["rollout"]
    n = len(ro["ctrl"])
    assert len(ro["t"]) == len(ro["qpos"]) == len(ro["qvel"]) == n + 1
    assert ro["push"] == [0.0] * n  # no pushes: n zeros
    assert np.allclose(ro["qpos"][0], [0, np.pi]) and np.allclose(ro["qvel"][0], [0, 0])
    qpos, qvel = replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
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
    # no --method: the default chose energy shaping for one pole driven by the cart, and it held
    assert [(t["method"], t["outcome"]) for t in doc["methods_tried"]] == [
        ("energy", "success"), ("trajopt", "skipped"), ("trajopt", "skipped")]
    assert doc["methods_tried"][2]["solver"] == "ddp" and doc["handover_at"] == doc["caught_at"]
    # the stages' settings, echoed
    assert doc["options"] == {"energy": EnergyOptions().as_dict(), "loop": LoopOptions().as_dict()}


def test_trajopt_json_contract_and_exact_replay(tmp_path, capsys):
    pytest.importorskip("cartpole.planning.trajopt")
    assert main(["swingup", "--method", "trajopt", "--json", "--no-video", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    _check_contract(doc, "trajopt", tmp_path)
    assert doc["options"] == {"plan": PlanOptions().as_dict(), "loop": LoopOptions().as_dict()}
    # the plan's report: every solver call, the guess that won among them, the kept plan's status and time
    plan = doc["plan"]
    kept = [a for a in plan["attempts"] if a["chosen"]]
    assert kept and all(a["success"] for a in kept) and plan["guess"] == kept[-1]["guess"]
    assert plan["status"] == kept[-1]["status"] and plan["iterations"] == kept[-1]["iterations"]
    assert plan["total_iterations"] == sum(a["iterations"] for a in plan["attempts"])
    assert plan["T"] == pytest.approx(doc["caught_at"], abs=0.01) and plan["T_min"] < plan["T"]
    assert plan["plan_time_s"] >= sum(a["solve_time_s"] for a in plan["attempts"])


def test_prose_summary(tmp_path, capsys):
    assert main(["swingup", "--no-video", "--out", str(tmp_path), "--duration", "6"]) == 0
    out = capsys.readouterr().out
    assert "SUCCESS" in out and "Caught at" in out and "time to upright" in out and "Peak |ctrl|" in out


@pytest.mark.parametrize("argv", [["--x0", "0", "nan", "0", "0"], ["--x0", "0", "3.14", "0"],
                                  ["--x0", "1.6", "3.14", "0", "0"], ["--duration", "-1"],
                                  ["--push", "abc"], ["--push", "1:nan"], ["--push", "-1:5"], ["--push", "1:2:3"],
                                  ["--model-error", "0"], ["--model-error", "nan"], ["--model-error", "x"],
                                  ["--period", "0.013"], ["--delay", "0.007"], ["--delay", "-0.01"],
                                  ["--estimator", "none", "--encoder-cpr", "2048"], ["--encoder-cpr", "0"],
                                  ["--sensor-noise", "nan"], ["--method", "trajopt", "--horizon", "1"],
                                  ["--method", "energy", "--time-budget", "60"], ["--time-budget", "0"],
                                  ["--method", "trajopt", "--ctrl-noise", "0.1"],
                                  ["--method", "energy", "--ctrl-noise", "1.5", "--encoder-cpr", "2048"],
                                  ["--method", "mpc", "--ctrl-noise", "0.1", "--encoder-cpr", "2048"],
                                  ["--method", "trajopt", "--search-s", "nan"], ["--mjcf", "NOT_A_CARTPOLE"]])
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


TWO_POLE = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")


def _fails_with_one_sentence(argv, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["swingup", "--json", "--no-video", "--out", str(out), *argv]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and lines[0].startswith("cartpole swingup: ")
    assert "Traceback" not in cap.err and not out.exists()
    return lines[0]


def test_energy_on_a_two_pole_cart_is_refused_with_the_controllers_sentence(tmp_path, capsys):
    line = _fails_with_one_sentence(["--mjcf", str(TWO_POLE), "--method", "energy"], tmp_path, capsys)
    assert "Energy shaping is for one pole" in line and "2 hinges" in line and "--method trajopt" in line


def test_x0_of_the_wrong_length_names_the_count_and_order(tmp_path, capsys):
    line = _fails_with_one_sentence(["--mjcf", str(TWO_POLE), "--method", "trajopt", "--x0", "0", "3.14", "0", "0"],
                                    tmp_path, capsys)
    assert "give exactly 6: slider (m), hinge (rad), hinge2 (rad), then their rates" in line


def _replays(doc, x0=None):
    ro = doc["rollout"]
    if x0 is not None:
        np.testing.assert_array_equal(np.hstack([ro["qpos"][0], ro["qvel"][0]]), x0)
    qpos, qvel = replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
    return np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))


def test_the_default_on_a_two_pole_cart_runs_the_planner_and_swings_up(tmp_path, capsys):
    """No --method on a chain: energy shaping does not apply (said, with why), the planner runs and holds both poles
    up; the DDP planner is not needed. The log replays exactly."""
    from cartpole.models import build_model

    pytest.importorskip("cartpole.planning.trajopt")
    out = tmp_path / "out"
    assert main(["swingup", "--json", "--no-video", "--mjcf", str(TWO_POLE), "--out", str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    tried = doc["methods_tried"]
    assert [(t["method"], t["solver"], t["outcome"]) for t in tried] == [
        ("energy", None, "not applicable"), ("trajopt", "auto", "success"), ("trajopt", "ddp", "skipped")]
    assert "2 hinges" in tried[0]["reason"] and tried[1]["seconds"] > 0
    assert doc["method"] == "trajopt" and doc["success"] is True and doc["plan"] is not None
    assert doc["caught_at"] is not None and doc["caught_at"] == doc["handover_at"]
    ro = doc["rollout"]
    assert np.array(ro["qpos"]).shape[1] == np.array(ro["qvel"]).shape[1] == 3 and np.array(ro["ctrl"]).shape[1] == 1
    assert _replays(doc, build_model(TWO_POLE).x_hanging)
    assert sorted(p.name for p in out.rglob("*") if p.is_file()) == ["swingup_trajopt.png"]


def test_the_default_falls_back_to_the_planner_on_a_short_rail_and_says_so(tmp_path, capsys):
    """The shipped cart on a rail of +-0.5 m: energy shaping's rail guard keeps the cart in but cannot pump the pole
    up there (failed in MuJoCo), the planner plans within the rail and swings up; prose and JSON say so."""
    pytest.importorskip("cartpole.planning.trajopt")
    short = tmp_path / "short_rail.xml"
    short.write_text(SHIPPED_MJCF.read_text().replace('range="-1.5 1.5"', 'range="-0.5 0.5"'))
    assert main(["swingup", "--json", "--no-video", "--mjcf", str(short), "--out", str(tmp_path / "out")]) == 0
    doc = json.loads(capsys.readouterr().out)
    tried = doc["methods_tried"]
    assert [(t["method"], t["outcome"]) for t in tried] == [("energy", "failed"), ("trajopt", "success"),
                                                          ("trajopt", "skipped")]
    assert tried[0]["reason"] and tried[0]["seconds"] > 0 and tried[2]["reason"] == "an earlier method succeeded"
    assert doc["method"] == "trajopt" and doc["success"] is True and _replays(doc)
    assert doc["figure"].endswith("swingup_trajopt.png")


def test_the_prose_says_which_methods_were_tried():
    from cartpole.apps.swingup import MethodTry
    from cartpole.commands.swingup import methods_sentence

    line = methods_sentence([MethodTry("energy", None, "failed", "cart reached its limit", 4.2),
                             MethodTry("trajopt", "auto", "failed", "not upright at rest over the last second", 30),
                             MethodTry("trajopt", "ddp", "success", "upright", 61.0)])
    assert line.startswith("Methods tried (--method auto): energy: failed after 4 s (cart reached its limit); "
                           "trajopt: failed after 30 s")
    assert "trajopt (ddp): success after 61 s (upright)" in line and line.endswith("Shown: the trajopt (ddp) run.")


def test_view_without_a_display_says_so_in_one_line_and_runs_as_usual(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("XDG_SESSION_TYPE", raising=False)
    assert main(["swingup", "--view", "desktop", "--json", "--no-video", "--duration", "0.5", "--out",
                 str(tmp_path)]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert doc["viewer"] is None and len(doc["rollout"]["ctrl"]) == 100
    (line,) = cap.err.strip().splitlines()
    assert line.startswith("cartpole swingup: no live view: No display for the live viewer (DISPLAY is not set)")
    assert (tmp_path / "figures" / "swingup_energy.png").exists()


def test_view_on_a_screen_shows_exactly_the_logged_run(tmp_path):
    import os
    import shutil
    import subprocess
    import sys

    if sys.platform != "linux" or shutil.which("Xvfb") is None:
        pytest.skip("needs Xvfb (apt-get install xvfb; .ci/run installs it)")
    r, w = os.pipe()
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "800x600x24", "-nolisten", "tcp"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(w)
    try:
        number = b""
        while not number.endswith(b"\n"):  # Xvfb writes the display number once it accepts connections
            chunk = os.read(r, 16)
            if not chunk:
                break
            number += chunk
        os.close(r)
        number = number.decode().strip()
        assert number, "Xvfb did not start"
        env = {**os.environ, "DISPLAY": f":{number}", "MUJOCO_GL": "egl"}
        env.pop("XDG_SESSION_TYPE", None)
        run = subprocess.run([sys.executable, "-m", "cartpole", "swingup", "--view", "--json", "--no-video",
                              "--duration", "0.5", "--out", str(tmp_path)], env=env, capture_output=True, text=True,
                             timeout=120)
    finally:
        xvfb.terminate()
        xvfb.wait(10)
    assert run.returncode == 0, run.stderr
    doc = json.loads(run.stdout)
    view = doc["viewer"]
    assert view is not None, run.stderr
    assert "--view: a display is available, so the desktop window" in run.stderr and "url" not in view
    # the window showed the run itself, stepped in real time: what it showed is what was logged
    assert view["steps_shown"] == len(doc["rollout"]["ctrl"]) == 100 and view["frames"] >= 2
    assert view["closed_early"] is False and view["wall_time"] >= 0.45  # real time: 0.5 s simulated
    qpos, qvel = replay_with_mj_step(doc["mjcf"], doc["rollout"]["qpos"][0], doc["rollout"]["qvel"][0],
                                      doc["rollout"]["ctrl"])
    assert np.array_equal(qpos, np.array(doc["rollout"]["qpos"]))


def test_objective_errors_end_in_one_sentence_and_no_files(tmp_path, capsys, monkeypatch):
    (tmp_path / "cli_costs.py").write_text("import math\n\ndef vec(x, u):\n    return x\n\n"
                                           "def nan(x, u):\n    return math.cos(x[1])\n\n"
                                           "def boom(x, u):\n    raise ValueError('no good')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    cases = [(["--objective", "no_such_mod_q:f"], "cannot be imported"),
             (["--objective", "cli_costs:missing"], "has no function 'missing'"),
             (["--objective", "cli_costs:vec"], "not a scalar"),
             (["--objective", "cli_costs:nan"], "casadi operations"),
             (["--objective", "cli_costs:boom"], "failed on CasADi symbols (ValueError: no good)"),
             (["--objective", "fastest"], "not known"),
             ([], "use it with --method trajopt")]
    for extra, words in cases:
        method = ["--method", "energy"] if not extra else ["--method", "trajopt"]  # no --method: the planner's
        line = _fails_with_one_sentence([*method, *(extra or ["--objective", "time"])], tmp_path, capsys)
        assert words in line, line


def test_trajopt_dmc_swingup_objective_reports_the_return(tmp_path, capsys):
    from chains import dmc_cartpole
    from cartpole.models import build_model
    from cartpole.sim import Rollout
    from cartpole.validation.metrics import dmc_swingup_return

    mjcf = tmp_path / "dmc.xml"
    mjcf.write_text(dmc_cartpole(1))
    assert main(["swingup", "--mjcf", str(mjcf), "--method", "trajopt", "--objective", "dmc_swingup", "--json",
                 "--no-video", "--out", str(tmp_path / "out")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["objective"] == "dmc_swingup" and doc["success"] is True and doc["return_steps"] == 1000
    ro = doc["rollout"]
    assert ro["t"][-1] == pytest.approx(10.0)  # dm_control's episode is simulated by default
    model = build_model(str(mjcf))
    run = Rollout(t=np.array(ro["t"]), qpos=np.array(ro["qpos"]), qvel=np.array(ro["qvel"]),
                  ctrl=np.array(ro["ctrl"]))
    assert doc["return"] == pytest.approx(dmc_swingup_return(run, model, 0.01), abs=1e-9)
    assert doc["return"] > 850


def test_push_and_model_error_json_replays_with_mj_step_and_its_pushes(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    assert main(["swingup", "--json", "--no-video", "--out", str(tmp_path), "--duration", "4", "--push", "1:25",
                 "--push", "2.5:-10", "--model-error", "1.1"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["push"] == [[1.0, 25.0], [2.5, -10.0]] and doc["model_error"] == 1.1
    ro = doc["rollout"]
    push = np.array(ro["push"])
    assert push.shape == (len(ro["ctrl"]),) and np.count_nonzero(push == 25.0) == np.count_nonzero(push == -10.0) == 20
    qpos, qvel = replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"], push)
    assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))
    unpushed, _ = replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
    assert not np.allclose(unpushed, np.array(ro["qpos"]))


def test_a_second_swingup_is_a_basin_cache_hit_with_the_identical_estimate(tmp_path, capsys, monkeypatch):
    import cartpole.validation.basin as basin_mod

    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    argv = ["swingup", "--json", "--no-video", "--out", str(tmp_path), "--duration", "1"]
    assert main(argv) == 0
    first = json.loads(capsys.readouterr().out)["basin"]
    monkeypatch.setattr(basin_mod, "estimate_basin", lambda *a, **k: pytest.fail("estimated again"))
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["basin"] == first


def test_mpc_json_contract_adds_solve_times_period_and_horizon(tmp_path, capsys):
    pytest.importorskip("cartpole.mpc.nmpc")
    assert main(["swingup", "--method", "mpc", "--json", "--no-video", "--out", str(tmp_path), "--push", "4:10",
                 "--horizon", "1.2"]) == 0
    doc = json.loads(capsys.readouterr().out)
    ro = doc["rollout"]
    assert doc["method"] == "mpc" and doc["horizon"] == 1.2 and doc["period"] > 0 and doc["basin"] is None
    opts = doc["options"]
    assert opts["mpc"] == MPCOptions(horizon=1.2).as_dict() and opts["plan"] == PlanOptions().as_dict()
    assert opts["loop"] == LoopOptions(push=[(4.0, 10.0)]).as_dict()
    hold = round(doc["period"] / (ro["t"][1] - ro["t"][0]))
    assert len(doc["solve_ms"]) == -(-len(ro["ctrl"]) // hold) and all(v > 0 for v in doc["solve_ms"])
    qpos, qvel = replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"], ro["push"])
    assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))
    assert doc["success"] is True


def test_swingup_says_which_joints_dry_friction_its_design_model_smooths(tmp_path, capsys):
    """Issue 38: the design model holds the undriven hinge's frictionloss as the smooth tanh, and says so."""
    mjcf = str(SHIPPED_MJCF.parent / "examples" / "cartpole_friction.xml")
    argv = ["swingup", "--no-video", "--duration", "0.5", "--mjcf", mjcf, "--out", str(tmp_path)]
    assert main(argv + ["--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    by = {e["joint"]: e for e in doc["smoothed_friction"]}
    assert by["slider"]["design"] == "cancelled" and by["hinge"]["design"] == "smooth"
    assert by["hinge"]["damping_at_rest"] == pytest.approx(by["hinge"]["frictionloss"] / by["hinge"]["width"])
    assert main(argv) == 0
    assert "hinge 0.002 N m as the smooth -0.002 tanh(qvel/" in capsys.readouterr().out


def test_library_sentences_are_rewritten_in_the_command_lines_options():
    from cartpole.commands._flags import as_flags

    text = ("`ctrl_noise` designs the catch; use it with `method='energy'` or `method='trajopt'` (`solver='ddp'`), "
            "raise the `time_budget`; `EnergyOptions` stays")
    assert as_flags(text) == ("--ctrl-noise designs the catch; use it with --method energy or --method trajopt "
                              "(--solver ddp), raise the --time-budget; `EnergyOptions` stays")


def test_a_search_budget_of_inf_is_no_wall_time_budget_and_nan_is_refused_naming_inf(tmp_path, capsys):
    import argparse

    from cartpole.commands.swingup import search_fields

    assert search_fields(argparse.Namespace(T_max=17.0, search_s=float("inf"))) == {"T_max": 17.0, "search_s": None}
    assert search_fields(argparse.Namespace(T_max=None, search_s=30.0)) == {"search_s": 30.0}
    line = _fails_with_one_sentence(["--method", "trajopt", "--search-s", "nan"], tmp_path, capsys)
    assert "--search-s inf" in line and "search_s=None" not in line
