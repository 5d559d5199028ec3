"""Re-measure every number the pages state (issue 19, item 6).

``claims.toml`` at the repository root lists each claim a page makes: the snippet of the page that states it
(``text``, verbatim up to whitespace, in ``README.md`` or some ``docs/**/*.md``), the shell command that measures
it (printing one JSON document on stdout), a ``key`` into that document, the ``value`` the page states and its
tolerance. This tool runs the commands (each distinct command once per run), reads each key, compares it with the
value and says which claims held and which moved. It also checks that each claim's text is on a page and that the
value is written inside that text, so the page and the claims file cannot disagree.

Usage::

    python tools/claims.py                    # every claim (slow: the sweeps and benchmarks too)
    python tools/claims.py --quick            # the claims marked quick = true (what the test suite runs)
    python tools/claims.py --id lab-K --id lab-mean-settling --json
    python tools/claims.py --no-run           # only the file's schema and the text-on-page rule

A whole run takes many hours (the score sweeps and the benchmarks), longer than a working session, and its numbers
depend on the machine (a chaotic acrobot lands elsewhere on a CPU that rounds differently). ``--ledger FILE`` appends
one JSON line per measured claim as it comes (its id, status, value and measurement, the claim's digest, the commit
and whether the checkout had changes, the CPU, the date and the command's seconds): the record of which number was
last measured where. ``--pending-since DATE`` then selects only the claims without a ``held`` line in that ledger,
for the same claim (digest: command, key, value and tolerance) on this CPU, dated on or after DATE, so an interrupted
campaign resumes where it stopped. ``make claims`` keeps ``claims-ledger.jsonl`` at the repository root.

Exit status: 0 every selected claim held, 1 some claim moved, failed to measure or is not on a page, 2 the claims
file is malformed (one sentence on stderr).

The claims file's schema, per ``[[claim]]``:

- ``id`` (unique, ``[a-z0-9][a-z0-9._-]*``), ``text`` (the page's snippet), ``command`` (run by ``sh`` in the
  repository root with the running Python's ``bin`` first on ``PATH``, ``MUJOCO_GL=egl`` unless set, and
  ``$CLAIMS_OUT`` a fresh empty directory for the files a command writes);
- ``key``: an expression over the command's JSON document: its top-level keys are names, ``a.b`` reads key ``b``
  of object ``a`` (``a["b"]`` where ``b`` is a keyword or a dict method name), ``a[0]`` indexes, ``doc`` is the
  whole document, ``command_seconds`` the command's wall time (s, for the timing of a whole command); arithmetic,
  comparisons, comprehensions and the functions ``abs all any deg len max mean median min round sorted std sum
  zip`` (``deg``: radians to degrees) are allowed, nothing else;
- ``value``: a number, a list of numbers, a boolean or a string; every number of it must be written in ``text``;
- ``tolerance`` (absolute) or ``rel_tolerance`` (a fraction of ``value``): exactly one for numeric values (a number,
  or for a list value a list of one per entry), none for booleans and strings (compared exactly);
- optional ``kind`` (``"result"``, the default, or ``"timing"``: a speed measured on a shared machine, given a wide
  relative tolerance), ``quick`` (default false: cheap enough for the test suite), ``timeout`` (s, default 3600),
  ``note`` (free text).
"""
from __future__ import annotations

import argparse
import ast
import datetime
import hashlib
import platform
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the tomli backport (same API)
    import tomli as tomllib

REPO = Path(__file__).resolve().parent.parent
CLAIMS_FILE = REPO / "claims.toml"
LEDGER_FILE = REPO / "claims-ledger.jsonl"
KINDS = ("result", "timing")
_ID = re.compile(r"[a-z0-9][a-z0-9._-]*\Z")
_FIELDS = {"id", "text", "command", "key", "value", "tolerance", "rel_tolerance", "kind", "quick", "timeout", "note"}


class ClaimsFileError(ValueError):
    """The claims file is malformed (its message is one sentence naming the claim and the field)."""


class KeyError_(ValueError):
    """A claim's key cannot be read from its command's JSON document."""


@dataclass(frozen=True)
class Claim:
    """One number (or list of numbers, or flag) a page states, and how to measure it again."""

    id: str
    text: str
    command: str
    key: str
    value: object
    tolerance: float | list | None = None
    rel_tolerance: float | list | None = None
    kind: str = "result"
    quick: bool = False
    timeout: float = 3600.0
    note: str = ""


@dataclass(frozen=True)
class Result:
    """What one claim gave: ``status`` is ``held``, ``moved``, ``error`` (not measured) or ``off-page``."""

    claim: Claim
    status: str
    measured: object = None
    detail: str = ""
    seconds: float = field(default=0.0, compare=False)

    def as_dict(self) -> dict:
        return {"id": self.claim.id, "status": self.status, "value": self.claim.value, "measured": self.measured,
                "kind": self.claim.kind, "detail": self.detail, "command": self.claim.command}


# ---- the file ---------------------------------------------------------------------------------------------------

def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _claim_from(entry, index: int) -> Claim:
    where = f"claim {index + 1}" + (f" ({entry.get('id')!r})" if isinstance(entry, dict) and "id" in entry else "")
    if not isinstance(entry, dict):
        raise ClaimsFileError(f"{where} is not a table.")
    unknown = set(entry) - _FIELDS
    if unknown:
        raise ClaimsFileError(f"{where} has unknown field(s) {', '.join(sorted(unknown))}.")
    for name in ("id", "text", "command", "key"):
        if not isinstance(entry.get(name), str) or not entry[name].strip():
            raise ClaimsFileError(f"{where} needs a non-empty string {name!r}.")
    if not _ID.match(entry["id"]):
        raise ClaimsFileError(f"{where}: id must match [a-z0-9][a-z0-9._-]*.")
    if "value" not in entry:
        raise ClaimsFileError(f"{where} has no 'value'.")
    value = entry["value"]
    numeric = _is_number(value) or (isinstance(value, list) and value and all(_is_number(v) for v in value))
    if not (numeric or isinstance(value, (bool, str))):
        raise ClaimsFileError(f"{where}: value must be a number, a non-empty list of numbers, a boolean or a string.")
    tol, rel = entry.get("tolerance"), entry.get("rel_tolerance")
    if numeric:
        if (tol is None) == (rel is None):
            raise ClaimsFileError(f"{where} needs exactly one of 'tolerance' (absolute) and 'rel_tolerance'.")
        t = tol if tol is not None else rel
        ts = t if isinstance(t, list) else [t]
        if isinstance(t, list) and not (isinstance(value, list) and len(t) == len(value)):
            raise ClaimsFileError(f"{where}: a list of tolerances needs a list value of the same length.")
        if not all(_is_number(x) and math.isfinite(x) and x >= 0 for x in ts):
            raise ClaimsFileError(f"{where}: the tolerance must be a finite number >= 0 (or a list of them).")
    elif tol is not None or rel is not None:
        raise ClaimsFileError(f"{where}: a boolean or string value is compared exactly and takes no tolerance.")
    kind = entry.get("kind", "result")
    if kind not in KINDS:
        raise ClaimsFileError(f"{where}: kind must be one of {', '.join(KINDS)}.")
    if kind == "timing" and rel is None:
        raise ClaimsFileError(f"{where}: a timing claim takes a rel_tolerance.")
    quick = entry.get("quick", False)
    if not isinstance(quick, bool):
        raise ClaimsFileError(f"{where}: quick must be true or false.")
    timeout = entry.get("timeout", 3600.0)
    if not _is_number(timeout) or timeout <= 0:
        raise ClaimsFileError(f"{where}: timeout must be a positive number of seconds.")
    try:
        _parse_key(entry["key"])
    except KeyError_ as e:
        raise ClaimsFileError(f"{where}: {e}") from None
    return Claim(id=entry["id"], text=entry["text"], command=entry["command"], key=entry["key"], value=value,
                 tolerance=tol, rel_tolerance=rel, kind=kind, quick=quick, timeout=float(timeout),
                 note=entry.get("note", ""))


def load_claims(path: Path | str = CLAIMS_FILE) -> list[Claim]:
    """Read and validate a claims file; raise `ClaimsFileError` (one sentence) when it is malformed."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise ClaimsFileError(f"Cannot read the claims file {path}: {e.strerror or e}.") from None
    except tomllib.TOMLDecodeError as e:
        raise ClaimsFileError(f"The claims file {path} is not valid TOML: {e}.") from None
    unknown = set(data) - {"claim"}
    if unknown:
        raise ClaimsFileError(f"The claims file has unknown top-level key(s) {', '.join(sorted(unknown))}.")
    entries = data.get("claim")
    if not isinstance(entries, list) or not entries:
        raise ClaimsFileError(f"The claims file {path} holds no [[claim]] tables.")
    claims = [_claim_from(e, i) for i, e in enumerate(entries)]
    seen = set()
    for c in claims:
        if c.id in seen:
            raise ClaimsFileError(f"Claim id {c.id!r} appears more than once.")
        seen.add(c.id)
    return claims


# ---- the pages --------------------------------------------------------------------------------------------------

def _squash(s: str) -> str:
    return " ".join(s.split())


def page_texts(root: Path | str = REPO) -> dict[str, str]:
    """``{relative path: text with whitespace runs squashed to one space}`` of README.md and docs/**/*.md (not under
    a folder whose name starts with ``_``, such as Sphinx's ``_build``)."""
    root = Path(root)
    docs = root / "docs"
    paths = [root / "README.md", *sorted(p for p in docs.glob("**/*.md")
                                          if not any(part.startswith("_") for part in p.relative_to(docs).parts))]
    return {str(p.relative_to(root)): _squash(p.read_text(encoding="utf-8")) for p in paths if p.is_file()}


# a number as written on a page: 1,070,000 / -0.23 / 4.4e+05 / 2e5; a minus counts only where it is a sign (not in
# "877-883" or "x-0.3"), a leading "+" is a sign too
_NUMBER = re.compile(r"(?<![\w.])(?P<sign>[-+\u2212]?)(?P<num>\d{1,3}(?:,\d{3})+(?:\.\d+)?|\d+(?:\.\d+)?|\.\d+)"
                     r"(?P<exp>[eE][-+]?\d+)?(?![\d])")


def numbers_in(text: str) -> list[float]:
    """Every number written in ``text`` (signed where a sign precedes it directly and a word does not)."""
    out = []
    for m in _NUMBER.finditer(text):
        start = m.start()
        sign = m.group("sign")
        if sign and start > 0 and (text[start - 1].isalnum() or text[start - 1] in ")]"):
            sign = ""  # "877-883", "A-0.5": a dash between words, not a sign
        x = float(m.group("num").replace(",", "") + (m.group("exp") or ""))
        out.append(-x if sign in ("-", "\u2212") else x)
    return out


def text_problems(claim: Claim, pages: dict[str, str]) -> list[str]:
    """Why ``claim`` breaks the text rule (its text on no page; a number of its value not in its text), or []."""
    problems = []
    snippet = _squash(claim.text)
    if not any(snippet in body for body in pages.values()):
        problems.append(f"text not found verbatim in {', '.join(pages) or 'any page'}: {snippet!r}")
    value = claim.value
    wanted = value if isinstance(value, list) else [value]
    written = numbers_in(snippet)
    for v in wanted:
        if _is_number(v) and not any(math.isclose(v, w, rel_tol=1e-12, abs_tol=1e-15) for w in written):
            problems.append(f"value {v!r} is not written in the text {snippet!r}")
        elif isinstance(v, str) and v not in snippet:
            problems.append(f"value {v!r} is not in the text {snippet!r}")
    return problems


# ---- the key ----------------------------------------------------------------------------------------------------

def _mean(xs):
    return statistics.fmean(xs)


def _deg(rad):
    return math.degrees(rad)


_FUNCTIONS = {"abs": abs, "all": all, "any": any, "deg": _deg, "len": len, "max": max, "mean": _mean,
              "median": statistics.median, "min": min, "round": round, "sorted": sorted,
              "std": statistics.pstdev, "sum": sum, "zip": zip}
_NODES = (ast.Expression, ast.Name, ast.Load, ast.Store, ast.Attribute, ast.Subscript, ast.Slice, ast.Constant,
          ast.Call, ast.BinOp, ast.UnaryOp, ast.BoolOp, ast.Compare, ast.IfExp, ast.List, ast.Tuple,
          ast.ListComp, ast.GeneratorExp, ast.comprehension, ast.keyword,
          ast.Add, ast.Sub, ast.Mult, ast.Div, ast.FloorDiv, ast.Mod, ast.Pow, ast.USub, ast.UAdd, ast.Not,
          ast.And, ast.Or, ast.Eq, ast.NotEq, ast.Lt, ast.LtE, ast.Gt, ast.GtE, ast.In, ast.NotIn, ast.Is, ast.IsNot)


class _Obj(dict):
    """A JSON object whose keys read as attributes too (``rollout.success``)."""

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise KeyError_(f"no key {name!r} (keys: {', '.join(sorted(self))[:300]})") from None


def _wrap(doc):
    if isinstance(doc, dict):
        return _Obj({k: _wrap(v) for k, v in doc.items()})
    if isinstance(doc, list):
        return [_wrap(v) for v in doc]
    return doc


def _parse_key(key: str):
    try:
        tree = ast.parse(key, mode="eval")
    except SyntaxError:
        raise KeyError_(f"key {key!r} is not an expression") from None
    for node in ast.walk(tree):
        if not isinstance(node, _NODES):
            raise KeyError_(f"key {key!r} uses {type(node).__name__}, which keys may not")
        if isinstance(node, ast.Attribute) and node.attr.startswith("_"):
            raise KeyError_(f"key {key!r} reads a private attribute")
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS):
            raise KeyError_(f"key {key!r} calls something other than {', '.join(_FUNCTIONS)}")
    return compile(tree, "<key>", "eval")


def evaluate_key(key: str, doc, extra: dict | None = None):
    """The value of ``key`` (see the module docstring) in the JSON document ``doc``; ``extra`` adds names (the
    runner adds ``command_seconds``)."""
    code = _parse_key(key)
    doc = _wrap(doc)
    names = dict(doc) if isinstance(doc, dict) else {}
    names.update(extra or {})
    names.update(_FUNCTIONS, doc=doc)
    try:
        # one namespace (globals), so that comprehensions, which have a scope of their own, see the names too
        return eval(code, {**names, "__builtins__": {}})  # noqa: S307 - the AST is checked by _parse_key
    except KeyError_:
        raise
    except Exception as e:  # a missing key, an index out of range, a type error: say which
        raise KeyError_(f"key {key!r}: {type(e).__name__}: {e}") from None


# ---- comparing --------------------------------------------------------------------------------------------------

def _plain(v):
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def holds(claim: Claim, measured) -> bool:
    """True when ``measured`` equals the claim's value within its tolerance (booleans and strings exactly)."""
    value = claim.value
    if isinstance(value, (bool, str)):
        return measured == value and type(measured) is type(value)
    values = value if isinstance(value, list) else [value]
    got = measured if isinstance(value, list) else [measured]
    if not isinstance(got, (list, tuple)) or len(got) != len(values):
        return False
    absolute = claim.tolerance is not None
    tols = claim.tolerance if absolute else claim.rel_tolerance
    tols = tols if isinstance(tols, list) else [tols] * len(values)
    for v, m, t in zip(values, got, tols):
        if not _is_number(m) or not math.isfinite(m):
            return False
        tol = t if absolute else t * abs(v)
        if abs(m - v) > tol * (1 + 1e-9) + 1e-12:
            return False
    return True


# ---- running ----------------------------------------------------------------------------------------------------

def command_env(out_dir: str) -> dict:
    """The environment a claim's command runs in (see the module docstring)."""
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env.setdefault("MUJOCO_GL", "egl")
    env["CLAIMS_OUT"] = out_dir
    env["PYTHONUNBUFFERED"] = "1"
    return env


def run_command(command: str, *, timeout: float = 3600.0, cwd: Path | str = REPO):
    """Run one claim command; return ``(document, seconds, error)`` where ``error`` is a sentence or None."""
    import time

    with tempfile.TemporaryDirectory(prefix="claims-") as out:
        t0 = time.perf_counter()
        try:
            p = subprocess.run(command, shell=True, cwd=cwd, env=command_env(out), capture_output=True, text=True,
                               timeout=timeout)
        except subprocess.TimeoutExpired:
            return None, time.perf_counter() - t0, f"timed out after {timeout:g} s"
        seconds = time.perf_counter() - t0
    tail = (p.stderr.strip().splitlines() or [""])[-1]
    if p.returncode != 0:
        return None, seconds, f"exit status {p.returncode}: {tail}"
    try:
        return json.loads(p.stdout), seconds, None
    except json.JSONDecodeError as e:
        return None, seconds, f"stdout is not one JSON document ({e}); last line on stderr: {tail}"


def run_claims(claims, *, pages: dict[str, str] | None = None, measure: bool = True, on_result=None,
               runner=run_command) -> list[Result]:
    """Check the text rule of each claim and, with ``measure``, run its command (each distinct command once) and
    compare its key with the value. ``on_result(result)`` sees each result as it comes; ``runner(command,
    timeout=...)`` returns ``(document, seconds, error)`` (`run_command`; tests pass their own)."""
    pages = page_texts() if pages is None else pages
    cache: dict[str, tuple] = {}
    results = []
    for claim in claims:
        problems = text_problems(claim, pages)
        if problems:
            result = Result(claim, "off-page", detail="; ".join(problems))
        elif not measure:
            result = Result(claim, "on-page")
        else:
            if claim.command not in cache:
                cache[claim.command] = runner(claim.command, timeout=claim.timeout)
            doc, seconds, error = cache[claim.command]
            if error is not None:
                result = Result(claim, "error", detail=error, seconds=seconds)
            else:
                try:
                    measured = _plain(evaluate_key(claim.key, doc, {"command_seconds": seconds}))
                except KeyError_ as e:
                    result = Result(claim, "error", detail=str(e), seconds=seconds)
                else:
                    result = Result(claim, "held" if holds(claim, measured) else "moved", measured=measured,
                                    seconds=seconds)
        results.append(result)
        if on_result is not None:
            on_result(result)
    return results


# ---- the ledger -------------------------------------------------------------------------------------------------

def claim_digest(claim: Claim) -> str:
    """16 hex digits naming what a claim measures and states (its command, key, value and tolerances): a ledger line
    counts for a claim only while these are unchanged."""
    what = {"command": claim.command, "key": claim.key, "value": claim.value, "tolerance": claim.tolerance,
            "rel_tolerance": claim.rel_tolerance}
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()[:16]


def machine() -> str:
    """The CPU the claims run on: its model name from ``/proc/cpuinfo`` where there is one, the architecture, and
    whether it has AVX-512 (which changes the round-off of the compiled code, and so where a chaotic run lands)."""
    try:
        info = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        info = []
    names = [line.split(":", 1)[1].strip() for line in info if line.startswith("model name")]
    flags = next((line.split(":", 1)[1].split() for line in info if line.startswith("flags")), [])
    if names:
        return f"{names[0]} ({platform.machine()}{', AVX-512' if 'avx512f' in flags else ''})"
    return platform.processor() or platform.machine() or "unknown"


def revision(cwd: Path | str = REPO) -> str:
    """The checkout's commit, with ``+changes`` when tracked files other than the ledger itself differ from it;
    ``unknown`` outside git."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, check=True)
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
                                 f":(exclude){LEDGER_FILE.name}"], cwd=cwd, capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head.stdout.strip() + ("+changes" if status.stdout.strip() else "")


def ledger_entry(result: Result, *, commit: str, cpu: str, when: datetime.datetime) -> dict:
    """The ledger's JSON line for one measured result (see the module docstring)."""
    return {"id": result.claim.id, "status": result.status, "value": result.claim.value,
            "measured": result.measured, "detail": result.detail, "digest": claim_digest(result.claim),
            "commit": commit, "machine": cpu, "date": when.isoformat(timespec="seconds"),
            "seconds": round(float(result.seconds), 3)}


def read_ledger(path: Path | str) -> list[dict]:
    """The ledger's lines (none when the file does not exist yet)."""
    path = Path(path)
    if not path.exists():
        return []
    entries = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            entry = None
        if not isinstance(entry, dict) or not {"id", "status", "digest", "machine", "date"} <= set(entry):
            raise ClaimsFileError(f"{path} line {n} is not a ledger entry (one JSON object with id, status, digest, "
                                  "machine and date); fix or remove that line")
        entries.append(entry)
    return entries


def pending(claims, entries, *, since: datetime.date, cpu: str) -> list[Claim]:
    """The ``claims`` with no ``held`` entry among ``entries`` for the same digest on ``cpu`` dated ``since`` or
    later: what a campaign begun on ``since`` has still to measure."""
    done = {(e["id"], e["digest"]) for e in entries
            if e["status"] == "held" and e["machine"] == cpu and e["date"][:10] >= since.isoformat()}
    return [c for c in claims if (c.id, claim_digest(c)) not in done]


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return json.dumps(v) if isinstance(v, str) else str(v)


def describe(result: Result) -> str:
    """One line for a result."""
    c = result.claim
    rel = c.rel_tolerance
    tol = (f" ± {_fmt(c.tolerance)}" if c.tolerance is not None else
           f" ± {_fmt([100 * r for r in rel]) if isinstance(rel, list) else format(100 * rel, 'g')} %" if rel is not None
           else "")
    if result.status == "held":
        return f"held     {c.id}: {_fmt(c.value)}{tol} (now {_fmt(result.measured)})"
    if result.status == "moved":
        return f"MOVED    {c.id}: page {_fmt(c.value)}{tol}, now {_fmt(result.measured)} [{c.kind}]"
    if result.status == "on-page":
        return f"on page  {c.id}"
    return f"{result.status.upper():8} {c.id}: {result.detail}"


def _recording(path, show):
    """``on_result`` that appends each measured result to the ledger at ``path`` (as it comes, so an interrupted
    run keeps what it measured), then calls ``show``."""
    commit, cpu = revision(), machine()

    def record(result: Result):
        if result.status in ("held", "moved", "error"):
            line = json.dumps(ledger_entry(result, commit=commit, cpu=cpu,
                                           when=datetime.datetime.now(datetime.timezone.utc)))
            with open(path, "a") as f:
                f.write(line + "\n")
        if show is not None:
            show(result)
    return record


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python tools/claims.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--file", default=str(CLAIMS_FILE), help="the claims file (default: claims.toml)")
    ap.add_argument("--quick", action="store_true", help="only the claims marked quick = true")
    ap.add_argument("--id", action="append", default=[], metavar="ID", help="only this claim (repeatable)")
    ap.add_argument("--kind", choices=KINDS, help="only claims of this kind")
    ap.add_argument("--no-run", action="store_true", help="check the schema and the text rule only")
    ap.add_argument("--json", action="store_true", help="one JSON document on stdout")
    ap.add_argument("--ledger", metavar="FILE", help="append one JSON line per measured claim to FILE")
    ap.add_argument("--pending-since", metavar="YYYY-MM-DD",
                    help="only claims not yet held in --ledger's file on this CPU since that date")
    args = ap.parse_args(argv)
    since = None
    if args.pending_since is not None:
        if args.ledger is None:
            print("claims: --pending-since reads the ledger: give --ledger FILE too.", file=sys.stderr)
            return 2
        try:
            since = datetime.date.fromisoformat(args.pending_since)
        except ValueError:
            print(f"claims: --pending-since {args.pending_since!r} is not a date: give it as YYYY-MM-DD.",
                  file=sys.stderr)
            return 2
    try:
        claims = load_claims(args.file)
        entries = read_ledger(args.ledger) if since is not None else []
    except ClaimsFileError as e:
        print(f"claims: {e}", file=sys.stderr)
        return 2
    unknown = set(args.id) - {c.id for c in claims}
    if unknown:
        print(f"claims: no claim with id {', '.join(sorted(unknown))} in {args.file}.", file=sys.stderr)
        return 2
    chosen = [c for c in claims if (not args.quick or c.quick) and (not args.id or c.id in args.id)
              and (args.kind is None or c.kind == args.kind)]
    if since is not None:
        chosen = pending(chosen, entries, since=since, cpu=machine())
    show = None if args.json else (lambda r: print(describe(r), flush=True))
    if args.ledger is not None and not args.no_run:
        show = _recording(args.ledger, show)
    results = run_claims(chosen, measure=not args.no_run, on_result=show)
    bad = [r for r in results if r.status not in ("held", "on-page")]
    counts = {s: sum(r.status == s for r in results) for s in ("held", "moved", "error", "off-page", "on-page")}
    if args.json:
        print(json.dumps({"file": str(Path(args.file).resolve()), "counts": counts,
                          "claims": [r.as_dict() for r in results]}, indent=1))
    else:
        print(", ".join(f"{n} {s}" for s, n in counts.items() if n) + f" of {len(results)} claims")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
