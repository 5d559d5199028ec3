"""Done when: 60 s of knockdowns on the shipped one- and two-pole carts and the shipped acrobot, every knockdown followed
by a swing-up and a catch, the uptime above a floor set by the time one swing-up takes, the run replaying exactly.

The floor: the run starts hanging at rest and its first swing-up (brake, plan, track, catch: ``T1`` s) is what one
swing-up takes; a knockdown costs its own ``LENGTH`` s and a recovery, which starts from a knocked, fast state (the
brake calms it first) and is allowed twice ``T1``. So ``uptime >= 1 - (T1 + knockdowns (LENGTH + 2 T1)) / 60``: a
run that gave up, or recovered slower than that on the whole, fails it. The planner's latency is charged as a fixed
``LATENCY`` s of simulated time (``SupervisorOptions.charged_latency``) so that the run, and what it asserts, is the
same on a loaded CI machine as on a quiet one; each plan's measured wall time is in the decisions.

CPU (2-core machine shared by 8 sessions, so 5-10x a quiet one's): one pole about 6 s (energy law, no plans); two poles
about 14 s, marked slow: the first plan is cold (2-8 s of wall time here, from hanging), the later ones warm-started
from the run's own plans (:mod:`cartpole.planning.library`). The acrobot: one minute from upright (a knock leaves it
less than its swing-up's energy above the upright's, which the supervisor calms in seconds before its swing-up MPC
takes over), with a floor that counts the measured waits and the MPC's budget; see its tests.
"""
import numpy as np
import pytest

from cartpole.models import build_model, read_params, wrap_angle
from cartpole.sim import UPRIGHT_BAND, Knockdown, Throw, replays_exactly, simulate
from cartpole.codegen import model_key
from cartpole.planning.library import cached_library, library_path, library_starts
from cartpole.planning.options import PlanOptions
from cartpole.supervise import SupervisorOptions, supervisor_for
from cartpole.supervise.supervisor import hinge_options
from cartpole.validation import uptime_metrics

DURATION = 60.0
AFTER, LENGTH = 3.0, 0.3
#: s of simulated time each plan is charged (above the warm plans' wall time on a quiet machine).
LATENCY = 2.0
ACROBOT = "cartpole/assets/dmc_acrobot.xml"


def _knockdown_run(mjcf: str, seed: int = 1, options=None, library=None):
    params = read_params(mjcf)
    model = build_model(params)
    sup = supervisor_for(params, model, options=options or SupervisorOptions(charged_latency=LATENCY), library=library)
    force = Knockdown(AFTER, LENGTH, seed=seed).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, sup, np.asarray(model.x_hanging, float), DURATION, disturbance=force)
    return params, model, sup, run, uptime_metrics(run, model, events=force.events, duration=DURATION)


def _assert_recovers_every_time(params, model, sup, run, m):
    assert run.info.get("qfrc_applied") is not None and replays_exactly(run, params)
    assert not run.info.get("diverged", False)
    assert m["knockdowns"] >= 2, "the run was knocked down at least twice"
    T1 = m["swingup_times"][0]  # the first swing-up, from hanging at rest
    # every knockdown is followed by a swing-up held 1 s, except a last one with too little run left for it
    for late in m["unrecovered_at"]:
        assert late == max(a for a in m["unrecovered_at"]) and DURATION - late < LENGTH + 2 * T1 + 1.0
    floor = 1.0 - (T1 + m["knockdowns"] * (LENGTH + 2 * T1)) / DURATION
    assert m["uptime"] >= floor, (m, floor)
    kinds = [d.kind for d in sup.decisions]
    assert kinds.count("catch") >= m["recoveries"]


def test_one_pole_recovers_from_every_knockdown_for_a_minute():
    params, model, sup, run, m = _knockdown_run("cartpole/assets/cartpole.xml")
    _assert_recovers_every_time(params, model, sup, run, m)
    assert sup.plans == 0  # the energy law swings up from anywhere: no plan needed


def test_one_pole_thrown_at_random_times_even_mid_swingup_swings_up_again():
    """The benchmark's form: the state thrown (every hinge rate changed by up to 15 rad/s at once) at random times,
    whatever the controller is doing; some throws land while it is still swinging up."""
    params = read_params("cartpole/assets/cartpole.xml")
    model = build_model(params)
    sup = supervisor_for(params, model, options=SupervisorOptions(charged_latency=LATENCY))
    throw = Throw(2.0, max_rate=15.0, seed=3).start(params, x_eq=model.x_eq, hinges=model.hinges,
                                                     timestep=params.timestep)
    duration = 30.0
    run = simulate(params, sup, np.asarray(model.x_hanging, float), duration, disturbance=throw)
    m = uptime_metrics(run, model, events=throw.events, duration=duration)
    assert replays_exactly(run, params) and not run.info.get("diverged", False)
    up = _upright_at(run, model)
    mid = [a for a, _ in throw.events if not up[np.searchsorted(run.t, a)]]
    assert m["knockdowns"] >= 8 and len(mid) >= 1, (m, mid)  # thrown often, at least once while not upright
    # a throw within one swing-up of the next may be overtaken by it; every other throw is followed by a swing-up
    T1 = m["swingup_times"][0]
    starts = [a for a, _ in throw.events] + [duration]
    for late in m["unrecovered_at"]:
        assert starts[starts.index(late) + 1] - late < 2 * T1 + 1.0, (late, m)
    assert m["uptime"] > 0.0 and [d.kind for d in sup.decisions].count("catch") >= m["recoveries"]


def _upright_at(run, model) -> np.ndarray:
    """Whether every hinge is within the upright band at each logged step."""
    q = np.asarray(run.qpos, float)[:, list(model.hinges)]
    return np.all(np.abs(wrap_angle(q - np.asarray(model.x_eq)[list(model.hinges)])) < UPRIGHT_BAND, axis=1)


@pytest.mark.slow
def test_a_chain_recovers_from_every_knockdown_for_a_minute():
    params, model, sup, run, m = _knockdown_run("cartpole/assets/cartpole_two_pole.xml")
    _assert_recovers_every_time(params, model, sup, run, m)
    assert sup.plans >= m["recoveries"] and sup.warm_plans >= 1  # later plans warm-started from the run's own


#: The acrobot's runs start upright, as a rig shown to visitors is when they poke it (its swing-up from hanging, about
#: 20 s, is tested below). A knock (``Knockdown(3, 0.3)``, its work bounded by the swing-up's energy) leaves it 13-32 J
#: above the upright's energy, which the supervisor's calming law (the energy drain,
#: :class:`~cartpole.control.drain.EnergyDrain`, then the soft brake) takes out in 0.7-6.3 s (median 1.3 s; seeds
#: 0-11, from the state at the knock's end, in MuJoCo: ``tools/acrobot_drain.py``); then the swing-up MPC
#: (``swingup_mpc``) takes the calm state over. Measured over the minute from upright, latency charged ``LATENCY`` s
#: (``python tools/acrobot_minute.py``; seed: knockdowns, recovered, uptime): 0: 7, 7, 0.399; 1: 6, 6, 0.337; 2: 7,
#: 6, 0.360; 3: 6, 5, 0.315; 4: 7, 6, 0.357; 5: 9, 8, 0.456; 6: 7, 6, 0.360; 7: 8, 7, 0.411; 8: 7, 6, 0.359; 9: 6,
#: 6, 0.340; 10: 6, 6, 0.344; 11: 8, 7, 0.405 (76 of 84 knocks recovered, every one by the MPC, no plan made). Each
#: knock not recovered was a last one 0.1-9.7 s before the minute's end; the MPC took 1.8-9.4 s from taking a calm
#: state over to the catch (median 3.0 s). With a band of 20 J (``mpc_energy``) seeds 1, 8 and 9 each had a knock
#: calmed further below, planned from: seed 8 never recovered it (21 s left), hence 35 J (``mpc_floor``). Re-measured
#: once a knock during the MPC no longer spent it (the MPC takes the calmed state again): the same for all 12 seeds.
#: Before the MPC (every calm state planned from, ``--no-mpc``): 0: 3, 2, 0.152; 1: 1, 0, 0.051; 2: 5, 4, 0.263; 3:
#: 2, 1, 0.104; 4: 3, 2, 0.169; 5: 4, 3, 0.205; 6: 3, 2, 0.156; 7: 3, 2, 0.157; 8: 3, 2, 0.153; 9: 1, 0, 0.051; 10: 3,
#: 2, 0.153; 11: 5, 4, 0.254 (24 of 36): plans warm-started from the library's knots were lost part way under TVLQR
#: (the funnel left 1-4 s in) or did not converge, and were made again (seeds 0, 1, 9 re-measured with the tool). The
#: seeds run: 3 and 9, not the best case (0, 1, 9 and 10 recovered every knock): 3 has the lowest uptime of the
#: twelve, 9 the slowest single MPC swing-up (9.4 s from taking over to the catch, near the 10 s budget) and was one
#: of the two that never recovered before. Wall time 15 s and 11 s (``--durations``, the 2-core machine shared, at a
#: quiet moment; 33 s and 41 s in the tool's run under load), against 76 s for seed 11 before.
ACROBOT_SEEDS = (3, 9)


def _acrobot_options():
    """What :func:`supervisor_for` gives a model driven at a hinge (:func:`~cartpole.supervise.supervisor.
    hinge_options`), the planner's latency charged (``LATENCY``) and its wall time allowed 300 s (a plan over it
    fails)."""
    return hinge_options(charged_latency=LATENCY, plan_budget=300.0)


def _calm_at(run, model, sup, after: float) -> float:
    """s: the first logged time from ``after`` on at which the supervisor would plan (energy at most ``calm_energy``,
    every hinge rate at most ``calm_rate``); inf when never."""
    t = np.asarray(run.t, float)
    x = np.hstack([run.qpos, run.qvel])
    opts = sup.options
    for k in np.nonzero(t >= after - 1e-9)[0]:
        rates = np.abs(x[k, [model.nq + h for h in model.hinges]])
        if np.all(rates <= opts.calm_rate) and float(model.energy(x[k])) <= opts.calm_energy:
            return float(t[k])
    return np.inf


@pytest.mark.slow
@pytest.mark.parametrize("seed", ACROBOT_SEEDS)
def test_the_acrobot_swings_up_again_after_every_knockdown_for_a_minute(seed):
    """Knocked, the acrobot holds 13-32 J above the upright's energy, which the supervisor calms first (a plan from
    above the upright's energy is not found); each knock is followed by a wait ``W_k`` for the energy to reach the
    upright's (measured on the run: the supervisor only calms until then), then the swing-up MPC takes the calm state
    over (``swingup_mpc``: no plan, no latency) and the catch takes it from the MPC. Every knock but a last one with
    less run left than its wait and the MPC's budget ``B`` (``mpc_budget``, 10 s: the supervisor plans after it) is
    followed by a swing-up and catch, each by the MPC within ``LENGTH + W_k + B`` of the knock (never a plan first,
    never the planner after the MPC gave up). The floor: each recovered knock costs its ``LENGTH``, its wait and half
    the MPC's budget, an unrecovered last knock the rest of the run: ``uptime >= 1 - (sum_k (LENGTH + W_k + B / 2) +
    rest) / duration``, so MPC swing-ups that took more than half their budget on the whole fail it (the plan from a
    calm state, before the MPC, was 5-12 s long and charged 2 s). The acrobot is upright only the ``AFTER`` s before
    each knock, so its uptime is mostly set by how many knocks the minute holds. Wall time: see ``ACROBOT_SEEDS``."""
    library = _acrobot_library()
    params = read_params(ACROBOT)
    model = build_model(params)
    sup = supervisor_for(params, model, options=_acrobot_options(), library=library)
    force = Knockdown(AFTER, LENGTH, seed=seed).start(params, x_eq=model.x_eq, hinges=model.hinges)
    run = simulate(params, sup, np.asarray(model.x_eq, float), DURATION, disturbance=force)
    m = uptime_metrics(run, model, events=force.events, duration=DURATION)
    assert run.info.get("qfrc_applied") is not None and replays_exactly(run, params)
    assert not run.info.get("diverged", False)
    waits = [_calm_at(run, model, sup, end) - end for _, end in force.events]
    assert m["knockdowns"] >= 3, m
    asked = [d for d in sup.decisions if d.kind in ("plan", "plan_failed", "calm_timeout", "mpc")]
    unrecovered = set(m["unrecovered_at"])
    down, budget = 0.0, sup.options.mpc_budget
    for (start, end), wait in zip(force.events, waits):
        # from the knock's end until the state is calm the supervisor only calms (no plan, no MPC)
        assert not [d for d in asked if end + 1e-9 < d.t < end + wait - 1e-9], (start, wait, asked)
        if start in unrecovered:  # only a last knock with too little run left for its wait and the MPC's budget
            assert start == force.events[-1][0] and DURATION - end < wait + budget, (start, wait, m)
            continue
        first = next(d for d in asked if d.t >= end + wait - 1e-9)
        assert first.kind == "mpc", (start, first)  # once calm the MPC swings it up, no plan first
        up = min(s for s in m["swingup_times"] if s > start)
        assert up - start <= LENGTH + wait + budget, (start, wait, up)  # by the MPC, within its budget
        down += LENGTH + wait + 0.5 * budget
    rest = sum(DURATION - start for start in unrecovered)
    floor = 1.0 - (down + rest) / DURATION
    assert 0.0 < floor <= m["uptime"], (m, waits, floor)
    kinds = [d.kind for d in sup.decisions]
    recovered = len(force.events) - len(unrecovered)
    assert recovered >= 3 and kinds.count("catch") >= recovered + 1, kinds  # held from the start, after each recovery
    assert len(sup.summary()["unreachable"]) == kinds.count("plan_failed")  # each failed plan reported


def _acrobot_library():
    """The acrobot's library: one cold plan from hanging (a pumping search: 70-280 s of wall time on a shared
    machine, not charged to the run), made once per model and kept in the user cache beside the model's own library
    (:func:`~cartpole.planning.library.cached_library`; the file of the model's hash)."""
    params = read_params(ACROBOT)
    model = build_model(params)
    default = library_path(model_key(model))
    library = cached_library(params, model, library_starts(model, 1),
                             options=PlanOptions(exact_discrete=False, search_s=900.0),
                             path=default.with_name(f"hanging-{default.name}"))
    assert len(library) == 1, library.failed
    return library


@pytest.mark.slow
@pytest.mark.parametrize("mpc", [False, True], ids=["replanning", "mpc_after_a_lost_plan"])
def test_the_acrobot_swings_up_from_hanging_by_replanning_as_it_goes(mpc):
    """dm_control's acrobot, driven at its elbow: TVLQR alone loses its 15 s pumping plan part way (in MuJoCo, 5.9 s
    in); re-planned every 2 s from the rest of the plan (each warm, charged ``LATENCY`` s), it swung up and was
    caught on one build, not on another (below). With the swing-up MPC (as shipped, tracking upright) hanging at rest
    is still planned from (39 J below the upright's energy, beyond ``mpc_floor``); a plan lost at rest within the
    MPC's band (above the floor) is handed to the MPC at once, one lost fast is calmed first, one lost below the
    floor planned from again (the rule on constructed states: ``tests/supervise/test_supervisor.py``). Whether the
    MPC's take-over is caught turns on round-off as well: on one machine the plan was lost after one re-plan and the
    MPC swung it up; on the AVX-512 EPYC (2026-12) lost after three re-plans, 9.89 s in, 24.6 J below the upright's
    energy and calm, the MPC took it at once and ran its 10 s budget without a catch (to 13.6 J below), then a plan
    (``mpc_failed``, ``plan``): no catch in 22 s. From that lost state perturbed by 1e-12 (per component, normal) the
    MPC caught it in one try of two (9.7 s after taking over), by 1e-9 in none of two, by 1e-6 in two of three: the
    chain is chaotic over the MPC's 10 s as over the plans. Pinned on any machine: the rule at each loss in the run
    (up to the first time the MPC ran out, which spends it until the next catch), each MPC take-over from a calm state
    within its band, and the honest accounting (no catch, no swing-up and no uptime). Slow: 20 s without the MPC
    and 8 s with it on the shared 2-core machine at a quiet moment (46 s without it under load; 6-7 s each on the
    EPYC at nice 19, ``--durations``); the library's cold plan from hanging (made once per model and kept on disk)
    took 277 s of wall time when it was loaded (55 s of CPU), 70 s when quieter."""
    params = read_params(ACROBOT)
    model = build_model(params)
    options = _acrobot_options().replace(swingup_mpc=mpc)
    sup = supervisor_for(params, model, options=options, library=_acrobot_library())
    run = simulate(params, sup, np.asarray(model.x_hanging, float), 22.0)
    m = uptime_metrics(run, model, duration=22.0)
    assert replays_exactly(run, params) and not run.info.get("diverged", False)
    kinds = [d.kind for d in sup.decisions]
    assert kinds[0] == "plan", kinds  # hanging: planned from
    if not mpc:
        # Without the MPC the re-planning path's outcome turns on round-off: the same seed swung up and was caught
        # on one build and not on another whose plans differed in the tenth digit (the chain is chaotic, the plans
        # 8-12 s long). Pinned here: it re-plans warm from the tracked plan's tail, and counts no swing-up it has not
        # held (issue 42: a run where the supervisor gave up is never counted as upright).
        assert kinds.count("replan") >= 2 and "mpc" not in kinds and sup.warm_plans >= 2, kinds
        if "catch" not in kinds:
            assert m["swingups"] == 0 and m["uptime"] == 0.0, (m, kinds)
        return
    opts, e_up = sup.options, float(model.energy(np.asarray(model.x_eq, float)))
    assert float(model.energy(np.asarray(model.x_hanging, float))) - e_up < -opts.mpc_floor  # why hanging is planned
    assert kinds.count("replan") >= 1 and kinds.index("plan") < kinds.index("track"), kinds
    t_log, x_log = np.asarray(run.t, float), np.hstack([run.qpos, run.qvel])
    rates = [model.nq + h for h in model.hinges]
    spent_at = next((d.t for d in sup.decisions if d.kind == "mpc_failed"), np.inf)
    for i, d in enumerate(sup.decisions):
        if d.kind == "mpc":  # the MPC takes only calm states within its band
            gap = d.detail["energy"] - e_up
            assert -opts.mpc_floor <= gap <= min(opts.mpc_energy, opts.calm_energy - e_up), (d, kinds)
        if d.kind != "lost" or d.t > spent_at:
            continue
        x = x_log[int(np.searchsorted(t_log, d.t - 1e-9))]  # the state the supervisor lost the plan at
        gap = float(model.energy(x)) - e_up
        calm = np.all(np.abs(x[rates]) <= opts.calm_rate) and float(model.energy(x)) <= opts.calm_energy
        handed = {"mpc"} if calm and -opts.mpc_floor <= gap <= opts.mpc_energy else {"brake"} if not calm else \
            {"plan", "plan_failed"}  # in the band: the MPC at once; fast: calmed first; below the floor: a plan
        nxt = sup.decisions[i + 1]
        assert nxt.t == d.t and nxt.kind in handed, (d, nxt, gap, calm, kinds)
    if "catch" not in kinds:  # the MPC (or the plans after it) did not swing it up: nothing counted as upright
        assert m["swingups"] == 0 and m["uptime"] == 0.0, (m, kinds)
        return
    caught = max(d.t for d in sup.decisions if d.kind == "catch")
    assert kinds[-1] == "catch", kinds  # once caught it is held: nothing knocks it here
    if 22.0 - caught > 2.0:
        assert m["swingups"] >= 1 and _upright_at(run, model)[-1], (m, kinds)


#: dm_control's acrobot-swingup seed 4: a start near hanging (the shoulder within 0.8 rad of it, at rest), which the
#: supervisor planned from before its MPC took every calm state (and lost the episode: return 0.0), and the episode's
#: steps it is run for (7 s: its MPC caught it 6.5 s in, ``python -m cartpole score --env acrobot-swingup --controller
#: supervisor --seed 4 --n 1``).
NEAR_HANGING_SEED, NEAR_HANGING_STEPS = 4, 700


def test_in_dm_controls_episode_a_near_hanging_acrobot_is_swung_up_by_the_mpc_without_a_plan():
    """From dm_control's own near-hanging start, in its own episode, the supervisor of ``cartpole score --controller
    supervisor`` (:func:`cartpole.apps.envscore.supervised`: its swing-up MPC on the task's objective takes every calm
    state, ``mpc_floor=None``) swings the acrobot up and the catch holds it, with no plan asked for (a plan would be
    charged a fixed latency, ``charged_latency``: the run does not depend on the machine's speed). About 15-30 s of
    wall time on the shared machine (one DDP iteration a step)."""
    pytest.importorskip("dm_control")
    from cartpole.apps.envscore import score_episode, supervised

    def charged(env, mjcf, x0, hold):
        return supervised(env, mjcf, x0, hold, charged_latency=LATENCY)
    ep = score_episode("acrobot-swingup", NEAR_HANGING_SEED, controller=charged, max_steps=NEAR_HANGING_STEPS)
    model = build_model(ep.mjcf)
    x0 = np.asarray(ep.x0, float)
    down = abs(float(wrap_angle(x0[model.hinges[0]] - float(np.asarray(model.x_hanging)[model.hinges[0]]))))
    assert down < 0.8 and np.allclose(x0[model.nq:], 0.0)  # near hanging, at rest
    assert ep.replays and not ep.warned
    kinds = [d["kind"] for d in ep.design["decisions"]]
    assert kinds[0] == "mpc" and "catch" in kinds, kinds  # the MPC from the start, then the catch
    assert not {"plan", "plan_failed", "mpc_failed", "calm_timeout"} & set(kinds), kinds  # no plan, no failure
    assert kinds[-1] == "catch" and ep.rewards[-1] > 0.5  # held up at the end: the tip near the target
    assert ep.design["mpc_ms"]["steps"] >= 1 and ep.design["plans"] == 0
