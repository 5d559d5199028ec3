"""The package's code has a readable shape, read from the source (the sibling of ``test_layering.py``).

Bounds, for every function and method under ``cartpole/`` (nested functions too, each on its own):

* **Length**: at most ``MAX_LINES`` = 100 lines, from its ``def`` line to its last line (docstring and comments
  included). A longer function is split into named steps.
* **Parameters**: at most ``MAX_PARAMS`` = 10, counting positional, keyword-only, ``*args`` and ``**kwargs`` alike and
  leaving out ``self`` and ``cls``. More belong in an options object (a frozen dataclass, as
  :class:`cartpole.sim.LoopOptions`).
* **Imports at the top of the module**: no ``import`` inside a function, except of the optional dependencies in
  ``OPTIONAL_IMPORTS`` (not installed with the package, or only for one feature, or only on POSIX; importing them at
  the top would make the package need them) and of the modules in ``COSTLY_IMPORTS`` inside the layers named there
  (heavy at import and needed by one path only). An import that breaks an import cycle is not allowed: the cycle's cause is fixed instead.
* **Library errors speak Python**: the text of an exception raised under ``cartpole/`` outside the command layer
  (``cartpole/commands``, ``cartpole/cli.py``) never names a command-line flag (``--name``). A library error names
  the Python argument and the physics; the command layer maps arguments to flags where it needs to.

Code written before these bounds and not yet brought within them is listed below, file by file, with the count of
offences (imports, flag texts) or the functions' names (length, parameters). **These lists only shrink**: a test
fails when a listed file gets worse, when an unlisted one offends, and also when a listed entry is better than its
entry says (lower or remove the entry in the same commit, so the list stays the truth). ``python
tests/test_code_shape.py`` prints today's offenders in the lists' own form.
"""
from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest

PACKAGE_DIR = Path(__file__).resolve().parent.parent / "cartpole"
MAX_LINES = 100
MAX_PARAMS = 10

#: Optional dependencies (importable only inside the functions that need them, anywhere in the package): the cluster
#: (dask, distributed, ray), the Crocoddyl comparison (crocoddyl, pinocchio, example_robot_data), the learned agents'
#: suites (dm_control, gymnasium), the browser (playwright, websockets); and the POSIX-only modules (fcntl, termios,
#: resource), so that the package still imports where they do not exist.
OPTIONAL_IMPORTS = frozenset({"dask", "distributed", "ray", "crocoddyl", "pinocchio", "pin", "example_robot_data",
                              "dm_control", "gymnasium", "playwright", "websockets", "fcntl", "termios", "resource"})

#: Modules heavy at import or tied to a display, imported by the one path that needs them, and only inside these
#: layers: matplotlib (about 0.5 s) in the figures; python-control (seconds: it imports matplotlib and SciPy's signal
#: tools) wherever a design is handed to it, so that the model and the command line do not pay for it; MuJoCo's
#: desktop viewer (it needs a GL window system) and MuJoCo Studio's web viewer (only in wheels that ship it) in the
#: figures; SciPy's signal tools (seconds: they load scipy.stats) in the PID tuning's pole placement, so that
#: every run that imports the PID does not pay for them.
#: The command line's own module, ``cartpole.cli``, imports nothing heavy at its top (``import cartpole.cli`` loads
#: no NumPy, CasADi or MuJoCo: tests/test_package_top.py), so that ``cartpole sweep --workers N`` starts its
#: workers' fork server first; it imports them when a command runs (and MuJoCo and matplotlib once, to say in one
#: sentence when they cannot load).
COSTLY_IMPORTS = {
    "matplotlib": ("cartpole.viz", "cartpole.cli"),
    "control": ("cartpole",),
    "scipy.signal": ("cartpole.control.pid",),
    "mujoco": ("cartpole.cli",),
    "mujoco.viewer": ("cartpole.viz",),
    "mujoco.studio": ("cartpole.viz",),
    "numpy": ("cartpole.cli",),
    "cartpole.codegen": ("cartpole.cli",),
    "cartpole.models": ("cartpole.cli",),
}

COMMAND_LAYER = ("cartpole/commands/", "cartpole/cli.py", "cartpole/__main__.py")

FLAG = re.compile(r"(?<![\w-])--[a-zA-Z][\w-]*")

# ---------------------------------------------------------------------------------------------------------------
# Still to fix, by file (sorted by path, so that each file's entry is changed on its own line). Whoever brings a
# file within the bounds lowers or removes its entry in the same commit; nothing is added here.
# ---------------------------------------------------------------------------------------------------------------

#: file -> imports inside functions not allowed above.
IMPORTS_TO_FIX = {
}

#: file -> qualified names of the functions longer than MAX_LINES.
LONG_TO_FIX = {
}

#: file -> qualified names of the functions with more than MAX_PARAMS parameters.
PARAMS_TO_FIX = {
}

#: file -> raised error texts naming a command-line flag.
FLAGS_TO_FIX = {
}


@functools.lru_cache(maxsize=None)
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), filename=str(path))


def _files() -> list[Path]:
    return [p for p in sorted(PACKAGE_DIR.rglob("*.py")) if "__pycache__" not in p.parts]


def _rel(path: Path) -> str:
    return path.relative_to(PACKAGE_DIR.parent).as_posix()


def _module(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def functions(tree: ast.AST) -> list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    """``(qualified name, node)`` of every function and method in ``tree``, nested ones included."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out.append((prefix + child.name, child))
                visit(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)

    visit(tree, "")
    return out


def length(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines from the ``def`` (decorators not counted) to the function's last line."""
    return node.end_lineno - node.lineno + 1


def parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> list[str]:
    """The parameter names, ``self`` and ``cls`` left out."""
    a = node.args
    names = [x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    return [n for n in names if n not in ("self", "cls")]


def _imported(node: ast.Import | ast.ImportFrom) -> list[str]:
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if node.level:
        return ["."]  # relative: a module of the package
    return [f"{node.module}.{alias.name}" for alias in node.names]


def allowed_inside(target: str, module: str) -> bool:
    """Whether ``module`` may import ``target`` (a dotted name) inside a function."""
    if target.split(".")[0] in OPTIONAL_IMPORTS:
        return True
    for costly, layers in COSTLY_IMPORTS.items():
        if (target == costly or target.startswith(costly + ".")) and any(
                module == layer or module.startswith(layer + ".") for layer in layers):
            return True
    return False


def inner_imports(source: str | ast.Module, module: str) -> list[tuple[int, str]]:
    """``(line, target)`` of each import inside a function of module ``module`` (its ``source`` text or tree) that
    the bounds do not allow; an import in a nested function counts once."""
    tree = ast.parse(source) if isinstance(source, str) else source
    out = []
    for _, fn in functions(tree):
        for node in ast.walk(fn):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                targets = [t for t in _imported(node) if not allowed_inside(t, module)]
                out += [(node.lineno, t) for t in targets[:1]]  # one statement, one offence
    return sorted(set(out))


def flag_texts(path: Path) -> list[tuple[int, str]]:
    """``(line, flag)`` for every ``--flag`` in a string of a ``raise`` statement (its exception's arguments)."""
    tree = _tree(path)
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and node.exc is not None:
            for sub in ast.walk(node.exc):
                if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
                    out.update((sub.lineno, m) for m in FLAG.findall(sub.value))
    return sorted(out)


def _is_library(path: Path) -> bool:
    rel = _rel(path)
    return not any(rel == c or rel.startswith(c) for c in COMMAND_LAYER)


def _over(limit_fn) -> dict[str, list[str]]:
    found = {}
    for path in _files():
        tree = _tree(path)
        names = [name for name, fn in functions(tree) if limit_fn(fn)]
        if names:
            found[_rel(path)] = sorted(names)
    return found


def long_functions() -> dict[str, list[str]]:
    """file -> functions longer than ``MAX_LINES``."""
    return _over(lambda fn: length(fn) > MAX_LINES)


def many_parameters() -> dict[str, list[str]]:
    """file -> functions with more than ``MAX_PARAMS`` parameters."""
    return _over(lambda fn: len(parameters(fn)) > MAX_PARAMS)


def import_counts() -> dict[str, int]:
    """file -> imports inside functions beyond the allowed ones."""
    return {_rel(p): n for p in _files() if (n := len(inner_imports(_tree(p), _module(p))))}


def flag_counts() -> dict[str, int]:
    """file -> flags named in raised library errors."""
    return {_rel(p): n for p in _files() if _is_library(p) and (n := len(flag_texts(p)))}


def _ratchet(found: dict, allowed: dict, what: str, fix: str) -> None:
    worse, better = [], []
    for f in sorted(set(found) | set(allowed)):
        now, then = found.get(f, 0 if isinstance(allowed.get(f, 0), int) else []), allowed.get(f)
        if isinstance(now, int):
            then = then or 0
            if now > then:
                worse.append(f"{f}: {now} {what} ({then} allowed)")
            elif now < then:
                better.append(f"{f}: {now} {what} now, the list says {then}")
        else:
            then = set(then or ())
            if set(now) - then:
                worse.append(f"{f}: {', '.join(sorted(set(now) - then))}")
            if then - set(now):
                better.append(f"{f}: {', '.join(sorted(then - set(now)))} no longer offend")
    assert not worse, f"{what}; {fix}:\n" + "\n".join(worse)
    assert not better, f"fixed, so shrink the list in {Path(__file__).name}:\n" + "\n".join(better)


def test_functions_are_at_most_max_lines_long():
    _ratchet(long_functions(), LONG_TO_FIX, f"functions over {MAX_LINES} lines",
             "split them into named steps")


def test_functions_take_at_most_max_params_parameters():
    _ratchet(many_parameters(), PARAMS_TO_FIX, f"functions over {MAX_PARAMS} parameters",
             "group them in an options object")


def test_imports_are_at_the_top_of_modules():
    _ratchet(import_counts(), IMPORTS_TO_FIX, "imports inside functions",
             "import at the top of the module (only OPTIONAL_IMPORTS and COSTLY_IMPORTS may be imported late)")


def test_library_errors_name_no_command_line_flag():
    _ratchet(flag_counts(), FLAGS_TO_FIX, "raised texts naming a --flag",
             "name the Python argument (and the physics); the command layer maps it to its flag")


@pytest.mark.parametrize("code, expected", [
    ("def f():\n    import numpy\n", 1),
    ("def f():\n    import dask.distributed\n", 0),
    ("def f():\n    from distributed import Client\n", 0),
    ("def f():\n    import matplotlib.pyplot as plt\n", 1),  # outside viz
    ("def f():\n    def g():\n        from . import x\n", 1),  # nested: counted once
    ("import numpy\nclass A:\n    def m(self):\n        import math\n", 1),
    ("import numpy\n", 0),
])
def test_inner_imports_are_read_as_documented(code, expected):
    assert len(inner_imports(code, "cartpole.sim.probe")) == expected


def test_matplotlib_may_be_imported_late_inside_viz_only():
    assert allowed_inside("matplotlib.pyplot", "cartpole.viz.lab_plot")
    assert not allowed_inside("matplotlib.pyplot", "cartpole.apps.lab")
    assert not allowed_inside("mujoco", "cartpole.viz.video")


@pytest.mark.parametrize("code, expected", [
    ("raise ValueError('give --u-max 2.')", ["--u-max"]),
    ("raise E(f'give --period {dt:g} or a longer --duration.')", ["--duration", "--period"]),
    ("raise E('a value -- like this, or x--y')", []),
    ("msg = '--not-raised'\n", []),
    ("raise E('give u_max at most 2 (N).')", []),
])
def test_flag_texts_are_read_as_documented(code, expected, tmp_path):
    path = tmp_path / "probe.py"
    path.write_text(code)
    assert sorted(f for _, f in flag_texts(path)) == expected


@pytest.mark.parametrize("code, lines, params", [
    ("def f(self, a, *b, c, **d):\n    pass\n", 2, ["a", "b", "c", "d"]),
    ("class A:\n    @classmethod\n    def f(cls, x):\n        return x\n", 2, ["x"]),
])
def test_length_and_parameters_are_read_as_documented(code, lines, params):
    (_, fn), = functions(ast.parse(code))
    assert length(fn) == lines and sorted(parameters(fn)) == params


def test_the_lists_only_shrink():
    """A listed file that gets worse fails, and so does one that got better without lowering its entry."""
    _ratchet({"a.py": 2}, {"a.py": 2}, "imports", "fix")
    with pytest.raises(AssertionError, match="a.py: 3"):
        _ratchet({"a.py": 3}, {"a.py": 2}, "imports", "fix")
    with pytest.raises(AssertionError, match="shrink the list"):
        _ratchet({"a.py": 1}, {"a.py": 2}, "imports", "fix")
    with pytest.raises(AssertionError, match="g no longer offend"):
        _ratchet({"a.py": ["f"]}, {"a.py": ["f", "g"]}, "long functions", "fix")
    with pytest.raises(AssertionError, match="b.py"):
        _ratchet({"b.py": ["h"]}, {}, "long functions", "fix")


if __name__ == "__main__":  # `python tests/test_code_shape.py`: today's offenders, as the lists above are written
    for title, found in (("IMPORTS_TO_FIX", import_counts()), ("LONG_TO_FIX", long_functions()),
                         ("PARAMS_TO_FIX", many_parameters()), ("FLAGS_TO_FIX", flag_counts())):
        print(f"{title} = {{")
        for path, value in sorted(found.items()):
            print(f"    {path!r}: {value!r},".replace("'", '"'))
        print("}\n")
