"""``cartpole sweep``: the swing-up's robustness sweep, one row per seeded start, results written as CSV."""
from __future__ import annotations

from pathlib import Path

HELP = "robustness sweep of the swing-up from seeded perturbed starts, in MuJoCo, one row per run"
DESCRIPTION = (HELP + ". Each run is `cartpole swingup` from its own start; a success swings up, holds and replays "
               "exactly. Runs on this machine only: --workers processes (a cluster --address is not implemented "
               "yet). Writes sweeps/sweep_<method>.csv under --out; no live view (--view is for one run, "
               "`cartpole swingup --view`).")

#: The results file under ``--out``.
RESULTS = Path("sweeps") / "sweep_{method}.csv"


def add_arguments(parser) -> None:
    """``--method``, ``--n``, ``--seed``, ``--workers``, ``--duration``, ``--jitter``."""
    from cartpole.sweep import MAX_RUNS, MAX_WORKERS

    parser.add_argument("--method", choices=("energy", "trajopt"), default="energy",
                        help="swing-up of every run: energy shaping + LQR catch (default) or collocation + TVLQR")
    parser.add_argument("--n", type=int, default=20, metavar="N",
                        help=f"number of runs (default 20, at most {MAX_RUNS})")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="seed of numpy's default_rng for the starts (and the jitter); default 0")
    parser.add_argument("--workers", type=int, default=1, metavar="W",
                        help=f"processes to spread the runs over, one model each (default 1, at most {MAX_WORKERS}); "
                             "the rows are the same for any W")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="simulated seconds per run (default 10 for energy, plan + 3 for trajopt)")
    parser.add_argument("--jitter", type=float, default=0.0, metavar="J",
                        help="energy only: relative jitter in [0, 1) of the energy-shaping gains per run (default 0)")


def _csv_rows(result, params):
    """The CSV header (start columns named by the MJCF's joints) and one row per run; empty cells for None."""
    names = [j.name for j in params.joints]
    header = (["run"] + [f"x0_{n}" for n in names] + [f"x0_{n}_rate" for n in names]
              + ["success", "replays", "time_to_upright_s", "caught_at_s", "cart_clearance_m", "peak_ctrl", "error"])
    rows = []
    for r in result.rows():
        def cell(v):
            return "" if v is None else v
        rows.append([r["run"], *[repr(float(v)) for v in r["start"]], r["success"], r["replays"],
                     cell(r["time_to_upright"]), cell(r["caught_at"]), cell(r["cart_clearance"]),
                     cell(r["peak_ctrl"]), cell(r["error"])])
    return header, rows


def run(args) -> dict:
    """Run the sweep on ``args.mjcf``, write the CSV results under ``args.out`` and return the JSON document:
    ``mjcf``, ``method``, ``n``, ``successes`` and the rest of :meth:`~cartpole.sweep.SweepResult.summary`,
    ``rows`` (one per run, in run order: ``run``, ``start``, ``success``, ``replays``, ``time_to_upright``,
    ``caught_at``, ``cart_clearance``, ``peak_ctrl``, ``error``) and ``results`` (the CSV's absolute path)."""
    from cartpole._files import write_csv
    from cartpole.commands.swingup import check_duration
    from cartpole.models import read_params
    from cartpole.sweep import _check, summary_line, swingup_sweep

    params = read_params(args.mjcf)
    _check(args.method, args.n, args.workers, args.jitter, None, None)
    duration = check_duration(args.duration, params)
    result = swingup_sweep(params, method=args.method, n=args.n, seed=args.seed, workers=args.workers,
                           duration=duration, gain_jitter=args.jitter)
    header, rows = _csv_rows(result, params)
    path = write_csv(Path(args.out) / str(RESULTS).format(method=args.method), header, rows).resolve()
    doc = {**result.summary(), "rows": result.rows(), "results": str(path)}
    if not args.json:
        print(summary_line(doc))
        for r in doc["rows"]:
            t = "never" if r["time_to_upright"] is None else f"{r['time_to_upright']:.3f} s"
            start = " ".join(f"{v:+.3f}" for v in r["start"])
            why = f" ({r['error']})" if r["error"] else ("" if r["replays"] else " (log does not replay)")
            print(f"  run {r['run']:3d}: start [{start}]: {'success' if r['success'] else 'FAILED'}, time to "
                  f"upright {t}{why}")
        print(f"Results: {path}")
    return doc
