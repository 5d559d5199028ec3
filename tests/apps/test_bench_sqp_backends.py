"""The QP-solver benchmark of the collocation SQP (cartpole.apps.bench.sqp_backends): it records the problems the
planner hands to the SQP and solves each again with each QP solver."""
from __future__ import annotations

from cartpole.apps.bench.sqp_backends import sqp_backend_benchmark
from cartpole.apps.bench.trajopt import shipped_plan_models
from cartpole.solvers.sqp import QP_SOLVERS


def test_the_one_pole_plans_sqp_problems_are_recorded_and_solved_by_each_qp_solver():
    rows = sqp_backend_benchmark(shipped_plan_models()[:1], backends=QP_SOLVERS, repeats=1)
    stages = [r["stage"] for r in rows]
    assert stages == ["time N=60", "effort N=100"]  # the minimum-time refinement, then the effort stage
    for r in rows:
        assert [res["backend"] for res in r["results"]] == list(QP_SOLVERS)
        riccati = r["results"][0]
        assert riccati["success"] and riccati["solve_ms_median"] > 0 and riccati["iterations"] > 0
    time_daqp = rows[0]["results"][1]
    assert "Riccati QP solver only" in time_daqp["refused"]  # minimum time needs the Riccati solver
    effort_daqp = rows[1]["results"][1]
    assert effort_daqp["qp_counts"]["daqp"] >= effort_daqp["iterations"] - 1
    assert "riccati" not in effort_daqp["qp_counts"]
