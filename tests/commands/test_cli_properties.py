"""Property: whatever MJCF and arguments a user hands the command line, the outcome is success (exit 0) or exactly
one sentence on stderr with exit status 2 - never a traceback, never a stray line, never a half-written --out.

`hypothesis <https://hypothesis.readthedocs.io>`_ (dev extra) draws the inputs, each one `Case`: one to three edits
of the shipped MJCF (gear, ctrlrange, damping, timestep, integrator, axis, masses, an added joint / actuator / tendon
/ contact, a deleted element, garbage text) and an argument list for ``linearize``, ``lqr`` (``--no-video``, small
options) or ``swingup`` (``--no-video``, short durations). Each example runs ``cartpole.cli.main`` in this process
with stdout and stderr captured.

Randomised: every run draws new examples from the seed that ``tests/conftest.py`` picks (``$HYPOTHESIS_SEED``, or a
fresh one) and prints in the pytest header and the summary: ``hypothesis seed: N (rerun with HYPOTHESIS_SEED=N)``.
The same seed draws the same examples for each test, whatever runs beside it, so
``HYPOTHESIS_SEED=N pytest tests/commands/test_cli_properties.py`` reproduces a failure. Bounded: ``max_examples``
per command is chosen so the three properties together stay within about a minute on two cores;
``CARTPOLE_PROPERTY_EXAMPLES=N`` draws N per command instead, to explore further.

A failure found once stays: hypothesis prints the failing input ("Failing test case") as ``case=Case(...)``, a value
whose ``repr`` rebuilds it (checked below); paste it as ``@example(case=Case(...))`` above the property,
with a comment naming the seed and what went wrong, so that every later run tries it first (there is no example
database; the explicit examples are the regression set). Until the package is fixed the example carries
``.xfail(raises=AssertionError, reason=...)``, which is strict: the fix then fails the example and asks for the mark
to go. The crashes found before the inputs were values are the plain tests at the end.

Hostile inputs (issue 24) are drawn too: extreme numbers (1e308, denormals) for every numeric option, pushes
after the run or beyond the force limit, NMPC horizons of a million seconds, negative seeds; ``--mjcf`` naming a
symbolic-link loop, a FIFO, a directory, ``/dev/zero`` or an empty file; and for ``swingup`` a cache directory others
may write to (always refused) or holding a truncated, impossible or unverifiable basin file or a planted library
(discarded, estimated or built again).

Time steps are drawn from plausible values (1 ms and up): below that a 300-sample basin estimate of 4 s per sample
is a run of minutes, not a bad input.
"""
import contextlib
import io
import os
import re
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from cartpole.cli import main  # noqa: E402
from cartpole.models import SHIPPED_MJCF  # noqa: E402

_EXPLORE = int(os.environ.get("CARTPOLE_PROPERTY_EXAMPLES", "0"))
PROGRESS_LINE = re.compile(r"^\w+: \S.* in \d+\.\d s$")


def _settings(n: int):
    """At most ``n`` examples (``$CARTPOLE_PROPERTY_EXAMPLES`` instead when set); MuJoCo work has no deadline.
    Randomisation, the seed and the absent example database come from the profile in ``tests/conftest.py``."""
    return settings(max_examples=_EXPLORE or n, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@dataclass(frozen=True)
class Case:
    """One drawn input, printed by hypothesis as a value that an ``@example`` can hold.

    ``edits``: tuples ``(kind, *arguments)`` applied in order to the shipped MJCF (see `_apply`); ``options``: the
    arguments after ``--mjcf PATH``; ``json``: whether ``--json`` is passed.
    """
    edits: tuple = ()
    options: tuple = ()
    json: bool = False
    #: What ``--mjcf PATH`` is: the edited file, or a path of the wrong kind (see `_mjcf_path`).
    mjcf_kind: str = "file"
    #: How the example's own cache directory is tampered with before the run (see `_tamper`), or None.
    cache: str | None = None


# ---- MJCF edits -----------------------------------------------------------------------------------------------

def _half_good(good, bad):
    """Draw from ``good`` or ``bad`` with even odds, so that about half the inputs get past validation."""
    return st.one_of(st.sampled_from(good), st.sampled_from(bad))


NUMBERS = _half_good(["0.5", "20", "1", "0.05", "2", "0.01"], ["0", "-1", "1e-9", "1e6", "nan", "inf", "-inf", "abc",
                                                              ""])
TIMESTEPS = _half_good(["0.001", "0.002", "0.01", "0.02"], ["0", "-0.005", "nan", "x"])
VECTORS = _half_good(["0 1 0", "0 -1 0", "1 0 0", "0 0 1"], ["0 0 0", "1 1 0", "nan 0 0", "1", "a b c"])
RANGES = _half_good(["-1 1", "-0.1 2", "-2 2", "-0.5 0.5"], ["1 -1", "0 0", "-inf inf", "-1e9 1e9", "a b", "-1",
                                                            "-1 1 2"])
# Which of several elements (or where in the text) an edit hits: taken modulo how many there are when it applies,
# so an edit stays meaningful after earlier edits added or deleted elements.
WHICH = st.integers(0, 10_000)


def _edit(kind, *arguments):
    return st.tuples(st.just(kind), *arguments)


EDITS = st.one_of(
    _edit("gear", NUMBERS),
    _edit("ctrlrange", RANGES, st.one_of(st.none(), st.sampled_from(["true", "false", "auto"]))),
    _edit("damping", WHICH, NUMBERS),
    _edit("timestep", TIMESTEPS),
    _edit("integrator", st.sampled_from(["Euler", "RK4", "implicit", "implicitfast", "bogus"])),
    _edit("axis", WHICH, VECTORS),
    _edit("range", WHICH, RANGES, st.sampled_from(["true", "false"])),
    _edit("mass", st.sampled_from(["cart_geom", "pole_geom"]), NUMBERS),
    _edit("joint", st.sampled_from(["cart", "pole"]), st.sampled_from(["hinge", "slide", "ball"]), VECTORS),
    _edit("actuator", st.sampled_from(["motor", "position", "velocity", "general"]),
          st.sampled_from(["hinge", "slider", "nope"]), NUMBERS),
    _edit("tendon"),
    _edit("contact", st.booleans()),
    _edit("delete", WHICH),
    _edit("gravity", st.sampled_from(["0 0 0", "0 0 9.81", "1 0 -9.81", "0 0 nan"])),
    _edit("garbage", WHICH, st.sampled_from(["", "<", "&", "<body>", "\x00", "]]>", "<!--", "é"]), st.integers(0, 40)),
)


def _one(root, tag, name=None):
    for el in root.iter(tag):
        if name is None or el.get("name") == name:
            return el
    return None


def _nth(elements, which):
    return elements[which % len(elements)] if elements else None


def _apply(root: ET.Element, edit: tuple) -> None:
    """Apply one tree edit (every kind but ``garbage``); an edit whose target an earlier edit deleted does nothing."""
    kind, *a = edit
    motor, option, act = _one(root, "motor"), _one(root, "option"), _one(root, "actuator")
    joint = _nth(list(root.iter("joint")), a[0]) if kind in ("damping", "axis", "range") else None
    if kind == "gear" and motor is not None:
        motor.set("gear", a[0])
    elif kind == "ctrlrange" and motor is not None:
        motor.set("ctrlrange", a[0])
        if a[1] is not None:
            motor.set("ctrllimited", a[1])
    elif kind == "damping" and joint is not None:
        joint.set("damping", a[1])
    elif kind == "timestep" and option is not None:
        option.set("timestep", a[0])
    elif kind == "integrator" and option is not None:
        option.set("integrator", a[0])
    elif kind == "axis" and joint is not None:
        joint.set("axis", a[1])
    elif kind == "range" and joint is not None:
        joint.set("range", a[1])
        joint.set("limited", a[2])
    elif kind == "mass" and (geom := _one(root, "geom", a[0])) is not None:
        geom.set("mass", a[1])
    elif kind == "joint" and (body := _one(root, "body", a[0])) is not None:
        ET.SubElement(body, "joint", name="extra", type=a[1], axis=a[2])
    elif kind == "actuator" and act is not None:
        ET.SubElement(act, a[0], name="extra_act", joint=a[1], gear=a[2])
    elif kind == "tendon":
        fixed = ET.SubElement(ET.SubElement(root, "tendon"), "fixed", name="t")
        ET.SubElement(fixed, "joint", joint="hinge", coef="1")
        ET.SubElement(fixed, "joint", joint="slider", coef="-1")
    elif kind == "contact" and option is not None:
        for flag in list(option):
            option.remove(flag)
        pole = _one(root, "geom", "pole_geom")
        if pole is not None and a[0]:
            pole.set("contype", "1")
            pole.set("conaffinity", "1")
    elif kind == "delete" and (pair := _nth([(p, c) for p in root.iter() for c in p], a[0])) is not None:
        pair[0].remove(pair[1])
    elif kind == "gravity" and option is not None:
        option.set("gravity", a[0])


def _mjcf(edits: tuple) -> str:
    """The shipped MJCF's text with ``edits`` applied: the tree edits in order, then the garbage ones on the text."""
    root = ET.fromstring(SHIPPED_MJCF.read_text())
    for edit in edits:
        if edit[0] != "garbage":
            _apply(root, edit)
    text = ET.tostring(root, encoding="unicode")
    for _, where, junk, span in (e for e in edits if e[0] == "garbage"):
        cut = where % (len(text) + 1)
        text = text[:cut] + junk + text[cut + span:]
    return text


# ---- argument lists -------------------------------------------------------------------------------------------

FLOATS = _half_good(["0", "1", "0.1", "10", "2.5"], ["-1", "1e-12", "1e12", "nan", "inf", "-0.5", "x", "1e308",
                                                    "-1e308", "1e-308", "5e-324"])
PUSHES = _half_good(["0.2:5", "0.1:-20", "0:1"], ["1e308:1", "1:1e12", "5:1", "nan:1", "-1:1", "1:inf", "1:", "x"])
#: What ``--mjcf`` names: mostly the edited file, now and then a path no MJCF reader may open.
MJCF_KINDS = st.one_of(st.just("file"), st.sampled_from(["loop", "fifo", "directory", "device", "missing", "empty"]))
#: Tampering with the example's own cache directory (a copy of one holding a real basin estimate).
CACHES = st.one_of(st.none(), st.sampled_from(["group-writable", "world-writable", "truncated-basin",
                                                "impossible-basin", "garbage-sidecar", "planted-library"]))


def _floats(draw, lo, hi):
    return draw(st.lists(FLOATS, min_size=lo, max_size=hi))


@st.composite
def _options(draw, command: str) -> tuple:
    argv = []
    if command == "lqr":
        argv += ["--no-video"]
        if draw(st.booleans()):
            argv += ["--discrete"]
        if draw(st.booleans()):  # the diagonal of Q: four numbers for the shipped cart, or anything
            argv += ["--Q", *_floats(draw, *draw(st.sampled_from([(4, 4), (1, 5)])))]
        if draw(st.booleans()):
            argv += ["--R", *_floats(draw, 1, 2)]
    elif command == "swingup":
        argv += ["--no-video", "--duration", draw(_half_good(["0.5", "0.3"], ["0", "-1", "nan", "1e12", "abc"]))]
        if draw(st.booleans()):  # a start: four numbers for the shipped cart, or anything
            argv += ["--x0", *_floats(draw, *draw(st.sampled_from([(4, 4), (3, 5)])))]
        if draw(st.booleans()):
            argv += ["--method", draw(st.sampled_from(["energy", "energy", "energy", "mpc"]))]
            if argv[-1] == "mpc" and draw(st.booleans()):
                argv += ["--horizon", draw(_half_good(["1.2", "0.5"], ["1e6", "1e-9", "30", "nan", "-1"]))]
        if draw(st.booleans()):
            argv += ["--push", draw(PUSHES)]
        if draw(st.sampled_from(range(4))) == 3:
            argv += ["--noise-seed", draw(st.sampled_from(["0", "7", "-1", "1e30", "x"]))]
    if draw(st.sampled_from(range(10))) == 9:  # now and then an option that does not exist or lacks its value
        argv += [draw(st.sampled_from(["--bogus", "--duration", "--Q", "--x0", "-x"]))]
    return tuple(argv)


def cases(command: str):
    """Strategy: a `Case` for ``command`` (up to three MJCF edits, its options, with or without ``--json``, what
    ``--mjcf`` names, and for ``swingup`` a tampered cache)."""
    return st.builds(Case, edits=st.lists(EDITS, max_size=3).map(tuple), options=_options(command),
                     json=st.booleans(), mjcf_kind=MJCF_KINDS,
                     cache=CACHES if command == "swingup" else st.none())


# ---- hostile paths and caches ---------------------------------------------------------------------------------

def _mjcf_path(tmp: Path, kind: str, text: str) -> Path:
    """``--mjcf``: the edited MJCF, or a symbolic-link loop, a FIFO, a directory, a device, a missing or empty
    file."""
    path = tmp / "model.xml"
    if kind == "file":
        path.write_text(text)
    elif kind == "loop":
        os.symlink(tmp / "other.xml", path)
        os.symlink(path, tmp / "other.xml")
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    elif kind == "device":
        path = Path("/dev/zero")
    elif kind == "empty":
        path.write_text("")
    return path


#: a cache directory holding the shipped cart's basin estimate, made once per session (a TemporaryDirectory, so
#: that it is removed when the session's interpreter exits: hypothesis' tests take no pytest fixtures)
_TEMPLATE: list = []


def _template_cache() -> Path:
    if not _TEMPLATE:
        from cartpole.validation.basin import BasinCache

        d = tempfile.TemporaryDirectory(prefix="cartpole-cache-template-")
        BasinCache.on_disk(Path(d.name) / "basins").get(None)
        _TEMPLATE.append(d)
    return Path(_TEMPLATE[0].name)


def _tamper(cache: Path, how: str) -> None:
    """Copy the template cache to ``cache`` and tamper with it as ``how`` says."""
    import shutil

    import numpy as np

    shutil.copytree(_template_cache(), cache)
    cache.chmod(0o700)
    basins = sorted((cache / "basins").glob("*.npz"))
    if how == "group-writable":
        cache.chmod(0o770)
    elif how == "world-writable":
        (cache / "basins").chmod(0o777)
    elif how == "truncated-basin":
        for b in basins:
            b.write_bytes(b.read_bytes()[:100])
    elif how == "impossible-basin":
        from cartpole.codegen import write_verified

        for b in basins:
            with np.load(b) as z:
                arrays = {k: np.array(z[k]) for k in z.files}
            arrays["scalars"][:3] = [-1.0, np.nan, -2.0]
            buf = io.BytesIO()
            np.savez(buf, **arrays)
            write_verified(b, buf.getvalue())  # a correct hash of impossible values
    elif how == "garbage-sidecar":
        for b in basins:
            Path(str(b) + ".sha256").write_bytes(b"\x00garbage")
    elif how == "planted-library":  # a file under a library's name, no recorded hash
        (cache / "hs_interval_r0123456789abcdef0123.so").write_bytes(b"\x7fELF not really")


# ---- the property -------------------------------------------------------------------------------------------

def _check_outcome(command, argv, rc, out, err, out_dir: Path, json_mode: bool):
    assert "Traceback" not in err, err
    if rc == 0:
        if json_mode:
            import json
            json.loads(out)  # stdout: exactly one JSON document
        return
    assert rc == 2, (rc, err)
    lines = err.strip().splitlines()
    problems = [line for line in lines if not PROGRESS_LINE.match(line)]
    assert len(problems) == 1, err  # one sentence (progress lines of the stages that finished may precede it)
    if json_mode:
        assert len(lines) == 1 and out == "", (out, err)
    sentence = problems[0]
    assert sentence.startswith(f"cartpole {command}: ") and sentence.endswith("."), sentence
    assert not out_dir.exists() or not any(out_dir.iterdir()), f"files left under --out: {list(out_dir.rglob('*'))}"


def _run_cli(command: str, case: Case):
    with tempfile.TemporaryDirectory() as tmp:
        path = _mjcf_path(Path(tmp), case.mjcf_kind, _mjcf(case.edits))
        out_dir = Path(tmp) / "out"
        argv = [command, "--mjcf", str(path), *(["--json"] if case.json else []), *case.options]
        if command != "linearize":
            argv[1:1] = ["--out", str(out_dir)]
        saved = os.environ.get("CARTPOLE_CACHE_DIR")
        if case.cache is not None:
            _tamper(Path(tmp) / "cache", case.cache)
            os.environ["CARTPOLE_CACHE_DIR"] = str(Path(tmp) / "cache")
        out, err = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                rc = main(argv)
        finally:
            if case.cache is not None:
                if saved is None:
                    os.environ.pop("CARTPOLE_CACHE_DIR", None)
                else:
                    os.environ["CARTPOLE_CACHE_DIR"] = saved
        _check_outcome(command, argv, rc, out.getvalue(), err.getvalue(), out_dir, case.json)
        if case.mjcf_kind != "file" or case.cache in ("group-writable", "world-writable"):
            assert rc == 2, (case, err.getvalue())  # never a run on such a path or from such a cache


@_settings(200)
@given(case=cases("linearize"))
def test_linearize_on_mutated_mjcf_succeeds_or_says_one_sentence(case):
    _run_cli("linearize", case)


@_settings(50)
@given(case=cases("lqr"))
def test_lqr_on_mutated_mjcf_succeeds_or_says_one_sentence(case):
    _run_cli("lqr", case)


@_settings(60)
@given(case=cases("swingup"))
def test_swingup_on_mutated_mjcf_succeeds_or_says_one_sentence(case):
    _run_cli("swingup", case)


@settings(max_examples=100, deadline=None)
@given(case=st.one_of(cases("linearize"), cases("lqr"), cases("swingup")))
def test_a_drawn_case_prints_as_the_example_that_rebuilds_it(case):
    assert eval(repr(case), {"Case": Case}) == case  # what hypothesis prints can be pasted into an @example


def _edited(old: str, new: str) -> str:
    text = SHIPPED_MJCF.read_text()
    assert old in text
    return text.replace(old, new)


@pytest.mark.parametrize("command, old, new", [
    pytest.param("linearize", 'gear="20"', 'gear="nan"', id="gear-nan"),
    pytest.param("lqr", 'axis="0 1 0"', 'axis="nan 0 0"', id="hinge-axis-nan"),
    pytest.param("swingup", 'gravity="0 0 -9.81"', 'gravity="0 0 nan"', id="gravity-nan"),
    pytest.param("swingup", 'gravity="0 0 -9.81"', 'gravity="0 0 0"', id="no-gravity"),
])
def test_crashes_hypothesis_found_end_in_one_sentence(command, old, new, tmp_path, capsys):
    path = tmp_path / "model.xml"
    path.write_text(_edited(old, new))
    argv = [command, "--json", "--mjcf", str(path)]
    if command != "linearize":
        argv += ["--out", str(tmp_path / "out"), "--no-video"]
    if command == "swingup":
        argv += ["--duration", "0.5"]
    rc = main(argv)
    cap = capsys.readouterr()
    assert rc == 2 and len(cap.err.strip().splitlines()) == 1 and cap.out == ""
