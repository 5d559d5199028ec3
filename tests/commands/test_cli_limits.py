"""Files that leave limits open, and starts on a range's edge, on the command line: a cart-pole without ctrlrange
balances (its LQR runs replayed with mj_step) and swings up within a default bound the JSON and the prose state; an
unlimited rail swings up; ``--u-max`` and ``--cart-max`` change the bounds; the default hanging start on a hinge
limited to +-3.14159 is moved onto the edge and said, 0.1 rad out it is refused naming ``--x0``; a refusal about a
file under a 400-character path still ends with its fix."""
import json

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF
from mj_replay import replay_with_mj_step

LAB = SHIPPED_MJCF.read_text()
NO_CTRLRANGE = LAB.replace(' ctrlrange="-1 1"', "")
NO_RAIL = LAB.replace('limited="true" range="-1.5 1.5"', 'range="-inf inf" limited="false"')
NO_LIMITS = NO_CTRLRANGE.replace('limited="true" range="-1.5 1.5"', 'limited="false"')


def hinge_range(half: float) -> str:
    return LAB.replace('<joint name="hinge" type="hinge" axis="0 1 0" damping="0.01"/>',
                       f'<joint name="hinge" type="hinge" axis="0 1 0" damping="0.01" range="{-half} {half}"/>'
                       ).replace('<mujoco model="cartpole">', '<mujoco model="cartpole">\n  <compiler angle="radian"/>')


def write(tmp_path, name, xml):
    path = tmp_path / name
    path.write_text(xml)
    return path


def run_json(argv, capsys):
    rc = main(argv)
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    return json.loads(cap.out), cap.err


def replays(doc_mjcf, ro) -> bool:
    qpos, qvel = replay_with_mj_step(doc_mjcf, ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
    return np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))


def test_a_cart_pole_without_ctrlrange_balances_and_its_runs_replay(tmp_path, capsys):
    mjcf = write(tmp_path, "no_ctrlrange.xml", NO_LIMITS)
    doc, _ = run_json(["lqr", "--json", "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "o")], capsys)
    assert all(doc["settled"]) and not any(doc["diverged"])
    assert all(replays(doc["mjcf"], ro) for ro in doc["rollouts"])


def test_energy_swings_up_a_file_without_ctrlrange_within_the_stated_default(tmp_path, capsys):
    mjcf = write(tmp_path, "no_ctrlrange.xml", NO_CTRLRANGE)
    doc, _ = run_json(["swingup", "--json", "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "o")], capsys)
    lim = doc["limits"]
    assert lim["u_source"] == ["default"] and lim["cart_source"] == "file" and lim["defaulted"] is True
    u = lim["u_high"][0]
    assert 0 < u < np.inf and lim["u_low"] == [-u] and any("--u-max" in n for n in lim["notes"])
    assert doc["success"] is True and replays(doc["mjcf"], doc["rollout"])
    assert np.max(np.abs(doc["rollout"]["ctrl"])) <= u  # the controllers kept to the bound the file does not clamp
    main(["swingup", "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "p")])
    prose = capsys.readouterr().out
    assert "no ctrlrange" in prose and f"{u:.4g}" in prose and "--u-max" in prose


def test_energy_swings_up_on_an_unlimited_rail_kept_within_the_stated_default(tmp_path, capsys):
    mjcf = write(tmp_path, "no_rail.xml", NO_RAIL)
    doc, _ = run_json(["swingup", "--json", "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "o")], capsys)
    lo, hi = doc["limits"]["cart_range"]
    assert doc["limits"]["cart_source"] == "default" and np.isfinite([lo, hi]).all() and lo < 0 < hi
    assert doc["success"] is True and replays(doc["mjcf"], doc["rollout"])
    s = np.array(doc["rollout"]["qpos"])[:, 0]
    assert lo < s.min() and s.max() < hi


def test_u_max_and_cart_max_change_the_bounds(tmp_path, capsys):
    mjcf = write(tmp_path, "no_limits.xml", NO_LIMITS)
    doc, _ = run_json(["swingup", "--json", "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "o"),
                       "--u-max", "0.8", "--cart-max", "2.5"], capsys)
    lim = doc["limits"]
    assert lim["u_high"] == [0.8] and lim["u_source"] == ["u_max"] and lim["cart_range"] == [-2.5, 2.5]
    assert lim["cart_source"] == "cart_max" and lim["notes"] == []
    assert np.max(np.abs(doc["rollout"]["ctrl"])) <= 0.8 and replays(doc["mjcf"], doc["rollout"])


def test_a_u_max_beyond_the_files_ctrlrange_is_one_sentence(tmp_path, capsys):
    rc = main(["swingup", "--no-video", "--out", str(tmp_path / "o"), "--u-max", "3"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "--u-max at most 1" in err and err.endswith(".")
    assert not (tmp_path / "o" / "figures").exists()


def test_the_default_start_a_hair_outside_a_hinge_range_is_moved_and_said(tmp_path, capsys):
    # energy shaping for 1.5 s: the start is the claim here (the default method's whole run on such a file, a failed
    # search against the range's wall, is the corpus's hinge_range_pi.xml, tests/commands/test_cli_corpus.py)
    mjcf = write(tmp_path, "hinge_314159.xml", hinge_range(3.14159))
    argv = ["swingup", "--method", "energy", "--duration", "1.5", "--no-video", "--mjcf", str(mjcf)]
    doc, _ = run_json([*argv, "--json", "--out", str(tmp_path / "o")], capsys)
    (move,) = doc["start_moved"]
    assert move["joint"] == "hinge" and move["before"] == np.pi and move["after"] == pytest.approx(3.14159)
    assert doc["rollout"]["qpos"][0][1] == pytest.approx(3.14159) and "--x0" in move["note"]
    assert replays(doc["mjcf"], doc["rollout"])
    assert main([*argv, "--out", str(tmp_path / "p")]) == 0
    assert move["note"] in capsys.readouterr().out  # said in prose too


def test_a_default_start_far_outside_a_range_is_refused_naming_x0(tmp_path, capsys):
    mjcf = write(tmp_path, "hinge_304.xml", hinge_range(3.04))
    rc = main(["swingup", "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "outside its joint range" in err and "--x0" in err


def test_a_refusal_about_a_file_under_a_400_character_path_ends_with_its_fix(tmp_path, capsys):
    deep = tmp_path
    while len(str(deep)) < 400:
        deep = deep / ("d" * 60)
    deep.mkdir(parents=True)
    bad = LAB.replace('<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/>',
                      '<general name="motor" joint="slider" gear="20" ctrlrange="-1 1" dyntype="filter" '
                      'dynprm="0.1"/>')
    mjcf = write(deep, "filtered_motor.xml", bad)
    assert len(str(mjcf)) > 400
    rc = main(["lqr", "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert err.endswith("or a <position>/<velocity> servo without timeconst."), err  # the fix's last words
    assert "filtered_motor.xml" in err and "..." in err and str(mjcf) not in err  # the path lost its middle only


def test_every_command_that_plans_offers_u_max_and_cart_max():
    import argparse

    from cartpole.cli import build_parser

    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    for name in ("swingup", "sweep", "feedforward", "export", "bench"):
        options = {o for a in sub.choices[name]._actions for o in a.option_strings}
        assert {"--u-max", "--cart-max"} <= options, name
    assert "--u-max" not in {o for a in sub.choices["lqr"]._actions for o in a.option_strings}  # balancing: none


def test_a_sweep_on_a_file_without_limits_plans_within_the_stated_defaults(tmp_path, capsys):
    mjcf = write(tmp_path, "no_limits.xml", NO_LIMITS)
    doc, _ = run_json(["sweep", "--json", "--n", "1", "--workers", "1", "--mjcf", str(mjcf), "--out",
                       str(tmp_path / "o")], capsys)
    assert doc["limits"]["defaulted"] is True and doc["limits"]["u_source"] == ["default"]
    assert doc["limits"]["cart_source"] == "default" and doc["successes"] == 1


def test_an_exported_swingup_controller_of_a_file_without_limits_states_them(tmp_path, capsys):
    import shutil

    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    mjcf = write(tmp_path, "no_limits.xml", NO_LIMITS)
    doc, _ = run_json(["export", "--json", "--controller", "energy", "--verify", "--duration", "6", "--mjcf",
                       str(mjcf), "--out", str(tmp_path / "o")], capsys)
    assert doc["limits"]["defaulted"] is True and doc["export"]["verified"] is True
    balance, _ = run_json(["export", "--json", "--controller", "lqr", "--mjcf", str(mjcf), "--out",
                           str(tmp_path / "p")], capsys)
    assert balance["limits"] is None  # a balance needs no bound


def test_the_planners_search_options_belong_to_the_planner(tmp_path, capsys):
    rc = main(["swingup", "--method", "energy", "--no-video", "--out", str(tmp_path / "o"), "--T-max", "20"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "--T-max" in err and "--method trajopt" in err and err.endswith(".")
    from cartpole.commands.swingup import search_fields

    class Args:
        T_max, search_s = 20.0, None

    assert search_fields(Args()) == {"T_max": 20.0}  # what PlanOptions(T_max=...) receives with --method trajopt


@pytest.mark.parametrize("command", [["swingup"], ["feedforward"], ["export", "--controller", "energy"],
                                     ["export", "--controller", "tvlqr"], ["sweep", "--n", "1"]])
def test_every_command_that_starts_a_run_refuses_a_default_start_far_outside_a_range_naming_its_x0(
        tmp_path, capsys, command):
    from cartpole.cli import build_parser
    import argparse

    mjcf = write(tmp_path, "hinge_304.xml", hinge_range(3.04))
    argv = [*command, "--no-video", "--mjcf", str(mjcf), "--out", str(tmp_path / "o")]
    argv = [a for a in argv if not (a == "--no-video" and command[0] in ("export", "sweep"))]
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "outside its joint range" in err and "--x0" in err, err
    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    assert "--x0" in sub.choices[command[0]]._option_string_actions  # the option it names exists there
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_export_and_sweep_start_a_hair_outside_a_hinge_range_on_its_edge_and_say_so(tmp_path, capsys):
    mjcf = write(tmp_path, "hinge_314159.xml", hinge_range(3.14159))
    doc, _ = run_json(["export", "--controller", "energy", "--json", "--mjcf", str(mjcf),
                       "--out", str(tmp_path / "c")], capsys)
    (move,) = doc["start_moved"]
    assert move["before"] == np.pi and doc["x0"][1] == move["after"] == pytest.approx(3.14159)
    assert main(["export", "--controller", "energy", "--mjcf", str(mjcf), "--out", str(tmp_path / "d")]) == 0
    assert move["note"] in capsys.readouterr().out  # said in prose too
    doc, _ = run_json(["sweep", "--json", "--n", "3", "--duration", "0.5", "--workers", "1", "--mjcf", str(mjcf),
                       "--out", str(tmp_path / "s")], capsys)
    angles = [r["start"][1] for r in doc["rows"]]  # [cart, hinge, rates]
    assert len(angles) == 3 and all(abs(a) <= 3.14159 for a in angles)  # the start box is cut by the range
    assert [m["after"] for m in doc["start_moved"]] == [move["after"]]  # and its centre's move said
