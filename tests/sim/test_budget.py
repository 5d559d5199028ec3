"""The work estimate and budget of cartpole.sim.budget (issue 38): steps counted per part, refused beyond the budget
in one sentence naming the option, and a numerically singular model refused naming its physics."""
import pytest

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.sim.budget import (BATCHED, DEFAULT_MAX_STEPS, MAX_CONDITION, BudgetError, IllConditionedError, check_conditioning,
                                 check_work, conditioning, estimate_work, physics_steps)


def test_physics_steps_count_every_run_at_the_time_step():
    assert physics_steps(6.0, 0.005, 5) == 6000
    assert physics_steps(6.0, 5e-5, 5) == 600_000
    assert physics_steps(0.0, 0.005, 5) == 0 and physics_steps(1.0, 0.005, 0) == 0
    work = estimate_work([(5, 6.0, "lab runs"), (1, 10.0, "video"), (1, 0.0, "nothing")], 0.005)
    assert work.steps == work.cost == 8000 and [p[1] for p in work.parts] == [6000, 2000, 0]
    assert "8e+03 MuJoCo steps" in work.describe() and "nothing" not in work.describe()
    # batched runs (a catch basin's samples) count a tenth against the budget, all of them in the steps
    batched = estimate_work([(1, 10.0, "run"), (300, 4.0, "basin", BATCHED)], 0.005)
    assert batched.steps == 2000 + 240_000 and batched.cost == pytest.approx(2000 + 24_000)
    assert check_work(batched, max_steps=30_000) is batched
    with pytest.raises(BudgetError, match="batched count a tenth"):
        check_work(batched, max_steps=20_000)


def test_work_beyond_the_budget_is_one_sentence_naming_the_option_and_a_figure_that_passes():
    work = estimate_work([(5, 100.0, "lab runs")], 5e-5)
    assert check_work(work, max_steps=work.steps) is work
    with pytest.raises(BudgetError) as info:
        check_work(work, option="--max-steps")
    text = str(info.value)
    assert text.count(".") >= 1 and text.endswith(".") and f"{DEFAULT_MAX_STEPS:.2g}" in text
    raised = float(text.split("--max-steps ")[1].split()[0])
    assert raised >= work.steps and check_work(work, max_steps=raised) is work
    with pytest.raises(BudgetError, match="give max_steps "):  # the library names its argument
        check_work(work)


def test_shipped_assets_are_well_conditioned():
    for name in ("cartpole.xml", "cartpole_two_pole.xml", "cartpole_three_pole.xml", "dmc_acrobot.xml"):
        c = check_conditioning(build_model(SHIPPED_MJCF.with_name(name)))
        assert c["condition"] < MAX_CONDITION / 1e4


def test_a_billionth_kilogram_pole_is_numerically_singular(tmp_path):
    text = SHIPPED_MJCF.read_text()
    path = tmp_path / "tiny.xml"
    path.write_text(text.replace('mass="0.1"', 'mass="1e-9"'))
    model = build_model(path)
    c = conditioning(model)
    assert c["condition"] > MAX_CONDITION and c["lightest"] == "pole" and c["heaviest"] == "cart"
    assert c["mass_ratio"] == pytest.approx(1e-9)
    with pytest.raises(IllConditionedError) as info:
        check_conditioning(model)
    text = str(info.value)
    assert "'pole', 1e-09 kg, is 1e-09 of body 'cart'" in text and "numerically singular" in text
    assert len(text) < 240 and text.endswith(".")
