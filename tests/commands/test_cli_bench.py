"""`cartpole bench --json --quick`: the JSON contract of DESIGN.md and the same optimum as the baseline."""
import json
from pathlib import Path

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF


def test_bench_json_follows_the_contract(capsys):
    assert main(["bench", "--json", "--quick"]) == 0
    captured = capsys.readouterr()
    doc = json.loads(captured.out)  # stdout is exactly one JSON document
    assert Path(doc["mjcf"]) == SHIPPED_MJCF
    tr, tv, rp = doc["trajopt"], doc["tvlqr"], doc["replay"]
    for key in ("solve_ms_median", "objective", "N", "T", "baseline_solve_ms_median", "baseline_objective",
                "speedup", "solver", "iterations"):
        assert key in tr, key
    assert tr["N"] == 100 and tr["T"] == 2.0 and tr["solver"] == "ipopt"
    assert tr["solve_ms_median"] > 0 and tr["baseline_solve_ms_median"] > 0 and tv["ms_median"] > 0
    assert tr["speedup"] == tr["baseline_solve_ms_median"] / tr["solve_ms_median"]
    # ours and the naive Opti transcription solve the same problem: same optimum within 1 %
    assert abs(tr["objective"] - tr["baseline_objective"]) <= 0.01 * abs(tr["baseline_objective"])
    for key in ("steps_per_s", "rollouts", "seconds_each"):
        assert key in rp, key
    assert rp["steps_per_s"] > 0 and rp["seconds_each"] == 2.0
    assert captured.err == ""  # --json: no progress at all


def test_bench_prose_prints_a_table_and_one_stderr_line_per_measurement(capsys):
    assert main(["bench", "--quick", "--no-replay", "--repeats", "1"]) == 0
    captured = capsys.readouterr()
    out = captured.out
    assert "baseline: casadi.Opti" in out and "TVLQR synthesis" in out and "Batched replay" not in out
    # stderr is not a terminal here: one finished line per measurement, no carriage returns, nothing on stdout
    lines = captured.err.splitlines()
    assert "\r" not in captured.err and len(lines) >= 5
    assert all(line.startswith("bench: ") and line.endswith(" s") and " in " in line for line in lines)
    assert any(line.startswith("bench: baseline (Opti, no expand): 1 solves in ") for line in lines)
    assert "bench: " not in out


def test_bench_writes_no_files_so_out_is_hidden_but_still_accepted(capsys):
    from cartpole.cli import build_parser

    assert build_parser().parse_args(["bench", "--out", "somewhere"]).out == "somewhere"  # old scripts still parse
    assert main(["bench", "--help"]) == 0
    assert "--out" not in capsys.readouterr().out


def test_bad_repeats_is_one_sentence_and_exit_2(capsys):
    assert main(["bench", "--json", "--repeats", "0"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "repeats" in captured.err
