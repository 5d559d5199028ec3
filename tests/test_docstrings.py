"""Every public function and class of the package has a docstring, and says the units of the physical quantities
it takes and returns (the standard: "docstrings on every public function with units and array shapes").

Public: a module-level function or class whose name does not start with ``_``, defined in (not imported into) a
module none of whose dotted parts starts with ``_`` (``cartpole.__main__``, which runs the CLI on import, is not a
library module).

The docstring rule: :func:`inspect.getdoc` is not empty, and for a class it is not the one ``dataclass`` or
``NamedTuple`` writes (``Name(field, ...)``).

The unit rule, made checkable: a parameter (or a numpydoc ``Returns`` entry) whose name denotes a physical quantity
(:data:`PHYSICAL`: times, durations, periods, forces, masses, lengths, states, inputs, pushes, delays, ...) must be
documented with a unit or a shape. Documented means: the numpydoc ``Parameters`` / ``Returns`` entry of that name
holds a unit or shape word (:data:`UNIT`: ``s``, ``ms``, ``m``, ``rad``, ``N``, ``kg``, ``ctrl``, ``SI``, ``m/s``,
``deg``, a word such as "seconds", or a shape such as ``(nx,)``, ``(N+1, nu)``); where the docstring has no
``Parameters`` section, a mention of the parameter (````name```` or ``name``) followed in the same clause by such a
word. What a value means beyond its unit is for review, not for this test.

Known gaps: the names in :data:`KNOWN_GAPS` broke one of these rules when this test was written; they are listed
so that the test fails on every new gap now, and the list is to be emptied (by fixing the docstrings, then deleting
the entry; an entry that no longer fails fails :func:`test_known_gaps_are_still_gaps`, so the list only shrinks).
"""
from __future__ import annotations

import dataclasses
import importlib
import inspect
import re
from pathlib import Path

import pytest

PACKAGE_DIR = Path(__file__).resolve().parent.parent / "cartpole"

#: Parameter and return names that denote physical quantities (exact names; plus the suffixes in PHYSICAL_SUFFIXES).
PHYSICAL = frozenset({
    "t", "T", "dt", "period", "duration", "horizon", "seconds", "time", "timestep", "t0", "t_end", "T_max",
    "T_min", "delay", "hold", "force", "forces", "push", "pushes", "mass", "length", "x0", "x", "xs", "X0", "x_eq",
    "u", "us", "u_eq", "ctrl", "u_max", "u_min", "cart_max", "x_goal", "qpos", "qvel",
})
PHYSICAL_SUFFIXES = ("_time", "_duration", "_period", "_force", "_seconds", "_s", "_ms")

#: A unit or shape word: SI unit symbols the toolkit uses, their names, ``ctrl`` (MuJoCo's input unit), ``SI``, or an
#: array shape in parentheses with a comma or a size name (``(nx,)``, ``(N+1, 2 nq)``, ``(n, nu)``).
UNIT = re.compile(
    r"(?<![\w.])(s|ms|us|m|rad|N|kg|Hz|J|W|deg|ctrl|SI|m/s|rad/s|m/s\^2|rad/s\^2|1/s|N m)(?![\w])"
    r"|(?i:\b(seconds?|metres?|meters?|radians?|newtons?|kilograms?|degrees?)\b)"
    r"|\([^()]*(,|\b(n[a-z]*|N|nx|nq|nv|nu|ny|nz)\b)[^()]*\)")

#: Names breaking a rule when this test was written: "module.name" -> the rule (lead: empty this list).
KNOWN_GAPS: dict[str, str] = {}


def public_modules() -> list[str]:
    """Dotted names of every module file of the package none of whose parts starts with ``_``."""
    names = []
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        if not any(p.startswith("_") for p in parts):
            names.append(".".join(parts))
    return names


def public_objects(module) -> list[tuple[str, object]]:
    """``(name, obj)`` of the functions and classes defined in ``module`` whose names do not start with ``_``."""
    out = []
    for name, obj in vars(module).items():
        if name.startswith("_") or not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue
        if getattr(obj, "__module__", None) == module.__name__:
            out.append((name, obj))
    return out


def _generated_class_doc(cls, doc: str) -> bool:
    """Whether a class's docstring is the one ``dataclass`` / ``NamedTuple`` / ``Enum`` writes, not an author's."""
    return bool(re.fullmatch(rf"{re.escape(cls.__name__)}\(.*\)", doc.strip(), flags=re.S)) or doc.strip() in (
        "An enumeration.", "")


def docstring_of(obj) -> str:
    """The object's own docstring ('' when there is none, or only a generated one)."""
    doc = obj.__doc__ if inspect.isclass(obj) else inspect.getdoc(obj)
    doc = inspect.cleandoc(doc) if doc else ""
    if inspect.isclass(obj) and _generated_class_doc(obj, doc):
        return ""
    return doc


def is_physical(name: str) -> bool:
    """Whether a parameter or return name denotes a physical quantity (:data:`PHYSICAL`, :data:`PHYSICAL_SUFFIXES`)."""
    return name in PHYSICAL or name.endswith(PHYSICAL_SUFFIXES)


def _sections(doc: str) -> dict[str, dict[str, str]]:
    """numpydoc ``Parameters`` (with ``Other Parameters`` and, for classes, ``Attributes``) and ``Returns`` entries:
    section -> {name: type and description}."""
    from numpydoc.docscrape import NumpyDocString

    try:
        parsed = NumpyDocString(doc)
    except Exception:  # not numpydoc at all: prose only
        return {"Parameters": {}, "Returns": {}}

    def entries(*keys):
        out = {}
        for key in keys:
            for p in parsed[key]:
                for name in re.split(r"\s*,\s*", p.name.strip()):
                    out[name.strip("*` ")] = f"{p.type} {' '.join(p.desc)}"
        return out

    return {"Parameters": entries("Parameters", "Other Parameters", "Attributes"), "Returns": entries("Returns")}


def _mentioned_with_unit(name: str, doc: str) -> bool:
    """Prose: a mention of ``name`` followed in the same clause (up to a ';' or a sentence end) by a unit or shape."""
    for m in re.finditer(rf"(``|`|\b){re.escape(name)}(``|`|\b)", doc):
        clause = re.split(r";|\.\s|\n\s*\n", doc[m.end():m.end() + 160])[0]
        if UNIT.search(clause):
            return True
    return False


def _signature_parameters(obj) -> list[str]:
    """The names a caller passes (a dataclass's fields), without flags: a parameter whose default is a bool is a
    switch (``free_time=False``), not a quantity."""
    if inspect.isclass(obj) and dataclasses.is_dataclass(obj):
        return [f.name for f in dataclasses.fields(obj) if not isinstance(f.default, bool)]
    target = obj.__init__ if inspect.isclass(obj) and "__init__" in vars(obj) else obj
    try:
        sig = inspect.signature(target)
    except (TypeError, ValueError):
        return []
    return [n for n, p in sig.parameters.items() if n not in ("self", "cls") and not isinstance(p.default, bool)]


def problems(obj) -> list[str]:
    """What ``obj`` lacks: 'no docstring', or 'units of <name>' per physical parameter or return undocumented."""
    doc = docstring_of(obj)
    if not doc:
        return ["no docstring"]
    if inspect.isclass(obj) and "__init__" in vars(obj) and not dataclasses.is_dataclass(obj):
        doc = doc + "\n\n" + (inspect.getdoc(obj.__init__) or "")
    found = _sections(doc)
    missing = []
    for name in _signature_parameters(obj):
        if not is_physical(name):
            continue
        entry = found["Parameters"].get(name)
        ok = UNIT.search(entry) is not None if entry is not None else (
            not found["Parameters"] and _mentioned_with_unit(name, doc))
        if not ok:
            missing.append(f"units of {name}")
    for name, entry in found["Returns"].items():
        if is_physical(name) and not UNIT.search(entry):
            missing.append(f"units of returned {name}")
    return missing


def all_problems() -> dict[str, str]:
    """``"module.name" -> "; ".join(problems)`` over every public object of the package."""
    out = {}
    for modname in public_modules():
        module = importlib.import_module(modname)
        for name, obj in public_objects(module):
            found = problems(obj)
            if found:
                out[f"{modname}.{name}"] = "; ".join(found)
    return out


@pytest.fixture(scope="module")
def found_problems() -> dict[str, str]:
    return all_problems()


def test_every_public_function_and_class_has_a_docstring_with_units(found_problems):
    new = {k: v for k, v in found_problems.items() if k not in KNOWN_GAPS}
    listing = "\n".join(f"  {k}: {v}" for k, v in sorted(new.items()))
    assert not new, ("public names without a docstring or without units (document them: a numpydoc Parameters "
                     f"entry with a unit or shape per physical quantity):\n{listing}")


def test_known_gaps_are_still_gaps(found_problems):
    fixed = sorted(k for k in KNOWN_GAPS if k not in found_problems)
    assert not fixed, "these KNOWN_GAPS are documented now; delete them from the list: " + ", ".join(fixed)


def test_the_walk_sees_the_package():
    """The walk reaches every layer's modules, and reaches into them (a walk that found nothing would pass)."""
    mods = public_modules()
    for expected in ("cartpole.models.symbolic", "cartpole.riccati.algebraic", "cartpole.sim.rollout", "cartpole.cli"):
        assert expected in mods
    assert "cartpole.__main__" not in mods and not any(m.split(".")[-1].startswith("_") for m in mods)
    from cartpole.riccati import algebraic as riccati

    assert ("lqr", riccati.lqr) in public_objects(riccati)
    assert all(n != "np" for n, _ in public_objects(riccati))  # imported names are not the module's


# ---- the checker can fail: synthetic objects ---------------------------------------------------------------------

def _no_doc(x0, duration):
    pass


def _no_units(x0, duration, gain):
    """Run something.

    Parameters
    ----------
    x0 : array
        Start state.
    duration : float
        How long.
    gain : float
        A gain.
    """


def _with_units(x0, duration, gain):
    """Run something.

    Parameters
    ----------
    x0 : (nx,) array
        Start state, [qpos, qvel].
    duration : float
        Simulated time, s.
    gain : float
        A gain (no unit needed: not a physical name).

    Returns
    -------
    t : (n+1,) array
        Times of the samples.
    """


def _prose_units(x0, period):
    """Hold each ``period`` (s) from ``x0`` ((nx,) array)."""


def _prose_without_units(x0, period):
    """Hold each ``period`` from ``x0``."""


def _returns_without_units():
    """Something.

    Returns
    -------
    duration : float
        How long it took.
    """


@dataclasses.dataclass(frozen=True)
class _Generated:
    duration: float


def test_the_checker_fails_where_a_docstring_or_a_unit_is_missing():
    assert problems(_no_doc) == ["no docstring"]
    assert problems(_Generated) == ["no docstring"]  # the dataclass's own "_Generated(duration: float)" is not one
    assert problems(_no_units) == ["units of x0", "units of duration"]
    assert problems(_prose_without_units) == ["units of x0", "units of period"]
    assert problems(_returns_without_units) == ["units of returned duration"]


def test_the_checker_passes_documented_units_and_shapes():
    assert problems(_with_units) == []
    assert problems(_prose_units) == []
