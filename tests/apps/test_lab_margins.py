"""cartpole.apps.margins: the lab's designs on a rig, and the refusal of designs without a linear loop."""
import pytest

from cartpole.analysis import AnalysisError
from cartpole.apps.margins import lab_margins, refuse_nonlinear
from cartpole.errors import CartPoleError
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions


@pytest.mark.parametrize("design", ["energy", "mpc", "ekf", "mhe"])
def test_a_design_without_a_linear_loop_is_refused_in_one_sentence_naming_why(design):
    with pytest.raises(AnalysisError) as err:
        refuse_nonlinear(design)
    text = str(err.value)
    assert isinstance(err.value, CartPoleError) and text.endswith(".") and text.count(". ") == 0
    assert "linear loop" in text and "`lab_margins`" in text and "`pid=True`" in text and "--" not in text


def test_the_rig_decides_which_loops_are_read():
    model = build_model()
    perfect = lab_margins(model)
    assert set(perfect.loops) == {"lqr", "lqr_continuous"} and perfect.steps == 1 and perfect.delay_steps == 0
    rig = lab_margins(model, loop=LoopOptions(period=0.01, delay=0.005, estimator="kf", encoder_cpr=2048), pid=True)
    assert set(rig.loops) == {"lqr", "lqg", "pid"} and rig.steps == 2 and rig.delay_steps == 1
    assert all(m.period == pytest.approx(0.01) for m in rig.margins.values())
    with pytest.raises(AnalysisError, match="EKF"):
        lab_margins(model, loop=LoopOptions(estimator="ekf", encoder_cpr=2048))
