"""The package is layered one way, read from the source (every import statement, also those inside functions).

Layers, lowest first; a module may import its own layer and the layers below it, never one above:

    base          cartpole.errors, _arrays, _files, progress, codegen, options   errors, read-only arrays, atomic
                  files, progress, generated C built and cached, the options values' shared shape
    models        cartpole.models          MJCF -> parameters -> symbolic model
    riccati       cartpole.riccati         lqr / dlqr, TVLQR, the default weights
    control       cartpole.control         controllers u = c(t, x)
    estimation    cartpole.estimation      (reserved) sensors, KF, EKF, MHE: x_hat from y
    analysis      cartpole.analysis        loops of the linear designs broken at the plant input, their margins
    sim           cartpole.sim             MuJoCo runs, exact replay, batch rollouts
    ocp           cartpole.ocp             trajectory-optimisation problems: transcription, guesses, objectives,
                                           trajectories, solve records
    solvers       cartpole.solvers         the SQP and its QP back-ends (iLQR / DDP to come)
    planning      cartpole.planning        the swing-up planner: minimum time, objectives, starts, TVLQR along it
    mpc           cartpole.mpc             NMPC, its compiled functions, the IPOPT baseline
    identify      cartpole.identify        (reserved) system identification, the fitted MJCF
    export        cartpole.export          (reserved) standalone C of controllers and estimators
    validation    cartpole.validation      metrics, Jacobian checks, catch basins
    supervise     cartpole.supervise       the supervisor: catch, swing-up law, brake, plan and track, at run time
    viz           cartpole.viz             figures and video
    apps          cartpole.apps            what each command does (lab, swingup, feedforward, sweep, bench)
    commands      cartpole.commands, cartpole.cli, cartpole.__main__   argparse and printing

Besides: no import cycles between modules; only ``cartpole/__init__.py`` imports the package top ``cartpole``
(nothing below it takes defaults from there); only apps and commands import ``cartpole.viz`` (the package
top names its figures only lazily, by module name: PEP 562, no import statement); outside ``cartpole.models``
model things come from the package ``cartpole.models``, never from its modules, so models/ can be reorganised inside; no private name (``_name``) crosses a module boundary: neither
``from x import _name`` nor ``x._name`` on an imported module, in the package (tests may).

The shape of the code inside the layers (function length and parameters, imports at the top of modules, library
errors without command-line flags) is checked by the sibling ``tests/test_code_shape.py``.

How an import names its target: ``import a.b`` names ``a.b``; ``from a.b import c`` names ``a.b.c`` when that is a
module, else ``a.b``. The parent packages Python imports on the way (``a`` for ``a.b``) are not counted: every
module would otherwise form a cycle with its own package's ``__init__``.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE_DIR = Path(__file__).resolve().parent.parent / "cartpole"

LAYERS = (
    ("base", ("cartpole.errors", "cartpole._arrays", "cartpole._files", "cartpole.progress", "cartpole.codegen",
              "cartpole.options")),
    ("models", ("cartpole.models",)),
    ("riccati", ("cartpole.riccati",)),
    ("control", ("cartpole.control",)),
    ("estimation", ("cartpole.estimation",)),
    ("analysis", ("cartpole.analysis",)),
    ("sim", ("cartpole.sim",)),
    ("ocp", ("cartpole.ocp",)),
    ("solvers", ("cartpole.solvers",)),
    ("planning", ("cartpole.planning",)),
    ("mpc", ("cartpole.mpc",)),
    ("identify", ("cartpole.identify",)),
    ("export", ("cartpole.export",)),
    ("validation", ("cartpole.validation",)),
    ("supervise", ("cartpole.supervise",)),
    ("viz", ("cartpole.viz",)),
    ("apps", ("cartpole.apps",)),
    ("commands", ("cartpole.commands", "cartpole.cli", "cartpole.__main__")),
)
TOP = "cartpole"



def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE_DIR.rglob("*.py")) if "__pycache__" not in p.parts}


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES[name].name == "__init__.py"


def _resolve(name: str) -> str | None:
    """The longest known module that ``name`` starts with (None outside the package)."""
    parts = name.split(".")
    while parts:
        cand = ".".join(parts)
        if cand in MODULES:
            return cand
        parts.pop()
    return None


def _source(node: ast.ImportFrom, package: str) -> str:
    """The absolute module an ``ImportFrom`` reads from (relative ones, ``from . import x``, resolved in ``package``)."""
    if node.level:
        base = package.split(".")[:len(package.split(".")) - node.level + 1]
        return ".".join(base + ([node.module] if node.module else []))
    return node.module or ""


def imports_of(name: str) -> list[tuple[str, int, bool]]:
    """``(target module, line, is a bare reference to the package top)`` for every import in module ``name``."""
    path = MODULES[name]
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if _is_package(name) else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = _resolve(alias.name)
                if target is not None:
                    out.append((target, node.lineno, alias.name == TOP))
        elif isinstance(node, ast.ImportFrom):
            src = _source(node, package)
            if _resolve(src) is None:
                continue
            for alias in node.names:
                target = _resolve(f"{src}.{alias.name}")
                if target == src or target is None:  # a name defined in src, not a submodule
                    target = _resolve(src)
                out.append((target, node.lineno, src == TOP))
    return out


GRAPH = {name: imports_of(name) for name in MODULES}


def layer_of(name: str) -> int | None:
    for i, (_, prefixes) in enumerate(LAYERS):
        if any(name == p or name.startswith(p + ".") for p in prefixes):
            return i
    return None


def test_every_module_has_a_layer():
    """A new module must be placed in LAYERS (and the README's architecture) before it can be imported."""
    missing = [m for m in MODULES if m != TOP and layer_of(m) is None]
    assert not missing, f"modules without a layer: {missing}; add them to LAYERS in {Path(__file__).name}"


def test_the_layers_point_one_way():
    bad = []
    for src, edges in GRAPH.items():
        if src == TOP:
            continue
        for dst, line, _ in edges:
            if dst == TOP:
                continue  # test_only_the_package_top_imports_the_package_top
            ls, ld = layer_of(src), layer_of(dst)
            if ls is not None and ld is not None and ld > ls:
                bad.append(f"{MODULES[src].relative_to(PACKAGE_DIR.parent)}:{line} ({LAYERS[ls][0]}) imports "
                           f"{dst} ({LAYERS[ld][0]})")
    assert not bad, "imports against the layer order:\n" + "\n".join(bad)


def _cycles() -> list[list[str]]:
    """Strongly connected components with more than one module, or a module importing itself (Tarjan)."""
    index, low, stack, on, comps = {}, {}, [], set(), []
    succ = {m: sorted({d for d, _, _ in GRAPH[m]}) for m in GRAPH}

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in succ[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in succ[v]:
                comps.append(sorted(comp))

    for m in sorted(GRAPH):
        if m not in index:
            visit(m)
    return comps


def test_no_import_cycles():
    assert _cycles() == []


def test_only_the_package_top_imports_the_package_top():
    bad = [f"{MODULES[src].relative_to(PACKAGE_DIR.parent)}:{line}" for src, edges in GRAPH.items() if src != TOP
           for dst, line, bare in edges if dst == TOP or bare]
    assert not bad, f"import the defaults from their own module, not from the package top: {bad}"


def test_only_apps_and_commands_import_viz():
    allowed = {"viz", "apps", "commands"}
    bad = [f"{src} imports {dst}" for src, edges in GRAPH.items() for dst, _, _ in edges
           if layer_of(dst) == layer_of("cartpole.viz") and (src == TOP or LAYERS[layer_of(src)][0] not in allowed)]
    assert not bad, bad


def test_model_things_come_from_the_models_package():
    bad = sorted({f"{MODULES[src].relative_to(PACKAGE_DIR.parent)}:{line} imports {dst}"
                  for src, edges in GRAPH.items() if layer_of(src) != layer_of("cartpole.models")
                  for dst, line, _ in edges if dst.startswith("cartpole.models.")})
    assert not bad, "import from cartpole.models, not its modules:\n" + "\n".join(bad)


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_uses(name: str) -> list[tuple[int, str]]:
    """``(line, what)`` for every private name module ``name`` takes from another module of the package:
    ``from x import _y`` and ``x._y`` where ``x`` is bound to a package module by an import."""
    path = MODULES[name]
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if _is_package(name) else name.rpartition(".")[0]
    modules_bound: dict[str, str] = {}  # local name -> package module it refers to
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if _resolve(alias.name) is not None:
                    local = alias.asname or alias.name.split(".")[0]
                    modules_bound[local] = alias.name if alias.asname else alias.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            src = _source(node, package)
            if _resolve(src) is None:
                continue
            for alias in node.names:
                full = f"{src}.{alias.name}"
                if full in MODULES:  # a module (cartpole._files is private to the package, its names are its API)
                    modules_bound[alias.asname or alias.name] = full
                elif _is_private(alias.name) and _resolve(src) != name:
                    out.append((node.lineno, f"from {src} import {alias.name}"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _is_private(node.attr):
            chain, value = [node.attr], node.value
            while isinstance(value, ast.Attribute):
                chain.append(value.attr)
                value = value.value
            if isinstance(value, ast.Name) and value.id in modules_bound:
                dotted = ".".join([modules_bound[value.id], *reversed(chain[1:])])
                if dotted in MODULES and dotted != name:
                    out.append((node.lineno, f"{dotted}.{node.attr}"))
    return out


def test_no_private_name_crosses_a_module_boundary():
    bad = [f"{MODULES[m].relative_to(PACKAGE_DIR.parent)}:{line} uses {what}"
           for m in MODULES for line, what in private_uses(m)]
    assert not bad, "make the name public (and document it) or keep it in its module:\n" + "\n".join(bad)


@pytest.mark.parametrize("code, expected", [
    ("from cartpole.sim.rollout import _helper", ["from cartpole.sim.rollout import _helper"]),
    ("import cartpole.sim.rollout as r\nr._helper()", ["cartpole.sim.rollout._helper"]),
    ("import cartpole.sim.rollout\ncartpole.sim.rollout._helper()", ["cartpole.sim.rollout._helper"]),
    ("from cartpole.sim import rollout\nrollout._helper", ["cartpole.sim.rollout._helper"]),
    ("from cartpole.sim.rollout import simulate as _simulate", []),
    ("from cartpole._files import atomic_write", []),
    ("class A:\n    def f(self):\n        return self._x", []),
    ("import numpy as np\nnp._private", []),
])
def test_private_uses_are_read_as_documented(code, expected, tmp_path, monkeypatch):
    monkeypatch.setitem(MODULES, "cartpole.sim.fake", tmp_path / "fake.py")
    (tmp_path / "fake.py").write_text(code)
    assert [what for _, what in private_uses("cartpole.sim.fake")] == expected


@pytest.mark.parametrize("code, expected", [
    ("import cartpole.sim", {"cartpole.sim"}),
    ("from cartpole.sim import simulate", {"cartpole.sim"}),
    ("from cartpole.sim import rollout", {"cartpole.sim.rollout"}),
    ("from cartpole.sim.rollout import Rollout", {"cartpole.sim.rollout"}),
    ("def f():\n    from cartpole.riccati import lqr", {"cartpole.riccati"}),
    ("import numpy", set()),
])
def test_imports_are_read_as_documented(code, expected, tmp_path, monkeypatch):
    """The reader itself: targets as the module docstring says, lazy imports included."""
    monkeypatch.setitem(MODULES, "cartpole.sim.fake", tmp_path / "fake.py")
    (tmp_path / "fake.py").write_text(code)
    assert {d for d, _, _ in imports_of("cartpole.sim.fake")} == expected
