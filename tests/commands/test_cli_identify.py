"""`cartpole excite` and `cartpole identify`: the JSON contract, the fitted MJCF used by `cartpole lqr`, and bad
input as one sentence, exit 2, no files."""
import json

import pytest

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cli_identify")
    truth = tmp / "truth.xml"
    truth.write_text(SHIPPED_MJCF.read_text().replace('gear="20"', 'gear="23"').replace('damping="0.01"',
                                                                                        'damping="0.014"'))
    return tmp, truth


def _json(capsys, argv):
    assert main(argv) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


def test_excite_then_identify_follow_the_contract_and_lqr_runs_on_the_fitted_file(run, capsys):
    tmp, truth = run
    common = ["--mjcf", str(truth), "--out", str(tmp), "--encoder-cpr", "2048", "--json"]
    a = _json(capsys, ["excite", *common, "--duration", "8", "--csv", "a.csv"])
    b = _json(capsys, ["excite", *common, "--duration", "6", "--csv", "b.csv", "--noise-seed", "1"])
    assert set(a["excite"]) >= {"csv", "rollout", "duration", "sample_time", "amplitude", "frequencies"}
    out = tmp / "fit"
    doc = _json(capsys, ["identify", "--json", "--log", a["excite"]["csv"], "--holdout", b["excite"]["csv"],
                         "--fit", "gear:motor", "damping:hinge", "--out", str(out)])
    ident = doc["identify"]
    assert set(ident) >= {"parameters", "correlation", "fit_rms", "holdout_rms", "mjcf", "figure", "solve_s"}
    assert set(ident["parameters"]) == {"gear:motor", "damping:hinge"}
    assert set(ident["parameters"]["gear:motor"]) == {"nominal", "fitted", "std"}
    assert ident["parameters"]["gear:motor"]["fitted"] == pytest.approx(23, rel=0.01)
    assert ident["parameters"]["damping:hinge"]["fitted"] == pytest.approx(0.014, rel=0.05)
    for k in ("fitted", "nominal"):
        assert set(ident["holdout_rms"][k]) == {"slider", "hinge"}
    assert ident["holdout_rms"]["fitted"]["hinge"] * 5 < ident["holdout_rms"]["nominal"]["hinge"]
    assert (out / "figures" / "identify_holdout.png").stat().st_size > 10_000
    lqr = _json(capsys, ["lqr", "--json", "--no-video", "--mjcf", ident["mjcf"], "--out", str(tmp / "lqr")])
    assert lqr["mjcf"] == ident["mjcf"] and all(lqr["settled"])


@pytest.mark.parametrize("extra, words", [
    (["--fit", "mass:nobody"], "no moving body 'nobody'"),
    (["--fit", "mass:pole", "--regularization", "-1"], "regularisation weight"),
])
def test_bad_identify_input_is_one_sentence_and_writes_nothing(run, tmp_path, capsys, extra, words):
    tmp, _ = run
    log = tmp / "a.csv"
    if not log.exists():
        pytest.skip("needs the excite log of the first test")
    out = tmp_path / "out"
    assert main(["identify", "--log", str(log), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and err[0].startswith("cartpole identify: ")
    assert not out.exists() or not any(out.rglob("*"))


def test_a_log_of_another_model_is_refused(run, tmp_path, capsys):
    two = SHIPPED_MJCF.parent / "cartpole_two_pole.xml"
    bad = tmp_path / "x.csv"
    bad.write_text("t,slider,hinge,motor\n0,0,3.14,0\n0.005,0,3.14,0\n0.01,0,3.14,0\n")
    assert main(["identify", "--mjcf", str(two), "--log", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "no column 'hinge2'" in capsys.readouterr().err
