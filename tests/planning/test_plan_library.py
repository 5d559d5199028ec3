"""The library of plans: stored under the model's hash in the user cache, the nearest plan (hinge angles modulo whole
turns) handed to the planner as a warm start, which skips the search or, when it does not converge, costs one solve
before the cold plan."""
import numpy as np
import pytest

from cartpole.models import build_model, read_params
from cartpole.ocp.trajectory import Trajectory
from cartpole.planning.library import PlanLibrary, PlanLibraryError, build_plan_library, library_path, library_starts
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.metrics import swingup_success


@pytest.fixture(scope="module")
def single():
    params = read_params("cartpole/assets/cartpole.xml")
    model = build_model(params)
    x0 = np.asarray(model.x_hanging, float)
    lib = build_plan_library(params, model, starts=[x0])
    return params, model, lib


def test_the_grid_has_the_chain_at_rest_and_never_upright(single):
    params, model, _ = single
    starts = library_starts(model, angles=5)
    h = model.hinges[0]
    assert starts.shape == (5, model.nx)
    assert np.all(starts[:, model.nq:] == 0.0)
    up = np.abs(np.angle(np.exp(1j * (starts[:, h] - model.x_eq[h]))))
    assert up.min() > 0.5 and np.isclose(up.max(), np.pi)  # hanging is among them (5 is odd), upright is not
    with pytest.raises(PlanLibraryError, match="at least 1 start angle"):
        library_starts(model, angles=0)


def test_the_nearest_plan_is_found_modulo_whole_turns_and_shifted_onto_the_start(single):
    params, model, lib = single
    h = model.hinges[0]
    x = np.asarray(lib.plans[0].x0, float).copy()
    x[h] += 4 * np.pi + 0.01
    plan, dist = lib.nearest(x)
    assert dist < 0.1
    guess = lib.guess_for(model, x)
    assert abs(guess.x[0, h] - x[h]) < 0.02  # the guess starts where the state is, two turns on
    assert np.isclose(guess.x[-1, h] - plan.trajectory.x[-1, h], 4 * np.pi)


def test_a_library_saved_in_the_cache_loads_for_its_model_only(single, tmp_path, monkeypatch):
    params, model, lib = single
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    path = lib.save()
    assert path == library_path(lib.key) and str(path).startswith(str(tmp_path))
    back = PlanLibrary.load(model)
    assert len(back) == 1 and np.array_equal(back.plans[0].trajectory.x, lib.plans[0].trajectory.x)
    other = build_model(read_params("cartpole/assets/cartpole_two_pole.xml"))
    assert len(PlanLibrary.load(other)) == 0  # another model's hash: another file
    path.write_bytes(path.read_bytes()[:-10])  # a truncated file is not the one written
    assert len(PlanLibrary.load(model)) == 0


def test_a_warm_start_skips_the_search_and_its_plan_swings_up_in_mujoco(single):
    params, model, lib = single
    h = model.hinges[0]
    x1 = np.asarray(model.x_hanging, float).copy()
    x1[h] += 0.3
    x1[model.nq + h] += 1.0
    plan = trajopt_swingup(params, x0=tuple(x1), plan_model=model, guess=lib.guess_for(model, x1))
    chosen = [a for a in plan.solve_info.attempts if a.chosen]
    assert chosen and all(a.stage.startswith("warm effort") for a in chosen)
    assert not any(a.stage.startswith("time") for a in plan.solve_info.attempts)  # no minimum-time search
    roll = simulate(params, plan.controller, x1, plan.T + 2.0)
    assert swingup_success(roll, model) and replays_exactly(roll, params)


def test_a_warm_start_that_does_not_converge_goes_on_cold(single):
    params, model, lib = single
    x0 = np.asarray(model.x_hanging, float)
    t = np.linspace(0.0, 0.2, 11)  # a swing-up in 0.2 s: no actuator does that
    x = np.linspace(x0, model.x_eq, 11)
    bad = Trajectory(t=t, x=x, u=np.zeros((11, model.nu)), xdot=np.zeros_like(x))
    plan = trajopt_swingup(params, x0=tuple(x0), plan_model=model, guess=bad)
    stages = [a.stage for a in plan.solve_info.attempts]
    assert stages[0].startswith("warm effort") and not plan.solve_info.attempts[0].chosen
    assert any(s.startswith("time") for s in stages)  # the cold search ran after it
    assert plan.T > 0.5


def test_a_state_near_a_knot_gets_the_rest_of_that_plan_and_a_mirrored_state_its_mirror_image(single):
    params, model, lib = single
    tr = lib.plans[0].trajectory
    k = len(tr.t) // 2
    x = np.asarray(tr.x[k], float)
    guess, dist = lib.knot_guess(model, x, mirror=False)
    assert dist == pytest.approx(0.0, abs=1e-12) and np.allclose(guess.x[0], x)
    assert guess.duration == pytest.approx(tr.duration - (tr.t[k] - tr.t[0]))
    assert np.allclose(guess.x[-1], tr.x[-1])  # still ends upright
    x_m = 2 * np.asarray(model.x_eq, float) - x  # the mirror image through upright
    assert lib.knot_guess(model, x_m, mirror=False)[1] > 0.1
    guess_m, dist_m = lib.knot_guess(model, x_m)  # the cart-pole is symmetric: mirror images searched
    assert dist_m == pytest.approx(0.0, abs=1e-9) and np.allclose(guess_m.x[0], x_m)


def test_a_mirrored_plan_obeys_the_dynamics_when_the_model_is_symmetric(single):
    from types import SimpleNamespace

    from cartpole.planning.library import mirror_symmetric, mirrored

    params, model, lib = single
    assert mirror_symmetric(model)
    m = mirrored(model, lib.plans[0].trajectory)
    f = np.array([model.dynamics(x, u) for x, u in zip(m.x, m.u)])
    assert np.allclose(m.xdot, f, atol=1e-6 * np.abs(f).max())
    lopsided = SimpleNamespace(x_eq=model.x_eq, u_eq=np.zeros(1), u_low=np.array([-1.0]), u_high=np.array([2.0]))
    assert not mirror_symmetric(lopsided)  # a ctrl range not centred on u*: the mirror image is not a plan


def test_a_cached_library_is_built_once_and_only_for_the_starts_it_lacks(single, tmp_path, monkeypatch):
    from cartpole.planning import library as library_module

    params, model, lib = single
    path = tmp_path / "plans.npz"
    lib.save(path)
    asked = []

    def build(params_, model_, starts, **kw):
        asked.append(np.array(starts))
        return kw["library"].with_plan(starts[0], lib.plans[0].trajectory)
    monkeypatch.setattr(library_module, "build_plan_library", build)
    again = library_module.cached_library(params, model, [lib.plans[0].x0], path=path)
    assert not asked and len(again) == 1
    other = np.asarray(lib.plans[0].x0, float).copy()
    other[model.hinges[0]] += 0.5
    more = library_module.cached_library(params, model, [lib.plans[0].x0, other], path=path)
    assert len(asked) == 1 and np.allclose(asked[0], [other]) and len(more) == 2
    assert len(PlanLibrary.load(model, path)) == 2  # saved


def test_an_energy_weight_picks_the_knot_of_the_states_energy(single):
    params, model, lib = single
    tr = lib.plans[0].trajectory
    x = np.asarray(tr.x[2], float).copy()
    x[model.nq + model.hinges[0]] += 3.0  # the pose of an early knot, with more energy than it has
    e_x = float(model.energy(x))
    knots = np.asarray(tr.x[:-2], float)
    gap = np.abs(np.array([float(model.energy(k)) for k in knots]) - e_x)
    plain, _ = lib.knot_guess(model, x, mirror=False)
    (by_energy, _), = lib.knot_guesses(model, x, count=1, mirror=False, energy_weight=1e6)
    assert abs(float(model.energy(by_energy.x[0])) - e_x) == pytest.approx(gap.min())
    assert abs(float(model.energy(plain.x[0])) - e_x) > gap.min()  # by pose alone, another knot


def test_a_minimum_tail_keeps_the_plans_last_knots_out(single):
    params, model, lib = single
    tr = lib.plans[0].trajectory
    x = np.asarray(tr.x[-3], float)  # at a knot near the end
    assert lib.knot_guess(model, x, mirror=False)[0].duration < 0.25 * tr.duration
    (guess, dist), = lib.knot_guesses(model, x, count=1, mirror=False, min_tail=0.5 * tr.duration)
    assert guess.duration >= 0.5 * tr.duration - 1e-9 and dist > 0


def test_a_warm_start_that_does_not_converge_raises_at_once_when_told_not_to_plan_cold(single):
    from cartpole.ocp.bounds import OCPError
    from cartpole.planning.library import trajectory_tail

    params, model, lib = single
    tr = lib.plans[0].trajectory
    short = trajectory_tail(tr, tr.duration)  # the plan's last two intervals: far too short from hanging
    with pytest.raises(OCPError, match="cold=False"):
        trajopt_swingup(params, x0=tuple(model.x_hanging), plan_model=model, guess=short, cold=False)


def test_each_objective_keeps_its_own_library_file(single, tmp_path, monkeypatch):
    """Plans of a dm_control task are another library than the effort plans of the same model: saved under the
    objective's name beside the model's hash, loaded only when that objective is asked for."""
    params, model, lib = single
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    path = lib.save(objective="dmc_cartpole_swingup")
    assert path == library_path(lib.key, "dmc_cartpole_swingup") != library_path(lib.key)
    assert library_path(lib.key, "effort") == library_path(lib.key)
    assert len(PlanLibrary.load(model, objective="dmc_cartpole_swingup")) == 1
    assert len(PlanLibrary.load(model)) == 0 and len(PlanLibrary.load(model, objective="tracking")) == 0


def test_a_running_objective_is_warm_started_at_the_guess_duration_on_the_task_step_grid():
    """A dm_control task's plan warm-started from a stored plan of that task: its objective solved at the stored
    plan's duration on the file's step grid, the minimum-time search skipped."""
    params = read_params("cartpole/assets/dmc_cartpole.xml")
    model = build_model(params)
    options = PlanOptions(objective="dmc_cartpole_swingup", solver="ipopt")
    lib = build_plan_library(params, model, starts=[model.x_hanging], options=options)
    x1 = np.asarray(model.x_hanging, float).copy()
    x1[model.hinges[0]] += 0.05
    plan = trajopt_swingup(params, x0=tuple(x1), plan_model=model, options=options, guess=lib.guess_for(model, x1),
                           cold=False)
    chosen = [a for a in plan.solve_info.attempts if a.chosen]
    assert chosen and all(a.stage.startswith("warm dmc_cartpole_swingup") for a in chosen)
    assert not any(a.stage.startswith("time") for a in plan.solve_info.attempts)
    stored = lib.plans[0].trajectory
    assert plan.trajectory.duration == pytest.approx(stored.duration)
    assert plan.trajectory.N == round(stored.duration / params.timestep)
