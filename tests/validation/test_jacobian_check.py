"""The Jacobian-check utilities the notebooks use agree with the exact model and detect a wrong one."""

from cartpole.models import build_model, read_params
from cartpole.validation.jacobians import check_jacobians, random_states


def test_check_jacobians_reports_tiny_errors_for_the_exact_model():
    model = build_model()
    x, u = random_states(model.params, 20, seed=3)
    for discrete in (False, True):
        res = check_jacobians(model, x, u, discrete=discrete)
        assert res.err_A.shape == (20,) and res.worst < 1e-6


def test_check_jacobians_detects_a_model_with_the_wrong_pole():
    p = read_params()
    wrong = build_model(p.scaled_pole(1.1, 1.0))
    x, u = random_states(p, 5, seed=4)
    assert check_jacobians(wrong, x, u).worst > 1e-3
