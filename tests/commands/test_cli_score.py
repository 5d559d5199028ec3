"""``cartpole score``: the environments' own episodes from the command line; bad input is one sentence, exit 2."""
from __future__ import annotations

import json

import pytest

from cartpole.cli import main


def test_score_json_is_one_document_with_each_environments_returns(capsys):
    assert main(["score", "--env", "InvertedPendulum-v5", "--n", "2", "--seed", "3", "--max-steps", "50",
                 "--json"]) == 0
    out = capsys.readouterr()
    doc = json.loads(out.out)
    (env,) = doc["environments"]
    assert env["env"] == "InvertedPendulum-v5" and env["seeds"] == [3, 4]
    assert [e["steps"] for e in env["episodes"]] == [50, 50] and env["returns"] == [50.0, 50.0]
    assert env["all_replay"] and not env["any_warned"] and env["reference"] is None
    assert all(e["design"] is None for e in env["episodes"])  # the LQR is not chosen among candidates
    assert out.err.count("InvertedPendulum-v5 seed") == 2  # progress on stderr, never on stdout


@pytest.mark.parametrize("args,words", [
    (["--mjcf", "cartpole/assets/dmc_acrobot.xml"], "leave out --mjcf"),
    (["--n", "0"], "--n 0"),
    (["--seed", "-1"], "--seed -1"),
    (["--max-steps", "0"], "--max-steps 0"),
    (["--env", "acrobot"], "invalid choice"),
    (["--controller", "lqr"], "invalid choice"),
])
def test_bad_score_input_is_one_sentence_and_exit_2(capsys, args, words):
    assert main(["score", *args]) == 2
    err = capsys.readouterr()
    assert err.out == "" and words in err.err and err.err.count("\n") == 1 and "Traceback" not in err.err


def test_score_runs_the_supervisor_and_says_so(capsys):
    """--controller supervisor drives the environment's own episode with the supervisor: the JSON names the
    controller and each episode keeps the supervisor's decisions; the run replays exactly."""
    assert main(["score", "--env", "InvertedPendulum-v5", "--n", "1", "--max-steps", "30", "--controller",
                 "supervisor", "--json"]) == 0
    (env,) = json.loads(capsys.readouterr().out)["environments"]
    assert env["controller"] == "supervisor" and env["all_replay"] and not env["any_warned"]
    (ep,) = env["episodes"]
    assert ep["steps"] == 30 and [d["kind"] for d in ep["design"]["decisions"]][:1] == ["catch"]
