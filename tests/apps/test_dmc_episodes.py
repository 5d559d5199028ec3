"""dm_control's episodes with zero training: ``cartpole swingup --objective dmc_*`` reports the exact return of its
MuJoCo run, and ``cartpole sweep --objective dmc_*`` runs the task's own seeded episodes (short: 1-2 starts)."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.models import build_model
from cartpole.ocp import dmc
from cartpole.sim import Rollout
from cartpole.validation.metrics import EPISODE, dmc_return, dmc_rewards
from mj_replay import replay_with_mj_step

PENDULUM = "cartpole/assets/dmc_pendulum.xml"
CARTPOLE = "cartpole/assets/dmc_cartpole.xml"
ACROBOT = "cartpole/assets/dmc_acrobot.xml"


def _rollout(doc) -> Rollout:
    ro = doc["rollout"]
    return Rollout(t=np.array(ro["t"]), qpos=np.array(ro["qpos"]), qvel=np.array(ro["qvel"]),
                   ctrl=np.array(ro["ctrl"]))


def test_pendulum_episode_reports_dm_controls_exact_sparse_return(tmp_path, capsys):
    model = build_model(PENDULUM)
    x0 = [0.18, 0.0]  # 10 degrees from upright, at rest: outside the 8 degree box; gravity 0.88 N m < the 1 N m motor
    assert main(["swingup", "--mjcf", PENDULUM, "--method", "trajopt", "--objective", "dmc_pendulum_swingup",
                 "--x0", *map(str, x0), "--json", "--no-video", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    ro = doc["rollout"]
    assert doc["success"] is True and doc["diverged"] is False
    assert doc["return_steps"] == 1000 and ro["t"][-1] == pytest.approx(20.0)  # 1000 steps of 0.02 s
    qpos, qvel = replay_with_mj_step(doc["mjcf"], ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
    assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))
    run = _rollout(doc)
    r = dmc_rewards(run, model, objective="dmc_pendulum_swingup", steps=EPISODE)
    assert doc["return"] == pytest.approx(float(r.sum()), abs=1e-9)
    assert set(np.unique(r)) <= {0.0, 1.0} and r[0] == 0.0 and r[-1] == 1.0  # the indicator, off then on
    assert 950 < doc["return"] < 1000  # into the box within 1 s of a 20 s episode


def test_sweep_runs_the_tasks_seeded_episodes_and_reports_their_mean_return(tmp_path, capsys):
    model = build_model(CARTPOLE)
    args = ["sweep", "--mjcf", CARTPOLE, "--method", "trajopt", "--objective", "dmc_cartpole_balance", "--n", "2",
            "--seed", "4", "--json", "--out", str(tmp_path)]
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    starts = dmc.episode_starts(model, "dmc_cartpole_balance", 2, seed=4)
    assert np.allclose([r["start"] for r in doc["rows"]], starts, rtol=0, atol=1e-12)
    returns = [r["return"] for r in doc["rows"]]
    assert doc["objective"] == "dmc_cartpole_balance" and doc["returns"] == returns and doc["return_runs"] == 2
    assert doc["mean_return"] == pytest.approx(np.mean(returns))
    assert all(r["return_steps"] == 1000 and r["success"] and r["replays"] for r in doc["rows"])
    assert all(900 < v <= 1000 for v in returns)  # it starts balanced: each step pays nearly 1
    with open(doc["results"]) as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["return"]) for r in rows] == pytest.approx(returns, abs=1e-9)
    # a resumed sweep keeps the returns it reads back
    assert main(args + ["--resume"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["resumed"] == 2 and again["returns"] == pytest.approx(returns, abs=1e-9)


def test_an_mpc_sweep_runs_the_ddp_mpc_on_the_tasks_reward_over_its_episodes(tmp_path, capsys):
    model = build_model(CARTPOLE)
    assert main(["sweep", "--mjcf", CARTPOLE, "--method", "mpc", "--objective", "dmc_cartpole_swingup", "--n", "2",
                 "--seed", "0", "--json", "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    starts = dmc.episode_starts(model, "dmc_cartpole_swingup", 2, seed=0)
    assert np.allclose([r["start"] for r in doc["rows"]], starts, rtol=0, atol=1e-12)
    assert doc["objective"] == "dmc_cartpole_swingup" and doc["return_runs"] == 2
    assert all(r["return_steps"] == 1000 and r["success"] and r["replays"] and not r["diverged"] for r in doc["rows"])
    assert all(800 < r["return"] <= 1000 for r in doc["rows"])  # swung up from hanging within about 2 s


def test_the_ddp_mpc_without_a_seed_plan_swings_the_acrobot_up_from_its_episodes_starts(tmp_path, capsys):
    # no offline plan at all: the MPC finds the pumping itself from the long-tailed surrogate (ocp.dmc)
    model = build_model(ACROBOT)
    assert main(["sweep", "--mjcf", ACROBOT, "--method", "mpc", "--objective", "dmc_acrobot_swingup",
                 "--no-seed-plan", "--period", "0.01", "--horizon", "2", "--n", "2", "--seed", "0", "--json",
                 "--out", str(tmp_path)]) == 0
    doc = json.loads(capsys.readouterr().out)
    starts = dmc.episode_starts(model, "dmc_acrobot_swingup", 2, seed=0)
    assert np.allclose([r["start"] for r in doc["rows"]], starts, rtol=0, atol=1e-12)
    assert doc["mpc"] == {"horizon": 2.0, "seed_plan": False}
    assert all(r["return_steps"] == 1000 and r["success"] and r["replays"] and not r["diverged"] for r in doc["rows"])
    assert all(r["return"] > 700 for r in doc["rows"])  # at the target within 3 s of a 10 s episode


@pytest.mark.parametrize("args,words", [
    (["swingup", "--method", "trajopt", "--no-seed-plan"], "use it with --method mpc --mpc-solver ddp"),
    (["swingup", "--method", "mpc", "--no-seed-plan"], "cannot run without one"),
    (["sweep", "--method", "trajopt", "--horizon", "2"], "the MPC's settings"),
    (["sweep", "--method", "mpc", "--no-seed-plan"], "needs an objective"),
])
def test_no_seed_plan_is_refused_where_no_ddp_mpc_runs_in_one_sentence(tmp_path, capsys, args, words):
    assert main([*args, "--mjcf", CARTPOLE, "--json", "--no-video" if args[0] == "swingup" else "--n", *(
        [] if args[0] == "swingup" else ["1"]), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr()
    assert err.out == "" and words in err.err and err.err.count("\n") == 1 and "Traceback" not in err.err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("extra,words", [
    (["--method", "energy", "--objective", "dmc_cartpole_swingup"], "with --method trajopt or mpc"),
    (["--method", "mpc", "--objective", "time"], "not a running cost"),
    (["--method", "trajopt", "--objective", "dmc_acrobot_swingup"], "without a cart"),
    (["--method", "trajopt", "--objective", "dmc_cartpole_swingup", "--model-error", "0.9", "1.1"],
     "where dm_control's episodes start"),
])
def test_sweep_refuses_a_dmc_objective_it_cannot_run_in_one_sentence(tmp_path, capsys, extra, words):
    assert main(["sweep", "--mjcf", CARTPOLE, "--n", "1", "--json", "--out", str(tmp_path), *extra]) == 2
    err = capsys.readouterr()
    assert err.out == "" and words in err.err and err.err.count("\n") == 1 and "Traceback" not in err.err
    assert not any(tmp_path.iterdir())


def test_return_of_a_rollout_counts_the_tasks_episode(tmp_path):
    model = build_model(PENDULUM)
    n = 1500
    run = Rollout(t=np.arange(n + 1) * 0.02, qpos=np.zeros((n + 1, 1)), qvel=np.zeros((n + 1, 1)),
                  ctrl=np.zeros((n, 1)))  # upright at rest for 30 s
    assert dmc_return(run, model, objective="dmc_pendulum_swingup", steps=EPISODE) == 1000.0
    assert dmc_return(run, model, objective="dmc_pendulum_swingup", steps=None) == 1500.0
