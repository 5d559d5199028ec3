"""Everything a user can get wrong about where outputs go ends in one sentence on stderr, exit status 2, and the
``--out`` tree exactly as it was: an ``--out`` that is a file or sits under one, a read-only file system, a full
disk (a tiny tmpfs when we may mount one, and ENOSPC injected into the writer), a duration too long to hold, NaN in
``--x0``; and a failure after some files were written removes them again."""
import errno
import os
import subprocess
import uuid

import pytest

import cartpole._files as files
from cartpole.cli import main


def _tree(root):
    """Every path under root with its bytes (None for a directory)."""
    if not root.exists():
        return None
    def content(p):
        if p.is_symlink():
            return "-> " + os.readlink(p)
        if not p.is_file():  # a directory, a FIFO (reading it would block)
            return None
        return p.read_bytes()
    return {str(p.relative_to(root)): content(p) for p in sorted(root.rglob("*"))}


def _fails_cleanly(argv, root, capsys, *words):
    before = _tree(root)
    rc = main(argv)
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert rc == 2, cap.err
    assert cap.out == "" and len(lines) == 1 and lines[0].startswith(f"cartpole {argv[0]}: "), cap.err
    assert "Traceback" not in cap.err and lines[0].endswith(".")
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert _tree(root) == before, "the --out tree changed"
    return lines[0]


SWINGUP = ["swingup", "--json", "--no-video", "--duration", "0.5"]


def test_an_out_that_is_a_file_is_refused(tmp_path, capsys):
    f = tmp_path / "results.txt"
    f.write_text("keep me")
    _fails_cleanly([*SWINGUP, "--out", str(f)], tmp_path, capsys, "is a file, not a directory")
    _fails_cleanly(["sweep", "--json", "--n", "1", "--out", str(f / "sub")], tmp_path, capsys,
                   "cannot be created", "is a file")


def test_an_out_that_cannot_be_created_is_refused(tmp_path, capsys):
    long = tmp_path / ("x" * 300)
    _fails_cleanly([*SWINGUP, "--out", str(long)], tmp_path, capsys, "shorter --out")


def test_a_duration_too_long_to_hold_is_refused_before_running(tmp_path, capsys):
    line = _fails_cleanly([*SWINGUP[:-2], "--duration", "1e9", "--out", str(tmp_path / "out")], tmp_path, capsys,
                          "too long to hold in memory", "give at most")
    assert "MiB" in line


def test_nan_in_x0_is_refused(tmp_path, capsys):
    _fails_cleanly([*SWINGUP, "--x0", "0", "nan", "0", "0", "--out", str(tmp_path / "out")], tmp_path, capsys,
                   "not finite")


def _raise_enospc_for(name):
    """An ``open`` for cartpole._files whose files raise ENOSPC on write when their target's name contains
    ``name``."""
    real = open

    class Full:
        def __init__(self, fh):
            self.fh = fh

        def write(self, data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def __getattr__(self, attr):
            return getattr(self.fh, attr)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

    def fake_open(path, mode="r", *args, **kwargs):
        fh = real(path, mode, *args, **kwargs)
        return Full(fh) if name in os.path.basename(str(path)) and "w" in mode else fh

    return fake_open


def test_a_full_disk_while_writing_is_one_sentence_and_leaves_no_file(tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("from before")
    monkeypatch.setattr(files, "open", _raise_enospc_for("swingup_energy.png"), raising=False)
    _fails_cleanly([*SWINGUP, "--out", str(out)], tmp_path, capsys, "No space left on device",
                   "free some space")


def test_a_failure_after_some_files_were_written_removes_them(tmp_path, monkeypatch, capsys):
    # the lab writes its figure first, then appends its metrics row: make the second write hit a full disk
    out = tmp_path / "out"
    monkeypatch.setattr(files, "open", _raise_enospc_for("metrics.csv"), raising=False)
    _fails_cleanly(["lqr", "--json", "--no-video", "--out", str(out)], tmp_path, capsys, "metrics.csv",
                   "No space left")
    assert not out.exists()


@pytest.fixture
def mount_point(tmp_path):
    """A fresh directory to mount a tmpfs on, unmounted afterwards; skips where we may not mount."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    d = tmp_path / f"mnt-{uuid.uuid4().hex[:6]}"
    d.mkdir()
    mounted = []

    def mount(options):
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(d)], capture_output=True, text=True)
        if r.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
        mounted.append(d)
        return d

    yield mount
    for m in mounted:
        subprocess.run(["umount", "-l", str(m)], capture_output=True)


def test_a_really_full_tmpfs_is_one_sentence_and_stays_empty(mount_point, capsys):
    d = mount_point("size=16k")
    line = _fails_cleanly([*SWINGUP, "--out", str(d)], d, capsys, "No space left on device")
    assert "swingup_energy.png" in line and list(d.iterdir()) == []


def test_a_read_only_file_system_is_refused_before_any_work(mount_point, capsys):
    d = mount_point("ro,size=1m")
    _fails_cleanly([*SWINGUP, "--out", str(d / "results")], d, capsys, "read-only file system")
    _fails_cleanly(["sweep", "--json", "--n", "1", "--out", str(d)], d, capsys, "read-only")


# ---- hostile paths (issue 24) -------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["loop", "fifo", "device", "directory"])
def test_an_mjcf_that_is_not_a_regular_file_is_one_sentence(tmp_path, capsys, kind):
    path = tmp_path / "m.xml"
    if kind == "loop":
        os.symlink(tmp_path / "n.xml", path)
        os.symlink(path, tmp_path / "n.xml")
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    else:
        path = "/dev/zero"
    words = {"loop": "loop of symbolic links", "fifo": "FIFO", "device": "a device", "directory": "a directory"}
    _fails_cleanly(["linearize", "--json", "--mjcf", str(path)], tmp_path, capsys, words[kind], "--mjcf")


@pytest.mark.parametrize("kind", ["fifo", "directory"])
def test_an_mjcf_including_a_file_that_is_not_regular_is_one_sentence_not_a_hang(tmp_path, capsys, kind):
    from cartpole.models import SHIPPED_MJCF

    target = tmp_path / "part.xml"
    if kind == "fifo":
        os.mkfifo(target)  # MuJoCo's reader would wait for a writer forever
    else:
        target.mkdir()
    mjcf = tmp_path / "m.xml"
    mjcf.write_text(SHIPPED_MJCF.read_text().replace("<worldbody>", '<include file="part.xml"/><worldbody>', 1))
    _fails_cleanly(["linearize", "--json", "--mjcf", str(mjcf)], tmp_path, capsys, "include file",
                   "FIFO" if kind == "fifo" else "a directory")


def test_an_empty_out_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _fails_cleanly([*SWINGUP, "--out", ""], tmp_path, capsys, "--out is empty")


@pytest.mark.parametrize("content", ["binary", "device"])
def test_a_resume_file_that_is_binary_or_a_device_is_one_sentence(tmp_path, capsys, content):
    results = tmp_path / "out" / "sweeps" / "sweep_energy.csv"
    results.parent.mkdir(parents=True)
    if content == "binary":
        results.write_bytes(bytes(range(256)) * 8)
    else:
        os.symlink("/dev/zero", results)
    _fails_cleanly(["sweep", "--json", "--n", "1", "--duration", "0.5", "--resume", "--out", str(tmp_path / "out")],
                   tmp_path, capsys, "Cannot resume", "drop --resume")


# ---- numbers range-checked before use (issue 24) ----------------------------------------------------------------

@pytest.mark.parametrize("argv, words", [
    (["sweep", "--json", "--n", "1", "--seed", "-1"], ("--seed", "0 to 2**63 - 1")),
    ([*SWINGUP, "--push", "1e308:1"], ("push", "start time in [0")),
    ([*SWINGUP, "--push", "1:1e12"], ("push", "1000 N")),
    ([*SWINGUP, "--push", "5:1"], ("starts after the run ends at 0.5 s",)),
    (["sweep", "--json", "--duration", "1", "--push-force", "1", "--push-time", "1e308"], ("after the runs end",)),
    (["sweep", "--json", "--duration", "1", "--push-force", "1e12"], ("1000 N limit",)),
    (["sweep", "--json", "--duration", "1", "--start", "slider", "5"], ("start:slider", "outside its joint range")),
    ([*SWINGUP, "--x0", "0", "3", "0", "1e308"], ("start rate", "100 rad/s limit")),
    ([*SWINGUP, "--x0", "0", "1e308", "0", "0"], ("start angle", "rad limit")),
    (["swingup", "--json", "--no-video", "--method", "mpc", "--horizon", "1e6"], ("stages", "500 limit")),
    (["swingup", "--json", "--no-video", "--method", "mpc", "--period", "0.005", "--horizon", "30"], ("500 limit",)),
    (["swingup", "--json", "--no-video", "--method", "mpc", "--period", "0.5", "--horizon", "0.2"],
     ("shorter than its 0.5 s control period",)),
    (["swingup", "--json", "--no-video", "--method", "mpc", "--period", "1e-9"], ("shorter than the MJCF's",)),
    (["swingup", "--json", "--no-video", "--period", "1e-9"], ("physics steps",)),
    (["lqr", "--json", "--no-video", "--period", "1e308"], ("1 s limit",)),
    (["lqr", "--json", "--no-video", "--delay", "1e6"], ("delay", "1 s limit")),
    ([*SWINGUP, "--estimator", "mhe", "--mhe-horizon", "1e6"], ("MHE horizon", "100 limit")),
    ([*SWINGUP, "--model-error", "1e-308"], ("[0.1, 10]",)),
    (["sweep", "--json", "--duration", "1", "--setting", "period", "1e308"], ("setting:period", "to 1 s")),
    (["sweep", "--json", "--duration", "1", "--setting", "period", "1e-9"], ("setting:period", "from 0.005")),
    (["sweep", "--json", "--duration", "1", "--setting", "delay", "1e308"], ("setting:delay",)),
    (["bench", "--json", "--repeats", "1000000000"], ("100 limit",)),
], ids=["seed", "push-time", "push-force", "push-after-end", "sweep-push-time", "sweep-push-force", "sweep-start",
        "x0-rate", "x0-angle", "mpc-horizon", "mpc-stages", "mpc-horizon-below-period", "mpc-period", "period",
        "period-long", "delay-long", "mhe-horizon", "model-error-tiny", "sweep-period-long", "sweep-period-short",
        "sweep-delay-long", "bench-repeats"])
def test_a_number_out_of_range_is_refused_before_any_work(tmp_path, capsys, argv, words):
    out = [] if argv[0] == "bench" else ["--out", str(tmp_path / "out")]  # bench writes no files
    _fails_cleanly([*argv, *out], tmp_path, capsys, *words)


def _variant(tmp_path, old, new):
    from cartpole.models import SHIPPED_MJCF

    text = SHIPPED_MJCF.read_text()
    assert old in text
    path = tmp_path / "variant.xml"
    path.write_text(text.replace(old, new))
    return str(path)


@pytest.mark.parametrize("old, new, argv, words", [
    ('ctrlrange="-1 1"', 'ctrlrange="-1e300 1e300"', SWINGUP, ("ctrlrange", "limit")),
    ('ctrlrange="-1 1"', 'ctrlrange="-1e300 1e300"', ["lqr", "--json", "--no-video"], ("ctrlrange", "limit")),
    ('<joint name="hinge" type="hinge"', '<joint name="hinge" type="hinge" limited="true" range="60 300"', SWINGUP,
     ("does not contain the upright angle",)),
    ('gear="20"', 'gear="-20"', [*SWINGUP, "--method", "energy"], ("positive gear",)),
], ids=["ctrlrange-swingup", "ctrlrange-lqr", "hinge-range", "negative-gear"])
def test_an_mjcf_no_swingup_can_use_as_given_is_one_sentence(tmp_path, capsys, old, new, argv, words):
    mjcf = _variant(tmp_path, old, new)
    line = _fails_cleanly([*argv, "--mjcf", mjcf, "--out", str(tmp_path / "out")], tmp_path, capsys, *words)
    assert "EnergyGains(" not in line


def test_a_bogus_matplotlib_backend_is_one_sentence(tmp_path):
    import sys

    # a process of its own: matplotlib imported with a bad backend leaves half a package in sys.modules
    env = dict(os.environ, MPLBACKEND="bogus")
    proc = subprocess.run([sys.executable, "-m", "cartpole", *SWINGUP, "--out", str(tmp_path / "out")], env=env,
                          capture_output=True, text=True, timeout=120, check=False)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "MPLBACKEND" in lines[0] and "Agg" in lines[0], proc.stderr
    assert proc.stdout == "" and not (tmp_path / "out").exists()


@pytest.mark.parametrize("flag, values, words", [("--Q", ["1e308"] * 4, "1e+12 limit"),
                                                  ("--R", ["1e-308"], "below the 1e-12 limit")])
def test_weights_that_overflow_print_their_sentence_alone(tmp_path, capsys, flag, values, words):
    _fails_cleanly(["lqr", "--json", "--no-video", flag, *values, "--out", str(tmp_path / "out")],
                   tmp_path, capsys, words)


# ---- bounded work (issue 24) ------------------------------------------------------------------------------------

def test_lqr_refuses_a_time_step_whose_logs_do_not_fit(tmp_path, capsys):
    mjcf = _variant(tmp_path, 'timestep="0.005"', 'timestep="1e-6"')
    _fails_cleanly(["lqr", "--json", "--mjcf", mjcf, "--out", str(tmp_path / "out")], tmp_path, capsys,
                   "256 MiB limit", "time step of at least")


def _chain(n: int) -> str:
    body = ""
    for i in range(n, 0, -1):
        body = (f'<body name="p{i}" pos="0 0 {0.05 if i == 1 else 0.3}"><joint name="h{i}" type="hinge" axis="0 1 0"'
                f' damping="0.01"/><geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.02" mass="0.1"/>{body}</body>')
    return ('<mujoco><option timestep="0.005"><flag contact="disable"/></option><worldbody><body name="cart" '
            'pos="0 0 4"><joint name="slider" type="slide" axis="1 0 0" limited="true" range="-1.5 1.5" '
            f'damping="0.1"/><geom type="box" size="0.1 0.05 0.05" mass="1"/>{body}</body></worldbody><actuator>'
            '<motor name="motor" joint="slider" gear="20" ctrlrange="-1 1"/></actuator></mujoco>')


@pytest.mark.parametrize("command", ["swingup", "sweep"])
def test_a_chain_too_long_to_plan_is_refused_before_anything_is_built(tmp_path, capsys, command):
    mjcf = tmp_path / "chain4.xml"
    mjcf.write_text(_chain(4))
    argv = [command, "--json", "--method", "trajopt", "--mjcf", str(mjcf), "--out", str(tmp_path / "out")]
    _fails_cleanly(argv + (["--no-video"] if command == "swingup" else ["--n", "1"]), tmp_path, capsys,
                   "chain of 4 poles", "at most 3")


@pytest.mark.parametrize("body, words", [("raise SystemExit(7)\n", "called SystemExit(7) at import"),
                                         ("raise RuntimeError('boom')\n", "raised RuntimeError (boom) at import"),
                                         (None, "PYTHONPATH")])
def test_an_objective_module_that_exits_or_raises_at_import_is_one_sentence(tmp_path, capsys, monkeypatch, body,
                                                                             words):
    name = f"cp_objective_{uuid.uuid4().hex[:8]}"
    if body is not None:
        (tmp_path / f"{name}.py").write_text(body)
        monkeypatch.syspath_prepend(str(tmp_path))
    _fails_cleanly(["swingup", "--json", "--method", "trajopt", "--objective", f"{name}:cost", "--out",
                    str(tmp_path / "out")], tmp_path, capsys, "cannot be imported", words)


# ---- resume and files (issue 24) -----------------------------------------------------------------------------

def test_a_second_sweep_into_the_same_out_is_refused_while_the_first_runs(tmp_path, capsys):
    import sys
    import time

    out = tmp_path / "out"
    results = out / "sweeps" / "sweep_energy.csv"
    first = subprocess.Popen([sys.executable, "-m", "cartpole", "sweep", "--n", "40", "--duration", "3", "--out",
                              str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                             env={**os.environ, "MUJOCO_GL": "egl"})
    try:
        deadline = time.monotonic() + 120
        while first.poll() is None and time.monotonic() < deadline and not (
                results.exists() and len(results.read_text().splitlines()) >= 2):
            time.sleep(0.05)
        if first.poll() is not None:
            pytest.skip("the first sweep finished before the second could start")
        kept = results.read_bytes()
        rc = main(["sweep", "--json", "--n", "40", "--duration", "3", "--out", str(out)])
        cap = capsys.readouterr()
        lines = cap.err.strip().splitlines()
        assert rc == 2 and len(lines) == 1 and "is in use by process" in lines[0], cap.err
        assert str(first.pid) in lines[0] and results.read_bytes().startswith(kept)
    finally:
        first.kill()
        first.communicate()


def test_resumed_counts_only_the_rows_that_are_kept(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["sweep", "--json", "--n", "3", "--duration", "1", "--out", str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    results = out / "sweeps" / "sweep_energy.csv"
    lines = results.read_text().splitlines()
    head = lines[0].split(",")
    cells = lines[2].split(",")
    cells[head.index("success")] = "banana"  # run 1 tampered with: not finished, run again
    results.write_text("\n".join([lines[0], lines[1], ",".join(cells), lines[3]]) + "\n")
    assert main([*argv, "--resume"]) == 0
    import json

    doc = json.loads(capsys.readouterr().out)
    assert doc["resumed"] == 2 and len(doc["rows"]) == 3
    assert "banana" not in results.read_text()


def test_a_read_only_metrics_file_is_refused_and_kept(tmp_path, capsys):
    out = tmp_path / "out"
    metrics = out / "metrics" / "metrics.csv"
    metrics.parent.mkdir(parents=True)
    metrics.write_text("kept,as,it,was\n")
    metrics.chmod(0o444)
    _fails_cleanly(["lqr", "--json", "--no-video", "--out", str(out)], tmp_path, capsys, "read-only",
                   "metrics.csv")
    assert metrics.read_text() == "kept,as,it,was\n" and metrics.stat().st_mode & 0o777 == 0o444


def test_the_documented_limits_are_the_codes():
    """docs/cli.md's "Limits and errors" table: each row's value is the constant it names."""
    import importlib
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs" / "cli.md").read_text()
    section = page.split("## Limits and errors", 1)[1]
    rows = re.findall(r"^\| [^|]+ \| ([^|]+) \| `([\w.]+)` \|$", section, flags=re.MULTILINE)
    assert len(rows) >= 10
    units = {"MiB": 2**20}
    for value, dotted in rows:
        module, _, name = dotted.rpartition(".")
        actual = getattr(importlib.import_module(module), name)
        number, *unit = value.split()
        expected = float(number) * (units.get(unit[0], 1) if unit else 1)
        assert actual == expected, (dotted, value, actual)


@pytest.mark.parametrize("argv, words", [
    (["--start", "hinge", "0", "1", "1000000000"], ("grid points", "100000 runs")),
    (["--start", "hinge", "0", "1", "1000", "--push-force", "0", "1", "1000"], ("1000000 runs",)),
    (["--setting", "energy_gain", "1e308"], ("setting:energy_gain", "1000 times its default")),
    (["--setting", "energy_gain", "0"], ("setting:energy_gain", "energy_gain = 0.0")),
], ids=["grid-axis", "grid-product", "energy-setting-huge", "energy-setting-zero"])
def test_a_sweep_description_no_run_could_use_is_refused_before_any_run(tmp_path, capsys, argv, words):
    line = _fails_cleanly(["sweep", "--json", "--duration", "1", *argv, "--out", str(tmp_path / "out")], tmp_path,
                          capsys, *words)
    assert "{" not in line  # names the settings, no dump of them


@pytest.mark.parametrize("where", ["full", "closed", "pipe-closed"])
def test_a_json_document_that_cannot_be_written_is_one_sentence_not_a_traceback(tmp_path, where):
    import sys

    argv = [sys.executable, "-m", "cartpole", "linearize", "--json"]
    env = {**os.environ, "MUJOCO_GL": "egl"}
    if where == "pipe-closed":
        r, w = os.pipe()
        os.close(r)  # the reader is gone before anything is written: EPIPE
        proc = subprocess.run(argv, stdout=w, stderr=subprocess.PIPE, text=True, env=env, timeout=120, check=False)
        os.close(w)
        assert proc.returncode == 141 and "Traceback" not in proc.stderr, proc.stderr
        return
    if where == "full" and not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    with open("/dev/full" if where == "full" else os.devnull, "w") as out:
        kw = {"stdout": out} if where == "full" else {"stdout": subprocess.DEVNULL,
                                                        "preexec_fn": lambda: os.close(1)}
        proc = subprocess.run(argv, stderr=subprocess.PIPE, text=True, env=env, timeout=120, check=False, **kw)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "cannot write the JSON document" in lines[0], proc.stderr
