"""``cartpole sweep``: the JSON contract of DESIGN.md, the CSV results file, the same rows for 1 and 2 workers and
through a real local Dask cluster, interrupt and --resume, the success map, and clean refusals."""
import csv
import json

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF
from cartpole.apps.sweep import sweep_starts


def _sweep(capsys, *argv):
    assert main(["sweep", "--json", *argv]) == 0
    cap = capsys.readouterr()
    assert cap.err == ""  # --json: no progress
    return json.loads(cap.out)


def test_sweep_json_follows_the_contract_and_the_csv_holds_the_rows(tmp_path, capsys):
    doc = _sweep(capsys, "--n", "4", "--seed", "0", "--out", str(tmp_path))
    assert doc["mjcf"] == str(SHIPPED_MJCF) and doc["method"] == "energy" and doc["n"] == 4
    rows = doc["rows"]
    assert [r["run"] for r in rows] == [0, 1, 2, 3]  # run order
    np.testing.assert_allclose([r["start"] for r in rows], sweep_starts(4, seed=0))
    assert doc["successes"] == sum(r["success"] for r in rows)
    # a success is a swing-up that holds and whose log replays exactly with mj_step; the energy sweep's
    # documented box swings up every time on the shipped asset
    assert all(r["success"] and r["replays"] and 0 < r["time_to_upright"] < 10 for r in rows)
    results = tmp_path / "sweeps" / "sweep_energy.csv"
    assert doc["results"] == str(results.resolve())
    with open(results, newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [int(t["run"]) for t in table] == [0, 1, 2, 3]
    for t, r in zip(table, rows):
        start = [float(t[k]) for k in ("x0_slider", "x0_hinge", "x0_slider_rate", "x0_hinge_rate")]
        assert start == r["start"]  # written with repr: the same doubles
        assert t["success"] == str(r["success"]) and float(t["time_to_upright_s"]) == r["time_to_upright"]
    assert all(t["sweep"] == doc["sweep"] and t["failure"] == "" for t in table)
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["figures", "sweep_energy.csv", "sweep_energy.png",
                                                          "sweeps"]
    png = tmp_path / "figures" / "sweep_energy.png"
    assert doc["figure"] == str(png.resolve()) and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from PIL import Image
    with Image.open(png) as im:
        assert im.format == "PNG" and im.size[0] >= 600 and im.size[1] >= 400


def test_one_and_two_workers_give_the_same_rows_bit_for_bit(tmp_path, capsys):
    one = _sweep(capsys, "--n", "4", "--seed", "3", "--duration", "4", "--workers", "1", "--out", str(tmp_path / "a"))
    two = _sweep(capsys, "--n", "4", "--seed", "3", "--duration", "4", "--workers", "2", "--out", str(tmp_path / "b"))
    assert one["workers"] == 1 and two["workers"] == 2
    assert one["rows"] == two["rows"]  # floats compared exactly
    a = (tmp_path / "a" / "sweeps" / "sweep_energy.csv").read_bytes()
    assert a == (tmp_path / "b" / "sweeps" / "sweep_energy.csv").read_bytes()


def test_trajopt_sweep_rows(tmp_path, capsys):
    pytest.importorskip("cartpole.planning.trajopt")
    doc = _sweep(capsys, "--method", "trajopt", "--n", "1", "--seed", "1", "--out", str(tmp_path))
    assert doc["method"] == "trajopt" and len(doc["rows"]) == 1
    for r in doc["rows"]:
        assert isinstance(r["success"], bool) and (r["replays"] or r["error"])
    assert (tmp_path / "sweeps" / "sweep_trajopt.csv").exists()


@pytest.mark.parametrize("argv, words", [
    (["--n", "0"], "1 to"), (["--workers", "0"], "--workers"), (["--method", "trajopt", "--jitter", "0.1"], "jitter"),
    (["--jitter", "1.5"], "gain_jitter"), (["--duration", "nan"], "Duration"), (["--duration", "1e12"], "memory"),
    (["--n", "two"], "invalid int"),
])
def test_bad_settings_are_one_sentence_exit_2_and_nothing_written(argv, words, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["sweep", "--json", "--out", str(out), *argv]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and lines[0].startswith("cartpole sweep: ") and words in lines[0]
    assert "Traceback" not in cap.err and not out.exists()


def test_energy_sweep_on_a_two_pole_cart_is_refused_before_any_run(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["sweep", "--json", "--mjcf", str(SHIPPED_MJCF.with_name("cartpole_two_pole.xml")),
                 "--method", "energy", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    assert "Energy shaping is for one pole" in cap.err and len(cap.err.strip().splitlines()) == 1
    assert not out.exists()


def test_the_default_sweep_on_a_two_pole_cart_is_the_planners(tmp_path, capsys):
    """No --method: the method `cartpole swingup` tries first on the model, the planner on a chain (gain jitter,
    energy shaping's, is refused naming --method energy, before any run)."""
    out = tmp_path / "out"
    assert main(["sweep", "--json", "--mjcf", str(SHIPPED_MJCF.with_name("cartpole_two_pole.xml")),
                 "--jitter", "0.1", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    assert "use --method energy" in cap.err and len(cap.err.strip().splitlines()) == 1
    assert not out.exists()


def test_help_documents_the_flags(capsys):
    assert main(["sweep", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for flag in ("--method", "--n N", "--seed S", "--workers W", "--address ADDR", "--duration", "--jitter",
                 "--resume", "--json", "--mjcf", "--out"):
        assert flag in text, flag
    assert "Dask" in text and "--view" in text and "--stop-after" not in text  # a testing option, hidden


QUICK = ("--n", "4", "--seed", "3", "--duration", "4")


def test_interrupted_sweep_keeps_its_rows_and_resume_finishes_it_like_an_uninterrupted_run(tmp_path, capsys):
    ref = _sweep(capsys, *QUICK, "--out", str(tmp_path / "ref"))
    out = tmp_path / "cut"
    results = out / "sweeps" / "sweep_energy.csv"
    # interrupted (as by Ctrl-C) after two runs: the two rows are in the file, one sentence says how to go on
    assert main(["sweep", "--json", *QUICK, "--out", str(out), "--stop-after", "2"]) == 130
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and "2 of 4 runs" in lines[0] and "--resume" in lines[0], cap.err
    with open(results, newline="") as fh:
        part = list(csv.DictReader(fh))
    assert [int(t["run"]) for t in part] == [0, 1]
    # resumed: only the other two run; the rows and the file are those of the uninterrupted sweep, no duplicates
    doc = _sweep(capsys, *QUICK, "--out", str(out), "--resume")
    assert doc["resumed"] == 2 and doc["rows"] == ref["rows"] and doc["sweep"] == ref["sweep"]
    assert results.read_bytes() == (tmp_path / "ref" / "sweeps" / "sweep_energy.csv").read_bytes()
    # resuming a finished sweep runs nothing and changes nothing
    again = _sweep(capsys, *QUICK, "--out", str(out), "--resume")
    assert again["resumed"] == 4 and again["rows"] == ref["rows"]


def test_resume_survives_a_row_cut_short_and_refuses_another_sweeps_file(tmp_path, capsys):
    ref = _sweep(capsys, *QUICK, "--out", str(tmp_path))
    results = tmp_path / "sweeps" / "sweep_energy.csv"
    whole = results.read_bytes()
    lines = whole.splitlines(keepends=True)
    results.write_bytes(b"".join(lines[:3]) + lines[3][:20])  # header, runs 0 and 1, run 2 cut by a crash
    doc = _sweep(capsys, *QUICK, "--out", str(tmp_path), "--resume")
    assert doc["resumed"] == 2 and doc["rows"] == ref["rows"] and results.read_bytes() == whole
    # another seed is another sweep: refused in one sentence, the file untouched
    assert main(["sweep", "--json", "--n", "4", "--seed", "4", "--duration", "4", "--out", str(tmp_path),
                 "--resume"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Cannot resume" in err[0] and "--seed" in err[0]
    assert results.read_bytes() == whole


@pytest.fixture(scope="module")
def dask_cluster():
    """A real Dask distributed cluster on loopback: two worker processes, one thread each, no dashboard."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, silence_logs=50) as cluster:
        yield cluster


def test_a_local_dask_cluster_gives_the_rows_of_one_worker_bit_for_bit(dask_cluster, tmp_path, capsys):
    addr = dask_cluster.scheduler_address
    assert addr.startswith("tcp://127.0.0.1:")
    one = _sweep(capsys, *QUICK, "--workers", "1", "--out", str(tmp_path / "a"))
    dask = _sweep(capsys, *QUICK, "--address", addr, "--out", str(tmp_path / "b"))
    assert dask["address"] == addr and dask["rows"] == one["rows"]  # floats compared exactly
    a = (tmp_path / "a" / "sweeps" / "sweep_energy.csv").read_bytes()
    assert a == (tmp_path / "b" / "sweeps" / "sweep_energy.csv").read_bytes()
    # the model is built once per worker process (two at most), not once per run
    import distributed

    with distributed.Client(addr, set_as_default=False) as client:
        built = client.run(_models_built)
    assert 1 <= sum(built.values()) <= 2, built


def _models_built() -> int:
    from cartpole.apps.sweep import runners_built

    return runners_built()


def test_an_unreachable_address_is_one_sentence(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    import socket

    import cartpole.apps.sweep.executors as executors

    monkeypatch.setattr(executors, "CONNECT_TIMEOUT", 1.0)
    with socket.socket() as s:  # a loopback port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "out"
    assert main(["sweep", "--json", "--n", "1", "--address", f"tcp://127.0.0.1:{port}", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Cannot reach a Dask scheduler" in err[0], err
    assert not out.exists()


def test_ctrl_c_on_a_two_worker_sweep_keeps_the_finished_rows_and_resume_completes_them(tmp_path, capsys):
    """A real SIGINT to the process group of a running ``cartpole sweep --workers 2`` (as Ctrl-C sends it)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    ref = _sweep(capsys, *QUICK[2:], "--n", "10", "--out", str(tmp_path / "ref"))
    out = tmp_path / "cut"
    results = out / "sweeps" / "sweep_energy.csv"
    argv = [sys.executable, "-m", "cartpole", "sweep", "--n", "10", *QUICK[2:], "--workers", "2", "--out", str(out)]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "MUJOCO_GL": "egl"},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if results.exists() and len(results.read_text().splitlines()) >= 3:  # header and two finished runs
            break
        time.sleep(0.05)
    if proc.poll() is not None:
        pytest.skip("the sweep finished before it could be interrupted (a very fast machine)")
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    kept = len(results.read_text().splitlines()) - 1
    if proc.returncode == 0:
        pytest.skip("the sweep finished as the interrupt arrived")
    assert proc.returncode == 130, err
    last = err.strip().splitlines()[-1]
    assert f"interrupted after {kept} of 10 runs" in last and "--resume" in last and "Traceback" not in err
    doc = _sweep(capsys, *QUICK[2:], "--n", "10", "--out", str(out), "--resume", "--workers", "2")
    assert doc["resumed"] == kept and doc["rows"] == ref["rows"]
    assert results.read_bytes() == (tmp_path / "ref" / "sweeps" / "sweep_energy.csv").read_bytes()


def test_a_push_by_mass_error_trajopt_sweep_writes_its_map_and_results_and_every_success_replays(tmp_path, capsys,
                                                                                                monkeypatch):
    """The issue's 2-axis sweep of the single pole (push size x model error): results file and success map exist,
    and every success, run again as `cartpole swingup` with its push and model error, replays with plain mj_step."""
    pytest.importorskip("cartpole.planning.trajopt")
    from mj_replay import replay_with_mj_step

    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    doc = _sweep(capsys, "--method", "trajopt", "--push-force", "-20", "20", "3", "--model-error", "0.9", "1.1", "3",
                 "--push-time", "0.5", "--out", str(tmp_path))
    rows = doc["rows"]
    assert doc["n"] == len(rows) == 9 and [a["name"] for a in doc["axes"]] == ["push_force", "model_error",
                                                                               "push_time"]
    assert [(r["push"][0][1] if r["push"] else 0.0, r["model_error"]) for r in rows] == [
        (f, s) for f in (-20.0, 0.0, 20.0) for s in (0.9, 1.0, 1.1)]
    with open(tmp_path / "sweeps" / "sweep_trajopt.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [float(t["push_force_N"]) for t in table] == [r["push"][0][1] if r["push"] else 0.0 for r in rows]
    assert [float(t["model_error"]) for t in table] == [r["model_error"] for r in rows]
    png = tmp_path / "figures" / "sweep_trajopt.png"
    assert doc["figure"] == str(png.resolve()) and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    wins = [r for r in rows if r["success"]]
    assert wins and all(r["replays"] for r in wins)
    for r in wins:
        push = [f"{T}:{F}" for T, F in r["push"]]
        argv = ["swingup", "--method", "trajopt", "--json", "--no-video", "--out", str(tmp_path / "one"),
                "--model-error", str(r["model_error"]), *[a for p in push for a in ("--push", p)]]
        assert main(argv) == 0
        one = json.loads(capsys.readouterr().out)
        assert one["success"] is True and one["time_to_upright"] == r["time_to_upright"]
        ro = one["rollout"]
        qpos, qvel = replay_with_mj_step(one["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"], ro["push"])
        assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))


def test_two_methods_write_each_sweep_and_the_maps_side_by_side(tmp_path, capsys):
    pytest.importorskip("cartpole.planning.trajopt")
    doc = _sweep(capsys, "--method", "trajopt", "energy", "--push-force", "-10", "10", "2", "--model-error", "1.0",
                 "1.1", "2", "--duration", "3", "--out", str(tmp_path))
    assert doc["methods"] == ["trajopt", "energy"] and [s["method"] for s in doc["sweeps"]] == doc["methods"]
    assert all(s["n"] == 4 for s in doc["sweeps"])
    fig = tmp_path / "figures" / "sweep_compare.png"
    assert doc["figure"] == str(fig.resolve()) and fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for m in doc["methods"]:
        assert (tmp_path / "sweeps" / f"sweep_{m}.csv").exists() and (tmp_path / "figures" / f"sweep_{m}.png").exists()


def test_trajopt_against_mpc_over_push_and_model_error(tmp_path, capsys):
    pytest.importorskip("cartpole.mpc.nmpc")
    doc = _sweep(capsys, "--method", "trajopt", "mpc", "--push-force", "0", "30", "2", "--model-error", "1.0", "1.2",
                 "2", "--push-time", "3", "--workers", "2", "--out", str(tmp_path))
    assert doc["methods"] == ["trajopt", "mpc"]
    for s in doc["sweeps"]:
        assert all(r["replays"] or r["error"] for r in s["rows"])
    assert (tmp_path / "figures" / "sweep_compare.png").exists()


@pytest.mark.parametrize("argv, words", [
    (["--push-force", "a"], "needs numbers"), (["--push-force", "1", "2", "3", "4"], "takes V"),
    (["--push-time", "1"], "without a push force"), (["--model-error", "0", "1", "3"], "scale in"),
    (["--start", "elbow", "1"], "No joint 'elbow'"), (["--start", "hinge"], "takes a name"),
    (["--setting", "horizon", "1"], "no setting 'horizon'"), (["--push-force", "-10", "10", "3", "--n", "4"], "grid"),
    (["--x0", "0", "3.14", "0", "0"], "--x0 fixes the start"),
    (["--push-force", "1", "--x0", "0", "3.14", "0"], "give exactly 4"),
])
def test_bad_axes_are_one_sentence_exit_2_and_nothing_written(argv, words, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["sweep", "--json", "--out", str(out), *argv]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and lines[0].startswith("cartpole sweep: ") and words in lines[0], cap.err
    assert not out.exists()


def test_a_basin_style_sweep_over_start_angle_and_rate_maps_them(tmp_path, capsys):
    doc = _sweep(capsys, "--start", "hinge", "2.9", "3.3", "2", "--start", "hinge_rate", "-1", "1", "2",
                 "--duration", "2", "--out", str(tmp_path))
    assert doc["n"] == 4 and sorted({tuple(r["start"][1::2]) for r in doc["rows"]}) == [
        (2.9, -1.0), (2.9, 1.0), (3.3, -1.0), (3.3, 1.0)]
    assert (tmp_path / "figures" / "sweep_energy.png").exists()


def test_x0_fixes_the_start_of_an_axis_sweep(tmp_path, capsys):
    doc = _sweep(capsys, "--push-force", "0", "5", "2", "--x0", "0.1", "3.0", "0", "0", "--duration", "1",
                 "--out", str(tmp_path))
    assert [r["start"] for r in doc["rows"]] == [[0.1, 3.0, 0.0, 0.0]] * 2
    assert [r["push"] for r in doc["rows"]] == [[], [[0.5, 5.0]]]  # 0 N is no push; the default push time 0.5 s


def test_the_sweep_has_one_command_line():
    """``python -m cartpole.apps.sweep`` (a second, weaker CLI) is gone: ``cartpole sweep`` is the command."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "cartpole.apps.sweep", "--n", "1"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode != 0 and "cannot be directly executed" in r.stderr and r.stdout == ""


def _running_sweep(out, workers=3, n=40):
    """A ``cartpole sweep --workers W`` started in a session of its own, once two runs are in its results file
    (None if it finished first), with the processes below it then."""
    import os
    import subprocess
    import sys
    import time

    psutil = pytest.importorskip("psutil")
    results = out / "sweeps" / "sweep_energy.csv"
    argv = [sys.executable, "-m", "cartpole", "sweep", "--n", str(n), "--duration", "4", "--workers", str(workers),
            "--out", str(out)]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "MUJOCO_GL": "egl"})
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if results.exists() and len(results.read_text().splitlines()) >= 3:
            break
        time.sleep(0.05)
    if proc.poll() is not None:
        return proc, []
    below = psutil.Process(proc.pid).children(recursive=True)
    return proc, below


def _alive_after(procs, seconds=60):
    import psutil

    _, alive = psutil.wait_procs(procs, timeout=seconds)
    return [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]


def test_sigterm_stops_a_pool_sweep_keeps_its_rows_and_leaves_no_worker(tmp_path):
    import os
    import signal
    import subprocess
    import sys

    out = tmp_path / "cut"
    proc, below = _running_sweep(out)
    if proc.poll() is not None:
        pytest.skip("the sweep finished before it could be stopped (a very fast machine)")
    assert len(below) >= 2  # the fork server (or spawned workers) and at least one worker
    os.kill(proc.pid, signal.SIGTERM)  # the sweep's process alone, as a service manager sends it
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err  # the status of a process ended by SIGTERM
    last = err.strip().splitlines()[-1]
    kept = len((out / "sweeps" / "sweep_energy.csv").read_text().splitlines()) - 1
    assert f"interrupted after {kept} of 40 runs" in last and "Traceback" not in err
    assert _alive_after(below) == []
    # the rows kept are resumable: the same sweep with --resume runs only the others
    again = subprocess.run([sys.executable, "-m", "cartpole", "sweep", "--json", "--n", "40", "--duration", "4",
                            "--workers", "2", "--out", str(out), "--resume"], capture_output=True, text=True,
                           timeout=600, env={**os.environ, "MUJOCO_GL": "egl"}, check=False)
    assert again.returncode == 0, again.stderr
    doc = json.loads(again.stdout)
    assert doc["resumed"] == kept and len(doc["rows"]) == 40


def test_a_killed_pool_sweep_leaves_no_worker(tmp_path):
    import os
    import signal

    proc, below = _running_sweep(tmp_path / "killed")
    if proc.poll() is not None:
        pytest.skip("the sweep finished before it could be killed (a very fast machine)")
    os.kill(proc.pid, signal.SIGKILL)  # no handler runs: the workers must notice on their own
    proc.communicate(timeout=60)
    assert _alive_after(below) == []
