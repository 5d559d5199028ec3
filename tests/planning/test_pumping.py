"""Pumping swing-ups: a weak actuator's plan pumps at the chain's slowest hanging mode, swings up and holds in MuJoCo
(plan + TVLQR, replayed with mj_step, never diverged, ctrl and cart inside their limits); where nothing is found and
nothing is proven the planner says so, and a weak cart is refused with its proof."""
import json
import re

import numpy as np
import pytest

from cartpole.cli import main
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.ocp.collocation import OCPInfeasible, OCPNotSolved
from cartpole.planning.options import PlanOptions
from cartpole.planning.pumping import hanging_mode
from cartpole.planning.trajopt import trajopt_swingup
from mj_replay import replay_with_mj_step

ASSETS = SHIPPED_MJCF.parent


def _cart(tmp_path, gear):
    path = tmp_path / f"cart_gear{gear}.xml"
    path.write_text(SHIPPED_MJCF.read_text().replace('gear="20"', f'gear="{gear}"'))
    return path


def test_the_pumped_mode_is_the_hanging_pendulums_own():
    omega, sigma, _, gain = hanging_mode(build_model(read_params(ASSETS / "dmc_pendulum.xml")))
    # from the file's numbers: a 1 kg sphere of radius 0.05 m at 0.5 m on a massless pole, hinge damping 0.1
    inertia = 1.0 * 0.5**2 + 0.4 * 1.0 * 0.05**2
    b, mgl = 0.1, 1.0 * 9.81 * 0.5
    assert sigma == pytest.approx(-b / (2 * inertia), rel=1e-9)
    assert omega == pytest.approx(np.sqrt(mgl / inertia - sigma**2), rel=1e-9)
    assert np.abs(gain).max() > 0


def test_the_carts_pumped_mode_swings_the_pole_against_the_cart(tmp_path):
    m = build_model(read_params(_cart(tmp_path, 5)))
    omega = hanging_mode(m)[0]
    # the pole's hanging frequency on a free cart: I_eff = I - (m l)^2 / M_total (pole 0.1 kg capsule, 0.6 m, r 0.02)
    p = m.params
    M = np.asarray(m.mass_matrix(m.x_hanging), float)
    k = float(np.asarray(m.potential(m.x_hanging[:m.nq])[1], float)[1, 1])  # gravity's stiffness at hanging
    assert omega == pytest.approx(np.sqrt(k / (M[1, 1] - M[0, 1] ** 2 / M[0, 0])), rel=0.02)
    assert p.slide == 0


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dmc_pendulum", "gear5", "gear6"])
def test_a_weak_actuator_pumps_the_chain_up_and_holds_it_in_mujoco(name, tmp_path, capsys):
    path = ASSETS / f"{name}.xml" if name.startswith("dmc") else _cart(tmp_path, int(name[-1]))
    out = tmp_path / "out"
    assert main(["swingup", "--method", "trajopt", "--mjcf", str(path), "--json", "--no-video",
                 "--out", str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["success"] is True and doc["diverged"] is False and doc["diverged_at"] is None
    ro = doc["rollout"]
    qpos, qvel = replay_with_mj_step(path, ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
    assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))
    p = read_params(path)
    u = np.array(ro["ctrl"])
    assert np.all(u >= p.ctrl_range[:, 0]) and np.all(u <= p.ctrl_range[:, 1])
    if p.slide is not None:  # off the rail's end stops (which could pump energy too) by the planner's margin
        assert doc["metrics"]["cart_clearance"] > 0.05
    plan = doc["plan"]
    assert any(a["stage"].startswith("pump") for a in plan["attempts"])  # the classic multi-start failed first
    assert not any("infeasible" in a["status"].lower() and a["chosen"] for a in plan["attempts"])
    assert plan["T_min"] is None or plan["T_min"] <= plan["T"]
    # it pumps: the hinge turns back and forth several times before it rises
    theta = np.array(ro["qpos"])[:, p.hinges[0]]
    turns = np.sum(np.diff(np.sign(np.diff(theta[: int(0.8 * plan["T"] / p.timestep)]))) != 0)
    assert turns >= 3


def test_a_cart_too_weak_is_refused_as_infeasible_with_its_proof_and_no_files(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["swingup", "--method", "trajopt", "--mjcf", str(_cart(tmp_path, 4)), "--json", "--no-video",
                 "--out", str(out)]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and "Traceback" not in cap.err
    assert "infeasible" in lines[0] and "4 N" in lines[0] and "damping 0.01" in lines[0]
    ceiling = float(re.search(r"only to (-?\d+\.\d+)", lines[0]).group(1))
    assert ceiling < 1.0  # below upright's energy
    assert not out.exists()


def test_nothing_found_and_nothing_proven_is_said_so(tmp_path):
    # dm_control's pendulum needs 6.5 s of pumping; allowed 4 s the search finds nothing, and no bound forbids it
    with pytest.raises(OCPNotSolved) as exc:
        trajopt_swingup(ASSETS / "dmc_pendulum.xml", options=PlanOptions(T_max=4.0))
    msg = str(exc.value)
    assert not isinstance(exc.value, OCPInfeasible) and "infeasible" not in msg.lower()
    assert msg.startswith("No swing-up found within T <= ") and "attempts" in msg and "proves nothing" in msg
    assert len(exc.value.attempts) >= 1


def test_the_pumping_rollout_is_deterministic_inside_its_bound_and_the_options_are_checked():
    from cartpole.ocp.bounds import bounds_from_params
    from cartpole.planning.options import PlanOptionsError
    from cartpole.planning.pumping import pump_rollout

    p = read_params(ASSETS / "dmc_pendulum.xml")
    m = build_model(p)
    b = bounds_from_params(p)
    a = pump_rollout(m, m.x_hanging, 3.0, b, first=-1.0)
    again = pump_rollout(m, m.x_hanging, 3.0, b, first=-1.0)
    np.testing.assert_array_equal(a[0], again[0])
    assert np.all(np.abs(a[1]) <= 1.0 + 1e-12) and a[2] is None  # within the bound; 3 s of pumping is not enough
    for bad in ({"pump_restarts": 0}, {"pump_seed": -1}, {"T_max": 0.0}, {"search_s": -1.0}):
        with pytest.raises(PlanOptionsError):
            PlanOptions(**bad)
    with pytest.raises(PlanOptionsError, match="give `search_s=None` for no wall-time budget"):
        PlanOptions(search_s=float("inf"))


def test_a_search_without_a_wall_time_budget_gives_no_deadline_to_either_stage(monkeypatch):
    """``search_s=None``: the acrobot's receding-horizon DDP and the pumping search after it run without a deadline
    (bounded by ``T_max`` and the restarts alone), so that the same guesses are tried on any machine at any load."""
    from types import SimpleNamespace

    from cartpole.ocp.bounds import bounds_from_params
    from cartpole.planning import trajopt

    class _Stop(Exception):
        pass

    deadlines = {}

    def receding(model, x0, *, search_s, **kw):  # found nothing: the planner goes on to its other stages
        deadlines["receding"] = search_s
        return None, None, SimpleNamespace(attempts=()), None

    def not_solved(*a, **k):
        raise OCPNotSolved("no guess converged", ())

    def pumping(*a, deadline_s, **k):
        deadlines["pumping"] = deadline_s
        raise _Stop

    monkeypatch.setattr(trajopt, "_receding_plan", receding)
    monkeypatch.setattr(trajopt, "minimum_time", not_solved)
    monkeypatch.setattr(trajopt, "infeasibility_proof", lambda *a, **k: SimpleNamespace(proven=False))
    monkeypatch.setattr(trajopt, "pumping_search", pumping)
    params = read_params(ASSETS / "dmc_acrobot.xml")
    model = build_model(params)
    for search_s in (None, 7.0):
        with pytest.raises(_Stop):
            trajopt._swingup_time_plan(model, params, model.x_hanging, N=50, bounds=bounds_from_params(params),
                                       options=PlanOptions(search_s=search_s))
        assert deadlines == {"receding": search_s, "pumping": search_s}


def test_the_whole_range_law_reaches_upright_energy_where_the_gentle_one_stalls():
    from cartpole.ocp.bounds import bounds_from_params
    from cartpole.planning.pumping import pump_rollout

    p = read_params(ASSETS / "dmc_pendulum.xml")
    m = build_model(p)
    b = bounds_from_params(p)
    period = 2 * np.pi / hanging_mode(m)[0]
    for off in (0.3, -0.7, 2.5):  # at rest, rad from upright (dm_control's pendulum starts anywhere)
        x0 = np.array(m.x_eq, float)
        x0[p.hinges[0]] += off
        gentle = pump_rollout(m, x0, 20.0, b)
        whole = pump_rollout(m, x0, 20.0, b, full=True)
        assert gentle[2] is None  # the proportional push balances the damping short of upright's energy
        assert whole[2] is not None and whole[2] < 4 * period
        assert np.all(np.abs(whole[1]) <= 1.0 + 1e-12)


@pytest.mark.slow
def test_a_pendulum_started_near_upright_swings_up_in_a_few_swings_not_a_full_pumping(tmp_path, capsys):
    path = ASSETS / "dmc_pendulum.xml"
    p = read_params(path)
    m = build_model(p)
    x0 = np.array(m.x_eq, float)
    x0[p.hinges[0]] += 0.3  # at rest, 0.3 rad off upright: more than the 1 N m can hold, so it falls and comes back
    assert main(["swingup", "--method", "trajopt", "--mjcf", str(path), "--json", "--no-video", "--out",
                 str(tmp_path), "--x0", *map(str, x0)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["success"] is True and doc["diverged"] is False
    ro = doc["rollout"]
    qpos, qvel = replay_with_mj_step(path, ro["qpos"][0], ro["qvel"][0], ro["ctrl"])
    assert np.array_equal(qpos, np.array(ro["qpos"])) and np.array_equal(qvel, np.array(ro["qvel"]))
    period = 2 * np.pi / hanging_mode(m)[0]
    # from hanging the pumping takes about 4.5 periods; from here a plan within two (the gentle law alone stalled
    # and its search started at 10 s, whose refinement stopped near 7 s)
    assert doc["plan"]["T_min"] is not None and doc["plan"]["T_min"] < 2 * period
    assert doc["time_to_upright"] < 2 * period
