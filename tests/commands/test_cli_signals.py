"""SIGTERM during any command leaves no partial file and no live child process (the encoder of a video; a sweep's
pool workers: tests/commands/test_cli_sweep.py), with one sentence and exit status 143; a malformed or unreachable
Dask address ends in one sentence with nothing printed after it. Each command runs as a subprocess in a session of
its own, so every process it started can be found afterwards by its session id."""
import os
import signal
import socket
import subprocess
import sys
import time

import pytest


def _start(argv, tmp_path):
    env = {**os.environ, "MUJOCO_GL": "egl"}
    return subprocess.Popen([sys.executable, "-m", "cartpole", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, env=env, cwd=tmp_path)


def _session(sid: int) -> list[str]:
    """Live (not zombie) processes of session ``sid``."""
    out = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        state, session = fields[0], int(fields[3])
        if session == sid and state != "Z":
            out.append(pid)
    return out


def _no_child_left(proc) -> None:
    deadline = time.monotonic() + 10
    while _session(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _session(proc.pid), f"processes of the command still alive: {_session(proc.pid)}"


def _wait_for(predicate, proc, seconds=120):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and proc.poll() is None:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def _files(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if not p.is_dir()) if root.exists() else []


def test_sigterm_while_a_video_renders_leaves_no_file_and_no_encoder(tmp_path):
    out = tmp_path / "out"
    proc = _start(["swingup", "--duration", "10", "--out", str(out)], tmp_path)
    videos = out / "videos"
    # the encoder writes a hidden temporary beside the target: rendering is under way
    if not _wait_for(lambda: videos.exists() and any(videos.iterdir()), proc):
        proc.kill()
        pytest.skip("the video was never started (no GL on this machine?)")
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    lines = err.strip().splitlines()
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "stopped by SIGTERM" in lines[-1] and "Traceback" not in err
    assert _files(out) == [], "a partial file was left"
    _no_child_left(proc)


@pytest.mark.parametrize("address", ["garbage", "http://127.0.0.1:8786", "tcp://127.0.0.1:99999", "free-port"])
def test_a_malformed_or_unreachable_dask_address_is_one_sentence_and_nothing_after(tmp_path, address):
    pytest.importorskip("distributed")
    if address == "free-port":
        with socket.socket() as s:  # a loopback port nobody listens on
            s.bind(("127.0.0.1", 0))
            address = f"tcp://127.0.0.1:{s.getsockname()[1]}"
    proc = _start(["sweep", "--json", "--n", "1", "--duration", "1", "--address", address, "--out",
                   str(tmp_path / "out")], tmp_path)
    out, err = proc.communicate(timeout=120)
    lines = err.strip().splitlines()
    assert proc.returncode == 2 and out == "" and len(lines) == 1, err
    assert "Dask scheduler" in lines[0] and "Exception ignored" not in err
    assert not (tmp_path / "out").exists()
    _no_child_left(proc)


def test_a_listener_that_is_not_a_dask_scheduler_is_one_sentence_and_nothing_after(tmp_path):
    pytest.importorskip("distributed")
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    port = server.getsockname()[1]

    def answer():  # an HTTP server's reply to anything: not Dask's protocol
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            try:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 8)
                time.sleep(0.2)
            finally:
                conn.close()

    threading.Thread(target=answer, daemon=True).start()
    try:
        proc = _start(["sweep", "--json", "--n", "1", "--duration", "1", "--address", f"tcp://127.0.0.1:{port}",
                       "--out", str(tmp_path / "out")], tmp_path)
        out, err = proc.communicate(timeout=120)
    finally:
        server.close()
    lines = err.strip().splitlines()
    assert proc.returncode == 2 and out == "" and len(lines) == 1 and "Cannot reach a Dask scheduler" in lines[0], err


def _signal_inside(sig, then):
    """A stand-in for a call the command makes: ``sig`` arrives while it runs, and what the handler raised becomes
    ``then()`` (an exception to raise, as pybind11 turns it into a TypeError when the signal comes while it converts
    a call's arguments) or, with ``then`` None, is swallowed (as a library's ``except Exception`` around that call
    would) and the call returns normally."""
    try:
        os.kill(os.getpid(), sig)  # os.kill runs the handler before it returns when the signal is its own process's
        for _ in range(1000):
            pass
    except BaseException:
        if then is not None:
            raise then() from None
    else:
        raise AssertionError("the command line's handler raised nothing")


@pytest.mark.parametrize("then", [lambda: TypeError("incompatible function arguments"), None],
                         ids=["converted-to-TypeError", "swallowed"])
def test_sigterm_whose_exception_a_library_converts_or_swallows_still_stops_the_command_cleanly(tmp_path, capsys,
                                                                                                 monkeypatch, then):
    """The CI race: SIGTERM while a C extension runs. Whatever becomes of the handler's exception, the command ends
    as SIGTERM does: status 143, one sentence, no traceback, none of the files it had written (the figure was)."""
    import cartpole.commands.lqr as lqr_command
    from cartpole.apps.lab import FIGURE
    from cartpole.cli import main

    out = tmp_path / "out"
    seen = {}
    real = lqr_command.append_metrics

    def append_metrics(*args, **kwargs):  # the last file the lab writes, after its figure
        seen["figure"] = (out / FIGURE).exists()
        _signal_inside(signal.SIGTERM, then)
        return real(*args, **kwargs)

    monkeypatch.setattr(lqr_command, "append_metrics", append_metrics)
    before = signal.getsignal(signal.SIGTERM)
    status = main(["lqr", "--no-video", "--out", str(out)])
    err = capsys.readouterr().err
    assert seen == {"figure": True}
    assert status == 128 + signal.SIGTERM, err
    assert err.strip().splitlines()[-1] == ("cartpole lqr: stopped by SIGTERM before it finished; no partial output "
                                            "is left.") and "Traceback" not in err
    assert _files(out) == [], "a file was left"
    assert signal.getsignal(signal.SIGTERM) is before


def test_a_second_signal_while_the_command_unwinds_is_recorded_not_raised():
    """Only the first signal raises: a second one (a service manager repeating SIGTERM) while the clean-up runs
    must not cut that clean-up short and leave half-written files or a live encoder."""
    from cartpole.cli import signals_as_interrupts
    from cartpole.errors import Terminated

    cleaned = False
    with signals_as_interrupts() as received:
        try:
            _signal_inside(signal.SIGTERM, lambda: TypeError("incompatible function arguments"))
        except TypeError:
            # the same signal again (SIGHUP may be ignored where the tests run, e.g. under nohup, and stays ignored)
            os.kill(os.getpid(), signal.SIGTERM)  # would raise here, inside the clean-up, if it were the first
            for _ in range(1000):
                pass
            cleaned = True
    assert cleaned and received.signums == [signal.SIGTERM, signal.SIGTERM]
    assert isinstance(received.exception(), Terminated) and received.exception().signum == signal.SIGTERM
