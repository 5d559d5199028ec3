"""Knockdowns and throws: generalized forces on the joints, seeded, logged every physics step, replayed exactly; a
knock's size stated in the model's own swing-up energy, and enough to bring the poles down against the catch."""
import mujoco
import numpy as np
import pytest

from cartpole.control import LinearFeedback
from cartpole.control.energy import EnergyShapingController
from cartpole.control.switching import SWINGUP_CATCH_R, SwitchingController
import cartpole.models.plant
from cartpole.models import CartPoleModel, MJCFError, build_model, read_params, wrap_angle
from cartpole.sim import (KNOCK_ENERGY, UPRIGHT_BAND, DisturbanceError, Knockdown, Rollout, Throw, replay,
                          replays_exactly, simulate, swingup_energy)
from cartpole.sim.disturbance import joint_space_inertia
from cartpole.sim.rollout import make_mujoco
from cartpole.validation import BasinCache, uptime_metrics


@pytest.fixture(scope="module")
def cart():
    params = read_params(None)
    return params, build_model(params)


def test_knock_waits_until_upright_for_after_seconds_then_pushes_only_the_hinges(cart):
    params, model = cart
    force = Knockdown(0.5, 0.2, seed=3).start(params, x_eq=model.x_eq, hinges=model.hinges)
    up = np.asarray(model.x_eq, dtype=float)
    h = params.timestep
    n_wait = int(round(0.5 / h))
    assert all(not force(k * h, up).any() for k in range(n_wait))
    f = force(n_wait * h, up)
    assert f[list(model.hinges)].all() and not np.delete(f, list(model.hinges)).any()
    assert len(force.events) == 1 and force.events[0][0] == pytest.approx(n_wait * h)
    assert np.array_equal(force(n_wait * h + 0.1, up), f)  # held while it does no work and its length lasts
    assert not force(n_wait * h + 0.2, up).any()  # over: wait again
    assert len(force.events) == 1 and force.events[0][1] - force.events[0][0] == pytest.approx(0.2)
    assert force.knocks[0].work == 0.0 and not force.knocks[0].downed


def test_a_knock_stops_pushing_once_its_work_reaches_its_budget(cart):
    params, model = cart
    force = Knockdown(0.01, 0.3, seed=3).start(params, x_eq=model.x_eq, hinges=model.hinges)
    up = np.asarray(model.x_eq, dtype=float)
    h = params.timestep
    t = next(k * h for k in range(100) if force(k * h, up).any())
    moved = up.copy()
    hinge = model.hinges[0]
    # moved along the push by more than the swing-up energy's worth of work: more than any budget
    moved[hinge] += 2.0 * force.swingup_energy / force.torque[hinge]
    assert not force(t + h, moved).any()
    knock = force.knocks[0]
    assert knock.work > knock.budget and knock.end == pytest.approx(t + h) and force.events[0] == (knock.start, knock.end)
    assert knock.downed  # the state it was called with is out of the band


@pytest.mark.parametrize("mjcf", ["cartpole/assets/cartpole.xml", "cartpole/assets/cartpole_three_pole.xml",
                                  "cartpole/assets/dmc_acrobot.xml"])
def test_a_knock_brings_the_poles_down_against_the_catch_with_a_bounded_share_of_the_swingup_energy(mjcf):
    """The work a knock does on the hinges, read from the logged ``qfrc_applied`` and the hinges' moves, is at most its
    budget, at most ``energy`` swing-up energies; yet the LQR catch, fighting it, cannot keep the poles upright: they
    fall past horizontal. The run replays exactly."""
    params = read_params(mjcf)
    model = build_model(params)
    e_swing = float(model.energy(model.x_eq)) - float(model.energy(model.x_hanging))
    force = Knockdown(0.2, 0.3, seed=5).start(params, x_eq=model.x_eq, hinges=model.hinges)
    assert force.swingup_energy == pytest.approx(e_swing) and swingup_energy(params) == pytest.approx(e_swing)
    run = simulate(params, LinearFeedback.for_model(model), model.x_eq, 1.5, disturbance=force)
    assert replays_exactly(run) and run.info["diverged"] is None
    knock = force.knocks[0]
    t = np.asarray(run.t)
    k0, k1 = np.searchsorted(t, knock.start - 1e-9), np.searchsorted(t, knock.end - 1e-9)
    qfrc = np.asarray(run.info["qfrc_applied"])
    dq = np.diff(np.asarray(run.qpos), axis=0)
    work = float(np.sum(np.maximum(qfrc[k0:k1] * dq[k0:k1], 0.0)))
    assert work == pytest.approx(knock.work) and 0.0 < work <= knock.budget * (1 + 1e-9)
    assert 0.5 * KNOCK_ENERGY * e_swing <= knock.budget <= KNOCK_ENERGY * e_swing
    assert not qfrc[k1:].any()  # spent before its length was up (or not) and nothing pushed after it
    hinges = list(model.hinges)
    err = np.abs(wrap_angle(np.asarray(run.qpos)[k0:, hinges] - np.asarray(model.x_eq)[hinges]))
    assert knock.downed and err.max() > np.pi / 2


@pytest.mark.parametrize("mjcf", ["cartpole/assets/cartpole.xml", "cartpole/assets/cartpole_three_pole.xml",
                                  "cartpole/assets/dmc_acrobot.xml"])
def test_a_model_without_a_hanging_rest_gets_its_poles_reach_as_its_swingup_energy(mjcf, monkeypatch):
    """``2 |g| m d`` of what the first hinge carries: on these chains, straight at qpos0, the swing-up energy itself."""
    model = build_model(read_params(mjcf))
    e_swing = swingup_energy(model)

    def no_hanging_rest(self):
        raise MJCFError("no hanging rest")
    monkeypatch.setattr(CartPoleModel, "x_hanging", property(no_hanging_rest))
    assert swingup_energy(model) == pytest.approx(e_swing, rel=1e-12)


def test_a_knock_started_with_the_callers_model_builds_none_and_knocks_the_same(cart, monkeypatch):
    params, model = cart
    up = np.asarray(model.x_eq, dtype=float)

    def first_knock(**model_kw):
        f = Knockdown(0.01, 0.1, seed=4).start(params, x_eq=model.x_eq, hinges=model.hinges, **model_kw)
        torque = next(v for k in range(100) if (v := f(k * params.timestep, up)).any())
        return torque, f.knocks[0].budget, f.swingup_energy
    built = first_knock()

    def refuse(*args, **kwargs):
        raise AssertionError("a second symbolic model was built")
    monkeypatch.setattr(cartpole.models.plant, "build_model", refuse)
    given = first_knock(model=model)
    assert np.array_equal(given[0], built[0]) and given[1:] == built[1:]


def test_the_joint_space_inertia_is_mujocos_mass_matrix_at_any_state(cart):
    """The one helper every disturbance takes ``M(q)`` from agrees with MuJoCo's full forward pass, rates aside."""
    params, model = cart
    m, d = make_mujoco(params)
    rng = np.random.default_rng(0)
    for _ in range(5):
        x = rng.normal(size=2 * m.nq)
        M = joint_space_inertia(m, d, x)
        d2 = mujoco.MjData(m)
        d2.qpos[:], d2.qvel[:] = x[:m.nq], x[m.nq:]
        mujoco.mj_forward(m, d2)
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d2, full)
        assert M.shape == (m.nv, m.nv) and np.array_equal(M, full)
    assert not np.array_equal(joint_space_inertia(m, d, np.ones(m.nq)), joint_space_inertia(m, d, np.zeros(m.nq)))


def test_a_knocks_budget_scales_with_its_energy_and_the_same_seed_draws_the_same_knock(cart):
    params, model = cart
    up = np.asarray(model.x_eq, dtype=float)

    def knock(energy):
        f = Knockdown(0.01, 0.1, seed=4, energy=energy).start(params, x_eq=model.x_eq, hinges=model.hinges)
        torque = next(v for k in range(100) if (v := f(k * params.timestep, up)).any())
        return torque, f.knocks[0].budget
    (t1, b1), (t2, b2) = knock(1.0), knock(0.25)
    assert np.array_equal(t1, t2) and b2 == pytest.approx(0.25 * b1)


def test_knocks_are_seeded(cart):
    params, model = cart
    up = np.asarray(model.x_eq, dtype=float)

    def first(seed):
        f = Knockdown(0.01, 0.1, seed=seed).start(params, x_eq=model.x_eq, hinges=model.hinges)
        return next(v for k in range(100) if (v := f(k * params.timestep, up)).any())
    assert np.array_equal(first(1), first(1)) and not np.array_equal(first(1), first(2))


def test_a_knocked_down_energy_swingup_swings_up_again_and_the_log_replays(cart, tmp_path):
    params, model = cart
    catch = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R)
    basin = BasinCache.on_disk(tmp_path / "basins").get(params, catch)
    controller = SwitchingController(EnergyShapingController(model), catch, basin.rho)
    force = Knockdown(1.0, 0.3, seed=1).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, controller, model.x_eq, 12.0, disturbance=force)
    assert run.info["diverged"] is None
    assert run.info["qfrc_applied"].shape == (run.ctrl.shape[0], params.nq)
    assert replays_exactly(run)
    stats = uptime_metrics(run, model, events=force.events)
    assert stats["knockdowns"] >= 2
    # every knock brings the pole down past horizontal against the catch, before the next knock
    starts = [k.start for k in force.knocks] + [run.t[-1]]
    hinge = model.hinges[0]
    for a, b in zip(starts[:-1], starts[1:]):
        seg = (run.t >= a) & (run.t < b)
        assert np.abs(wrap_angle(run.qpos[seg, hinge] - model.x_eq[hinge])).max() > np.pi / 2, (a, b)
    # every knock is followed by a swing-up, but the last may have had too little run left
    assert stats["recoveries"] >= stats["knockdowns"] - 1
    assert all(t > run.t[-1] - 4.0 for t in stats["unrecovered_at"])
    assert 0.2 < stats["uptime"] < 1.0
    path = tmp_path / "run.json"
    run.save(path)
    again = Rollout.load(path)
    assert np.array_equal(again.info["qfrc_applied"], run.info["qfrc_applied"]) and replays_exactly(again)


def test_without_the_logged_forces_the_replay_differs(cart):
    params, model = cart
    hold = LinearFeedback.for_model(model)
    force = Knockdown(0.2, 0.2, seed=0).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, hold, model.x_eq, 1.0, disturbance=force)
    bare = replay(params, run.x[0], run.ctrl)
    assert not np.allclose(bare.x, run.x)


def test_throws_change_the_hinge_rates_at_random_times(cart):
    params, model = cart
    force = Throw(0.5, max_rate=8.0, seed=2).start(params, x_eq=model.x_eq, hinges=model.hinges,
                                                   timestep=params.timestep)
    run = simulate(params, lambda t, x: np.zeros(params.nu), model.x_eq, 2.0, disturbance=force)
    assert len(force.events) >= 2 and replays_exactly(run)
    k = int(round(force.events[0][0] / params.timestep))
    jump = run.qvel[k + 1] - run.qvel[k]
    assert np.abs(jump[list(model.hinges)]).max() > 0.5


def test_a_throw_that_sets_the_rates_leaves_them_within_its_bound_however_fast_the_pole_spun(cart):
    params, model = cart
    h = model.hinges[0]
    spinning = np.asarray(model.x_eq, float).copy()
    spinning[model.nq + h] = 30.0  # rad/s: far beyond the throw's bound
    after = {}
    for set_rates in (False, True):
        force = Throw(0.3, max_rate=2.0, seed=1, set_rates=set_rates).start(
            params, x_eq=model.x_eq, hinges=model.hinges, timestep=params.timestep)
        run = simulate(params, lambda t, x: np.zeros(params.nu), spinning, 0.5, disturbance=force)
        assert replays_exactly(run)
        k = int(round(force.events[0][0] / params.timestep))
        after[set_rates] = abs(run.qvel[k + 1][h])
    assert after[True] <= 2.0 + 0.5 and after[False] > 20.0, after  # set: within the bound; added: still spinning


def test_uptime_counts_a_run_held_upright_as_up_without_swingups(cart):
    params, model = cart
    run = simulate(params, LinearFeedback.for_model(model), model.x_eq, 1.0)
    stats = uptime_metrics(run, model)
    assert stats["uptime"] == pytest.approx(1.0) and stats["swingups"] == 0 and stats["upright_band"] == UPRIGHT_BAND
    assert uptime_metrics(run, model, duration=2.0)["uptime"] == pytest.approx(0.5)


@pytest.mark.parametrize("text, fix", [("3", "AFTER:LENGTH"), ("a:b", "seconds"), ("3:0.3:-1", "seed"),
                                       ("0:0.3", "wait"), ("3:1e9", "length"), ("3:0.3:1:0", "ENERGY"),
                                       ("3:0.3:1:x", "swing-up energies"), ("3:0.3:1:1:1", "AFTER:LENGTH")])
def test_bad_knockdowns_are_refused_in_one_sentence(text, fix):
    with pytest.raises(DisturbanceError, match=fix):
        Knockdown.parse(text)


def test_a_knockdowns_text_takes_an_optional_size_in_swingup_energies():
    assert Knockdown.parse("3:0.3:7") == Knockdown(3.0, 0.3, 7, energy=KNOCK_ENERGY)
    assert Knockdown.parse("3:0.3:7:0.25") == Knockdown(3.0, 0.3, 7, energy=0.25)


def test_loop_options_take_a_knockdown_as_text_and_build_the_runs_disturbance(cart):
    from cartpole.sim import LoopOptions

    params, model = cart
    loop = LoopOptions(knockdown="2:0.3:5", throw=Throw(1.0, seed=1))
    assert loop.knockdown == Knockdown(2.0, 0.3, 5) and loop.disturbed and not LoopOptions().disturbed
    force = loop.disturbance(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, LinearFeedback.for_model(model), model.x_eq, 3.0, disturbance=force)
    assert len(force.events) >= 2 and replays_exactly(run)
    assert LoopOptions().disturbance(params, x_eq=model.x_eq, hinges=model.hinges) is None
