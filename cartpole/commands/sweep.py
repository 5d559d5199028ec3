"""``cartpole sweep``: the swing-up's robustness sweep, one row per seeded start, appended to a CSV results file as
each run finishes (so an interrupt or a crash keeps what finished; ``--resume`` goes on from there), on this
machine's processes or on a Dask distributed cluster, and a success map figure."""
from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from pathlib import Path

HELP = "robustness sweep of the swing-up from seeded perturbed starts, in MuJoCo, one row per run"
DESCRIPTION = (HELP + ". Each run is `cartpole swingup` from its own start; a success swings up, holds and replays "
               "exactly. Runs on --workers processes of this machine, or on the workers of a running Dask "
               "distributed scheduler at --address tcp://HOST:PORT. Appends each finished run to "
               "sweeps/sweep_<method>.csv under --out (an interrupt keeps them; --resume skips them), then writes "
               "the success map figures/sweep_<method>.png; no live view (--view is for one run, "
               "`cartpole swingup --view`).")

#: The results file and the success map under ``--out``.
RESULTS = Path("sweeps") / "sweep_{method}.csv"
FIGURE = Path("figures") / "sweep_{method}.png"


def add_arguments(parser) -> None:
    """``--method``, ``--n``, ``--seed``, ``--workers``, ``--address``, ``--duration``, ``--jitter``, ``--resume``
    (and the hidden testing option ``--stop-after K``)."""
    import argparse

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
    parser.add_argument("--address", default=None, metavar="ADDR",
                        help="run on the Dask distributed scheduler at ADDR (tcp://host:port) instead of local "
                             "processes; one model per Dask worker; the same rows")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="simulated seconds per run (default 10 for energy, plan + 3 for trajopt)")
    parser.add_argument("--jitter", type=float, default=0.0, metavar="J",
                        help="energy only: relative jitter in [0, 1) of the energy-shaping gains per run (default 0)")
    parser.add_argument("--resume", action="store_true",
                        help="keep the runs already in the results file (the same sweep: method, N, seed, "
                             "duration, jitter, MJCF) and run only the others")
    parser.add_argument("--stop-after", type=int, default=None, help=argparse.SUPPRESS)  # testing: interrupt after K


def sweep_id(params, args, duration) -> str:
    """12 hex digits naming the sweep description (MJCF path and content, method, n, seed, duration, jitter): the
    ``sweep`` column of every row, which ``--resume`` matches."""
    try:
        digest = hashlib.sha256(Path(params.mjcf).read_bytes()).hexdigest()
    except OSError:
        digest = ""
    desc = {"mjcf": str(params.mjcf), "mjcf_sha256": digest, "method": args.method, "n": int(args.n),
            "seed": int(args.seed), "duration": duration, "jitter": float(args.jitter)}
    return hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:12]


def header(params) -> list[str]:
    """The CSV header: ``sweep``, ``run``, the start (columns named by the MJCF's joints), the outcome."""
    names = [j.name for j in params.joints]
    return (["sweep", "run"] + [f"x0_{n}" for n in names] + [f"x0_{n}_rate" for n in names]
            + ["success", "replays", "time_to_upright_s", "caught_at_s", "cart_clearance_m", "peak_ctrl", "failure",
               "error"])


def failure(row) -> str:
    """Why a run failed, in a few words ('' for a success)."""
    if row["success"]:
        return ""
    if row["error"]:
        return "raised"
    if not row["replays"]:
        return "log does not replay"
    if row["cart_clearance"] is not None and row["cart_clearance"] <= 1e-3:
        return "cart reached its limit"
    return "not upright at rest over the last second"


def _cell(v):
    return "" if v is None else v


def _csv_line(sid, i, start, row) -> list:
    num = {k: (None if row[k] is None or not math.isfinite(row[k]) else float(row[k]))
           for k in ("time_to_upright", "caught_at", "cart_clearance", "peak_ctrl")}
    r = {**row, **num}
    return [sid, int(i), *[repr(float(v)) for v in start], bool(r["success"]), bool(r["replays"]),
            *[_cell(num[k]) for k in ("time_to_upright", "caught_at", "cart_clearance", "peak_ctrl")],
            failure(r), _cell(r["error"])]


def _parse(line: dict) -> dict:
    """A runner row (the keys :class:`cartpole.sweep._Runner` returns) from one CSV row."""
    def f(text):
        return math.nan if text == "" else float(text)
    return {"success": line["success"] == "True", "replays": line["replays"] == "True",
            "time_to_upright": f(line["time_to_upright_s"]), "caught_at": f(line["caught_at_s"]),
            "cart_clearance": f(line["cart_clearance_m"]), "peak_ctrl": f(line["peak_ctrl"]),
            "rho": math.nan, "error": line["error"] or None}


def read_done(path: Path, head: list[str], sid: str, n: int) -> dict:
    """``{run: row}`` of the runs already in the results file ``path`` for the sweep ``sid``.

    Raises
    ------
    SweepError
        The file holds another sweep's rows (or another header), in one sentence.
    """
    from cartpole._files import short
    from cartpole.sweep import SweepError

    if not path.exists():
        return {}
    try:
        text = path.read_text()
    except OSError as exc:
        raise SweepError(f"Cannot read {short(path)} to resume ({exc.strerror}); check it or drop --resume.") \
            from None
    lines = text.splitlines()
    if not lines:
        return {}
    if not text.endswith("\n"):
        lines = lines[:-1]  # a row cut short by a crash: run it again
    reader = csv.reader(io.StringIO("\n".join(lines) + "\n"))
    first = next(reader, [])
    if first != head:
        raise SweepError(f"Cannot resume from {short(path)}: its columns are not this sweep's; move it away or drop "
                         "--resume.")
    done = {}
    for fields in reader:
        if len(fields) != len(head):
            continue
        line = dict(zip(head, fields))
        if line["sweep"] != sid:
            raise SweepError(f"Cannot resume from {short(path)}: it holds sweep {line['sweep']}, not this one "
                             f"({sid}: other method, --n, --seed, --duration, --jitter or MJCF); give the same "
                             "settings, another --out, or drop --resume.")
        i = int(line["run"])
        if 0 <= i < n:
            done[i] = _parse(line)
    return done


class _Appender:
    """The results file, opened for appending: one CSV row written and flushed as each run finishes."""

    def __init__(self, path: Path, head: list[str], fresh: bool):
        from cartpole._files import output_error

        self.path = path
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            new = fresh or not path.exists() or path.stat().st_size == 0
            if not new and not path.read_bytes().endswith(b"\n"):  # drop a row a crash cut short
                data = path.read_bytes()
                path.write_bytes(data[:data.rfind(b"\n") + 1])
            self.fh = open(path, "w" if new else "a", newline="")
        except OSError as exc:
            raise output_error(path, exc) from None
        self.writer = csv.writer(self.fh, lineterminator="\n")
        if new:
            self.write(head)

    def write(self, fields) -> None:
        self.writer.writerow(fields)
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def close(self) -> None:
        self.fh.close()


def run(args) -> dict:
    """Run the sweep on ``args.mjcf``, appending each finished run to the CSV results under ``args.out``, then
    rewrite it in run order and draw the success map; return the JSON document: ``mjcf``, ``method``, ``n``,
    ``successes`` and the rest of :meth:`~cartpole.sweep.SweepResult.summary`, ``rows`` (one per run, in run order:
    ``run``, ``start``, ``success``, ``replays``, ``time_to_upright``, ``caught_at``, ``cart_clearance``,
    ``peak_ctrl``, ``error``, ``failure``), ``results`` (the CSV's absolute path), ``figure`` (the PNG's),
    ``sweep`` (the description's id) and ``resumed`` (runs taken from the file)."""
    from cartpole._files import short, write_csv
    from cartpole.commands.swingup import check_duration
    from cartpole.errors import CartPoleError
    from cartpole.models import read_params
    from cartpole.sweep import SweepError, _check, summary_line, swingup_sweep
    from cartpole.viz.sweep_plot import plot_success_map

    params = read_params(args.mjcf)
    _check(args.method, args.n, args.workers, args.jitter, None, None)
    if args.stop_after is not None and args.stop_after < 1:
        raise SweepError(f"--stop-after needs at least 1 run (got {args.stop_after}).")
    duration = check_duration(args.duration, params)
    sid = sweep_id(params, args, duration)
    head = header(params)
    path = Path(args.out) / str(RESULTS).format(method=args.method)
    done = read_done(path, head, sid, args.n) if args.resume else {}
    appender = []  # opened on the first finished run, so a sweep refused before any run writes nothing
    count = [0]

    def on_row(i, start, row):
        if not appender:
            appender.append(_Appender(path, head, fresh=not args.resume))
        appender[0].write(_csv_line(sid, i, start, row))
        count[0] += 1
        if args.stop_after is not None and count[0] >= args.stop_after and len(done) + count[0] < args.n:
            raise KeyboardInterrupt

    try:
        result = swingup_sweep(params, method=args.method, n=args.n, seed=args.seed, workers=args.workers,
                               duration=duration, gain_jitter=args.jitter, address=args.address, done=done,
                               on_row=on_row)
        for a in appender:
            a.close()
        rows = result.rows()
        for r in rows:
            r["failure"] = failure(r)
        write_csv(path, head, [_csv_line(sid, r["run"], r["start"], r) for r in rows])  # whole, in run order
    except KeyboardInterrupt:
        for a in appender:
            a.close()
        try:  # what the file holds now is what a resume will keep
            finished = len(read_done(path, head, sid, args.n))
        except CartPoleError:
            finished = len(done) + count[0]
        again = "the same command with --resume" if not args.resume else "the same command again"
        raise KeyboardInterrupt(f"interrupted after {finished} of {args.n} runs, kept in {short(path)}; run "
                                f"{again} to finish the others.") from None
    finally:
        for a in appender:
            a.close()
    figure = plot_success_map(result, params, Path(args.out) / str(FIGURE).format(method=args.method))
    doc = {**result.summary(), "rows": rows, "results": str(path.resolve()), "figure": str(Path(figure).resolve()),
           "sweep": sid, "resumed": len(done)}
    if not args.json:
        print(summary_line(doc))
        for r in doc["rows"]:
            t = "never" if r["time_to_upright"] is None else f"{r['time_to_upright']:.3f} s"
            start = " ".join(f"{v:+.3f}" for v in r["start"])
            why = f" ({r['error']})" if r["error"] else (f" ({r['failure']})" if r["failure"] else "")
            print(f"  run {r['run']:3d}: start [{start}]: {'success' if r['success'] else 'FAILED'}, time to "
                  f"upright {t}{why}")
        if done:
            print(f"Resumed: {len(done)} of {args.n} runs were already in the results file.")
        print(f"Results: {doc['results']}")
        print(f"Success map: {doc['figure']}")
    return doc

