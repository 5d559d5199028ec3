"""Sphinx configuration of the cartpole documentation site (``make docs``; warnings are errors there).

The pages are Markdown (MyST). The API reference is generated from the package's numpydoc docstrings
(one page per public module, written at build time into ``docs/api/generated/`` by layer, autodoc reads
it, numpydoc lays out its sections).

The notebooks are shown with their outputs (figures, printed numbers). The test suite already executes every notebook
(``tests/test_notebooks.py``, with ``CARTPOLE_QUICK=1``), and ``make test`` keeps what it executed in
``docs/_build/executed_notebooks/`` (``CARTPOLE_NOTEBOOK_OUTPUTS``): a kept notebook whose cells are the committed
ones is rendered as executed there, so CI runs each notebook once. A notebook with no kept run (``make docs`` alone,
or a notebook changed since ``make test``) is executed here by myst-nb through jupyter-cache, with the same
``CARTPOLE_QUICK=1``, in a scratch folder, and cached in ``docs/_build/.jupyter_cache`` until its code changes; a
notebook that raises fails the build. Either way the copy goes to ``docs/notebooks/`` (git-ignored), because Sphinx
reads sources only below this directory.

The site needs no network: the theme (pydata-sphinx-theme, as NumPy's and SciPy's sites) ships its assets, and MathJax
3 comes from the ``sphinx-mathjax-offline`` package, copied into ``_static/mathjax/`` (``tests/docs/test_site.py``
checks that no page loads anything from another host).
"""
from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
sys.path.insert(0, str(REPO))  # document this checkout's package, whatever the environment has installed

project = "cartpole"
author = "the cartpole authors"
copyright = "the cartpole authors, MIT licence"

extensions = [
    "myst_nb",                      # Markdown pages (myst-parser inside) and .ipynb notebooks
    "sphinx.ext.autodoc",
    "numpydoc",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",       # MathJax 3 shipped with the site (mathjax_path into _static/), no CDN
]

# ---- sources -------------------------------------------------------------------------------------------------
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "**.ipynb_checkpoints", "notebooks/*.py"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3            # `[text](page.md#a-heading)` links resolve to headings
# Notebooks: the test suite's executed copies where they are current, else executed here once and cached (see above).
EXECUTED = Path(os.environ.get("CARTPOLE_NOTEBOOK_OUTPUTS") or DOCS / "_build" / "executed_notebooks")
os.environ["CARTPOLE_QUICK"] = "1"  # the kernels myst-nb starts inherit it: the test suite's short runs
nb_execution_mode = "cache"
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_in_temp = True         # a notebook's output files go to a scratch folder, not into docs/
nb_execution_timeout = 300          # s per cell, as tests/test_notebooks.py
nb_execution_raise_on_error = True  # a notebook that fails fails the build

# ---- API reference -------------------------------------------------------------------------------------------
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"          # the signatures are shown; the types are in the numpydoc sections
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set = set()

html_theme = "pydata_sphinx_theme"  # the scientific Python family's (NumPy, SciPy, python-control)
html_title = "cartpole"
html_static_path: list = []
# The guide is flat: a top-level page has no sub-pages for the left sidebar to list, and the theme would show it empty;
# the notebooks' and the API's pages keep it (their siblings). Exact names, not a `**` pattern, which would clash with
# those sections' own patterns.
html_sidebars = {page.stem: [] for page in DOCS.glob("*.md") if page.stem != "notebooks"}
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 4,  # the guide's titles are long: the rest under "More"
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}


def _cells(notebook: dict) -> list[tuple[str, str]]:
    """(cell type, source) of every cell of a notebook read as JSON: what executing it leaves unchanged."""
    return [(c["cell_type"], "".join(c["source"]).strip()) for c in notebook["cells"]]


def _copy_notebooks() -> None:
    """Put every notebook into ``docs/notebooks/`` for myst-nb: the test suite's executed copy when its cells are the
    committed notebook's (rendered as it is, execution off for it), else the committed, output-free one (executed at
    build through the cache)."""
    target = DOCS / "notebooks"
    target.mkdir(exist_ok=True)
    for old in target.glob("*.ipynb"):
        old.unlink()
    for nb in sorted((REPO / "notebooks").glob("*.ipynb")):
        committed = json.loads(nb.read_text())
        kept = EXECUTED / nb.name
        if kept.is_file():
            executed = json.loads(kept.read_text())
            if _cells(executed) == _cells(committed):
                executed["metadata"].setdefault("mystnb", {})["execution_mode"] = "off"
                (target / nb.name).write_text(json.dumps(executed, indent=1))
                continue
        shutil.copy2(nb, target / nb.name)


_copy_notebooks()


def _layers() -> list[tuple[str, tuple[str, ...]]]:
    """``LAYERS`` of ``tests/test_layering.py`` (the one statement of the layer order), read without importing it."""
    import ast

    tree = ast.parse((REPO / "tests" / "test_layering.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "LAYERS" for t in node.targets):
            return ast.literal_eval(node.value)
    raise RuntimeError("tests/test_layering.py defines no LAYERS")


def _public_modules() -> list[str]:
    """Every module of the package, from its files, but private ones (a part starting with ``_``)."""
    names = []
    for path in sorted((REPO / "cartpole").rglob("*.py")):
        parts = list(path.relative_to(REPO).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        if not any(p.startswith("_") for p in parts):
            names.append(".".join(parts))
    return names


API_INTRO = """API reference
=============

Every public module of the package, generated from its docstrings (numpydoc style: parameters with their units and
shapes, what is returned, what is raised), grouped by layer, lowest first, in the order the layering test enforces
(:doc:`../architecture`). The names most people start from are re-exported by the package top, ``cartpole``.
"""


def _write_api_pages() -> None:
    """``docs/api/index.rst`` and one page per public module under ``docs/api/generated/``, by layer. ``automodule``
    imports each by its module path."""
    api = DOCS / "api"
    out = api / "generated"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    modules = _public_modules()
    sections, placed = [], set()
    for layer, prefixes in _layers():
        mine = [m for m in modules if m not in placed and any(m == p or m.startswith(p + ".") for p in prefixes)]
        placed.update(mine)
        if mine:
            sections.append((layer, mine))
    top = [m for m in modules if m not in placed]  # the package top
    for name in modules:
        (out / f"{name}.rst").write_text(f"{name}\n{'=' * len(name)}\n\n.. automodule:: {name}\n")
    lines = [API_INTRO]
    for layer, mine in [("package top", top)] + sections:
        lines += [layer, "-" * len(layer), "", ".. toctree::", "   :maxdepth: 1", ""]
        lines += [f"   generated/{m}" for m in mine] + [""]
    (api / "index.rst").write_text("\n".join(lines))


_write_api_pages()


# ---- docstrings as written -----------------------------------------------------------------------------------
# The package's docstrings are numpydoc sections around plain-text prose that writes absolute values as |x| and
# formulas in indented blocks. reStructuredText reads |x| as a substitution and an indented block as a quotation,
# so before numpydoc lays out the sections: bars outside literals are escaped, and prose that still is not valid
# reStructuredText is shown preformatted, as written (tests/test_docstrings.py checks what the docstrings say).
import io  # noqa: E402
import re  # noqa: E402

from docutils.core import publish_doctree  # noqa: E402
from docutils.utils import Reporter  # noqa: E402

_SECTION = re.compile(r"^(Parameters|Returns|Yields|Raises|Warns|Attributes|Methods|See Also|Notes|References|"
                      r"Examples|Other Parameters|Receives|Warnings)\s*$")
_LITERAL = re.compile(r"(``.*?``|`[^`]*`)")


def _escape_bars(line: str) -> str:
    """``|`` outside literal and interpreted text escaped (an absolute value, not a substitution)."""
    row = line.strip()
    if (row.startswith("|") and row.endswith("|") and len(row) > 2) or row.startswith(("+-", "+=")):  # a table
        return line
    return "".join(part if _LITERAL.fullmatch(part) else part.replace("|", r"\|") for part in _LITERAL.split(line))


def _valid_rst(text: str) -> bool:
    """Whether docutils parses ``text`` without a warning (Sphinx roles replaced by literals bare docutils knows)."""
    text = re.sub(r":[a-z:]+:`([^`]*)`", r"``\1``", text)
    stream = io.StringIO()
    publish_doctree(text, settings_overrides={"report_level": Reporter.WARNING_LEVEL, "halt_level": 5,
                                              "warning_stream": stream})
    return not stream.getvalue()


def _prose_then_sections(lines: list[str]) -> int:
    """Index of the first numpydoc section header (a known name underlined by dashes), or len(lines)."""
    for i in range(len(lines) - 1):
        if _SECTION.match(lines[i].strip()) and set(lines[i + 1].strip()) == {"-"}:
            return i
    return len(lines)


def _docstring_as_written(app, what, name, obj, options, lines):
    lines[:] = [_escape_bars(line) for line in lines]
    end = _prose_then_sections(lines)
    start = next((i for i, line in enumerate(lines[:end]) if not line.strip()), end)  # after the summary line(s)
    prose = lines[start:end]
    if any(line.strip() for line in prose) and not _valid_rst("\n".join(prose)):
        lines[start:end] = ["", "::", ""] + ["    " + line if line.strip() else "" for line in prose] + [""]


def setup(app):
    app.connect("autodoc-process-docstring", _docstring_as_written, priority=400)  # before numpydoc (500)
