"""The bench's plan-library rows: cold and warm-started plans from the same starts, the ratio measured, not
asserted (a speed figure, not a test)."""
from cartpole.apps.bench.plan_library import plan_library_benchmark, print_plan_library_table, probe_starts
from cartpole.models import SHIPPED_MJCF, build_model, read_params

import numpy as np


def test_the_rows_plan_both_ways_from_each_probe_and_say_how_often_the_warm_start_held(capsys):
    rows = plan_library_benchmark([("1 pole", str(SHIPPED_MJCF))], angles=1, probes=1)
    (row,) = rows
    assert row["library_plans"] == 1 and row["probes"] == 1
    assert len(row["cold_s"]) == len(row["warm_s"]) == 1 and None not in row["cold_s"] + row["warm_s"]
    assert row["warm_hits"] == 1  # a start 0.15-0.35 rad from the stored one converges from its plan
    assert row["fraction_median"] == row["warm_s"][0] / row["cold_s"][0]
    print_plan_library_table(rows)
    assert "warm/cold" in capsys.readouterr().out


def test_the_probes_are_near_the_stored_starts_and_seeded():
    model = build_model(read_params(SHIPPED_MJCF))
    stored = [np.asarray(model.x_hanging, float)]
    a, b = probe_starts(model, stored, 4, seed=1), probe_starts(model, stored, 4, seed=1)
    assert np.array_equal(a, b)
    moved = np.abs(a[:, model.hinges[0]] - stored[0][model.hinges[0]])
    assert np.all((moved >= 0.15) & (moved <= 0.35))


def test_the_acrobots_probes_are_near_its_plans_knots_every_second_one_mirrored():
    from cartpole.apps.bench.plan_library import knot_probes
    from cartpole.ocp.trajectory import Trajectory
    from cartpole.planning.library import mirrored
    from cartpole.supervise.supervisor import hinge_driven

    model = build_model(read_params("cartpole/assets/dmc_acrobot.xml"))
    assert hinge_driven(model)
    t = np.linspace(0.0, 4.0, 9)
    s = (t / 4.0)[:, None]
    x = np.asarray(model.x_hanging, float) * (1 - s) + np.asarray(model.x_eq, float) * s
    x[:, model.nq:] = 0.7
    tr = Trajectory(t=t, x=x, u=np.zeros((9, model.nu)), xdot=np.zeros_like(x))
    a, b = knot_probes(model, [tr], 2, seed=4), knot_probes(model, [tr], 2, seed=4)
    assert np.array_equal(a, b)
    for i, ref in enumerate([tr.state(4.0 / 3), mirrored(model, tr).state(8.0 / 3)]):
        d = a[i] - ref
        assert np.all(np.abs(d[:model.nq]) <= 0.1) and np.all(np.abs(d[model.nq:]) <= 0.5), (i, d)
