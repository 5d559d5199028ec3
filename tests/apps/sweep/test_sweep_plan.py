"""Sweep descriptions and run planning (cartpole.apps.sweep.plan): axes, their checks, the seeded start box, and
every run's inputs drawn before any run."""
import numpy as np
import pytest

from cartpole.apps.sweep import (Axis, SweepError, SweepRuns, axis, check_axes, check_settings, default_half_widths,
                                 plan_runs, swingup_sweep, sweep_starts, total_runs)
from cartpole.models import build_model, read_params


def test_axis_reads_a_fixed_value_a_sample_or_a_grid():
    assert axis("push_time", "0.5") == Axis("push_time", 0.5, 0.5, 1)
    assert axis("push_force", -20, 20) == Axis("push_force", -20.0, 20.0, None) and axis("push_force", -20, 20).random
    g = axis("model_error", 0.8, 1.2, 5)
    assert not g.random and np.allclose(g.values(), [0.8, 0.9, 1.0, 1.1, 1.2])
    for bad in [("a",), (1, 2, 3, 4), (2, 1), (0, 1, 2.5), (0, 1, 0), (np.nan,)]:
        with pytest.raises(SweepError):
            axis("push_force", *bad)


def test_check_settings_refuses_each_bad_setting_in_one_sentence():
    check_settings("energy", 3, 2, 0.1)  # fine: no error
    for args, words in [(("magic", 1, 1, 0.0), "Unknown sweep method"), (("energy", 0, 1, 0.0), "1 to"),
                        (("energy", 1, 0, 0.0), "`workers` must be"), (("energy", 1, 1, 1.5), "gain_jitter"),
                        (("trajopt", 1, 1, 0.1), "use `method='energy'`"), (("energy", 1.5, 1, 0.0), "1 to")]:
        with pytest.raises(SweepError, match=words):
            check_settings(*args)
    with pytest.raises(SweepError, match="half-widths"):
        check_settings("energy", 1, 1, 0.0, half_widths=[0.1, -0.1, 0, 0])


def test_bad_settings_raise_before_any_run():
    for method, runs, kw, words in [("energy", SweepRuns(n=0), {}, "1 to"),
                                    ("energy", SweepRuns(n=2, gain_jitter=1.5), {}, "gain_jitter"),
                                    ("magic", SweepRuns(n=1), {}, "Unknown sweep method"),
                                    ("trajopt", SweepRuns(n=1, gain_jitter=0.1), {}, "use `method='energy'`"),
                                    ("energy", SweepRuns(n=1), {"workers": 0}, "workers")]:
        with pytest.raises(SweepError, match=words):
            swingup_sweep(None, method, runs=runs, on_row=lambda *a: pytest.fail("ran"), **kw)


@pytest.mark.parametrize("axes, words", [
    ([("wind", 1.0)], "Unknown sweep axis"), ([("start:elbow", 1.0)], "No joint 'elbow'"),
    ([("setting:horizon", 1.0)], "no setting 'horizon'"), ([("push_time", 1.0)], "without a push force"),
    ([("model_error", 0.0, 1.0, 3)], "scale in"), ([("push_force", 1.0), ("push_force", 2.0)], "twice"),
])
def test_bad_axes_are_refused_before_any_run(axes, words):
    with pytest.raises(SweepError, match=words):
        swingup_sweep(None, runs=SweepRuns(axes=[axis(name, *v) for name, *v in axes]),
                      on_row=lambda *a: pytest.fail("ran"))


def test_the_start_box_is_seeded_and_kept_inside_the_rail():
    params = read_params()
    model = build_model(params)
    hw = default_half_widths(params)
    runs = plan_runs(params, model.x_hanging, (), 50, 3, center=model.x_hanging, half_widths=hw)
    assert runs.starts.shape == (50, 2 * params.nq) and not runs.starts.flags.writeable
    np.testing.assert_array_equal(runs.starts, plan_runs(params, model.x_hanging, (), 50, 3, center=model.x_hanging,
                                                         half_widths=hw).starts)
    assert np.all(np.abs(runs.starts - model.x_hanging) <= hw)
    # the documented starts: the box drawn first from the same seed (before the rail clip, which these stay inside)
    np.testing.assert_array_equal(runs.starts, sweep_starts(50, seed=3, center=model.x_hanging, half_widths=hw))
    lo, hi = params.cart_range
    wide = plan_runs(params, model.x_hanging, (), 50, 3, center=model.x_hanging, half_widths=hw * [20, 1, 1, 1])
    assert np.all((wide.starts[:, params.slide] >= lo + 1e-3) & (wide.starts[:, params.slide] <= hi - 1e-3))


def test_a_grid_is_the_product_of_its_axes_first_axis_slowest_and_total_runs_counts_it():
    params = read_params()
    x0 = build_model(params).x_hanging
    axes = check_axes([axis("push_force", -10, 10, 3), axis("model_error", 0.9, 1.1, 2), axis("push_time", 0.7)],
                      params, "energy")
    runs = plan_runs(params, x0, axes, 1, 0, center=x0, half_widths=default_half_widths(params))
    assert total_runs(axes, 1) == len(runs.starts) == 6
    assert [p[0][1] if p else 0.0 for p in runs.pushes] == [-10.0, -10.0, 0.0, 0.0, 10.0, 10.0]
    assert all(p[0][0] == 0.7 for p in runs.pushes if p) and runs.pushes[2] == ()  # 0 N is no push
    assert runs.model_errors.tolist() == [0.9, 1.1] * 3
    sampled = (axis("start:hinge", 2.9, 3.4), axis("setting:energy_gain", 12, 18, 2))
    assert total_runs(sampled, 5) == len(plan_runs(params, x0, sampled, 5, 0, center=x0,
                                                   half_widths=default_half_widths(params)).starts) == 10
    assert total_runs((), 7) == 7


def test_the_jitter_is_drawn_after_the_starts_so_the_starts_do_not_depend_on_it():
    params = read_params()
    x0 = build_model(params).x_hanging
    hw = default_half_widths(params)
    plain = plan_runs(params, x0, (), 4, 9, center=x0, half_widths=hw)
    jittered = plan_runs(params, x0, (), 4, 9, center=x0, half_widths=hw, gain_jitter=0.2)
    np.testing.assert_array_equal(plain.starts, jittered.starts)
    assert plain.options == ({},) * 4 and len({o["energy_gain"] for o in jittered.options}) == 4
    assert np.array_equal(jittered.job(2)[0], jittered.starts[2])
    assert jittered.job(2)[1:] == (jittered.options[2], (), 1.0, {})


def test_sweep_runs_are_a_read_only_value_and_the_sweep_keeps_only_changed_settings():
    from cartpole.apps.sweep.run import energy_changes, mpc_changes, sweep_objective
    from cartpole.apps.swingup import SwingupOptions
    from cartpole.mpc.options import MPCOptions
    from cartpole.planning.options import PlanOptions

    runs = SweepRuns(n=3, center=[0, 3.0, 0, 0], axes=[axis("push_force", 1.0)])
    assert isinstance(runs.axes, tuple) and not runs.center.flags.writeable
    with pytest.raises(SweepError, match="SweepRuns.x0 must be numbers"):
        SweepRuns(x0="up")
    assert energy_changes(None) == {} and energy_changes({"energy_gain": 20.0}) == {"energy_gain": 20.0}
    ddp = MPCOptions(solver="ddp", objective="dmc_swingup", horizon=2.0)
    assert mpc_changes(ddp) == {"horizon": 2.0} and mpc_changes(None) == {}
    assert sweep_objective("mpc", SwingupOptions(mpc=ddp)) == "dmc_swingup"
    assert sweep_objective("trajopt", SwingupOptions(plan=PlanOptions(objective="time"))) == "time"
