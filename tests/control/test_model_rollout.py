"""model_rollout: a controller on the symbolic model's exact discrete step is the MuJoCo run of that controller."""
import numpy as np

from cartpole.control import LinearFeedback, model_rollout
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.sim import simulate


def test_model_rollout_of_an_lqr_is_mujocos_run_on_the_two_pole_cart():
    params = read_params(SHIPPED_MJCF.with_name("cartpole_two_pole.xml"))
    model = build_model(params)
    ctrl = LinearFeedback.for_model(model)
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += 0.05
    steps = 400
    x, u = model_rollout(model, ctrl, x0, steps)
    run = simulate(params, ctrl, x0, steps * params.timestep)
    assert x.shape == (steps + 1, model.nx) and u.shape == (steps, model.nu)
    np.testing.assert_allclose(u, run.ctrl[:steps], atol=1e-9)
    np.testing.assert_allclose(x, run.x[:steps + 1], atol=1e-9)


def test_model_rollout_clips_to_the_limits_and_starts_at_t0():
    model = build_model(read_params(SHIPPED_MJCF))
    seen = []

    def bang(t, x):
        seen.append(t)
        return np.full(model.nu, 5.0)

    x, u = model_rollout(model, bang, model.x_hanging, 3, u_limits=[[-0.5, 0.25]], t0=1.0)
    assert np.all(u == 0.25)
    np.testing.assert_allclose(seen, 1.0 + model.dt * np.arange(3))
    np.testing.assert_array_equal(x[1], model.step_np(x[0], u[0]))
