"""Property: whatever MJCF and arguments a user hands the command line, the outcome is success (exit 0) or exactly
one sentence on stderr with exit status 2 - never a traceback, never a stray line, never a half-written --out.

`hypothesis <https://hypothesis.readthedocs.io>`_ (dev extra) draws the inputs: the shipped MJCF with one to three
plausible edits (gear, ctrlrange, damping, timestep, integrator, axis, masses, an added joint / actuator / tendon /
contact, a deleted element, garbage text) and argument lists for ``linearize``, ``lqr`` (``--no-video``, small
options) and ``swingup`` (``--no-video``, short durations). Each example runs ``cartpole.cli.main`` in this process
with stdout and stderr captured. Bounded: a fixed, derandomised set of examples per command (each well under a
few seconds); ``CARTPOLE_PROPERTY_EXAMPLES=N`` draws N random ones per command instead, to explore.

Time steps are drawn from plausible values (1 ms and up): below that a 300-sample basin estimate of 4 s per sample
is a run of minutes, not a bad input.
"""
import contextlib
import io
import os
import re
import tempfile
import xml.etree.ElementTree as ET
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
    return settings(max_examples=_EXPLORE or n, deadline=None, derandomize=not _EXPLORE, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# ---- MJCF mutations -------------------------------------------------------------------------------------------

def _half_good(good, bad):
    """Draw from ``good`` or ``bad`` with even odds, so that about half the inputs get past validation."""
    return st.one_of(st.sampled_from(good), st.sampled_from(bad))


NUMBERS = _half_good(["0.5", "20", "1", "0.05", "2", "0.01"], ["0", "-1", "1e-9", "1e6", "nan", "inf", "-inf", "abc",
                                                              ""])
TIMESTEPS = _half_good(["0.001", "0.002", "0.01", "0.02"], ["0", "-0.005", "nan", "x"])
VECTORS = _half_good(["0 1 0", "0 -1 0", "1 0 0", "0 0 1"], ["0 0 0", "1 1 0", "nan 0 0", "1", "a b c"])
RANGES = _half_good(["-1 1", "-0.1 2", "-2 2", "-0.5 0.5"], ["1 -1", "0 0", "-inf inf", "-1e9 1e9", "a b", "-1",
                                                            "-1 1 2"])


def _one(root, tag, name=None):
    for el in root.iter(tag):
        if name is None or el.get("name") == name:
            return el
    return None


def _pick(data, elements):
    elements = [e for e in elements if e is not None]
    return data.draw(st.sampled_from(elements)) if elements else None


def _mutate(root: ET.Element, kind: str, data) -> None:
    """One edit of the kind named; an edit whose target an earlier edit deleted does nothing."""
    joints = list(root.iter("joint"))
    motor, option, act = _one(root, "motor"), _one(root, "option"), _one(root, "actuator")
    if kind == "gear" and motor is not None:
        motor.set("gear", data.draw(NUMBERS))
    elif kind == "ctrlrange" and motor is not None:
        motor.set("ctrlrange", data.draw(RANGES))
        if data.draw(st.booleans()):
            motor.set("ctrllimited", data.draw(st.sampled_from(["true", "false", "auto"])))
    elif kind == "damping" and joints:
        _pick(data, joints).set("damping", data.draw(NUMBERS))
    elif kind == "timestep" and option is not None:
        option.set("timestep", data.draw(TIMESTEPS))
    elif kind == "integrator" and option is not None:
        option.set("integrator", data.draw(st.sampled_from(["Euler", "RK4", "implicit", "implicitfast", "bogus"])))
    elif kind == "axis" and joints:
        _pick(data, joints).set("axis", data.draw(VECTORS))
    elif kind == "range" and joints:
        j = _pick(data, joints)
        j.set("range", data.draw(RANGES))
        j.set("limited", data.draw(st.sampled_from(["true", "false"])))
    elif kind == "mass":
        geom = _pick(data, [_one(root, "geom", "cart_geom"), _one(root, "geom", "pole_geom")])
        if geom is not None:
            geom.set("mass", data.draw(NUMBERS))
    elif kind == "joint":
        body = _pick(data, [_one(root, "body", "cart"), _one(root, "body", "pole")])
        if body is not None:
            ET.SubElement(body, "joint", name="extra", type=data.draw(st.sampled_from(["hinge", "slide", "ball"])),
                          axis=data.draw(VECTORS))
    elif kind == "actuator" and act is not None:
        tag = data.draw(st.sampled_from(["motor", "position", "velocity", "general"]))
        ET.SubElement(act, tag, name="extra_act", joint=data.draw(st.sampled_from(["hinge", "slider", "nope"])),
                      gear=data.draw(NUMBERS))
    elif kind == "tendon":
        tendon = ET.SubElement(root, "tendon")
        fixed = ET.SubElement(tendon, "fixed", name="t")
        ET.SubElement(fixed, "joint", joint="hinge", coef="1")
        ET.SubElement(fixed, "joint", joint="slider", coef="-1")
    elif kind == "contact" and option is not None:
        for flag in list(option):
            option.remove(flag)
        pole = _one(root, "geom", "pole_geom")
        if pole is not None and data.draw(st.booleans()):
            pole.set("contype", "1")
            pole.set("conaffinity", "1")
    elif kind == "delete":
        pairs = [(p, c) for p in root.iter() for c in list(p)]
        if pairs:
            parent, child = data.draw(st.sampled_from(pairs))
            parent.remove(child)
    elif kind == "gravity" and option is not None:
        option.set("gravity", data.draw(st.sampled_from(["0 0 0", "0 0 9.81", "1 0 -9.81", "0 0 nan"])))


KINDS = ["gear", "ctrlrange", "damping", "timestep", "integrator", "axis", "range", "mass", "joint", "actuator",
         "tendon", "contact", "delete", "gravity", "garbage"]


def _mjcf(data) -> str:
    root = ET.fromstring(SHIPPED_MJCF.read_text())
    kinds = data.draw(st.lists(st.sampled_from(KINDS), min_size=0, max_size=3))
    for kind in kinds:
        if kind != "garbage":
            _mutate(root, kind, data)
    text = ET.tostring(root, encoding="unicode")
    if "garbage" in kinds:
        cut = data.draw(st.integers(0, len(text)))
        junk = data.draw(st.sampled_from(["", "<", "&", "<body>", "\x00", "]]>", "<!--", "é"]))
        text = text[:cut] + junk + text[cut + data.draw(st.integers(0, 40)):]
    return text


# ---- argument lists -------------------------------------------------------------------------------------------

FLOATS = _half_good(["0", "1", "0.1", "10", "2.5"], ["-1", "1e-12", "1e12", "nan", "inf", "-0.5", "x"])


def _floats(data, lo, hi):
    return data.draw(st.lists(FLOATS, min_size=lo, max_size=hi))


def _argv(data, command: str) -> list[str]:
    argv = []
    if command == "lqr":
        argv += ["--no-video"]
        if data.draw(st.booleans()):
            argv += ["--discrete"]
        if data.draw(st.booleans()):  # the diagonal of Q: four numbers for the shipped cart, or anything
            argv += ["--Q", *_floats(data, *data.draw(st.sampled_from([(4, 4), (1, 5)])))]
        if data.draw(st.booleans()):
            argv += ["--R", *_floats(data, 1, 2)]
    elif command == "swingup":
        argv += ["--no-video", "--duration", data.draw(_half_good(["0.5", "0.3"], ["0", "-1", "nan", "1e12", "abc"]))]
        if data.draw(st.booleans()):  # a start: four numbers for the shipped cart, or anything
            argv += ["--x0", *_floats(data, *data.draw(st.sampled_from([(4, 4), (3, 5)])))]
        if data.draw(st.booleans()):
            argv += ["--method", data.draw(st.sampled_from(["energy", "energy", "energy", "mpc"]))]
    if data.draw(st.sampled_from(range(10))) == 9:  # now and then an option that does not exist or lacks its value
        argv += [data.draw(st.sampled_from(["--bogus", "--duration", "--Q", "--x0", "-x"]))]
    return argv


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


def _run_cli(command, data):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.xml"
        path.write_text(_mjcf(data))
        out_dir = Path(tmp) / "out"
        json_mode = data.draw(st.booleans())
        argv = [command, "--mjcf", str(path), *(["--json"] if json_mode else []), *_argv(data, command)]
        if command != "linearize":
            argv[1:1] = ["--out", str(out_dir)]
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(argv)
        _check_outcome(command, argv, rc, out.getvalue(), err.getvalue(), out_dir,
                       json_mode)


@_settings(25)
@given(data=st.data())
def test_linearize_on_mutated_mjcf_succeeds_or_says_one_sentence(data):
    _run_cli("linearize", data)


@_settings(10)
@given(data=st.data())
def test_lqr_on_mutated_mjcf_succeeds_or_says_one_sentence(data):
    _run_cli("lqr", data)


@_settings(12)
@given(data=st.data())
def test_swingup_on_mutated_mjcf_succeeds_or_says_one_sentence(data):
    _run_cli("swingup", data)


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
