"""``cartpole score``: the dm_control suite's and Gymnasium's own episodes, from their own resets, run with the
toolkit's controllers and scored by the environments' own rewards (:mod:`cartpole.apps.envscore`)."""
from __future__ import annotations

import sys

from cartpole.apps.envscore import CONTROLLERS, ENVIRONMENTS, EnvScoreError, score

HELP = ("run dm_control's and Gymnasium's own episodes (their resets, their rewards) with the toolkit's controllers "
        "and report the returns beside the best published learned agent's")

#: score prints and writes no files.
WRITES_FILES = False


def add_arguments(parser) -> None:
    """``--env NAME`` (repeatable), ``--n N``, ``--seed S``, ``--max-steps K``, ``--controller NAME``."""
    parser.add_argument("--env", action="append", default=None, metavar="NAME", choices=list(ENVIRONMENTS),
                        help=f"environment to score, repeatable: {', '.join(ENVIRONMENTS)} (default: every one)")
    parser.add_argument("--n", type=int, default=10, metavar="N",
                        help="episodes per environment, reset with seeds S, S+1, ..., S+N-1 (default 10)")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="first reset seed (default 0)")
    parser.add_argument("--max-steps", type=int, default=None, metavar="K", dest="max_steps",
                        help="stop each episode after K environment steps (default: the environment's own episode)")
    parser.add_argument("--controller", default="toolkit", choices=list(CONTROLLERS),
                        help="toolkit: each environment's controller designed from its start (default); supervisor: "
                             "the supervisor that decides in the loop (catch, swing-up law or plan, track, brake), its "
                             "planning charged its wall time; supervisor-stepped: the same supervisor with the "
                             "environment waiting for each action, as for any agent (planning charged no time; the "
                             "acrobot's swing-up MPC designed afresh at each take-over)")


def run(args) -> dict:
    """Score each ``--env`` over ``--n`` seeds from ``--seed``.

    JSON: ``environments``, one object per environment (:func:`cartpole.apps.envscore.score`): ``env``, ``seeds``,
    ``returns`` (one per seed, the sum of the rewards the environment's ``step`` paid), ``mean_return``,
    ``min_return``, ``reference`` (the best published learned agent's return, or null), ``reference_source``,
    ``above_reference``, ``all_replay`` (every episode's states reproduced bit for bit by the toolkit's MuJoCo run of
    its logged ctrl), ``any_warned`` and ``episodes`` (per seed: ``seed``, ``x0``, ``return``, ``steps``,
    ``terminated``, ``replays``, ``warned``, ``design_s``, ``mjcf``, ``design``) and ``controller`` (the
    ``--controller`` that ran).
    """
    if args.mjcf is not None:
        raise EnvScoreError("score runs each environment on its own file; leave out --mjcf (pick environments with "
                            "--env).")
    if args.max_steps is not None and args.max_steps < 1:
        raise EnvScoreError(f"--max-steps {args.max_steps} must be at least 1 environment step.")
    if args.n < 1:
        raise EnvScoreError(f"--n {args.n} must be at least 1 episode.")
    if args.seed < 0:
        raise EnvScoreError(f"--seed {args.seed} must be a whole number >= 0.")
    names = args.env or list(ENVIRONMENTS)

    def report(ep):
        looped = sum(d.get("design_s", 0.0) for d in (ep.design or {}).get("decisions", ()))
        print(f"{ep.env} seed {ep.seed}: return {ep.return_:.1f} over {ep.steps} steps"
              f"{' (terminated)' if ep.terminated else ''}, replays {'exactly' if ep.replays else 'NOT exactly'}"
              f"{', MuJoCo warned' if ep.warned else ''}; controller designed in {ep.design_s:.1f} s"
              f"{f', its MPC designed in the loop in {looped:.1f} s' if looped else ''}",
              file=sys.stderr if args.json else sys.stdout, flush=True)

    results = [{**score(name, args.n, args.seed, controller=CONTROLLERS[args.controller], on_episode=report,
                        max_steps=args.max_steps), "controller": args.controller} for name in names]
    if not args.json:
        for r in results:
            ref = "" if r["reference"] is None else (f"; best published learned agent {r['reference']:g} "
                                                     f"({'below' if r['above_reference'] else 'NOT below'} ours)")
            print(f"{r['env']} ({r['controller']}): mean return {r['mean_return']:.1f} over seeds {r['seeds'][0]}-{r['seeds'][-1]} "
                  f"(least {r['min_return']:.1f}){ref}")
    return {"environments": results}
