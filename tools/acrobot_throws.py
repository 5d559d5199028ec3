"""The acrobot thrown at random times for a minute, per seed, in MuJoCo: RealAIGym's robustness setting with today's
supervisor (docs/recovery.md, "Thrown at random (RealAIGym's setting)"; claims.toml).

For each seed, dm_control's acrobot (``cartpole/assets/dmc_acrobot.xml``) starts hanging at rest, as RealAIGym's
acrobot does, under the supervisor of the acrobot's knockdown test (``tools/acrobot_minute.py``'s options: each plan
charged ``LATENCY`` s of simulated time, so the run is the same on any machine; the swing-up MPC; the library's plan
from hanging) and is thrown by :class:`cartpole.sim.Throw` (``EVERY`` s apart on average, each gap uniform in
[0.5, 1.5] ``EVERY``; each throw a one-step impulse changing every hinge's rate by up to ``RATE`` rad/s, or with
``--set-rates`` setting it to at most that), whatever it is doing, also mid swing-up, for ``--duration`` s. Each run is checked to replay exactly from its logged ctrl and
``qfrc_applied`` with ``mj_step`` (``replays``).

Prints one JSON document: ``seeds``, ``mjcf``, ``reset``, ``resets`` (None without ``--reset``), ``period``,
``mpc_band``, ``stepped``, ``mpc_horizon``, ``mpc_iterations``, ``mpc_objective``, ``mpc_converge``, ``every``,
``rate``, ``set_rates``, ``duration``, and per seed (``runs``, in seed order)
``uptime`` (fraction of the run with every hinge within the toolkit's upright band, 0.2 rad, of upright),
``uptime_height`` (RealAIGym's own measure: fraction with the tip above 0.9 of the chain's length over the shoulder),
``throws`` (with ``--reset``: resets), ``throws_while_up`` (throws landing with every hinge in the band), ``swingups``, ``recovered`` (throws
followed by a swing-up before the next throw or the end), ``recover_s`` (s from each of those throws to its swing-up),
``energy_after_J`` (each throw's state's energy just after it, J above upright rest), ``missed_at`` (s, each other
throw) with ``left_s`` (s to the next throw or the end after each), ``decisions`` (kind -> count), ``mpcs``, ``plans``,
``mpc_ms``, ``peak_rate`` (rad/s, the largest hinge rate logged), ``replays``, ``diverged``, ``wall_s``; then ``uptime_mean``, ``uptime_median``,
``uptime_height_mean``, ``throws``, ``swingups``, ``recovered``, ``recover_s``, ``energy_after_J`` and
``missed_gap_s`` (``min``, ``median``, ``max``, ``count`` over every seed: the recoveries' times, the energies the
throws left, and the time each missed throw had before the next), ``swingup_energy_J`` (the model's own, J), ``all_replay``.

``--mjcf FILE``: another acrobot (a chain driven at the elbow with a site ``tip`` and a shoulder body ``upper_arm``),
e.g. ``cartpole/assets/realaigym_acrobot.xml``, RealAIGym's own; its library of one plan from hanging is built as
``acrobot_minute``'s (once per model, kept on disk). ``--reset``: RealAIGym's own reset (:class:`cartpole.sim.Reset`,
double_pendulum's ``GlobalPolicyTestingControllerV2`` as leaderboard/acrobot/simulation_v3 builds it: ``--resets``
resets spread over ``--duration`` at ``linspace(d, duration - d, resets)``, ``d = duration / (resets + 1)``, each
moved by up to 1 s; each 0.2 s of a gravity-compensated PID on both hinges, at most 6 N m each, towards a random
pose at rest, the supervisor switched off) instead of the throws; the seed is the reset's. ``--period``: the
supervisor's control period (s; default every physics step), its ctrl held over it (RealAIGym's acrobot steps at 2 ms,
where the swing-up MPC's 2 s horizon would be 1000 stages, over its limit: 0.01 s makes it 200, as on dm_control's). ``--mpc-band F``:
the supervisor's swing-up MPC takes every state up to ``F`` of the model's swing-up energies above the upright's,
however fast, instead of only calm ones (every hinge slower than 6 rad/s and the energy at or below the upright's),
and keeps it while the energy stays within the larger of its 35 J and ``F + 1`` swing-up energies above it
(:func:`band_options`).

The stepped setting, RealAIGym's leaderboard's (its simulator calls the controller each step and waits for it, so no
controller's compute is charged simulated time): ``--stepped`` charges each plan 0 s of simulated time
(``SupervisorOptions.charged_latency=0``) instead of ``acrobot_minute``'s 2 s; the swing-up MPC's wall time per step
is never charged (``mpc_step_budget`` None), so it may do more a step: ``--mpc-iterations N`` DDP iterations a control
period (``SupervisorOptions.mpc_iterations``, default 1), ``--mpc-horizon S`` s ahead (``mpc_horizon``, default 2),
``--mpc-converge`` its solution converged from the state at each take-over (``mpc_converge``; the solve charged as a
plan is: 0 s with ``--stepped``), ``--mpc-objective tip`` dm_control's acrobot swing-up reward on the tip's distance
from its upright position (:func:`tip_objective`) instead of the tracking of upright (and from any calm state,
``mpc_floor`` None). Each run's row then has ``mpc_ms`` too (the MPC's wall time per control step: ``median``,
``max`` ms, ``steps``; on a shared machine, what it cost, not what was charged).

    python tools/acrobot_throws.py [--seeds 0 1 ...] [--every 3.75] [--rate 45] [--set-rates] [--duration 60]
                                   [--mjcf FILE] [--reset] [--resets 15] [--period S] [--mpc-band F] [--stepped]
                                   [--mpc-iterations N] [--mpc-horizon S] [--mpc-converge] [--mpc-objective tip]
                                   [--out FILE]
"""
import argparse
import json
import sys
import time
from collections import Counter

import casadi as ca
import mujoco
import numpy as np
from tqdm import tqdm

from acrobot_minute import ACROBOT, _spread, acrobot_library, acrobot_options  # this directory: the knockdown test's supervisor
from cartpole.errors import CartPoleError
from cartpole.models import build_model, read_params, wrap_angle
from cartpole.sim import UPRIGHT_BAND, Reset, SimOptions, Throw, replays_exactly, simulate, swingup_energy
from cartpole.sim.disturbance import joint_space_inertia
from cartpole.sim.rollout import make_mujoco
from cartpole.ocp import dmc
from cartpole.ocp.objectives import reward
from cartpole.planning.options import PlanOptions
from cartpole.supervise import supervisor_for
from cartpole.validation import uptime_metrics

#: RealAIGym's acrobot benchmark: 15 throws in 60 s, at ``linspace(60/16, 60 - 60/16, 15)`` plus up to 1 s either
#: way (double_pendulum's ``GlobalPolicyTestingControllerV2``): one every 3.75 s on average.
EVERY = 60.0 / 16
#: rad/s: the largest change of a hinge's rate (issue 42's statement of that benchmark).
RATE = 45.0
#: RealAIGym's upright: the tip higher over the shoulder than this fraction of the chain's length.
HEIGHT = 0.9
#: ``--mpc-objective tip``: dm_control's acrobot target radius (0.2 m) and reward margin (1 m) as fractions of its
#: chain's length (2 m), for :func:`tip_objective`.
TARGET_RADIUS, TARGET_MARGIN = 0.1, 0.5


def _tip_and_shoulder(params):
    """MuJoCo's model of ``params`` and ``qpos -> (tip, shoulder)``: the site ``tip``'s position (3,) m and the body
    ``upper_arm``'s height (m) in that configuration."""
    m, d = make_mujoco(params)
    tip, shoulder = m.site("tip").id, m.body("upper_arm").id

    def at(qpos):
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        return np.array(d.site_xpos[tip], float), float(d.xpos[shoulder][2])
    return m, at


def height_uptime(run, params, model, fraction: float = HEIGHT) -> float:
    """RealAIGym's uptime: the fraction of the run's steps (each counted at its start) whose tip (site ``tip``) is
    above the shoulder (body ``upper_arm``) by more than ``fraction`` of the tip's height over it at upright.

    Parameters
    ----------
    run : Rollout
    params : CartPoleParams
        The model MuJoCo ran (dm_control's acrobot: a site ``tip``, a body ``upper_arm``).
    model : CartPoleModel
        Its upright ``x_eq``.
    fraction : float
        Of the chain's length, as RealAIGym's ``height`` (0.9).

    Returns
    -------
    float
        Fraction of the logged time upright by that measure.
    """
    m, tip_and_shoulder = _tip_and_shoulder(params)

    def height(qpos) -> float:
        tip, shoulder = tip_and_shoulder(qpos)
        return float(tip[2] - shoulder)

    top = height(np.asarray(model.x_eq, float)[:m.nq])
    qpos, t = np.asarray(run.qpos, float), np.asarray(run.t, float)
    up = np.array([height(q) > fraction * top for q in qpos[:-1]])
    return float(np.sum(np.diff(t)[up]) / (t[-1] - t[0]))


def tip_objective(params, model):
    """dm_control's acrobot swing-up reward (``dmc_acrobot_swingup``'s planning form, :func:`cartpole.ocp.dmc.
    reward_expression`) on this chain, for a model without dm_control's ``target`` site: ``tolerance(d, (0, r),
    margin, 'long_tail') - w u'u`` with ``d`` the distance (m) from the site ``tip`` to where it is at upright,
    ``r`` and the margin the target's radius and the margin as fractions of the chain's length (``TARGET_RADIUS``,
    ``TARGET_MARGIN``: dm_control's 0.2 m and 1 m of its 2 m chain) and ``w`` dm_control's
    :data:`~cartpole.ocp.dmc.ACROBOT_INPUT_WEIGHT` per ctrl range squared (its ctrl range is 1). A
    :func:`~cartpole.ocp.objectives.reward` of ``x`` (nx,) and ``u`` (nu,), maximised."""

    site = dmc.site(params, "tip")
    m, tip_and_shoulder = _tip_and_shoulder(params)
    top, shoulder = tip_and_shoulder(np.asarray(model.x_eq, float)[:m.nq])
    length = float(top[2] - shoulder)
    radius, margin = TARGET_RADIUS * length, TARGET_MARGIN * length
    u_max = float(np.max(np.abs(m.actuator_ctrlrange)))
    weight = dmc.ACROBOT_INPUT_WEIGHT / u_max**2

    @reward
    def tip_distance(x, u):
        gap = ca.DM(top.reshape(3, 1)) - dmc.site_world(params, site, x[:model.nq])
        dist = ca.sqrt(ca.sumsqr(gap) + dmc.DISTANCE_FLOOR)
        return (dmc.tolerance(dist, (0.0, radius), margin=margin, sigmoid=dmc.SURROGATE_SIGMOID)
                - weight * ca.sumsqr(u))
    return tip_distance


def band_options(params, model, band: float):
    """``acrobot_options()`` with the swing-up MPC taking every state up to ``band`` swing-up energies
    (:func:`cartpole.sim.swingup_energy`) above the upright's, however fast, and kept on up to there: ``calm_energy``
    and ``mpc_energy`` that many J, and ``calm_rate`` the largest hinge rate a state so low can have (all of its
    energy over the lowest pose's kinetic, in the slowest direction of the joint-space inertia over the elbow's
    angles), so that the energy alone decides what is calm."""
    e_swing = swingup_energy(model)
    m, d = make_mujoco(params)
    lowest = min(float(np.linalg.eigvalsh(joint_space_inertia(m, d, np.array([0.0, a])))[0])
                 for a in np.linspace(-np.pi, np.pi, 73))
    top = float(np.sqrt(2.0 * (band + 1.0) * e_swing / lowest))
    opts = acrobot_options()
    return opts.replace(calm_energy=band * e_swing, calm_rate=top, mpc_energy=max(opts.mpc_energy, (band + 1) * e_swing))


def one_run(params, model, library, seed: int, every: float, rate: float, duration: float,
            set_rates: bool = False, decisions: bool = False, resets: int | None = None,
            period: float | None = None, band: float | None = None, stepped: bool = False,
            horizon: float | None = None, iterations: int = 1, objective: str | None = None,
            converge: bool = False) -> dict:
    """One thrown minute from hanging: its row (module docstring; with ``decisions`` each decision's ``t``, ``kind``
    and details but the state); with ``resets`` RealAIGym's reset that many times instead of the throws; ``period``
    the supervisor's control period (s, None: every physics step); ``stepped``, ``horizon``, ``iterations``,
    ``objective`` and ``converge`` as ``--stepped``, ``--mpc-horizon``, ``--mpc-iterations``, ``--mpc-objective`` and
    ``--mpc-converge``."""
    tic = time.perf_counter()
    opts = acrobot_options() if band is None else band_options(params, model, band)
    opts = opts.replace(mpc_horizon=horizon, mpc_iterations=iterations, mpc_converge=converge,
                        **({"charged_latency": 0.0} if stepped else {}),
                        **({"mpc_floor": None} if objective is not None else {}))
    plan = None if objective is None else PlanOptions(exact_discrete=False, objective=tip_objective(params, model))
    sup = supervisor_for(params, model, period=period, plan=plan, options=opts, library=library)
    if resets is None:
        throw = Throw(every, max_rate=rate, seed=seed, set_rates=set_rates).start(
            params, x_eq=model.x_eq, hinges=model.hinges, timestep=params.timestep)
        controller = sup
    else:
        throw = Reset(count=resets, duration=duration, seed=seed).start(
            params, x_hanging=model.x_hanging, hinges=model.hinges, timestep=params.timestep, period=period)
        controller = throw.gate(sup)
    run = simulate(params, controller, np.asarray(model.x_hanging, float), duration, disturbance=throw,
                   options=SimOptions(control_period=period))
    m = uptime_metrics(run, model, events=throw.events, duration=duration)
    hinges = list(model.hinges)
    q = np.asarray(run.qpos, float)[:, hinges]
    up = np.all(np.abs(wrap_angle(q - np.asarray(model.x_eq, float)[hinges])) < UPRIGHT_BAND, axis=1)
    starts = [a for a, _ in throw.events]
    nxt = starts[1:] + [duration]
    left = [b - a for a, b in zip(starts, nxt) if a in m["unrecovered_at"]]
    rates = np.asarray(run.qvel, float)[:, hinges]  # 1-DOF hinges: the same index in qvel as in qpos
    x = np.hstack([np.asarray(run.qpos, float), np.asarray(run.qvel, float)])
    after = [float(model.energy(x[min(np.searchsorted(run.t, b - 1e-9) + 1, len(x) - 1)])) for _, b in throw.events]
    took = [min(s for s in m["swingup_times"] if a < s < b) - a for a, b in zip(starts, nxt)
            if any(a < s < b for s in m["swingup_times"])]
    return {"seed": seed, "uptime": m["uptime"], "uptime_height": height_uptime(run, params, model),
            "throws": m["knockdowns"],
            "throws_while_up": int(sum(up[np.searchsorted(run.t, a)] for a in starts)),
            "swingups": m["swingups"], "recovered": m["recoveries"], "missed_at": m["unrecovered_at"],
            "left_s": left, "recover_s": took, "energy_after_J": after, "decisions": dict(Counter(d.kind for d in sup.decisions)),
            "mpcs": sum(1 for d in sup.decisions if d.kind == "mpc"), "plans": sup.plans,
            "mpc_ms": sup.summary()["mpc_ms"],
            "peak_rate": float(np.max(np.abs(rates))), "replays": bool(replays_exactly(run, params)),
            "diverged": bool(run.info.get("diverged", False)), "wall_s": time.perf_counter() - tic,
            **({"decision_log": [{k: v for k, v in d.to_dict().items() if k != "x0"} for d in sup.decisions]}
               if decisions else {})}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(12)))
    ap.add_argument("--every", type=float, default=EVERY, help="mean s between throws")
    ap.add_argument("--rate", type=float, default=RATE, help="largest change of a hinge's rate, rad/s")
    ap.add_argument("--duration", type=float, default=60.0, help="s of MuJoCo per seed")
    ap.add_argument("--set-rates", action="store_true",
                    help="each throw sets the hinge rates (to at most RATE) instead of adding to them")
    ap.add_argument("--decisions", action="store_true", help="each run's decisions too (decision_log)")
    ap.add_argument("--mjcf", default=ACROBOT, help="the acrobot's MJCF (default dm_control's)")
    ap.add_argument("--reset", action="store_true", help="RealAIGym's reset (PID to a random pose) instead of throws")
    ap.add_argument("--period", type=float, default=None,
                    help="the supervisor's control period, s (default every physics step)")
    ap.add_argument("--mpc-band", type=float, default=None,
                    help="the swing-up MPC takes any state up to this many swing-up energies above the upright's")
    ap.add_argument("--stepped", action="store_true",
                    help="RealAIGym's stepped simulation: each plan charged 0 s of simulated time (not 2 s)")
    ap.add_argument("--mpc-horizon", type=float, default=None, help="the swing-up MPC's horizon, s (default 2)")
    ap.add_argument("--mpc-iterations", type=int, default=1, help="the swing-up MPC's DDP iterations a control period")
    ap.add_argument("--mpc-objective", choices=("tip",), default=None,
                    help="the swing-up MPC's objective: tip, dm_control's acrobot reward on the tip's distance from "
                         "upright (default: the tracking of upright)")
    ap.add_argument("--mpc-converge", action="store_true",
                    help="the swing-up MPC's solution converged at each take-over (its solve charged as a plan is)")
    ap.add_argument("--resets", type=int, default=15, help="with --reset: resets in the run")
    ap.add_argument("--out", default=None, help="also write each row, as it comes, to this JSON-lines file")
    args = ap.parse_args()
    try:  # the supervisor's own checks, before any model is built
        acrobot_options().replace(mpc_horizon=args.mpc_horizon, mpc_iterations=args.mpc_iterations)
    except CartPoleError as exc:
        print(exc, file=sys.stderr)
        sys.exit(2)
    params = read_params(args.mjcf)
    model = build_model(params)
    library = acrobot_library(params, model)
    rows = []
    for s in tqdm(args.seeds, desc="acrobot thrown minutes", file=sys.stderr):
        rows.append(one_run(params, model, library, s, args.every, args.rate, args.duration, args.set_rates,
                            args.decisions, args.resets if args.reset else None, args.period, args.mpc_band,
                            args.stepped, args.mpc_horizon, args.mpc_iterations, args.mpc_objective,
                            args.mpc_converge))
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(rows[-1], default=float) + "\n")
    ups = [r["uptime"] for r in rows]
    print(json.dumps({"seeds": args.seeds, "mjcf": args.mjcf, "reset": args.reset,
                      "resets": args.resets if args.reset else None, "period": args.period, "mpc_band": args.mpc_band,
                      "stepped": args.stepped, "mpc_horizon": args.mpc_horizon, "mpc_iterations": args.mpc_iterations,
                      "mpc_objective": args.mpc_objective, "mpc_converge": args.mpc_converge,
                      "every": args.every, "rate": args.rate, "set_rates": args.set_rates,
                      "duration": args.duration,
                      "runs": rows, "uptime_mean": float(np.mean(ups)), "uptime_median": float(np.median(ups)),
                      "uptime_height_mean": float(np.mean([r["uptime_height"] for r in rows])),
                      "throws": sum(r["throws"] for r in rows), "swingups": sum(r["swingups"] for r in rows),
                      "recovered": sum(r["recovered"] for r in rows),
                      "recover_s": _spread([v for r in rows for v in r["recover_s"]]),
                      "energy_after_J": _spread([v for r in rows for v in r["energy_after_J"]]),
                      "swingup_energy_J": swingup_energy(model),
                      "missed_gap_s": _spread([v for r in rows for v in r["left_s"]]),
                      "all_replay": all(r["replays"] for r in rows)}, default=float))


if __name__ == "__main__":
    main()
