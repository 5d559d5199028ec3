"""The options values every stage shares (StageOptions) and the closed loop's own (LoopOptions)."""
import json

import numpy as np
import pytest

from cartpole.errors import CartPoleError
from cartpole.options import json_ready
from cartpole.sim.options import PUSH_SECONDS, LoopError, LoopOptions


def test_loop_options_normalise_pushes_and_scales_and_echo_as_json():
    loop = LoopOptions(duration=3, push=[(2, -5), (1.0, 20)], model_error=np.float64(1.2))
    assert loop.push == ((1.0, 20.0), (2.0, -5.0)) and loop.duration == 3.0 and type(loop.model_error) is float
    doc = loop.as_dict()
    assert doc == {"duration": 3.0, "period": None, "push": [[1.0, 20.0], [2.0, -5.0]], "model_error": 1.2,
                   "delay": 0.0, "estimator": None, "encoder_cpr": None, "encoder_resolution": None,
                   "sensor_noise": None, "process_noise": None, "mhe_horizon": None, "seed": 0,
                   "delay_compensation": True, "friction_compensation": True, "knockdown": None, "throw": None}
    assert json.loads(json.dumps(doc)) == doc
    knocked = LoopOptions(knockdown="3:0.2:7").as_dict()["knockdown"]
    assert knocked == {"after": 3.0, "length": 0.2, "seed": 7, "strength": 1.0, "energy": 1.0}


@pytest.mark.parametrize("changes, words", [
    (dict(duration=0.0), "LoopOptions.duration = 0.0 must be a finite number > 0 s; give e.g. `duration=8`"),
    (dict(period=-0.02), "period = -0.02 must be a finite number > 0 s"),
    (dict(duration="long"), "LoopOptions.duration must be a number; got 'long'"), (dict(push=[(1.0, np.nan)]), "finite force"),
    (dict(push=[(1.0,)]), "pair"), (dict(model_error=11.0), "scale in \\[0.1, 10\\]"),
    (dict(durations=1.0), "LoopOptions has no field 'durations'; the fields are duration, period, push, model_error"),
    (dict(delay=-0.01), "delay = -0.01 must be a finite number >= 0"), (dict(encoder_cpr=0.5), "whole number"),
    (dict(sensor_noise=np.inf), "sensor_noise"), (dict(estimator="ukf"), "not one of none, kf, ekf, mhe"),
])
def test_bad_loop_settings_are_one_sentence_of_the_loops_error(changes, words):
    with pytest.raises(LoopError, match=words) as err:
        LoopOptions().replace(**changes)
    assert isinstance(err.value, CartPoleError) and isinstance(err.value, ValueError)
    msg = str(err.value)
    assert "\n" not in msg and msg.endswith(".")


def test_options_are_frozen_values_varied_by_field_name():
    loop = LoopOptions(duration=2.0)
    with pytest.raises(AttributeError):
        loop.duration = 3.0
    assert loop.replace() is loop
    for name in LoopOptions.scalar_names():
        v = 3 if name in ("encoder_cpr", "seed") else 0.5  # counts and seeds are whole numbers
        assert getattr(loop.replace(**{name: v}), name) == v
    assert LoopOptions.names()[:4] == ("duration", "period", "push", "model_error")
    assert set(LoopOptions.names()) >= {"delay", "estimator", "encoder_cpr", "encoder_resolution", "sensor_noise"}
    assert loop == LoopOptions(duration=2.0) and hash(loop) == hash(LoopOptions(duration=2.0))
    assert loop != loop.replace(duration=2.5) and len({loop, LoopOptions(duration=2.0)}) == 1


def test_push_force_acts_for_push_seconds_on_whole_physics_steps():
    h = 0.005
    force = LoopOptions(push=[(1.0, 20.0), (1.05, 5.0)]).push_force(h)
    steps = np.arange(0, 400) * h
    f = np.array([force(t) for t in steps])
    k = int(round(1.0 / h))
    n = int(round(PUSH_SECONDS / h))
    assert np.count_nonzero(f) == n + int(round(0.05 / h))
    assert f[k] == 20.0 and f[k + n - 1] == 25.0 and f[k + n] == 5.0 and f[k - 1] == 0.0
    assert LoopOptions().push_force(h) is None


def test_json_ready_turns_arrays_functions_and_mappings_into_plain_json():
    def cost(x, u):
        return x

    doc = json_ready({"a": np.eye(2), "f": cost, "n": np.int64(3), "t": (1, 2.5), "m": {"k": np.float32(0.5)}})
    assert doc == {"a": [[1.0, 0.0], [0.0, 1.0]], "f": f"{__name__}:{cost.__qualname__}", "n": 3, "t": [1, 2.5],
                   "m": {"k": 0.5}}
    assert json.loads(json.dumps(doc)) == doc
