"""The excitation: around the hanging natural frequency, inside the rail and the ctrl range, logged through the
rig's encoders in the --log format, replaying exactly."""
import numpy as np
import pytest

from cartpole.apps.excite import ExciteOptions, run_excite
from cartpole.identify.excite import ExciteError, multisine, natural_frequencies
from cartpole.identify.logs import read_log
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.sim.rollout import replays_exactly


def test_natural_frequency_is_the_small_oscillation_pendulums():
    model = build_model()
    p = model.params
    # hinge held still by a heavy cart: sqrt(m g l / J) of the pole about its hinge, the cart free lowers it
    w = natural_frequencies(model)
    fixed = np.sqrt(p.pole_mass * p.g * p.pole_com_distance / p.pole_inertia_about_hinge)
    assert w.shape == (1,) and fixed < w[0] < 1.2 * fixed


def test_excite_stays_inside_rail_and_ctrl_and_its_log_reads_back(tmp_path):
    res = run_excite(None, tmp_path, ExciteOptions(duration=6, encoder_cpr=1024, encoder_resolution=1e-3, seed=2))
    p = read_params(SHIPPED_MJCF)
    assert np.all(np.abs(res.rollout.qpos[:, 0]) < 0.9 * 1.5)
    assert np.all(np.abs(res.excitation.ctrl) <= 1)
    log = read_log(res.csv, p)
    q = 2 * np.pi / 1024
    np.testing.assert_allclose(log.qpos[:, 1] / q, np.round(log.qpos[:, 1] / q), atol=1e-6)  # quantised
    assert np.max(np.abs(log.qpos[:, 1] - res.rollout.qpos[:, 1])) <= q / 2 + 1e-12
    assert np.ptp(log.qpos[:, 1]) > 0.2  # the pole swings
    assert replays_exactly(res.rollout)


def test_dry_run_writes_the_ctrl_only(tmp_path):
    res = run_excite(None, tmp_path, ExciteOptions(duration=4, sample_time=0.01), dry_run=True)
    lines = res.csv.read_text().splitlines()
    assert lines[0] == "t,slider,hinge,motor" and len(lines) == 402
    assert lines[5].split(",")[1:3] == ["", ""] and res.rollout is None
    assert not (tmp_path / "excite_rollout.json").exists()


@pytest.mark.parametrize("kw, words", [({"duration": 1}, "too short"), ({"sample_time": 0.007}, "whole number"),
                                       ({"amplitude": 2}, "not in")])
def test_bad_excitation_is_one_sentence(kw, words):
    args = {"duration": 5, "sample_time": 0.005, **kw}
    with pytest.raises(ExciteError, match=words):
        multisine(build_model(), args["duration"], args["sample_time"], amplitude=kw.get("amplitude"))


def test_balance_mode_holds_the_pole_logs_the_applied_ctrl_and_identifies(tmp_path):
    from cartpole.identify.fit import fit
    from cartpole.identify.parameters import parse_parameters

    truth = tmp_path / "truth.xml"
    truth.write_text(SHIPPED_MJCF.read_text().replace('gear="20"', 'gear="23"'))
    res = run_excite(truth, tmp_path, ExciteOptions(duration=8, mode="balance", encoder_cpr=2048,
                                                   encoder_resolution=1e-4))
    assert replays_exactly(res.rollout)
    assert np.max(np.abs(res.rollout.qpos[:, 1])) < 0.6
    np.testing.assert_array_equal(res.log.ctrl[:-1, 0], res.rollout.ctrl[:, 0])
    p = read_params(SHIPPED_MJCF)
    out = fit(p, parse_parameters(p, ["gear:motor", "damping:slider", "damping:hinge"]), [res.log])
    assert out.fitted[0] == pytest.approx(23, rel=0.01)


def test_balance_dry_run_is_refused(tmp_path):
    from cartpole.errors import CartPoleError

    with pytest.raises(CartPoleError, match="cannot be written ahead"):
        run_excite(None, tmp_path, ExciteOptions(duration=4, mode="balance"), dry_run=True)


def test_an_unknown_mode_and_options_of_another_kind_are_one_sentence(tmp_path):
    with pytest.raises(ExciteError, match="Unknown excitation mode 'spin'; choose one of hanging, balance"):
        ExciteOptions(mode="spin")
    with pytest.raises(ExciteError, match="run_excite's options must be an ExciteOptions"):
        run_excite(None, tmp_path, {"duration": 4})
    assert list(tmp_path.iterdir()) == []
