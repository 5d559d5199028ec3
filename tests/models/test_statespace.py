"""CartPoleModel.statespace: python-control systems with the MJCF's names; the toolkit's LQR equals
python-control's on the same matrices."""
import control
import numpy as np
import pytest

from cartpole.riccati import dlqr, default_weights, lqr
from cartpole.models import MJCFError, PeriodError, build_model


@pytest.fixture(scope="module")
def model():
    return build_model()


def test_states_inputs_and_outputs_are_named_after_the_mjcf_joints_and_actuators(model):
    sys = model.statespace()
    joints = [j.name for j in model.params.joints]
    assert sys.state_labels == joints + [f"{j}_vel" for j in joints]
    assert sys.input_labels == [a.name for a in model.params.actuators]
    assert sys.output_labels == sys.state_labels and sys.dt == 0


def test_the_continuous_and_the_held_discrete_system_round_trip_the_models_matrices(model):
    A, B = model.linearize()
    sys = model.statespace()
    assert np.array_equal(sys.A, A) and np.array_equal(sys.B, B)
    T = 2 * model.dt
    Ad, Bd = model.hold(2).linearize()
    sysd = model.statespace(dt=T)
    assert sysd.dt == pytest.approx(T) and np.array_equal(sysd.A, Ad) and np.array_equal(sysd.B, Bd)


def test_measured_outputs_are_the_rows_of_C_with_their_names(model):
    C = np.eye(model.nx)[list(range(model.nq))]
    sys = model.statespace(C=C, outputs=["cart", "angle"])
    assert sys.output_labels == ["cart", "angle"] and np.array_equal(sys.C, C)
    with pytest.raises(MJCFError, match="one per row"):
        model.statespace(C=C, outputs=["cart"])
    with pytest.raises(MJCFError, match="one column per state"):
        model.statespace(C=np.eye(3))
    with pytest.raises(PeriodError):
        model.statespace(dt=0.0071)


@pytest.mark.parametrize("asset", ["cartpole.xml", "cartpole_two_pole.xml", "cartpole_three_pole.xml"])
def test_toolkit_lqr_and_dlqr_equal_python_controls_on_the_same_matrices(asset):
    from cartpole.models import SHIPPED_MJCF

    m = build_model(str(SHIPPED_MJCF.parent / asset))
    Q, R = default_weights(m)
    sys = m.statespace()
    K, S, _ = control.lqr(sys, Q, R)
    assert np.allclose(lqr(sys.A, sys.B, Q, R).K, K, rtol=1e-8, atol=1e-10)
    sysd = m.statespace(dt=2 * m.dt)
    Kd, _, _ = control.dlqr(sysd, Q, R)
    assert np.allclose(dlqr(sysd.A, sysd.B, Q, R).K, Kd, rtol=1e-8, atol=1e-10)
