"""cartpole.apps.bench.planner_stage: the planner's effort stage, from its minimum-time plan, by the default
planner's solver and by the naive script from the same guess; a model without a minimum-time plan is a row saying
why."""
import pytest

from cartpole.apps.bench import planner_stage
from cartpole.models import SHIPPED_MJCF
from cartpole.ocp.collocation import OCPNotSolved


def test_a_model_without_a_minimum_time_plan_is_skipped_with_its_sentence(monkeypatch, capsys):
    def no_plan(*args, **kwargs):
        raise OCPNotSolved("No swing-up found within T <= 10 s after 4 attempts.")

    monkeypatch.setattr(planner_stage, "minimum_time", no_plan)
    rows = planner_stage.planner_stage_benchmark([("weak", str(SHIPPED_MJCF))], repeats=1)
    assert [r["objective"] for r in rows] == list(planner_stage.STAGE_OBJECTIVES)
    assert all(r["model"] == "weak" and "No swing-up found" in r["skipped"] for r in rows)
    row = rows[0]
    planner_stage.print_planner_stage_table([row])
    assert "not measured: No swing-up found" in capsys.readouterr().out


def test_the_two_pole_stages_are_the_sqps_at_the_scripts_optima():
    rows = planner_stage.planner_stage_benchmark([("2 poles", str(SHIPPED_MJCF.with_name("cartpole_two_pole.xml")))],
                                                 repeats=1)
    by = {r["objective"]: r for r in rows}
    for name in planner_stage.STAGE_OBJECTIVES:
        r = by[name]
        assert r["success"] and r["baseline_success"] and r["solver"] == "sqp" and r["baseline"] == "generic", name
        assert r["N"] == 100, name
        if name.startswith("dmc_"):  # a reward's landscape has several optima: ours at the script's or above it
            assert r["cost"] <= r["baseline_cost"] + 1e-6 * abs(r["baseline_cost"]), name
        else:
            assert r["cost_rel_diff"] < 1e-6, name
    assert by["effort"]["T"] == pytest.approx(1.2 * by["effort"]["T_min"])
    assert by["time"]["T"] == by["time"]["T_min"]
