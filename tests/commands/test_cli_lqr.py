"""`cartpole lqr`: the JSON contract, prose, files, metrics row appended, clean failures, and the printed
settling times reproduced by an independent mj_step replay of the printed K."""
import csv
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF

CONTRACT = {"mjcf", "K", "initial_conditions", "settling_times_seed", "settling_times", "mean_settling_time_seed",
            "settled", "figure", "video", "metrics"}


def handout_settling_time(t, history, threshold=0.05):
    """The lab handout's function, verbatim."""
    abs_theta = np.abs(history[:, 1])
    above = np.where(abs_theta > threshold)[0]
    if len(above) == 0:
        return 0.0
    return t[above[-1] + 1] if above[-1] + 1 < len(t) else t[-1]


def independent_replay(mjcf, K, x0, seconds=6.0):
    """Plain MuJoCo: u = -K x clipped to ctrlrange, mj_step, log every state (no cartpole code)."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(mjcf))
    d = mujoco.MjData(m)
    d.qpos[:] = x0[:2]
    d.qvel[:] = x0[2:]
    mujoco.mj_forward(m, d)
    n = int(round(seconds / m.opt.timestep))
    xs = [np.concatenate([d.qpos, d.qvel])]
    for _ in range(n):
        d.ctrl[:] = np.clip(-K @ xs[-1], *m.actuator_ctrlrange[0])
        mujoco.mj_step(m, d)
        xs.append(np.concatenate([d.qpos, d.qvel]))
    return np.arange(n + 1) * m.opt.timestep, np.array(xs)


@pytest.fixture(scope="module")
def lab_json(tmp_path_factory):
    out = tmp_path_factory.mktemp("lab")
    import io
    from contextlib import redirect_stdout

    buf = io.StringIO()
    with redirect_stdout(buf):
        assert main(["lqr", "--json", "--no-video", "--out", str(out)]) == 0
    return json.loads(buf.getvalue()), out


def test_json_follows_the_contract(lab_json):
    doc, out = lab_json
    assert CONTRACT <= set(doc)
    assert Path(doc["mjcf"]) == SHIPPED_MJCF
    assert np.array(doc["K"]).shape == (1, 4) and np.array(doc["initial_conditions"]).shape == (5, 4)
    assert len(doc["settling_times_seed"]) == len(doc["settling_times"]) == len(doc["settled"]) == 5
    assert all(isinstance(s, bool) for s in doc["settled"]) and all(doc["settled"])
    assert doc["mean_settling_time_seed"] == pytest.approx(np.mean(doc["settling_times_seed"]), abs=1e-15)
    assert doc["video"] is None
    assert Path(doc["figure"]) == (out / "figures" / "day5_cartpole_lqr.png").resolve()
    assert Path(doc["metrics"]) == (out / "metrics" / "metrics.csv").resolve()
    assert Path(doc["figure"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (out / "videos").exists()


def test_printed_settling_times_are_reproduced_by_an_independent_replay(lab_json):
    doc, _ = lab_json
    K = np.array(doc["K"])[0]
    for x0, ts_seed, ts_strict in zip(np.array(doc["initial_conditions"]), doc["settling_times_seed"],
                                      doc["settling_times"]):
        t, x = independent_replay(doc["mjcf"], K, x0)
        # the handout logged n states before each step; both conventions agree when the run settles
        assert ts_seed == pytest.approx(handout_settling_time(t[:-1], x[:-1]), abs=1e-12)
        inside = np.all(np.abs(x) <= 0.01, axis=1)
        k = len(t) - np.argmin(inside[::-1]) if not inside.all() else 0
        assert inside[-1] and ts_strict == pytest.approx(t[k], abs=1e-12)


def test_metrics_row_is_appended_not_overwritten(tmp_path, capsys):
    for _ in range(2):
        assert main(["lqr", "--json", "--no-video", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    rows = list(csv.reader((tmp_path / "metrics" / "metrics.csv").open()))
    assert rows[0][0] == "run_id" and len(rows) == 3
    for row in rows[1:]:
        assert len(row) == 13
        assert row[:4] == ["day5_cartpole_lqr", row[1], "5", "cartpole_lqr"]
        assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", row[1]) and re.fullmatch(r"[0-9a-f]{4,40}|nogit", row[4])
        assert row[5:8] == ["0", "cartpole", "lqr"] and row[8] == "1200" and row[9] == "1"
        assert row[10] == "settling_time_sec" and row[12] == "5_ICs"
        assert float(row[11]) == pytest.approx(doc["mean_settling_time_seed"], abs=5e-5)


def test_prose_prints_matrices_and_the_mean_line(lab_json, tmp_path, capsys):
    assert main(["lqr", "--no-video", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for word in ("A =", "B =", "K =", "Closed-loop eigenvalues"):
        assert word in out
    ts = re.findall(r"IC \d: .*settling time (\d+\.\d\d) s", out)
    line = re.search(r"^Mean settling time: (\d+\.\d\d) s ± (\d+\.\d\d) s across 5 initial conditions$", out, re.M)
    assert line and len(ts) == 5
    # recomputed from plain mj_step replays with the JSON's full-precision K (the prose rounds K)
    doc, _ = lab_json
    K = np.array(doc["K"])[0]
    ref = [handout_settling_time(*(a[:-1] for a in independent_replay(SHIPPED_MJCF, K, x0)))
           for x0 in np.array(doc["initial_conditions"])]
    assert line.groups() == (f"{np.mean(ref):.2f}", f"{np.std(ref):.2f}")
    assert ts == [f"{v:.2f}" for v in ref]


def test_stdout_is_pure_json_through_python_m(tmp_path):
    r = subprocess.run([sys.executable, "-m", "cartpole", "lqr", "--json", "--no-video", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert CONTRACT <= set(json.loads(r.stdout))


def test_video_is_10_s_at_30_fps(tmp_path, capsys):
    import imageio_ffmpeg

    assert main(["lqr", "--json", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    if doc["video"] is None:
        pytest.skip(f"no OpenGL backend on this machine: {cap.err.strip()}")
    assert Path(doc["video"]) == (tmp_path / "videos" / "day5_cartpole.mp4").resolve()
    frames, secs = imageio_ffmpeg.count_frames_and_secs(doc["video"])
    gen = imageio_ffmpeg.read_frames(doc["video"])
    meta = next(gen)
    gen.close()
    assert frames == 300 and tuple(meta["size"]) == (960, 540) and meta["fps"] == 30
    assert "\r" not in cap.err and "%" not in cap.err  # --json: no progress fragments anywhere
    assert sorted(p.name for p in (tmp_path / "videos").iterdir()) == ["day5_cartpole.gif", "day5_cartpole.mp4"]


def test_no_gl_backend_still_writes_the_rest(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MUJOCO_GL"] = "glx"
    r = subprocess.run([sys.executable, "-m", "cartpole", "lqr", "--json", "--out", str(tmp_path)],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["video"] is None and Path(doc["figure"]).is_file() and Path(doc["metrics"]).is_file()
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "video" in lines[0] and "OpenGL" in lines[0]
    assert not (tmp_path / "videos").exists()


@pytest.mark.parametrize("case", ["missing", "not_a_cartpole"])
def test_bad_mjcf_exits_2_with_one_line_and_writes_nothing(case, tmp_path, capsys):
    from variants import variant_xml

    bad = tmp_path / "in" / "model.xml"
    if case == "not_a_cartpole":
        bad.parent.mkdir()
        bad.write_text(variant_xml("rk4_fine_step").replace('type="slide" axis="1 0 0"', 'type="ball"'))
    out = tmp_path / "out"
    assert main(["lqr", "--json", "--mjcf", str(bad), "--out", str(out)]) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartpole lqr: ") and "Traceback" not in cap.err
    assert ("does not exist" in lines[0]) if case == "missing" else ("ball" in lines[0])
    assert not out.exists()


def _lqr_json(capsys, *argv):
    assert main(["lqr", "--json", "--no-video", *argv]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("asset", ["cartpole_two_pole.xml", "cartpole_three_pole.xml"])
def test_chain_lab_settles_from_all_five_starts_and_its_rollouts_replay(asset, tmp_path, capsys):
    from cartpole.models import build_model, wrap_angle
    from cartpole.sim import Rollout, replays_exactly

    path = SHIPPED_MJCF.with_name(asset)
    doc = _lqr_json(capsys, "--mjcf", str(path), "--out", str(tmp_path))
    model = build_model(path)
    nx = model.nx
    assert CONTRACT <= set(doc) and doc["mjcf"] == str(path)
    assert np.array(doc["K"]).shape == (1, nx) and np.array(doc["initial_conditions"]).shape == (5, nx)
    assert doc["settled"] == [True] * 5 and doc["start_scale"] == 1.0
    x_eq = np.array(doc["x_eq"])
    for row, x0 in zip(doc["rollouts"], doc["initial_conditions"]):
        run = Rollout(t=row["t"], qpos=row["qpos"], qvel=row["qvel"], ctrl=row["ctrl"])
        assert run.qpos.shape[1] == model.nq and run.ctrl.shape[1] == model.nu
        np.testing.assert_array_equal(run.x[0], x0)
        assert replays_exactly(run, doc["mjcf"])
        e = run.x[-1] - x_eq
        e[list(model.hinges)] = wrap_angle(e[list(model.hinges)])
        assert np.abs(e).max() < 0.01  # at rest upright at the end, checked without the metrics module
    assert Path(doc["figure"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    row = list(csv.reader((tmp_path / "metrics" / "metrics.csv").open()))[-1]
    assert row[12] == f"5_ICs_{len(model.hinges)}_poles"
    assert float(row[11]) == pytest.approx(doc["mean_settling_time_seed"], abs=5e-5)


def test_chain_prose_names_the_first_pole_and_prints_the_mean_line(tmp_path, capsys):
    path = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
    assert main(["lqr", "--no-video", "--mjcf", str(path), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert len(re.findall(r"IC \d: hinge = .* deg, x0 = .* m: settling time", out)) == 5
    assert re.search(r"^Mean settling time: \d+\.\d\d s ± \d+\.\d\d s across 5 initial conditions$", out, re.M)
    assert "scaled" not in out


def test_q_and_r_override_the_lab_weights(tmp_path, capsys):
    import scipy.linalg

    from cartpole.models import build_model

    doc = _lqr_json(capsys, "--Q", "2", "10", "0.1", "0.1", "--R", "1", "--out", str(tmp_path))
    A, B = build_model().linearize()
    S = scipy.linalg.solve_continuous_are(A, B, np.diag([2, 10, 0.1, 0.1]), [[1.0]])
    np.testing.assert_allclose(doc["K"], B.T @ S, rtol=1e-10)
    assert doc["Q"] == np.diag([2, 10, 0.1, 0.1]).tolist() and doc["R"] == [[1.0]]
    full = _lqr_json(capsys, "--Q", *map(str, np.diag([2, 10, 0.1, 0.1]).ravel()), "--R", "1", "--out",
                     str(tmp_path))
    assert full["K"] == doc["K"]


@pytest.mark.parametrize("argv, count, names", [(["--Q", "1", "10", "0.1"], "give 6 ", "hinge2 rate (rad/s)"),
                                                 (["--R", "1", "2"], "give 1 ", "u = [motor]")])
def test_weights_of_the_wrong_size_are_one_sentence(argv, count, names, tmp_path, capsys):
    out = tmp_path / "out"
    path = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
    assert main(["lqr", "--json", "--no-video", "--mjcf", str(path), "--out", str(out), *argv]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and lines[0].startswith("cartpole lqr: --")
    assert count in lines[0] and names in lines[0]
    assert not out.exists()


def test_starts_scaled_for_a_model_are_said_in_prose_and_json(chain_dir, tmp_path, capsys):
    from cartpole.apps.lab import lab_initial_conditions, lab_start_scale

    path = chain_dir / "dmc_3poles.xml"
    doc = _lqr_json(capsys, "--mjcf", str(path), "--out", str(tmp_path))
    scale = lab_start_scale(path)
    assert doc["start_scale"] == scale < 1 and doc["settled"] == [True] * 5
    np.testing.assert_array_equal(doc["initial_conditions"], lab_initial_conditions(path, scale=scale))
    assert main(["lqr", "--no-video", "--mjcf", str(path), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"all five are scaled by {scale:g}" in out
    # starts the scaling put inside the 0.05 rad band are not in the mean: the row says how many are (issue 38)
    n = sum(doc["counted"])
    counted = "" if n == 5 else f"_{n}_counted"
    row = list(csv.reader((tmp_path / "metrics" / "metrics.csv").open()))[-1]
    assert row[12] == f"5_ICs_3_poles_scaled_{scale:g}{counted}"


# ---- --compare-pid: the cascaded PID beside the LQR from the same five starts -----------------------------------

PID_KEYS = {"gains", "settling_times_seed", "settling_times", "mean_settling_time_seed", "settled", "peak_ctrl",
            "cart_excursion", "rollouts"}


def mj_step_replay(mjcf, x0, ctrl, push):
    """Plain MuJoCo (no cartpole code): from x0, apply each logged ctrl and push for one mj_step; every state."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(mjcf))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = x0[:m.nq], x0[m.nq:]
    mujoco.mj_forward(m, d)
    cart = m.jnt_bodyid[0]
    xs = [np.concatenate([d.qpos, d.qvel])]
    for u, f in zip(ctrl, push):
        d.ctrl[:] = u
        d.xfrc_applied[cart, 0] = f
        mujoco.mj_step(m, d)
        xs.append(np.concatenate([d.qpos, d.qvel]))
    return np.array(xs)


@pytest.fixture(scope="module")
def pid_json(tmp_path_factory):
    import io
    from contextlib import redirect_stderr, redirect_stdout

    out = tmp_path_factory.mktemp("pid")
    buf, err = io.StringIO(), io.StringIO()
    with redirect_stdout(buf), redirect_stderr(err):
        assert main(["lqr", "--json", "--no-video", "--compare-pid", "--out", str(out)]) == 0
    return json.loads(buf.getvalue()), out, err.getvalue()


def test_compare_pid_balances_all_five_starts_and_every_pid_rollout_replays_exactly(pid_json):
    from cartpole.control.pid import tune_pid

    doc, _, err = pid_json
    pid = doc["pid"]
    assert CONTRACT <= set(doc) and PID_KEYS <= set(pid) and err == ""
    assert pid["gains"] == json.loads(json.dumps(tune_pid(None).to_dict()))
    assert pid["settled"] == [True] * 5 and len(pid["rollouts"]) == 5
    for row, lqr_row, x0 in zip(pid["rollouts"], doc["rollouts"], doc["initial_conditions"]):
        assert set(row) == set(lqr_row) == {"t", "qpos", "qvel", "ctrl", "push"}
        assert row["push"] == [0.0] * len(row["ctrl"]) and row["t"] == lqr_row["t"]  # same duration and step
        logged = np.hstack([row["qpos"], row["qvel"]])
        np.testing.assert_array_equal(logged[0], x0)  # the LQR's own start
        np.testing.assert_array_equal(mj_step_replay(doc["mjcf"], logged[0], row["ctrl"], row["push"]), logged)
        assert np.abs(logged[-1]).max() < 0.01  # balanced upright at rest at x* = 0, checked without the metrics
        assert row["ctrl"] != lqr_row["ctrl"]


def test_compare_pid_writes_one_png_figure_under_out_beside_the_lqr_figure(pid_json):
    doc, out, _ = pid_json
    assert Path(doc["pid"]["figure"]) == (out / "figures" / "day5_cartpole_pid_vs_lqr.png").resolve()
    assert Path(doc["pid"]["figure"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert Path(doc["figure"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (out / "figures").iterdir()) == ["day5_cartpole_lqr.png",
                                                                    "day5_cartpole_pid_vs_lqr.png"]


def _strict_settling(t, x, tol=0.01):
    inside = np.all(np.abs(x) <= tol, axis=1)
    if not inside[-1]:
        return np.inf
    outside = np.flatnonzero(~inside)
    return t[outside[-1] + 1] if outside.size else t[0]


def test_printed_table_equals_the_metrics_recomputed_from_the_json_rollouts(pid_json, tmp_path, capsys):
    doc, _, _ = pid_json
    assert main(["lqr", "--no-video", "--compare-pid", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    head = next(i for i, line in enumerate(lines) if re.fullmatch(r"\s+IC 1\s+IC 2\s+IC 3\s+IC 4\s+IC 5\s+mean", line))
    table = [re.findall(r"\b(LQR|PID)\s+(.*)$", line)[0] for line in lines[head + 1:head + 9]]
    assert [name for name, _ in table] == ["LQR", "PID"] * 4
    printed = {}
    for k, (name, cells) in enumerate(table):
        printed[(k // 2, name)] = cells.split()
    # recomputed here from the JSON's logs (x* = 0 on the shipped cart), not with cartpole.validation.metrics
    for name, side in (("LQR", doc), ("PID", doc["pid"])):
        stats = [[], [], [], []]
        for row in side["rollouts"]:
            t, x = np.array(row["t"]), np.hstack([row["qpos"], row["qvel"]])
            stats[0].append(handout_settling_time(t[:-1], x[:-1]))  # settled runs: both conventions agree
            stats[1].append(_strict_settling(t, x))
            stats[2].append(np.abs(row["ctrl"]).max())
            stats[3].append(np.abs(np.array(row["qpos"])[:, 0]).max())
        for k, vals in enumerate(stats):
            expect = [f"{v:.3f}" for v in vals] + [f"{np.mean(vals):.3f}"]
            assert printed[(k, name)] == expect, (k, name)
        # and the JSON's own numbers are those
        np.testing.assert_allclose(side["peak_ctrl"], stats[2], rtol=0, atol=0)
        np.testing.assert_allclose(side["cart_excursion"], stats[3], rtol=0, atol=0)
        np.testing.assert_allclose(side["settling_times"], stats[1], rtol=0, atol=1e-12)
    assert re.search(r"^Wrote .*day5_cartpole_pid_vs_lqr\.png$", out, re.M)


def test_compare_pid_on_a_two_pole_cart_is_a_note_and_the_lqr_lab_runs_as_usual(tmp_path, capsys):
    from cartpole.control.pid import PIDError, check_cascade
    from cartpole.models import build_model

    path = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")
    with pytest.raises(PIDError) as refusal:
        check_cascade(build_model(path))
    assert main(["lqr", "--json", "--no-video", "--compare-pid", "--mjcf", str(path), "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert cap.err.strip().splitlines() == [f"cartpole lqr: --compare-pid skipped: {refusal.value}"]
    assert doc["pid"] == {"skipped": str(refusal.value)}
    assert CONTRACT <= set(doc) and doc["settled"] == [True] * 5
    assert sorted(p.name for p in (tmp_path / "figures").iterdir()) == ["day5_cartpole_lqr.png"]
    assert (tmp_path / "metrics" / "metrics.csv").is_file()


# ---- --view desktop without a display: the viewer's sentence on stderr, the rest as usual ----------------------
# (--view alone there picks the web page: tests/commands/test_cli_view_web.py)

def test_view_without_a_display_says_so_and_writes_every_output(tmp_path, capsys, monkeypatch):
    from cartpole.sim import Rollout, replays_exactly

    for var in ("DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(var, raising=False)
    assert main(["lqr", "--json", "--no-video", "--view", "desktop", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartpole lqr: No display for the live viewer")
    assert "DISPLAY is not set" in lines[0] and "Traceback" not in cap.err
    assert CONTRACT <= set(doc) and doc["settled"] == [True] * 5
    assert Path(doc["figure"]).is_file() and Path(doc["metrics"]).is_file()
    first = doc["rollouts"][0]
    assert replays_exactly(Rollout(t=first["t"], qpos=first["qpos"], qvel=first["qvel"], ctrl=first["ctrl"]),
                           doc["mjcf"])


def test_friction_is_reported_and_no_friction_compensation_turns_the_feedforward_off(tmp_path, capsys):
    mjcf = str(SHIPPED_MJCF.parent / "examples" / "cartpole_friction.xml")
    on = _lqr_json(capsys, "--mjcf", mjcf, "--out", str(tmp_path / "on"))
    off = _lqr_json(capsys, "--mjcf", mjcf, "--no-friction-compensation", "--out", str(tmp_path / "off"))
    assert on["friction"] == {"frictionloss": {"slider": 0.5, "hinge": 0.002}, "compensation": True}
    assert off["friction"]["compensation"] is False
    assert np.array(on["residual_error"]).shape == (5, 4)
    # the feedforward changes the runs: the logged ctrl differs, the gain does not
    assert on["K"] == off["K"] and on["settling_times_seed"] != off["settling_times_seed"]
    assert _lqr_json(capsys, "--out", str(tmp_path / "plain"))["friction"] is None
    assert main(["lqr", "--mjcf", mjcf, "--no-video", "--out", str(tmp_path / "prose")]) == 0
    assert "Friction (frictionloss slider 0.5, hinge 0.002): designed without" in capsys.readouterr().out


def test_delay_margin_writes_its_figure_and_the_curve_behind_it(tmp_path, capsys):
    doc = _lqr_json(capsys, "--delay-margin", "0.01", "--period", "0.005", "--out", str(tmp_path))
    runs = doc["delay_margin"]["lqr_runs"]
    assert [r["delay"] for r in runs] == pytest.approx([0.0, 0.005, 0.01]) and all(r["balances"] for r in runs)
    assert doc["delay_margin"]["lqr"] == pytest.approx(0.01) and doc["delay_margin"]["lqr_first_failure"] is None
    assert Path(doc["figure"]) == (tmp_path / "figures" / "delay_margin.png").resolve()
    assert Path(doc["figure"]).read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("argv, says", [(["--noise-margin", "0"], "--noise-margin 0 is not a sensor noise"),
                                        (["--delay-margin", "-1"], "--delay-margin -1 is not a delay"),
                                        (["--delay-margin", "0.01", "--noise-margin", "0.01"], "one at a time")])
def test_bad_margin_searches_are_one_sentence_and_write_nothing(argv, says, tmp_path, capsys):
    assert main(["lqr", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


# ---- an honest lab (issue 38) -------------------------------------------------------------------------------------

TEST_ASSETS = Path(__file__).resolve().parent.parent / "assets"


def test_heavy_cart_prints_no_vacuous_mean_and_says_why_its_starts_were_shrunk(tmp_path, capsys):
    mjcf = str(TEST_ASSETS / "heavy_cart.xml")
    doc = _lqr_json(capsys, "--mjcf", mjcf, "--out", str(tmp_path / "json"))
    assert CONTRACT <= set(doc) and doc["start_scale"] < 1 and "ctrl limit" in doc["start_scale_reason"]
    assert doc["counted"] == [False] * 5 and doc["mean_settling_time_seed"] is None
    tau = 1.0 / min(-np.array(doc["closed_loop_eigenvalues"]["real"]))
    assert doc["slowest_time_constant_s"] == pytest.approx(tau)
    assert main(["lqr", "--no-video", "--mjcf", mjcf, "--out", str(tmp_path / "prose")]) == 0
    out = capsys.readouterr().out
    assert "Mean settling time: 0.00 s" not in out and "settling time 0.00 s" not in out
    assert "Mean settling time: none" in out and out.count("inside the 0.05 rad band from the start") == 5
    assert f"Slowest closed-loop time constant: {tau:.3g} s" in out and "ctrl limit" in out


def test_slow_heavy_cart_says_it_did_not_settle_by_how_much_and_the_duration_that_would(tmp_path, capsys):
    mjcf = str(TEST_ASSETS / "heavy_slow_cart.xml")
    doc = _lqr_json(capsys, "--mjcf", mjcf, "--out", str(tmp_path / "json"))
    assert doc["start_scale"] == 1.0 and doc["start_scale_reason"] is None and doc["settled"] == [False] * 5
    assert doc["counted"] == [True] * 5 and doc["mean_settling_time_seed"] == pytest.approx(
        np.mean(doc["settling_times_seed"]))
    for why in doc["not_settled"]:
        assert why["reason"] == "slow" and why["final_angle_error"] < 0.05 < why["final_error"]
        assert why["linear_settling_time"] > doc["duration"]
    assert main(["lqr", "--no-video", "--mjcf", mjcf, "--out", str(tmp_path / "prose")]) == 0
    out = capsys.readouterr().out
    assert f"slowest time constant, {doc['slowest_time_constant_s']:.3g} s" in out
    longer = float(re.search(r"--duration (\S+)\.", out).group(1))
    assert longer > max(w["linear_settling_time"] for w in doc["not_settled"])
    assert out.count("NOT settled in 6 s") == 5 and "the run is too short" in out


def test_lqr_duration_sets_each_run_length(tmp_path, capsys):
    doc = _lqr_json(capsys, "--duration", "2", "--out", str(tmp_path))
    assert doc["duration"] == 2.0 and all(r["t"][-1] == pytest.approx(2.0) for r in doc["rollouts"])


def test_lqr_says_which_joints_dry_friction_its_design_leaves_out(tmp_path, capsys):
    mjcf = str(SHIPPED_MJCF.parent / "examples" / "cartpole_friction.xml")
    on = _lqr_json(capsys, "--mjcf", mjcf, "--out", str(tmp_path / "on"))
    by = {e["joint"]: e for e in on["smoothed_friction"]}
    assert by["slider"]["design"] == "cancelled" and by["hinge"]["design"] == "omitted"
    assert by["slider"]["frictionloss"] == 0.5 and by["hinge"]["frictionloss"] == 0.002
    assert _lqr_json(capsys, "--out", str(tmp_path / "plain"))["smoothed_friction"] == []


def test_view_on_a_screen_shows_the_first_start_in_the_desktop_window(tmp_path):
    """Under Xvfb, ``--view`` alone picks MuJoCo's window and says so; the lab runs as usual (the web page's options
    are not involved), the first start's logged run being the one shown."""
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
        run = subprocess.run([sys.executable, "-m", "cartpole", "lqr", "--view", "--json", "--no-video",
                              "--duration", "1", "--out", str(tmp_path)], env=env, capture_output=True, text=True,
                             timeout=300)
    finally:
        xvfb.terminate()
        xvfb.wait(10)
    assert run.returncode == 0, run.stderr
    assert "--view: a display is available, so the desktop window" in run.stderr
    assert "No display" not in run.stderr and "differs" not in run.stderr
    doc = json.loads(run.stdout)
    assert "live" not in doc or doc["live"] is None
    assert len(doc["settling_times"]) == 5
