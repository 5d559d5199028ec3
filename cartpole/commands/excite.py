"""``cartpole excite``: log an informative experiment (hanging, open-loop multisine) in the ``--log`` CSV format."""
from __future__ import annotations

import math
from pathlib import Path

import cartpole.apps.excite as excite_app
from cartpole.commands._rig import add_budget_argument, check_budget
from cartpole.commands._view import add_view_arguments, show_runs, view_mode
from cartpole.models import build_model, read_params

HELP = ("run an open-loop multisine from hanging rest around the pendulum's natural frequencies (or add it to the "
        "LQR balancing the pole: --mode balance), inside the rail and ctrl limits, and log it as the CSV "
        "`cartpole identify --log` reads")


def add_arguments(parser) -> None:
    """``--duration``, ``--sample``, ``--amplitude``, ``--dry-run``, ``--csv``, the encoder and noise options,
    ``--max-steps``."""
    parser.add_argument("--mode", choices=("hanging", "balance"), default="hanging",
                        help="hanging: open loop from hanging rest (default); balance: the LQR holds the pole "
                             "upright with the multisine added to its ctrl")
    parser.add_argument("--duration", type=float, default=20.0, metavar="S", help="seconds to log (default 20)")
    parser.add_argument("--sample", type=float, default=None, metavar="S",
                        help="log step and ctrl hold in s, a whole number of MJCF steps (default one step)")
    parser.add_argument("--amplitude", type=float, default=None, metavar="A",
                        help="multisine envelope as a fraction of the ctrl half-range (default hanging: the "
                             "largest, up to 0.8, keeping the nominal cart within 60 %% of its rail; balance: 0.15)")
    parser.add_argument("--dry-run", action="store_true",
                        help="write the ctrl only (positions left empty), to play the signal on a real rig")
    parser.add_argument("--csv", default="excite.csv", metavar="NAME", help="CSV file name under --out")
    parser.add_argument("--encoder-cpr", type=float, default=None, metavar="N",
                        help="counts per revolution of every hinge encoder (e.g. 2048); default not quantised")
    parser.add_argument("--encoder-resolution", type=float, default=None, metavar="M",
                        help="metres per count of every slide encoder (e.g. 0.001); default not quantised")
    parser.add_argument("--sensor-noise", type=float, default=None, metavar="STD",
                        help="standard deviation of every sensor's noise in its units; default the MJCF's, else 0")
    parser.add_argument("--noise-seed", type=int, default=0, metavar="N", help="seed of the sensor noise")

    add_budget_argument(parser)

    add_view_arguments(parser, "show the experiment live once logged, in real time, replayed from its log (desktop "
                               "without a display: a note on stderr and the rest as usual)")


def run(args) -> dict:
    """Design, run and log. JSON ``excite`` {``csv``, ``rollout``, ``duration``, ``sample_time``, ``amplitude``,
    ``frequencies``, ``natural_frequencies``, ``dry_run``}."""
    if not args.dry_run and math.isfinite(args.duration) and args.duration > 0:  # else run_excite's own sentence
        check_budget(args, build_model(args.mjcf), [(1, args.duration, "the experiment")])

    view = view_mode(args, "excite")
    experiment = excite_app.ExciteOptions(duration=args.duration, sample_time=args.sample, amplitude=args.amplitude,
                                          mode=args.mode, seed=args.noise_seed, encoder_cpr=args.encoder_cpr,
                                          encoder_resolution=args.encoder_resolution, sensor_noise=args.sensor_noise)
    res = excite_app.run_excite(args.mjcf, args.out, experiment, dry_run=args.dry_run, csv_name=args.csv)
    e = res.excitation
    if view and res.rollout is not None:
        show_runs(read_params(args.mjcf), [res.rollout], view, args, command="excite")
    rollout = None if res.rollout is None else str(Path(args.out) / (Path(args.csv).stem + "_rollout.json"))
    doc = {"mjcf": str(Path(args.mjcf).resolve()) if args.mjcf else None,
           "excite": {"csv": str(res.csv), "rollout": rollout, "duration": float(e.t[-1]),
                      "sample_time": float(e.t[1] - e.t[0]), "amplitude": e.amplitude,
                      "frequencies": e.frequencies, "natural_frequencies": e.natural_frequencies,
                      "dry_run": bool(args.dry_run), "mode": args.mode}}
    if not args.json:
        print(f"Hanging natural frequencies: {', '.join(f'{w:.3f}' for w in e.natural_frequencies)} rad/s; "
              f"multisine of {len(e.frequencies)} sines {e.frequencies[0]:.2f}..{e.frequencies[-1]:.2f} rad/s at "
              f"{e.amplitude:.2f} of the ctrl half-range.")
        print(f"{'Ctrl written (dry run)' if args.dry_run else 'Logged'}: {res.csv}")
    return doc
