"""One command surface: --out exactly where a command writes files, every option documented in the command-line
contract (docs/cli.md) and nothing documented there that does not exist, the README's command table naming only real
commands, the Makefile using only real options."""
import argparse
import re
from pathlib import Path

import pytest

from cartpole.cli import _load_commands, build_parser, writes_files

ROOT = Path(__file__).resolve().parents[2]


def _subparsers():
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return sub.choices


def _visible_options(p) -> set[str]:
    return {o for a in p._actions if a.help != argparse.SUPPRESS for o in a.option_strings
            if o.startswith("--") and o != "--help"}


def _command_line_contract() -> str:
    return (ROOT / "docs" / "cli.md").read_text()


def test_out_is_offered_exactly_by_the_commands_that_write_files():
    mods = _load_commands()
    for name, p in _subparsers().items():
        assert ("--out" in _visible_options(p)) == writes_files(mods[name]), name
    assert not writes_files(mods["linearize"]) and not writes_files(mods["bench"])
    assert writes_files(mods["swingup"]) and writes_files(mods["sweep"])


def test_every_option_is_in_the_contract_and_the_contract_names_no_other():
    documented = set(re.findall(r"(?<![\w-])(--[A-Za-z][A-Za-z0-9-]*)", _command_line_contract()))
    offered = set().union(*(_visible_options(p) for p in _subparsers().values()))
    missing = offered - documented
    assert not missing, f"options without a word in docs/cli.md: {sorted(missing)}"
    phantom = documented - offered - {"--help", "--out"}  # --out: also named where it was removed (linearize, bench)
    assert not phantom, f"docs/cli.md names options no command has: {sorted(phantom)}"


def test_the_readme_command_table_names_every_command_and_no_other():
    text = (ROOT / "README.md").read_text()
    named = set(re.findall(r"^\| `cartpole (\w+)", text, flags=re.M))
    assert named == set(_subparsers()), (sorted(named), sorted(_subparsers()))


@pytest.mark.parametrize("target", ["demo", "bench"])
def test_the_makefile_passes_out_only_to_commands_that_write(target):
    mods = _load_commands()
    text = (ROOT / "Makefile").read_text()
    recipe = text.split(f"\n{target}:", 1)[1].split("\n\n", 1)[0]
    calls = re.findall(r"cartpole (\w+)([^\n]*)", recipe)
    assert calls, recipe
    for name, rest in calls:
        assert name in mods, name
        assert ("--out" in rest) == writes_files(mods[name]), (name, rest)
