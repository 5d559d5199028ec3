"""cartpole.codegen: compiler flags by source size, the cache key, buffered evaluation, a library built and loaded."""
import casadi as ca
import numpy as np

from cartpole import codegen

def test_large_generated_sources_are_compiled_without_optimisation(monkeypatch):
    assert codegen.choose_cflags("x" * 10) == codegen.CFLAGS
    assert codegen.choose_cflags("x" * codegen.LARGE_SOURCE) == codegen.LARGE_CFLAGS
    monkeypatch.setenv("CARTPOLE_CFLAGS", "-O3 -march=native")
    assert codegen.choose_cflags("x" * codegen.LARGE_SOURCE)[:2] == ("-O3", "-march=native")


def test_a_library_is_built_once_cached_by_content_and_loaded_by_name(tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    x = ca.SX.sym("x", 3)
    fn = ca.Function("cg_square", [x], [x * x])
    lib, now = codegen.build_library([fn], "test-digest")
    again, now_again = codegen.build_library([fn], "test-digest")
    assert now and not now_again and lib == again and lib.startswith(str(tmp_path))
    other, _ = codegen.build_library([fn], "another-digest")
    assert other != lib
    loaded = codegen.load_library(lib, ["cg_square"])["cg_square"]
    np.testing.assert_array_equal(np.asarray(loaded([1.0, 2.0, -3.0])).ravel(), [1.0, 4.0, 9.0])


def test_buffered_evaluation_equals_the_function_and_reuses_its_output_arrays():
    x = ca.SX.sym("x", 2)
    y = ca.SX.sym("y", 2, 2)
    fn = ca.Function("f", [x, y], [ca.mtimes(y, x), ca.sum1(x)])
    buffered = codegen.Buffered(fn)
    Y = np.array([[1.0, 2.0], [3.0, 4.0]])
    out = buffered(np.array([1.0, -1.0]), Y.ravel(order="F"))
    np.testing.assert_allclose(out[0], (Y @ [1.0, -1.0]))
    np.testing.assert_allclose(out[1], [0.0])
    first = out[0]
    assert buffered(np.array([2.0, 0.0]), Y.ravel(order="F"))[0] is first  # overwritten in place
    np.testing.assert_allclose(first, Y @ [2.0, 0.0])


def test_the_cpu_key_is_stable_within_a_process():
    assert codegen.cpu_key() == codegen.cpu_key() and len(codegen.cpu_key()) == 16


def _alive(pid: int) -> bool:
    """The process exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def test_a_compiler_timeout_kills_its_whole_process_group(tmp_path):
    import subprocess
    import time

    import pytest

    pidfile = tmp_path / "child.pid"
    # a "compiler" whose driver waits on a child of its own (gcc and its cc1)
    script = f"sleep 60 & echo $! > {pidfile}; wait"
    with pytest.raises(subprocess.TimeoutExpired):
        codegen.run_compiler(["sh", "-c", script], timeout=1.0)
    child = int(pidfile.read_text())
    deadline = time.monotonic() + 5
    while _alive(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(child), "the compiler's child outlived the timeout"


def test_a_compiler_run_returns_its_status_and_output():
    proc = codegen.run_compiler(["sh", "-c", "echo out; echo err >&2; exit 3"])
    assert proc.returncode == 3 and proc.stdout.strip() == "out" and proc.stderr.strip() == "err"


# ---- a cache that cannot be turned against its user (issue 24) ------------------------------------------------

def test_the_cache_directory_is_created_private(tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "fresh" / "cache"))
    d = codegen.private_cache_dir()
    assert d.is_dir() and d.stat().st_mode & 0o777 == 0o700


def test_a_cache_directory_others_may_write_to_is_refused(tmp_path, monkeypatch):
    import pytest

    d = tmp_path / "shared"
    d.mkdir()
    d.chmod(0o777)
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(d))
    with pytest.raises(codegen.CacheError, match="may be written by its group or by others"):
        codegen.private_cache_dir()
    x = ca.SX.sym("x")
    with pytest.raises(codegen.CacheError):
        codegen.build_library([ca.Function("cg_never", [x], [x])], "t")
    assert list(d.iterdir()) == []


def test_a_cache_directory_of_another_user_is_refused(tmp_path, monkeypatch):
    import os

    import pytest

    if os.getuid() != 0:
        pytest.skip("giving a directory to another user needs root")
    d = tmp_path / "theirs"
    d.mkdir(mode=0o700)
    os.chown(d, 65534, 65534)
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(d))
    with pytest.raises(codegen.CacheError, match="belongs to another user"):
        codegen.private_cache_dir()


def _square_library(tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    x = ca.SX.sym("x", 2)
    fn = ca.Function("cg_tamper", [x], [x * x])
    lib, now = codegen.build_library([fn], "tamper-digest")
    assert now
    return fn, lib


def test_a_corrupted_library_is_built_again_not_loaded(tmp_path, monkeypatch):
    from pathlib import Path

    fn, lib = _square_library(tmp_path, monkeypatch)
    good = Path(lib).read_bytes()
    Path(lib).write_bytes(good[: len(good) // 2])  # truncated (a full disk, a crash of another writer)
    again, now = codegen.build_library([fn], "tamper-digest")
    assert again == lib and now and Path(lib).read_bytes() != good[: len(good) // 2]
    loaded = codegen.load_library(lib, ["cg_tamper"])["cg_tamper"]
    np.testing.assert_array_equal(np.asarray(loaded([3.0, -2.0])).ravel(), [9.0, 4.0])


def test_a_library_planted_under_the_expected_name_is_never_loaded(tmp_path, monkeypatch):
    import subprocess
    from pathlib import Path

    import pytest

    fn, lib = _square_library(tmp_path, monkeypatch)
    marker = tmp_path / "constructor-ran"
    src = tmp_path / "planted.c"
    src.write_text('#include <stdio.h>\n__attribute__((constructor)) static void planted(void) { FILE *f = '
                   f'fopen("{marker}", "w"); if (f) fclose(f); }}\n')
    cc = codegen.compiler()
    if cc is None:
        pytest.skip("no C compiler")
    subprocess.run([cc, "-shared", "-fPIC", str(src), "-o", lib], check=True)  # the sidecar still has the real hash
    with pytest.raises(RuntimeError, match="does not match the hash"):
        codegen.load_library(lib, ["cg_tamper"])
    again, now = codegen.build_library([fn], "tamper-digest")
    assert now and again == lib
    codegen.load_library(lib, ["cg_tamper"])
    assert not marker.exists(), "the planted library's constructor ran"
    Path(lib + codegen.HASH_SUFFIX).unlink()  # a library with no recorded hash is not trusted either
    assert codegen.build_library([fn], "tamper-digest")[1]


def test_a_cache_others_may_write_to_is_one_sentence_on_the_command_line(tmp_path, monkeypatch, capsys):
    from cartpole.cli import main

    d = tmp_path / "shared"
    d.mkdir()
    d.chmod(0o757)
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(d))
    out = tmp_path / "out"
    assert main(["swingup", "--json", "--no-video", "--duration", "0.5", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and "chmod 700" in lines[0] and not out.exists()


def test_an_interrupt_during_a_compile_kills_the_compilers_whole_process_group(tmp_path):
    import os
    import signal
    import threading
    import time

    import pytest

    class Stop(Exception):
        pass

    def stop(signum, frame):
        raise Stop

    pidfile = tmp_path / "child.pid"
    previous = signal.signal(signal.SIGUSR1, stop)  # stands for SIGTERM / Ctrl-C arriving mid-compile
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGUSR1))
    try:
        timer.start()
        with pytest.raises(Stop):
            codegen.run_compiler(["sh", "-c", f"sleep 60 & echo $! > {pidfile}; wait"], timeout=30)
    finally:
        timer.cancel()
        signal.signal(signal.SIGUSR1, previous)
    child = int(pidfile.read_text())
    deadline = time.monotonic() + 5
    while _alive(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(child), "the compiler's child outlived the interrupt"


# ---- cache keys that cannot go stale (issue 39) ---------------------------------------------------------------

def test_a_changed_function_builder_is_rebuilt_and_the_same_builder_is_a_cache_hit(tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    x = ca.SX.sym("x", 2)
    first = ca.Function("cg_builder", [x], [x * x])
    changed = ca.Function("cg_builder", [x], [x * x * x])  # same name, same digest and recipe: another builder
    lib, now = codegen.build_library([first], "same-digest")
    hit, now_hit = codegen.build_library([first], "same-digest")
    other, now_other = codegen.build_library([changed], "same-digest")
    assert now and not now_hit and hit == lib
    assert now_other and other != lib
    loaded = codegen.load_library(other, ["cg_builder"])["cg_builder"]
    np.testing.assert_array_equal(np.asarray(loaded([2.0, -1.0])).ravel(), [8.0, -1.0])


def test_a_recipe_never_hides_a_changed_source_across_processes(tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    x = ca.SX.sym("x")
    lib, _ = codegen.build_library([ca.Function("cg_recipe", [x], [2 * x])], "d", recipe="same-recipe")
    codegen._BUILT.clear()  # a new process: the recipe memo is per process
    other, now = codegen.build_library([ca.Function("cg_recipe", [x], [3 * x])], "d", recipe="same-recipe")
    assert now and other != lib


def test_a_complete_recipe_keys_the_library_without_generating_its_source(tmp_path, monkeypatch):
    import pytest

    if codegen.compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("CARTPOLE_CFLAGS", raising=False)
    x = ca.SX.sym("x")
    calls = []

    def builder(k):
        def funcs():
            calls.append(k)
            return [ca.Function("cg_keyed", [x], [k * x])]
        return funcs

    lib, now = codegen.build_library(builder(2), "d", recipe="r2", cflags=("-O0",), recipe_is_key=True)
    codegen._BUILT.clear()  # a new process
    hit, now_hit = codegen.build_library(builder(2), "d", recipe="r2", cflags=("-O0",), recipe_is_key=True)
    other, now_other = codegen.build_library(builder(3), "d", recipe="r3", cflags=("-O0",), recipe_is_key=True)
    assert now and not now_hit and hit == lib and calls == [2, 3]
    assert now_other and other != lib
    np.testing.assert_array_equal(np.asarray(codegen.load_library(other, ["cg_keyed"])["cg_keyed"](2.0)).ravel(), [6.0])
    auto, now_auto = codegen.build_library(builder(2), "d", recipe="r2", recipe_is_key=True)  # choose_cflags's flags
    assert now_auto and auto != lib
    with pytest.raises(ValueError, match="recipe_is_key needs a recipe"):
        codegen.build_library(builder(2), "d", recipe_is_key=True)


def test_an_included_c_file_a_flag_or_the_compiler_changes_the_key(tmp_path, monkeypatch):
    import pytest

    if codegen.compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    inc = tmp_path / "inc"
    inc.mkdir()
    (inc / "cg_value.h").write_text("#define CG_VALUE 1\n")
    src = '#include "cg_value.h"\nint cg_value(void) { return CG_VALUE; }\n'
    lib = codegen.build_c_library(src, "cg_inc", [inc])
    assert codegen.build_c_library(src, "cg_inc", [inc]) == lib  # the same inputs: a cache hit
    (inc / "cg_value.h").write_text("#define CG_VALUE 2\n")
    changed = codegen.build_c_library(src, "cg_inc", [inc])
    assert changed != lib
    import ctypes

    assert ctypes.CDLL(changed).cg_value() == 2
    assert codegen.build_c_library(src, "cg_inc", [inc], cflags=("-O1",)) != changed
    key = codegen.library_key(src, codegen.CFLAGS, codegen.compiler(), [inc])
    assert codegen.library_key(src, codegen.CFLAGS, "/bin/sh", [inc]) != key  # another compiler


def test_render_fills_a_template_and_refuses_an_undefined_name(tmp_path, monkeypatch):
    import jinja2
    import pytest

    monkeypatch.setattr(codegen, "CSRC", tmp_path)
    codegen._jinja_env.cache_clear()
    try:
        (tmp_path / "t.h.jinja").write_text("static const double K[{{ k|length }}] = { {{ k|c_list }} };\n"
                                            "#define HI {{ hi|c_real }}\n")
        text = codegen.render("t.h.jinja", k=np.array([1.0, 0.1, -2.5]), hi=np.inf)
        assert text == "static const double K[3] = { 1.0, 0.1, -2.5 };\n#define HI INFINITY\n"
        with pytest.raises(jinja2.UndefinedError):
            codegen.render("t.h.jinja", k=[1.0])
    finally:
        codegen._jinja_env.cache_clear()


def _objects(cache):
    return sorted(p.name for p in (cache / codegen.OBJECT_DIR).glob("*.o"))


def test_a_second_folder_sharing_a_file_and_its_headers_compiles_only_the_files_that_differ(tmp_path, monkeypatch):
    import ctypes

    import pytest

    if codegen.compiler() is None:
        pytest.skip("no C compiler")
    cache = tmp_path / "cache"
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(cache))
    model = {"src/cg_model.h": "double cg_model(double x);\n",
             "src/cg_model.c": '#include "cg_model.h"\ndouble cg_model(double x) { return 3.0 * x; }\n'}

    def folder(gain):
        return {**model, "src/cg_plan.c": f'#include "cg_model.h"\ndouble cg_plan(double x) {{ return {gain} * '
                                          'cg_model(x); }\n'}

    first = codegen.build_sources(folder(2.0), "cg_prog", cflags=("-O2",))
    after_first = _objects(cache)
    second = codegen.build_sources(folder(5.0), "cg_prog", cflags=("-O2",))
    new = sorted(set(_objects(cache)) - set(after_first))
    assert second != first
    assert [n.split("_")[1] for n in after_first] == ["model", "plan"]
    assert [n.split("_")[1] for n in new] == ["plan"]  # the model's object taken from the cache, not compiled again
    fn = ctypes.CDLL(second).cg_plan
    fn.restype, fn.argtypes = ctypes.c_double, [ctypes.c_double]
    assert fn(1.0) == 15.0
    # a header the shared file includes is part of its object's key: edited, the model's object is compiled again
    edited = {**folder(5.0), "src/cg_model.h": "/* edited */\ndouble cg_model(double x);\n"}
    before = set(_objects(cache))
    codegen.build_sources(edited, "cg_prog", cflags=("-O2",))
    assert sorted(n.split("_")[1] for n in set(_objects(cache)) - before) == ["model", "plan"]


def test_a_corrupted_cached_object_is_compiled_again(tmp_path, monkeypatch):
    import pytest

    if codegen.compiler() is None:
        pytest.skip("no C compiler")
    cache = tmp_path / "cache"
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(cache))
    files = {"src/cg_one.c": "int cg_one(void) { return 1; }\n"}
    codegen.build_sources(files, "cg_obj", cflags=("-O1",))
    (obj,) = (cache / codegen.OBJECT_DIR).glob("*.o")
    obj.write_bytes(b"planted")
    lib = codegen.build_sources({**files, "src/cg_two.c": "int cg_two(void) { return 2; }\n"}, "cg_obj",
                                cflags=("-O1",))
    assert codegen.is_verified(obj) and obj.read_bytes() != b"planted"
    import ctypes

    assert ctypes.CDLL(lib).cg_one() == 1


def test_two_builds_of_one_object_at_once_compile_it_once(tmp_path, monkeypatch):
    import threading
    import time

    import pytest

    if codegen.compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    real, compiled = codegen.run_compiler, []

    def slow(cmd, timeout=None, cwd=None):
        if "-c" in cmd:
            compiled.append(cmd[cmd.index("-c") + 1])
            time.sleep(0.5)  # both builds are inside the compile at once without the lock
        return real(cmd, timeout, cwd)

    monkeypatch.setattr(codegen, "run_compiler", slow)
    shared = {"src/cg_shared.c": "int cg_shared(void) { return 7; }\n"}
    libs = {}

    def build(i):
        libs[i] = codegen.build_sources({**shared, f"src/cg_own{i}.c": f"int cg_own{i}(void) {{ return {i}; }}\n"},
                                        "cg_lock", cflags=("-O1",))

    threads = [threading.Thread(target=build, args=(i,)) for i in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert len(libs) == 2 and libs[0] != libs[1]
    assert sorted(compiled) == ["src/cg_own0.c", "src/cg_own1.c", "src/cg_shared.c"]  # the shared file once
