"""Identify, then design on the fitted model and run on the "rig": with the pole 30 % heavier than nominal, the
trajopt + TVLQR swing-up designed on the nominal MJCF fails on the rig, designed on the fitted MJCF it swings up,
holds and replays exactly; the LQR designed on the fitted file settles as the one designed on the rig's own."""
import json

import numpy as np
import pytest

from cartpole.apps.excite import ExciteOptions, run_excite
from cartpole.apps.identify import run_identify
from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF
from cartpole.sim.rollout import Rollout, replays_exactly

RIG = SHIPPED_MJCF.parent / "examples" / "cartpole_rig_truth.xml"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("identify_app")
    a = run_excite(RIG, tmp, ExciteOptions(duration=10, encoder_cpr=2048, encoder_resolution=1e-4), csv_name="a.csv")
    b = run_excite(RIG, tmp, ExciteOptions(duration=6, encoder_cpr=2048, encoder_resolution=1e-4, seed=1),
                   csv_name="b.csv")
    res = run_identify(None, [a.csv], tmp, holdout=[b.csv])
    return tmp, res


def test_identify_result_is_checked_on_the_holdout_and_written(fitted):
    _, res = fitted
    for joint in ("slider", "hinge"):
        assert res.holdout_rms["fitted"][joint] * 20 < res.holdout_rms["nominal"][joint]
    assert res.mjcf.exists() and res.figure.exists()
    doc = res.to_dict()
    assert set(doc["parameters"]) == set(res.fit.names) and len(doc["correlation"]) == len(res.fit.names)


def _swingup(capsys, tmp, plan):
    out = tmp / f"sw_{plan.stem}"
    assert main(["swingup", "--method", "trajopt", "--mjcf", str(RIG), "--plan-mjcf", str(plan), "--no-video",
                 "--out", str(out), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_swingup_designed_on_the_fitted_mjcf_succeeds_where_the_nominal_design_fails(fitted, capsys):
    tmp, res = fitted
    nominal = _swingup(capsys, tmp, SHIPPED_MJCF)
    fit = _swingup(capsys, tmp, res.mjcf)
    assert nominal["plan_mjcf"] == str(SHIPPED_MJCF) and not nominal["success"]
    assert fit["plan_mjcf"] == str(res.mjcf) and fit["success"]
    r = fit["rollout"]
    roll = Rollout(t=r["t"], qpos=r["qpos"], qvel=r["qvel"], ctrl=r["ctrl"], mjcf=str(RIG))
    assert replays_exactly(roll)


def test_lqr_designed_on_the_fitted_file_settles_like_the_rigs_own_design(fitted, capsys, tmp_path):
    _, res = fitted
    docs = []
    for extra in ([], ["--plan-mjcf", str(res.mjcf)]):
        assert main(["lqr", "--mjcf", str(RIG), "--no-video", "--out", str(tmp_path), "--json", *extra]) == 0
        docs.append(json.loads(capsys.readouterr().out))
    own, fit = docs
    assert all(fit["settled"])
    np.testing.assert_allclose(fit["K"], own["K"], rtol=0.02)
    np.testing.assert_allclose(fit["settling_times"], own["settling_times"], atol=0.03)


def test_plan_mjcf_of_another_machine_is_one_sentence(tmp_path, capsys):
    two = SHIPPED_MJCF.parent / "cartpole_two_pole.xml"
    assert main(["swingup", "--mjcf", str(RIG), "--plan-mjcf", str(two), "--out", str(tmp_path), "--no-video"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not the same machine" in err[0]
    assert main(["swingup", "--plan-mjcf", str(RIG), "--model-error", "1.2", "--out", str(tmp_path)]) == 2
    assert "give one of them" in capsys.readouterr().err


def test_feedforward_plans_on_the_plan_mjcf_and_tracks_on_the_rig(fitted, capsys, tmp_path):
    _, res = fitted
    assert main(["feedforward", "--mjcf", str(RIG), "--plan-mjcf", str(res.mjcf), "--no-video", "--out",
                 str(tmp_path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["plan_mjcf"] == str(res.mjcf) and doc["runs"]["feedforward_tvlqr"]["success"]
    assert doc["runs"]["feedforward_tvlqr"]["replays_exactly"]
