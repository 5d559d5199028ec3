"""`cartpole bench --json --quick`: the JSON contract of DESIGN.md and the same optimum as the baseline."""
import json
from pathlib import Path

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF


def test_bench_json_follows_the_contract(capsys):
    assert main(["bench", "--json", "--quick", "--no-mpc"]) == 0
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
    # the same Opti script with expand=True finds the same optimum
    assert abs(tr["expand_baseline_objective"] - tr["baseline_objective"]) <= 1e-6 * abs(tr["baseline_objective"])
    assert tr["speedup_vs_expand"] == tr["expand_baseline_solve_ms_median"] / tr["solve_ms_median"]
    # the SQP on the stage-structured QP solves the same NLP from the same guess: same optimum as our IPOPT
    for key in ("sqp_solve_ms_median", "sqp_iterations", "sqp_objective", "sqp_success", "sqp_speedup",
                "sqp_speedup_vs_expand"):
        assert key in tr, key
    assert tr["sqp_success"] and tr["sqp_solve_ms_median"] > 0
    assert abs(tr["sqp_objective"] - tr["objective"]) <= 1e-6 * abs(tr["objective"])
    assert tr["sqp_speedup"] == tr["baseline_solve_ms_median"] / tr["sqp_solve_ms_median"]
    # the hand-typed naive script (one pole): the same optimum, and every ratio is taken against it
    assert tr["reference_baseline"] == "hand" and tr["hand_baseline_success"]
    assert abs(tr["hand_baseline_objective"] - tr["baseline_objective"]) <= 1e-6 * abs(tr["baseline_objective"])
    assert tr["reference_solve_ms_median"] == tr["hand_baseline_solve_ms_median"]
    assert tr["speedup_vs_reference"] == tr["hand_baseline_solve_ms_median"] / tr["solve_ms_median"]
    assert tr["sqp_speedup_vs_reference"] == tr["hand_baseline_solve_ms_median"] / tr["sqp_solve_ms_median"]
    # the default planner (solver "auto"): the SQP's plan, the same optimum, its ratio against the reference
    assert tr["default_success"] and tr["default_solver"] == "sqp"
    assert abs(tr["default_objective"] - tr["objective"]) <= 1e-6 * abs(tr["objective"])
    assert tr["default_speedup_vs_reference"] == tr["hand_baseline_solve_ms_median"] / tr["default_solve_ms_median"]
    # --quick: the default planner on effort and time against the naive script with each objective, same optima
    rows = {r["objective"]: r for r in tr["objectives"]}
    assert set(rows) == {"effort", "time"}
    for r in rows.values():
        assert r["success"] and r["baseline_success"] and r["baseline"] == "hand"
        assert r["cost_rel_diff"] < 1e-6 and r["speedup"] == r["baseline_solve_ms_median"] / r["solve_ms_median"]
    assert rows["effort"]["solver"] == "sqp" and rows["time"]["solver"] == "sqp"
    # --quick: the planner's effort and time stages on one pole, from its minimum-time plan, by the SQP and the
    # naive script
    effort, time_ = tr["planner_stage"]
    assert (effort["objective"], time_["objective"]) == ("effort", "time")
    for stage in (effort, time_):
        assert stage["model"] == "1 pole" and stage["success"] and stage["baseline_success"]
        assert stage["solver"] == "sqp" and stage["cost_rel_diff"] < 1e-6
        assert stage["speedup"] == stage["baseline_solve_ms_median"] / stage["solve_ms_median"]
    assert effort["T"] == (1.0 + 0.2) * effort["T_min"] and time_["T"] == time_["T_min"]
    # box-DDP on the exact discrete step of the same problem: it converges, inside the ctrl box
    assert tr["ddp_success"] and tr["ddp_steps"] == round(tr["T"] / tr["ddp_dt"])
    assert tr["ddp_speedup_vs_reference"] == tr["hand_baseline_solve_ms_median"] / tr["ddp_solve_ms_median"]
    for key in ("steps_per_s", "rollouts", "seconds_each"):
        assert key in rp, key
    assert rp["steps_per_s"] > 0 and rp["seconds_each"] == 2.0
    # --quick: the plan row for one pole, planned, run in MuJoCo and replayed
    (plan,) = doc["plan"]
    assert plan["model"] == "1 pole" and plan["success"] and plan["replays"] and plan["plan_s_median"] > 0
    assert plan["time_to_upright"] is not None and plan["time_to_upright"] <= plan["T"] + 3.0
    # --quick: the identification fit on the one-pole cart, IPOPT on the same problem beside it, both on the truth
    (row,) = doc["identify"]["rows"]
    assert row["model"] == "cartpole" and row["fit_s"] > 0 and row["max_rel_error"] < 0.01
    assert row["ipopt_status"] == "Solve_Succeeded" and row["ipopt_max_rel_error"] < 0.01
    assert row["speedup"] == row["ipopt_s"] / row["fit_s"]
    # the export row: the exported LQR + KF step, timed in C on the loop's measurements, beside the Python path
    ex = doc["export"]["lqr_kf"]
    assert ex["replayed_same_ctrl"] and ex["c_step_us_median"] > 0 and ex["python_step_us_median"] > 0
    assert captured.err == ""  # --json: no progress at all


def test_bench_prose_prints_a_table_and_one_stderr_line_per_measurement(capsys):
    assert main(["bench", "--quick", "--no-replay", "--no-plan", "--no-mpc", "--repeats", "1"]) == 0
    captured = capsys.readouterr()
    out = captured.out
    assert "baseline: casadi.Opti" in out and "TVLQR synthesis" in out and "Batched replay" not in out
    assert "ours, SQP on the stage QP" in out
    # stderr is not a terminal here: one finished line per measurement, no carriage returns, nothing on stdout
    lines = captured.err.splitlines()
    assert "\r" not in captured.err and len(lines) >= 5
    assert all(line.startswith("bench: ") and line.endswith(" s") and " in " in line for line in lines)
    assert any(line.startswith("bench: baseline (Opti, no expand): 1 solves in ") for line in lines)
    assert "bench: " not in out


def test_bench_writes_no_files_so_out_is_hidden_and_refused(tmp_path, capsys):
    assert main(["bench", "--quick", "--out", str(tmp_path / "somewhere")]) == 2
    err = capsys.readouterr().err
    assert err == "cartpole bench: --out was removed from bench: bench writes no files; drop the option.\n"
    assert list(tmp_path.iterdir()) == []
    assert main(["bench", "--help"]) == 0
    assert "--out" not in capsys.readouterr().out


def test_bad_repeats_is_one_sentence_and_exit_2(capsys):
    assert main(["bench", "--json", "--repeats", "0"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "repeats" in captured.err


def test_bench_json_has_an_mpc_row_beside_its_ipopt_baseline(capsys):
    """With NMPC installed, `--quick` measures it in the MuJoCo loop beside IPOPT re-solving the same NLP."""
    import pytest

    pytest.importorskip("cartpole.apps.bench.mpc")
    assert main(["bench", "--json", "--quick", "--no-replay", "--no-plan", "--repeats", "1"]) == 0
    mpc = json.loads(capsys.readouterr().out)["mpc"]
    assert mpc["solve_ms_median"] > 0 and mpc["solve_ms_max"] >= mpc["solve_ms_median"]
    assert mpc["baseline"]["solve_ms_median"] > 0
    assert mpc["speedup_median"] == pytest.approx(mpc["baseline"]["solve_ms_median"] / mpc["solve_ms_median"])
    if mpc["implementation"] == "c":  # the exported program's step as the loop calls it: its own time, Python's around
        over = mpc["overhead"]
        assert mpc["in_loop_program"] and 0 < mpc["qp_iterations_median"] <= mpc["qp_iterations_max"]
        assert 0 < over["c_us_median"] <= over["call_us_median"] and over["python_us_median"] > 0
    assert mpc["met"]["p99_ms"] == (mpc["solve_ms_p99"] < mpc["targets"]["p99_ms"]) and len(mpc["load_average"]) == 2
    for row in mpc["ddp"].values():  # MPC by DDP on one and two poles, in the same loop
        assert row["success"] and 0 < row["solve_ms_median"] <= row["solve_ms_max"] and row["steps"] > 0
    assert set(mpc["ddp"]) == {"one_pole", "two_pole"}


def test_a_duration_outside_its_range_is_one_sentence_and_exit_2(capsys):
    assert main(["bench", "--duration", "0", "--json"]) == 2
    err = capsys.readouterr().err
    assert "--duration 0" in err and err.count("\n") == 1 and "Traceback" not in err
