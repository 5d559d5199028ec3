"""A pushed run (``simulate(push=...)``) replays exactly only with its logged pushes, and saving keeps them."""
import numpy as np
import pytest

from cartpole.control.linear import LinearFeedback
from cartpole.errors import CartPoleError
from cartpole.sim import Rollout, replay, replays_exactly, simulate


@pytest.fixture(scope="module")
def pushed():
    law = LinearFeedback([[-1.0, -20.0, -2.0, -3.0]])
    return simulate(None, law, [0.0, 0.05, 0.0, 0.0], 0.3, push=lambda t: 8.0 if 0.1 <= t < 0.15 else 0.0)


def test_replays_exactly_applies_the_logged_pushes(pushed):
    push = pushed.info["push"]
    assert push.shape == (len(pushed.ctrl),) and np.count_nonzero(push) > 0
    assert replays_exactly(pushed)
    again = replay(None, pushed.x[0], pushed.ctrl, push=push)
    np.testing.assert_array_equal(again.x, pushed.x)
    np.testing.assert_array_equal(again.info["push"], push)
    without = replay(None, pushed.x[0], pushed.ctrl)  # the same ctrl without the pushes is another run
    assert not np.allclose(without.x, pushed.x)
    stripped = Rollout(t=pushed.t, qpos=pushed.qpos, qvel=pushed.qvel, ctrl=pushed.ctrl, mjcf=pushed.mjcf)
    assert not replays_exactly(stripped)


def test_save_and_load_keep_the_push_log(pushed, tmp_path):
    pushed.save(tmp_path / "run.json")
    back = Rollout.load(tmp_path / "run.json")
    np.testing.assert_array_equal(back.info["push"], pushed.info["push"])
    assert replays_exactly(back)


def test_a_push_log_of_the_wrong_length_is_one_sentence(pushed):
    with pytest.raises(CartPoleError, match="one force per step"):
        replay(None, pushed.x[0], pushed.ctrl, push=[1.0, 2.0])
