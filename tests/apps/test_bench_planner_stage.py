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
    (row,) = planner_stage.planner_stage_benchmark([("weak", str(SHIPPED_MJCF))], repeats=1)
    assert row["model"] == "weak" and "No swing-up found" in row["skipped"]
    planner_stage.print_planner_stage_table([row])
    assert "not measured: No swing-up found" in capsys.readouterr().out


def test_the_two_pole_stage_is_the_sqps_at_the_scripts_optimum():
    (row,) = planner_stage.planner_stage_benchmark([("2 poles", str(SHIPPED_MJCF.with_name("cartpole_two_pole.xml")))],
                                                   repeats=1)
    assert row["success"] and row["baseline_success"] and row["solver"] == "sqp" and row["baseline"] == "generic"
    assert row["T"] == pytest.approx(1.2 * row["T_min"]) and row["N"] == 100
    assert row["objective_rel_diff"] < 1e-6
