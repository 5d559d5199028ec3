"""The documentation site as a reader sees it: the built HTML, checked page by page.

A page fails on what a reader would trip over: a machine path (an absolute path of a checkout, ``/work/...``,
``/tmp/...``, a home folder) anywhere in its text or links; a Markdown table that fell apart (rendered as a paragraph
of pipes, or a row split into more cells than its header by a bare ``|`` such as ``|theta|``, whose extra cells
Markdown drops); a link that leads nowhere inside the site, or a file named that is not in the repository (the
project's ``shared/seed/...`` folder, a ``../`` path, a repository path that does not exist); anything loaded from
another host (the site must work offline: MathJax is shipped in ``_static/``), and LaTeX left as raw text.

The site is the one ``make docs`` builds: it runs ``sphinx-build`` and then this module with ``CARTPOLE_SITE`` naming
the built folder, so CI builds the site once and checks it in seconds. Without ``CARTPOLE_SITE`` the tests over the
built site skip (building it takes minutes); the tests of the checks themselves, on small pages written here, and the
check of the Markdown sources' tables always run.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SITE = os.environ.get("CARTPOLE_SITE")
# The Markdown the site is built from: the pages and the files they include.
SOURCES = sorted((REPO / "docs").glob("*.md")) + [p for p in [REPO / "CHANGELOG.md"] if p.is_file()]

# ---- reading a page -------------------------------------------------------------------------------------------
VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}
HIDDEN = {"script", "style", "template"}


class Page(HTMLParser):
    """One HTML page read into what the checks need: text runs with their enclosing tags and classes, the paragraphs'
    text, inline literals, and every URL the page links to or loads."""

    def __init__(self, html: str):
        super().__init__(convert_charrefs=True)
        self.stack: list[tuple[str, str]] = []    # (tag, class) of the open elements
        self.texts: list[tuple[str, tuple[tuple[str, str], ...]]] = []
        self.paragraphs: list[str] = []
        self.literals: list[str] = []
        self.cells: list[str] = []                # table cells' text outside inline literals
        self.links: list[str] = []                # <a href>: where a reader goes
        self.loads: list[tuple[str, str]] = []     # (tag, URL) the browser fetches to show the page
        self._para: list[str] | None = None
        self._literal: list[str] | None = None
        self._cell: list[str] | None = None
        self.feed(html)
        self.close()

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        cls = a.get("class") or ""
        if tag == "a" and a.get("href"):
            self.links.append(a["href"])
        if tag in ("script", "img", "iframe", "source", "video", "audio", "embed") and a.get("src"):
            self.loads.append((tag, a["src"]))
        if tag == "link" and a.get("href") and not {"canonical", "alternate", "search", "index", "next", "prev",
                                                    "author", "copyright"} & set((a.get("rel") or "").split()):
            self.loads.append((tag, a["href"]))
        if tag in VOID:
            return
        self.stack.append((tag, cls))
        if tag == "p" and not self._inside("pre"):
            self._para = []
        if tag == "code" and "literal" in cls.split():
            self._literal = []
        if tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in VOID or not any(t == tag for t, _ in self.stack):
            return
        while self.stack:
            t, cls = self.stack.pop()
            if t == "p" and self._para is not None:
                self.paragraphs.append("".join(self._para))
                self._para = None
            if t == "code" and self._literal is not None and "literal" in cls.split():
                self.literals.append("".join(self._literal))
                self._literal = None
            if t in ("td", "th") and self._cell is not None:
                self.cells.append("".join(self._cell))
                self._cell = None
            if t == tag:
                break

    def handle_data(self, data):
        if self.stack and self.stack[-1][0] in HIDDEN:
            return
        self.texts.append((data, tuple(self.stack)))
        if self._para is not None:
            self._para.append(data)
        if self._literal is not None:
            self._literal.append(data)
        if self._cell is not None and not self._inside("code"):
            self._cell.append(data)

    def _inside(self, *tags):
        return any(t in tags for t, _ in self.stack)

    def text(self) -> str:
        """Everything a reader can read on the page (scripts and styles left out)."""
        return "".join(t for t, _ in self.texts)


def _in_math_or_code(stack) -> bool:
    return any(t in ("pre", "code", "kbd", "samp", "textarea") or "math" in cls.split() or "highlight" in cls
               for t, cls in stack)


# ---- the checks: each returns the faults it finds, one sentence each ------------------------------------------
def _machine_path_pattern() -> re.Pattern:
    roots = r"(?:work|tmp|home|root|Users|private|mnt|var/folders|scratch)"
    extra = {str(REPO), str(Path.home())} - {"/"}
    alternatives = [r"(?<![\w.~/-])/" + roots + r"(?:/[^\s\"'<>)\]]*)?", r"\b[A-Z]:\\(?:Users|home)\\"]
    alternatives += [r"(?<![\w.~/-])" + re.escape(p) + r"(?![\w-])" for p in sorted(extra, key=len, reverse=True)]
    return re.compile("|".join(alternatives))


MACHINE_PATH = _machine_path_pattern()


def machine_paths(page: Page) -> list[str]:
    """Absolute paths of some machine (a checkout, a scratch folder, a home folder) in the text or the links."""
    found = [m.group(0) for m in MACHINE_PATH.finditer(page.text())]
    found += [m.group(0) for url in page.links + [u for _, u in page.loads]
              if not re.match(r"[a-z][a-z0-9+.-]*://", url) for m in [MACHINE_PATH.search(url)] if m]
    return [f"machine path {p!r}" for p in dict.fromkeys(found)]


DELIMITER_ROW = re.compile(r"^\s*\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)+\|?\s*$")
ROW = re.compile(r"^\s*\|.*\|.*\|\s*$")


def broken_tables(page: Page) -> list[str]:
    """Markdown tables that Markdown did not recognise (a paragraph holding a delimiter row ``|---|---|`` or rows of
    pipes), and cells cut inside a code span (a cell's text outside literals left with a lone backtick: a ``|`` in
    the code span split the cell)."""
    faults = [f"a table rendered as a paragraph of pipes: {p.strip()[:80]!r}" for p in page.paragraphs
              if any(DELIMITER_ROW.match(line) for line in p.splitlines())
              or sum(bool(ROW.match(line)) for line in p.splitlines()) >= 2]
    faults += [f"a table cell cut inside a code span: {c.strip()[:80]!r}" for c in page.cells if c.count("`") % 2]
    return faults


def _cells(row: str) -> list[str]:
    """A Markdown table row split as GitHub-flavoured Markdown does: on every ``|`` not escaped by a backslash, in
    code spans too."""
    row = row.strip()
    row = row[1:] if row.startswith("|") else row
    row = row[:-1] if row.endswith("|") and not row.endswith("\\|") else row
    return re.split(r"(?<!\\)\|", row)


def table_rows_cut(markdown: str) -> list[str]:
    """Table rows with more cells than their header: Markdown drops the extra cells (a bare ``|`` in a cell)."""
    faults, lines, fence = [], markdown.splitlines(), None
    header = None
    for i, line in enumerate(lines):
        stripped = line.strip()
        if re.match(r"^(`{3,}|~{3,}|:{3,})", stripped):  # code fences and directives: no tables inside to split
            mark = re.match(r"^(`{3,}|~{3,}|:{3,})", stripped).group(1)
            fence = None if fence and mark.startswith(fence) else (fence or mark)
            continue
        if fence or not stripped.startswith("|"):
            header = None
            continue
        if header is None:
            nxt = lines[i + 1].strip() if i + 1 < len(lines) else ""
            if re.fullmatch(r"\|?\s*:?-+:?\s*(\|\s*:?-+:?\s*)*\|?", nxt):
                header = len(_cells(stripped))
            continue
        n = len(_cells(stripped))
        if n > header:
            faults.append(f"line {i + 1}: a table row of {n} cells under a header of {header} (escape a bare | "
                          f"as \\|): {stripped[:80]!r}")
    return faults


# first components of a path that are this repository's, and folders that are not in it
REPO_TOP = {"cartpole", "tests", "notebooks", "docs", "benchmarks", "tools", ".ci"}
OUTSIDE = {"shared", "seed", ".."}
BUILD_OUTPUTS = ("docs/_build", "docs/api/generated", "docs/notebooks/")
PATH_TOKEN = re.compile(r"(?<![\w/.-])((?:\.\./|\.ci/|[A-Za-z_][\w.-]*/)[\w./*<>{}-]*)")


def outside_references(page: Page, site: Path, path: Path) -> list[str]:
    """Links that lead out of the site or to nothing, and files named that are not in the repository."""
    faults = []
    for url in page.links + [u for _, u in page.loads]:
        if re.match(r"([a-z][a-z0-9+.-]*:|#|//)", url):
            continue
        target = url.split("#")[0].split("?")[0]
        if not target:
            continue
        resolved = os.path.normpath(os.path.join(path.parent, target))
        if os.path.commonpath([resolved, os.path.abspath(site)]) != os.path.abspath(site):
            faults.append(f"link {url!r} leads out of the site")
        elif not os.path.exists(resolved):
            faults.append(f"link {url!r} leads to no file of the site")
    for literal in page.literals:
        for token in PATH_TOKEN.findall(literal):
            token = token.rstrip(".")
            first = token.split("/")[0]
            if re.search(r"(^|/)[A-Z][A-Z_]*(\b|_)", token):  # a placeholder: cartpole/assets/examples/NAME
                continue
            if first in OUTSIDE:
                faults.append(f"{token!r} names a file outside the repository")
            elif (first in REPO_TOP and not re.search(r"[*<>{}]", token) and not token.startswith(BUILD_OUTPUTS)
                  and not (REPO / token).exists()):
                faults.append(f"{token!r} names a file the repository does not have")
    return list(dict.fromkeys(faults))


TEX = re.compile(r"\\(?:frac|dfrac|tfrac|sqrt|theta|omega|alpha|beta|gamma|delta|lambda|mu|sigma|tau|phi|psi|pi|"
                 r"Delta|Sigma|Omega|dot|ddot|hat|bar|tilde|vec|mathrm|mathbf|mathcal|operatorname|rm|text|left|"
                 r"right|begin|end|sum|int|partial|cdot|cdots|ldots|top|le|ge|leq|geq|neq|approx|quad|qquad|in|"
                 r"infty|min|max|arg|sin|cos|tan|exp|log|det|tr|mid|lVert|rVert|Vert|langle|rangle)(?![A-Za-z])"
                 r"|\\[()\[\]]|\$\$")


def network_loads(page: Page) -> list[str]:
    """What the page would fetch from another host (a CDN): nothing may be, the site works offline."""
    return list(dict.fromkeys(f"<{tag}> loads {url!r} from another host" for tag, url in page.loads
                              if re.match(r"([a-z][a-z0-9+.-]*:)?//", url) and not url.startswith("file:")))


def raw_latex(page: Page, site: Path, path: Path) -> list[str]:
    """LaTeX a reader would see as source: TeX outside math and code, or math on a page that loads no local
    MathJax."""
    faults = [f"raw LaTeX {t.strip()[:60]!r}" for t, stack in page.texts
              if TEX.search(t) and not _in_math_or_code(stack)]
    has_math = any("math" in cls.split() for _, stack in page.texts for _, cls in stack)
    if has_math:
        mathjax = [url for tag, url in page.loads if tag == "script" and "mathjax" in url.lower()]
        local = [u for u in mathjax if not re.match(r"([a-z][a-z0-9+.-]*:)?//", u)
                 and (path.parent / u.split("?")[0]).is_file()]
        if not local:
            faults.append(f"math on the page but no MathJax shipped with the site loads it (scripts: {mathjax})")
    return faults


PRIMARY_SIDEBAR = re.compile(r'<div[^>]*\bid="pst-primary-sidebar"[^>]*\bclass="([^"]*)"')


def empty_sidebar(html: str) -> list[str]:
    """A left sidebar shown on a wide screen with no navigation in it (the theme keeps the column for a page with no
    sub-pages unless ``html_sidebars`` removes it)."""
    m = PRIMARY_SIDEBAR.search(html)
    if m is None or "hide-on-wide" in m.group(1).split() or "bd-docs-nav" in html:
        return []
    return ["an empty left sidebar (give the page no sidebar in docs/conf.py's html_sidebars)"]


ARTICLE = re.compile(r"<article\b.*?</article>", re.S)


def reader_part(html: str) -> str:
    """What a page adds to the site: its head (every script and stylesheet it loads) and its article. The theme's
    navigation, repeated on every page, lists the pages' titles and links that Sphinx wrote; the article is read once
    on its own page."""
    head = html[: html.find("</head>") + len("</head>")] if "</head>" in html else ""
    article = ARTICLE.search(html)
    return head + (article.group(0) if article else html)


def site_faults(site: Path) -> dict[str, list[str]]:
    """Every fault of every page of a built site, by page (pages without faults left out)."""
    out, site = {}, Path(os.path.abspath(site))
    for path in sorted(site.rglob("*.html")):
        if "_static" in path.relative_to(site).parts:
            continue
        html = path.read_text(encoding="utf-8")
        page = Page(reader_part(html))
        faults = (empty_sidebar(html) + machine_paths(page) + broken_tables(page) + outside_references(page, site, path)
                  + network_loads(page) + raw_latex(page, site, path))
        if faults:
            out[str(path.relative_to(site))] = faults
    return out


# ---- the checks themselves, on small pages --------------------------------------------------------------------
def _page(body: str, head: str = "") -> Page:
    return Page(f"<html><head>{head}</head><body>{body}</body></html>")


def test_a_machine_path_in_text_or_output_is_found_and_a_relative_one_is_not():
    bad = _page("<pre>MJCF: /work/main/cartpole/assets/cartpole.xml</pre><p>see <code>/tmp/docrun/x.png</code></p>"
                f"<p>in {Path.home()}/src</p>")
    found = " ".join(machine_paths(bad))
    assert "/work/main" in found and "/tmp/docrun" in found and str(Path.home()) in found
    good = _page("<p>writes <code>figures/lab.png</code> under <code>--out</code>; units m/s, rad/s; "
                 "<a href='https://example.org/tmp/x'>a site</a></p>")
    assert machine_paths(good) == []


def test_a_table_left_as_pipes_and_a_row_cut_by_a_bare_bar_are_found():
    assert broken_tables(_page("<p>| a | b |\n|---|---|\n| 1 | 2 |</p>"))
    assert broken_tables(_page("<table><tr><td><p>|x|</p></td></tr></table><p>peak |ctrl| is 1</p>")) == []
    assert broken_tables(_page("<table><tr><td><p>within: `</p></td><td><code class='literal'>a`b</code></td>"
                               "</tr></table>")) == ["a table cell cut inside a code span: 'within: `'"]
    source = "| | a | b |\n|---|---|---|\n| settling (|theta| small) | 1 | 2 |\n| peak \\|ctrl\\| | - | 1 |\n"
    faults = table_rows_cut(source)
    assert len(faults) == 1 and "line 3" in faults[0]
    assert table_rows_cut("```\n| a |\n|---|\n| b | c |\n```\n") == []


def test_links_out_of_the_site_and_files_outside_the_repository_are_found(tmp_path):
    (tmp_path / "a.html").write_text("")
    page = _page("<a href='a.html#x'>ok</a><a href='../b.html'>out</a><a href='c.html'>none</a>"
                 "<p><code class='docutils literal'><span class='pre'>shared/seed/lab.txt</span></code> "
                 "<code class='docutils literal'>cartpole/no_such_module.py</code> "
                 "<code class='docutils literal'>cartpole/__init__.py</code> "
                 "<code class='docutils literal'>figures/lab.png</code></p>")
    faults = " ".join(outside_references(page, tmp_path, tmp_path / "index.html"))
    assert "'../b.html' leads out" in faults and "'c.html' leads to no file" in faults
    assert "shared/seed/lab.txt" in faults and "no_such_module" in faults
    assert "a.html" not in faults and "__init__" not in faults and "figures" not in faults


def test_an_empty_left_sidebar_is_found_and_a_hidden_or_filled_one_is_not():
    shown = '<div id="pst-primary-sidebar" class="bd-sidebar-primary bd-sidebar"><div class="sidebar-primary-items"></div>'
    assert empty_sidebar(shown)
    assert not empty_sidebar(shown.replace("bd-sidebar\"", "bd-sidebar hide-on-wide\""))
    assert not empty_sidebar(shown + '<nav class="bd-docs-nav bd-links"><a href="x.html">x</a></nav>')


def test_a_cdn_script_and_raw_latex_are_found_and_shipped_mathjax_is_not(tmp_path):
    (tmp_path / "_static" / "mathjax").mkdir(parents=True)
    (tmp_path / "_static" / "mathjax" / "tex-chtml.js").write_text("")
    math = "<span class='math notranslate nohighlight'>\\(\\theta\\)</span>"
    cdn = _page(math, "<script src='https://cdn.jsdelivr.net/npm/mathjax@4/tex-mml-chtml.js'></script>")
    assert network_loads(cdn) and raw_latex(cdn, tmp_path, tmp_path / "index.html")
    local = _page(math + "<pre>\\frac{a}{b}</pre>", "<script src='_static/mathjax/tex-chtml.js'></script>"
                  "<link rel='stylesheet' href='_static/x.css'>")
    assert network_loads(local) == [] and raw_latex(local, tmp_path, tmp_path / "index.html") == []
    assert raw_latex(_page("<p>the gain \\frac{1}{2} \\theta</p>"), tmp_path, tmp_path / "index.html")


# ---- the Markdown sources and the built site -------------------------------------------------------------------
@pytest.mark.parametrize("path", SOURCES, ids=[p.name for p in SOURCES])
def test_no_table_row_of_the_pages_loses_cells(path):
    faults = table_rows_cut(path.read_text(encoding="utf-8"))
    assert not faults, f"{path.relative_to(REPO)}: " + "; ".join(faults)


@pytest.fixture(scope="module")
def site() -> Path:
    if not SITE:
        pytest.skip("no built site: `make docs` builds it and runs this module on it (CARTPOLE_SITE)")
    path = Path(SITE)
    assert (path / "index.html").is_file(), f"CARTPOLE_SITE={SITE} holds no built site (no index.html)"
    return path


def test_every_page_of_the_built_site_reads_without_faults(site):
    faults = site_faults(site)
    assert not faults, "\n".join(f"{page}: {'; '.join(f)}" for page, f in faults.items())


def test_every_notebook_page_shows_outputs_a_figure_and_printed_numbers(site):
    pages = sorted((site / "notebooks").glob("*.html"))
    assert len(pages) == len(list((REPO / "notebooks").glob("*.ipynb"))), "a notebook has no page"
    for path in pages:
        html = path.read_text(encoding="utf-8")
        assert 'class="cell_output' in html, f"{path.name} shows no output"
        assert re.search(r'<img[^>]+src="[^"]*\.png"', html), f"{path.name} shows no figure"
        assert re.search(r'class="output (stream|text_plain)', html), f"{path.name} prints nothing"


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(not CHROMIUM, reason="no chromium to render a page with")
def test_math_renders_in_a_browser_with_no_network(site):
    page = next(p for p in sorted(site.rglob("*.html")) if 'class="math' in p.read_text(encoding="utf-8"))
    dom = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--proxy-server=127.0.0.1:9",
         "--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=20000", "--dump-dom", page.as_uri()],
        capture_output=True, text=True, timeout=120).stdout
    assert "<mjx-container" in dom, f"MathJax typeset nothing on {page.relative_to(site)} offline"
