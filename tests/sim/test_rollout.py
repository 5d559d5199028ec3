"""Rollouts: logged every physics step, replayed exactly, saved whole or not at all."""
import numpy as np
import pytest

from cartpole.control.linear import LinearFeedback
from cartpole.sim import Rollout, replay, replays_exactly, simulate


@pytest.fixture(scope="module")
def run():
    return simulate(None, LinearFeedback([[-1.0, -20.0, -2.0, -3.0]]), [0.0, 0.05, 0.0, 0.0], 0.2)


def test_a_simulated_run_replays_bit_for_bit(run):
    assert run.ctrl.shape == (run.t.size - 1, 1) and run.x.shape == (run.t.size, 4)
    assert replays_exactly(run)
    again = replay(None, run.x[0], run.ctrl)
    np.testing.assert_array_equal(again.x, run.x)


def test_save_and_load_round_trip_without_a_temporary_left(run, tmp_path):
    path = tmp_path / "logs" / "run.json"  # parent directories are created
    run.save(path)
    back = Rollout.load(path)
    for name in ("t", "qpos", "qvel", "ctrl"):
        np.testing.assert_array_equal(getattr(back, name), getattr(run, name))
    assert back.mjcf == run.mjcf
    assert [p.name for p in path.parent.iterdir()] == ["run.json"]


def test_a_failed_save_leaves_the_old_file_untouched(run, tmp_path, monkeypatch):
    path = tmp_path / "run.json"
    path.write_text("old")
    monkeypatch.setattr(Rollout, "to_dict", lambda self: {"t": object()})  # not JSON-serialisable
    with pytest.raises(TypeError):
        run.save(path)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["run.json"]
