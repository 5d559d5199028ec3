"""One plant argument: a path, the parameters or the model resolve alike (cartpole.models.plant_model/plant_params),
and anything else is one sentence naming the argument."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.errors import CartPoleError
from cartpole.models import PlantError, is_plant, plant_model, plant_params


def test_a_path_params_and_model_resolve_to_the_same_plant():
    model = cp.build_model()
    assert plant_model(model) is model
    assert plant_params(model) is model.params and plant_params(model.params) is model.params
    for plant in (None, cp.SHIPPED_MJCF, str(cp.SHIPPED_MJCF), model.params):
        assert plant_params(plant).mjcf == model.params.mjcf
    np.testing.assert_array_equal(plant_model(model.params).x_eq, model.x_eq)
    assert all(is_plant(p) for p in (None, cp.SHIPPED_MJCF, "x.xml", model, model.params))


def test_anything_else_is_a_plant_error_naming_the_argument():
    assert not is_plant(3.0)
    with pytest.raises(PlantError, match="plant is a float; give an MJCF or URDF path") as err:
        plant_params(3.0)
    assert isinstance(err.value, CartPoleError) and isinstance(err.value, TypeError)
    with pytest.raises(PlantError):
        plant_model([1, 2])


def test_simulate_and_replay_accept_the_model_as_they_accept_its_path():
    model = cp.build_model()
    catch = cp.LinearFeedback.for_model(model)
    x0 = np.array(model.x_eq) + np.array([0.0, 0.05, 0.0, 0.0])
    by_model = cp.simulate(model, catch, x0, 0.2)
    by_path = cp.simulate(model.params.mjcf, catch, x0, 0.2)
    np.testing.assert_array_equal(by_model.qpos, by_path.qpos)
    assert by_model.mjcf == by_path.mjcf
    again = cp.replay(model, x0, by_model.ctrl)
    np.testing.assert_array_equal(again.qpos, by_model.qpos)
