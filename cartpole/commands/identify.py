"""``cartpole identify``: fit MJCF parameters to logged runs and write the fitted MJCF."""
from __future__ import annotations

from cartpole.apps.identify import run_identify
from cartpole.identify.fit import DEFAULT_REGULARIZATION, DEFAULT_SEGMENT_S
from cartpole.progress import stage

HELP = ("fit MJCF parameters (mass, com, inertia, damping, frictionloss, armature, gear) to logged runs by "
        "multiple-shooting least squares; standard errors, correlations, a held-out check and the fitted MJCF")


def add_arguments(parser) -> None:
    """``--log``, ``--holdout``, ``--fit``, ``--regularization``, ``--segment``, ``--name``, ``--no-figure``."""
    parser.add_argument("--log", nargs="+", required=True, metavar="FILE",
                        help="runs to fit: CSV (t, one column per joint, optional <joint>_vel, one per actuator) "
                             "or rollout JSON")
    parser.add_argument("--holdout", nargs="+", default=[], metavar="FILE",
                        help="runs not used for the fit: the fitted and nominal models simulated on them")
    parser.add_argument("--fit", nargs="+", default=["all"], metavar="WHAT",
                        help="parameters by MJCF name: mass:BODY com:BODY inertia:BODY damping:JOINT "
                             "frictionloss:JOINT armature:JOINT gear:ACTUATOR, or all (default: gear, com and "
                             "inertia of hinged bodies, damping and frictionloss of every joint)")
    parser.add_argument("--regularization", type=float, default=DEFAULT_REGULARIZATION, metavar="W",
                        help=f"weight pulling the parameters toward the nominal (default {DEFAULT_REGULARIZATION})")
    parser.add_argument("--segment", type=float, default=DEFAULT_SEGMENT_S, metavar="S",
                        help=f"multiple-shooting segment in s (default {DEFAULT_SEGMENT_S})")
    parser.add_argument("--name", default="fitted", help="stem of the fitted MJCF's file name (default fitted)")
    parser.add_argument("--no-figure", action="store_true", help="skip the held-out figure")


def run(args) -> dict:
    """Fit and write. JSON ``mjcf`` (the nominal) and ``identify`` {``parameters`` (name -> ``nominal``,
    ``fitted``, ``std``), ``names``, ``correlation``, ``warnings``, ``fit_rms`` and ``holdout_rms`` ({``fitted``,
    ``nominal``} -> joint -> m or rad), ``mjcf`` (the fitted file), ``figure``, ``solve_s``, ``iterations``}."""
    with stage("fit"):
        res = run_identify(args.mjcf, args.log, args.out, fit_names=args.fit, holdout=args.holdout,
                           regularization=args.regularization, segment_s=args.segment,
                           figure=not args.no_figure, name=args.name)
    doc = {"mjcf": res.nominal_mjcf, "identify": res.to_dict()}
    if not args.json:
        f = res.fit
        print(f"Fitted {len(f.names)} parameter(s) to {len(args.log)} run(s) in {f.solve_s:.2f} s "
              f"({f.iterations} Gauss-Newton iterations):")
        for q, v, s in zip(f.parameters, f.fitted, f.std):
            print(f"  {q.name:24s} nominal {q.nominal:<12.6g} fitted {v:<12.6g} +- {s:.3g}")
        for w in f.warnings:
            print(f"Warning: {w}")
        for label, rms in (("fitted runs", res.fit_rms), ("held-out runs", res.holdout_rms)):
            if rms:
                print(f"Open-loop RMS on the {label}: " + "; ".join(
                    f"{j}: nominal {rms['nominal'][j]:.3g}, fitted {rms['fitted'][j]:.3g}" for j in rms["fitted"]))
        print(f"Fitted MJCF: {res.mjcf}")
        if res.figure:
            print(f"Figure: {res.figure}")
    return doc
