"""Every sentence in the package that names a command-line option (``--something``) names one that exists: each flag
in every string of ``cartpole/`` is looked up among the option strings of every ``cartpole`` subcommand's parser
(built from :func:`cartpole.cli.build_parser`). Not sentences, and so not checked: C sources the export writes
(``--i;``), a bare argv element (``"--host"``, passed to another program) and a module's own argparse options
(a benchmark script's ``--rounds``), which are checked against that module's parser instead."""
import argparse
import ast
import re
from pathlib import Path

import cartpole
from cartpole.cli import build_parser

PACKAGE = Path(cartpole.__file__).resolve().parent
FLAG = re.compile(r"(?<![\w-])(--[A-Za-z][\w-]*)")


def cli_flags() -> set:
    """Every option string of the ``cartpole`` parser and of each of its subcommands."""
    flags = set()

    def collect(parser):
        for action in parser._actions:
            flags.update(action.option_strings)
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    collect(sub)

    collect(build_parser())
    return flags


def _own_flags(tree) -> set:
    """Options a module declares itself with ``add_argument("--x", ...)`` (scripts with their own parser)."""
    own = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "add_argument":
            own.update(a.value for a in node.args if isinstance(a, ast.Constant) and isinstance(a.value, str))
    return own


def _is_c_source(text: str) -> bool:
    return "\n" in text and ";" in text and ("{" in text or "}" in text)


def named_flags():
    """``(flag, "file:line", text)`` for every flag named in a string of the package."""
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Constant) and isinstance(node.value, str)):
                continue
            text = node.value
            if _is_c_source(text) or FLAG.fullmatch(text.strip()):
                continue
            for flag in FLAG.findall(text):
                yield flag, f"{path.relative_to(PACKAGE.parent)}:{node.lineno}", text, _own_flags(tree)


def test_every_flag_a_sentence_names_is_an_option_of_the_cli():
    known = cli_flags()
    seen, missing = 0, []
    for flag, where, text, own in named_flags():
        seen += 1
        if flag not in known and flag not in own:
            missing.append(f"{where}: {flag} in {text.strip()[:120]!r}")
    assert seen > 100, "the scan found almost no flags: is it reading the package?"
    assert not missing, "sentences name options the command line does not have:\n" + "\n".join(missing)


def test_the_scan_catches_a_flag_that_does_not_exist():
    assert "--u-max" in cli_flags() and "--cart-max" in cli_flags() and "--T-max" in cli_flags()
    assert "--no-such-option" not in cli_flags()
    assert FLAG.findall("give a longer --T-max or --search-s, or --no-such-option.") == [
        "--T-max", "--search-s", "--no-such-option"]
    assert _is_c_source("for (i = n; i >= 0; --i) {\n x; }") and not _is_c_source("give --x0 (4 numbers).")
