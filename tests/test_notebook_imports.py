"""Every notebook meets the toolkit through its package top only, in one style: ``import cartpole as cp`` and then
``cp.<name>`` with ``<name>`` one of ``cartpole.__all__`` (no ``from cartpole.x import ...``, no ``cp.sim.<name>``)."""
import ast
from pathlib import Path

import pytest

import cartpole

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"
SOURCES = sorted(NOTEBOOK_DIR.glob("*.py"))


def _offences(tree: ast.AST) -> list[str]:
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "cartpole":
            bad.append(f"line {node.lineno}: from {node.module} import ...")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "cartpole" and (alias.name, alias.asname) != ("cartpole", "cp"):
                    bad.append(f"line {node.lineno}: import {alias.name}" + (f" as {alias.asname}" if alias.asname
                                                                                  else ""))
        elif (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "cp"
              and node.attr not in cartpole.__all__):
            bad.append(f"line {node.lineno}: cp.{node.attr} is not a name of the package top")
    return bad


@pytest.mark.parametrize("path", SOURCES, ids=[p.stem for p in SOURCES])
def test_every_notebook_imports_only_from_the_package_top(path):
    tree = ast.parse(path.read_text())
    assert any(isinstance(n, ast.Import) and any((a.name, a.asname) == ("cartpole", "cp") for a in n.names)
               for n in ast.walk(tree)), f"{path.name} does not import cartpole as cp"
    assert _offences(tree) == [], path.name


def test_the_check_catches_a_deep_import_and_a_subpackage_attribute():
    tree = ast.parse("import cartpole as cp\nfrom cartpole.sim import simulate\nimport cartpole.viz\n"
                     "cp.sim.replays_exactly\ncp.simulate\n")
    assert [b.split(":")[0] for b in _offences(tree)] == ["line 2", "line 3", "line 4"]
