"""The claims file (issue 19, item 6): its schema, the text-on-page rule for every claim, the quick claims
re-measured, and the runner's ability to see a value that moved."""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def _load_runner():
    spec = importlib.util.spec_from_file_location("claims_runner", REPO / "tools" / "claims.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


claims_tool = _load_runner()
CLAIMS = claims_tool.load_claims(REPO / "claims.toml")
PAGES = claims_tool.page_texts(REPO)
QUICK = [c for c in CLAIMS if c.quick]
#: the quick claims grouped by their command (each command runs once, for all the claims that read it), so that
#: the suite's workers share them out instead of one test running every command in turn
QUICK_BY_COMMAND: dict[str, list] = {}
for _c in QUICK:
    QUICK_BY_COMMAND.setdefault(_c.command, []).append(_c)


def test_the_claims_file_is_well_formed_and_has_quick_and_slow_claims():
    assert len({c.id for c in CLAIMS}) == len(CLAIMS)
    assert QUICK and len(QUICK) < len(CLAIMS)
    assert all(c.kind == "result" for c in QUICK), "timings are never quick: the shared machine moves them"
    assert all(c.rel_tolerance is not None for c in CLAIMS if c.kind == "timing")


@pytest.mark.parametrize("claim", CLAIMS, ids=lambda c: c.id)
def test_every_claims_text_is_on_a_page_and_holds_its_value(claim):
    assert claims_tool.text_problems(claim, PAGES) == []


@pytest.mark.parametrize("claims", list(QUICK_BY_COMMAND.values()), ids=lambda cs: cs[0].id)
def test_quick_claims_hold_when_measured_again(claims):
    results = claims_tool.run_claims(claims, pages=PAGES)
    bad = [claims_tool.describe(r) for r in results if r.status != "held"]
    assert not bad, "\n".join(bad)


def _claim(**kw):
    base = dict(id="synthetic", text="settles in 0.129 s", command="echo", key="t", value=0.129, tolerance=0.0005)
    return claims_tool.Claim(**{**base, **kw})


def _runner(doc):
    return lambda command, timeout: (doc, 0.0, None)


def test_a_value_that_moved_is_reported_moved_with_old_and_new_value():
    pages = {"README.md": "It settles in 0.129 s."}
    held, = claims_tool.run_claims([_claim()], pages=pages, runner=_runner({"t": 0.1292}))
    moved, = claims_tool.run_claims([_claim()], pages=pages, runner=_runner({"t": 0.131}))
    assert held.status == "held"
    assert moved.status == "moved" and moved.measured == 0.131
    assert "0.129" in claims_tool.describe(moved) and "0.131" in claims_tool.describe(moved)


def test_a_real_command_whose_value_moved_makes_the_runner_exit_1(tmp_path, capsys):
    path = tmp_path / "claims.toml"
    text = "Mean settling time: 0.13 s"  # on the lab page; the command below prints another number
    path.write_text(f'[[claim]]\nid = "moved"\ntext = "{text}"\n'
                    'command = "python -c \\"print(0.5)\\""\nkey = "doc"\nvalue = 0.13\ntolerance = 0.005\n')
    assert claims_tool.main(["--file", str(path), "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["claims"][0]["status"] == "moved" and out["claims"][0]["measured"] == 0.5


def test_text_off_the_pages_or_without_its_value_breaks_the_rule():
    pages = {"README.md": "It settles in 0.129 s, the cart within [-0.23, 0.50] m."}
    assert claims_tool.text_problems(_claim(), pages) == []
    assert claims_tool.text_problems(_claim(text="settles in 0.13 s"), pages)  # not on the page
    assert claims_tool.text_problems(_claim(value=0.13), pages)  # page says 0.129, file 0.13
    ranged = _claim(text="[-0.23, 0.50] m", value=[-0.23, 0.5])
    assert claims_tool.text_problems(ranged, pages) == []
    assert claims_tool.text_problems(_claim(text="[-0.23, 0.50] m", value=[0.23, 0.5]), pages)  # the sign counts


def test_numbers_are_read_as_written():
    assert claims_tool.numbers_in("[-0.23, 0.50] m, 877-883, 4.4e+05, 1,070,000 steps, 2e5, +-0.3") == [
        -0.23, 0.5, 877, 883, 4.4e5, 1070000, 2e5, -0.3]


def test_keys_read_paths_and_small_expressions_and_nothing_else():
    doc = {"rollout": {"success": True}, "settling_times_seed": [0.055, 0.445], "return": 1.0}
    assert claims_tool.evaluate_key("rollout.success", doc) is True
    assert claims_tool.evaluate_key("settling_times_seed[1]", doc) == 0.445
    assert claims_tool.evaluate_key("round(mean(settling_times_seed), 2)", doc) == 0.25
    assert claims_tool.evaluate_key('doc["return"]', doc) == 1.0
    for bad in ("__import__('os')", "rollout.__class__", "open('x')", "[x for x in ().__class__.__mro__]"):
        with pytest.raises(claims_tool.KeyError_):
            claims_tool.evaluate_key(bad, doc)
    with pytest.raises(claims_tool.KeyError_, match="no key"):
        claims_tool.evaluate_key("rollout.missing", doc)


@pytest.mark.parametrize("body,match", [
    ("", "no \\[\\[claim\\]\\]"),
    ("[[claim]]\nid = 'a'\n", "non-empty string 'text'"),
    ("[[claim]]\nid = 'a'\ntext = 't 1'\ncommand = 'c'\nkey = 'k'\nvalue = 1\n", "exactly one of"),
    ("[[claim]]\nid = 'a'\ntext = 't 1'\ncommand = 'c'\nkey = 'k'\nvalue = 1\ntolerance = 0.1\nkind = 'timing'\n",
     "timing claim takes a rel_tolerance"),
    ("[[claim]]\nid = 'a'\ntext = 't'\ncommand = 'c'\nkey = 'k'\nvalue = true\ntolerance = 0.1\n", "compared exactly"),
    ("[[claim]]\nid = 'a'\ntext = 't 1'\ncommand = 'c'\nkey = 'k'\nvalue = 1\ntolerance = 0\nspeed = 1\n", "unknown"),
    ("[[claim]]\nid = 'a'\ntext = 't 1'\ncommand = 'c'\nkey = 'import os'\nvalue = 1\ntolerance = 0\n", "not an expression"),
    ("[[claim]\n", "not valid TOML"),
])
def test_a_malformed_claims_file_is_one_sentence_and_exit_2(tmp_path, capsys, body, match):
    path = tmp_path / "claims.toml"
    path.write_text(body)
    with pytest.raises(claims_tool.ClaimsFileError, match=match):
        claims_tool.load_claims(path)
    assert claims_tool.main(["--file", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("claims: ") and "\n" not in err


def _one_claim_file(tmp_path, printed: float, value: float = 0.13):
    path = tmp_path / "claims.toml"
    text = "Mean settling time: 0.13 s"  # on the lab page
    path.write_text(f'[[claim]]\nid = "settling"\ntext = "{text}"\n'
                    f'command = "python -c \\"print({printed})\\""\nkey = "doc"\nvalue = {value}\ntolerance = 0.005\n'
                    f'[[claim]]\nid = "moving"\ntext = "{text}"\n'
                    'command = "python -c \\"print(0.5)\\""\nkey = "doc"\nvalue = 0.13\ntolerance = 0.005\n')
    return path


def test_the_ledger_records_each_measured_claim_and_a_resumed_run_measures_only_what_has_not_held(tmp_path, capsys):
    path, ledger = _one_claim_file(tmp_path, printed=0.131), tmp_path / "ledger.jsonl"
    today = claims_tool.datetime.date.today().isoformat()
    assert claims_tool.main(["--file", str(path), "--ledger", str(ledger), "--json"]) == 1
    lines = [json.loads(line) for line in ledger.read_text().splitlines()]
    assert [(e["id"], e["status"], e["measured"]) for e in lines] == [("settling", "held", 0.131),
                                                                     ("moving", "moved", 0.5)]
    assert all(e["machine"] == claims_tool.machine() and e["date"][:10] >= today for e in lines)
    capsys.readouterr()
    # resumed: the claim that held is done, the one that moved is measured again (and appended again)
    assert claims_tool.main(["--file", str(path), "--ledger", str(ledger), "--pending-since", today, "--json"]) == 1
    assert [c["id"] for c in json.loads(capsys.readouterr().out)["claims"]] == ["moving"]
    assert len(ledger.read_text().splitlines()) == 3
    # a claim whose stated value changed is not the claim that held: it is pending again
    restated = _one_claim_file(tmp_path, printed=0.131, value=0.131)
    assert claims_tool.main(["--file", str(restated), "--ledger", str(ledger), "--pending-since", today,
                             "--json"]) == 1
    assert [c["id"] for c in json.loads(capsys.readouterr().out)["claims"]] == ["settling", "moving"]


def test_held_lines_of_another_cpu_or_before_the_campaign_do_not_count():
    claim = _claim()
    held = {"id": claim.id, "status": "held", "digest": claims_tool.claim_digest(claim), "machine": "cpu A",
            "date": "2026-12-07T10:00:00+00:00"}
    since = claims_tool.datetime.date(2026, 12, 7)
    assert claims_tool.pending([claim], [held], since=since, cpu="cpu A") == []
    assert claims_tool.pending([claim], [held], since=since, cpu="cpu B") == [claim]
    assert claims_tool.pending([claim], [held], since=claims_tool.datetime.date(2026, 12, 8), cpu="cpu A") == [claim]
    assert claims_tool.pending([claim], [{**held, "status": "moved"}], since=since, cpu="cpu A") == [claim]


@pytest.mark.parametrize("args, ledger_text, match", [
    (["--pending-since", "2026-12-07"], None, "give --ledger FILE too"),
    (["--pending-since", "yesterday"], "", "not a date"),
    (["--pending-since", "2026-12-07"], "{not json\n", "line 1 is not a ledger entry"),
])
def test_a_bad_ledger_argument_is_one_sentence_and_exit_2(tmp_path, capsys, args, ledger_text, match):
    path = _one_claim_file(tmp_path, printed=0.13)
    if ledger_text is not None:
        ledger = tmp_path / "ledger.jsonl"
        ledger.write_text(ledger_text)
        args = args + ["--ledger", str(ledger)]
    assert claims_tool.main(["--file", str(path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("claims: ") and "\n" not in err and match in err
