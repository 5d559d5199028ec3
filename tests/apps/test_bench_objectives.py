"""cartpole.apps.bench.objectives: on each objective the default planner's solver and the naive Opti script with
that objective written into it solve the same problem (same optimum), and the rows say whose plan it was."""
import pytest

from cartpole.apps.bench.objectives import objective_benchmark


@pytest.fixture(scope="module")
def rows():
    return {r["objective"]: r for r in objective_benchmark(N=100, repeats=1,
                                                             objectives=("effort", "tracking", "dmc_swingup",
                                                                         "time"))}


@pytest.mark.parametrize("name", ["effort", "tracking", "dmc_swingup", "time"])
def test_ours_and_the_naive_script_reach_the_same_optimum_on_every_objective(rows, name):
    r = rows[name]
    assert r["success"] and r["baseline_success"] and r["baseline"] == "hand"
    assert r["cost_rel_diff"] < 1e-6
    assert r["speedup"] == r["baseline_solve_ms_median"] / r["solve_ms_median"]


def test_every_objective_is_the_sqps(rows):
    """The default's SQP converges on each (time by its time scale): no row is IPOPT's fallback."""
    assert all(rows[n]["solver"] == "sqp" for n in ("effort", "tracking", "dmc_swingup", "time"))


def test_the_time_row_minimises_the_duration_it_reports(rows):
    r = rows["time"]
    assert 0.5 < r["cost"] < 2.0  # T + 1e-3 effort, T well below the guess's 2 s


def test_an_objective_the_model_cannot_have_is_skipped_with_its_sentence(capsys):
    from cartpole.apps.bench.objectives import print_objective_table
    from cartpole.models import SHIPPED_MJCF

    rows = objective_benchmark(SHIPPED_MJCF.with_name("dmc_pendulum.xml"), N=20, repeats=1,
                               objectives=("dmc_cartpole_swingup", "effort"))
    skipped, effort = rows
    assert skipped["objective"] == "dmc_cartpole_swingup" and "needs a cart" in skipped["skipped"]
    # the rest is measured (the 1 N m pendulum cannot swing up in 2 s: neither converges, no ratio is claimed)
    assert effort["objective"] == "effort" and effort["baseline"] == "generic" and effort["solve_ms_median"] > 0
    assert effort["speedup"] is None or (effort["success"] and effort["baseline_success"])
    print_objective_table(rows)
    assert "not measured: " in capsys.readouterr().out


def test_without_a_c_compiler_the_time_row_is_ipopts(monkeypatch):
    """The SQP's minimum time needs its compiled Riccati solver: without a compiler the row is IPOPT's, as the
    planner's would be, and says so."""
    monkeypatch.setenv("CARTPOLE_NO_COMPILE", "1")
    (row,) = objective_benchmark(N=30, repeats=1, objectives=("time",))
    assert row["success"] and row["solver"] == "ipopt" and row["cost_rel_diff"] < 1e-6
