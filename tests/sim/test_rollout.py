"""Rollouts: logged every physics step, replayed exactly, saved whole or not at all."""
import numpy as np
import pytest

from cartpole.control.linear import LinearFeedback
from cartpole.sim import Rollout, SimOptions, replay, replays_exactly, simulate


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


def test_two_motor_rollout_logs_every_actuator_and_replays(chain_dir, tmp_path):
    path = chain_dir / "two_motors.xml"
    law = lambda t, x: np.array([0.3 * np.sin(10 * t), -2.0])  # noqa: E731  (the second is clipped to 0.5)
    r = simulate(path, law, np.zeros(6), 0.1)
    n = r.t.size - 1
    assert r.qpos.shape == (n + 1, 3) and r.qvel.shape == (n + 1, 3) and r.ctrl.shape == (n, 2)
    assert (r.nq, r.nu) == (3, 2) and np.all(r.ctrl[:, 1] == -0.5)
    assert replays_exactly(r)
    np.testing.assert_array_equal(replay(path, r.x[0], r.ctrl).x, r.x)
    r.save(tmp_path / "two.json")
    back = Rollout.load(tmp_path / "two.json")
    np.testing.assert_array_equal(back.ctrl, r.ctrl)
    assert replays_exactly(back)


def test_bad_starts_controllers_and_logs_are_one_sentence(chain_dir):
    from cartpole import CartPoleError, read_params

    path = chain_dir / "two_motors.xml"
    with pytest.raises(CartPoleError, match="has 4 entries; give 6: the positions of slider, hinge, hinge2, then"):
        simulate(path, lambda t, x: np.zeros(2), np.zeros(4), 0.1)
    with pytest.raises(CartPoleError, match="it must return 2 finite ctrl values"):
        simulate(path, lambda t, x: 0.0, np.zeros(6), 0.1)
    with pytest.raises(CartPoleError, match=r"give \(n, 2\)"):
        replay(path, np.zeros(6), np.zeros(10))
    params = read_params(xml=path.read_text())  # built from text: the rollout cannot name its file
    r = simulate(params, lambda t, x: np.zeros(2), np.zeros(6), 0.02)
    with pytest.raises(CartPoleError, match="pass the CartPoleParams"):
        replays_exactly(r)
    assert replays_exactly(r, params)


def test_sim_options_hold_the_ctrl_and_their_hooks_end_the_run():
    seen, steps = [], []
    held = simulate(None, lambda t, x: np.array([np.sin(50 * t)]), np.zeros(4), 0.2,
                    options=SimOptions(control_period=0.02, progress=seen.append,
                                       on_step=lambda m, d: steps.append(d.time)))
    per = int(round(0.02 / held.dt))
    assert per > 1 and np.all(held.ctrl[:per] == held.ctrl[0]) and held.ctrl[per] != held.ctrl[0]
    assert seen and seen[-1] == pytest.approx(1.0) and len(steps) == held.t.size  # the start state too
    short = simulate(None, lambda t, x: 0.0, np.zeros(4), 0.2, options=SimOptions(stop=lambda t, x: t >= 0.05))
    assert short.t[-1] == pytest.approx(0.05) and replays_exactly(short)


@pytest.mark.parametrize("bad, match", [
    (dict(control_period=0.0), r"SimOptions.control_period = 0.0 must be a finite number > 0 s"),
    (dict(control_period="fast"), "SimOptions.control_period must be a number"),
    (dict(stop=True), "SimOptions.stop must be a callable or None"),
])
def test_bad_sim_options_are_one_sentence(bad, match):
    from cartpole import CartPoleError

    with pytest.raises(CartPoleError, match=match):
        SimOptions(**bad)


def test_simulate_refuses_options_that_are_not_sim_options():
    from cartpole import CartPoleError

    with pytest.raises(CartPoleError, match="simulate's options must be a SimOptions"):
        simulate(None, lambda t, x: 0.0, np.zeros(4), 0.01, options={"control_period": 0.02})
