"""``cartpole sweep``: robustness sweeps of the swing-up over a description (grids and seeded samples of starts, pushes,
model error and controller settings; :mod:`cartpole.apps.sweep`), one row per run, appended to a CSV results file as each
run finishes (so an interrupt or a crash keeps what finished; ``--resume`` goes on from there), on this machine's
processes or on a Dask distributed cluster, and a success map figure (with several ``--method``, also side by
side)."""
from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from pathlib import Path

HELP = ("robustness sweep of the swing-up over starts, pushes, model error and controller settings (grids or "
        "seeded samples), in MuJoCo, one row per run")
DESCRIPTION = (HELP + ". Each run is `cartpole swingup` with its own start, push, model error and settings; a success "
               "swings up, holds and replays exactly. An axis option takes V (fixed), LO HI (a seeded uniform sample "
               "per run, --n of them) or LO HI K (a grid of K points); grid axes multiply. Without axis options: --n "
               "seeded starts around hanging rest. Runs on --workers processes of this machine, or on the workers of "
               "a running Dask distributed scheduler at --address tcp://HOST:PORT. Appends each finished run to "
               "sweeps/sweep_<method>.csv under --out (an interrupt keeps them; --resume skips them), then writes "
               "the success map figures/sweep_<method>.png (over the first two swept axes, or the start angle and "
               "rate); with two or more methods (--method trajopt mpc) each method's sweep, and their success maps "
               "side by side in figures/sweep_compare.png. No live view (--view is for one run, "
               "`cartpole swingup --view`).")

#: The results file and the success map under ``--out``; the side-by-side map of several methods.
RESULTS = Path("sweeps") / "sweep_{method}.csv"
FIGURE = Path("figures") / "sweep_{method}.png"
COMPARE = Path("figures") / "sweep_compare.png"
#: Runs without axes (and draws per grid cell with a sampled axis) when --n is not given.
DEFAULT_N = 20


def add_arguments(parser) -> None:
    """``--method``, ``--n``, ``--seed``, ``--workers``, ``--address``, ``--duration``, ``--jitter``, ``--resume``
    (and the hidden testing option ``--stop-after K``)."""
    import argparse

    from cartpole.apps.sweep import MAX_RUNS, MAX_WORKERS

    parser.add_argument("--method", nargs="+", choices=("energy", "trajopt", "mpc"), default=["energy"],
                        metavar="M", help="swing-up of every run: energy (energy shaping + LQR catch, default), "
                                          "trajopt (collocation + TVLQR) or mpc (nonlinear MPC); two or more: the "
                                          "same sweep for each, and their success maps side by side")
    parser.add_argument("--n", type=int, default=None, metavar="N",
                        help=f"number of runs without axis options (default {DEFAULT_N}), or of seeded draws per "
                             f"grid cell when an axis is sampled (LO HI); at most {MAX_RUNS} runs in all")
    axis_help = "V (fixed), LO HI (seeded uniform sample) or LO HI K (grid of K points)"
    parser.add_argument("--push-force", nargs="+", type=str, default=None, metavar="F",
                        help=f"push force in N on the cart for 0.1 s (0: no push): {axis_help}")
    parser.add_argument("--push-time", nargs="+", type=str, default=None, metavar="T",
                        help=f"push start time in s (default 0.5 with --push-force): {axis_help}")
    parser.add_argument("--model-error", nargs="+", type=str, default=None, metavar="S",
                        help="scale of the planning model's pole masses and lengths (1: the MJCF's own; MuJoCo "
                             f"keeps the MJCF's): {axis_help}")
    parser.add_argument("--start", nargs="+", action="append", default=None, metavar="NAME V",
                        help="a start-state component: NAME a joint of the MJCF (its position, m or rad) or "
                             f"NAME_rate (its rate), then {axis_help}; repeatable; other components from --x0")
    parser.add_argument("--setting", nargs="+", action="append", default=None, metavar="NAME V",
                        help="a controller setting: for energy a scaling of the energy shaping (energy_gain, "
                             "overshoot, ...), for mpc period or horizon (s); then " + axis_help + "; repeatable")
    parser.add_argument("--x0", nargs="+", type=float, default=None, metavar="V",
                        help="with axis options: the start of every run where no --start sets a component, 2 nq "
                             "numbers [qpos, qvel] (default hanging at rest)")
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
                             "duration, jitter, axes, x0, MJCF) and run only the others")
    parser.add_argument("--stop-after", type=int, default=None, help=argparse.SUPPRESS)  # testing: interrupt after K


def sweep_id(params, args, duration, method: str | None = None, axes=(), x0=None) -> str:
    """12 hex digits naming the sweep description (MJCF path and content, method, n, seed, duration, jitter, axes,
    x0): the ``sweep`` column of every row, which ``--resume`` matches. (A description without axes keeps the id it
    had before axes existed.)"""
    try:
        digest = hashlib.sha256(Path(params.mjcf).read_bytes()).hexdigest()
    except OSError:
        digest = ""
    method = method or (args.method if isinstance(args.method, str) else args.method[0])
    desc = {"mjcf": str(params.mjcf), "mjcf_sha256": digest, "method": method, "n": int(args.n),
            "seed": int(args.seed), "duration": duration, "jitter": float(args.jitter)}
    if axes:
        desc["axes"] = [a.describe() for a in axes]
    if x0 is not None:
        desc["x0"] = [float(v) for v in x0]
    return hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:12]


def header(params, settings=()) -> list[str]:
    """The CSV header: ``sweep``, ``run``, the start (columns named by the MJCF's joints), the push
    (``push_time_s``, empty without a push, and ``push_force_N``), ``model_error``, one ``setting_<name>`` per
    swept controller setting, the outcome."""
    names = [j.name for j in params.joints]
    return (["sweep", "run"] + [f"x0_{n}" for n in names] + [f"x0_{n}_rate" for n in names]
            + ["push_time_s", "push_force_N", "model_error"] + [f"setting_{k}" for k in settings]
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


def _csv_line(sid, i, start, row, settings=()) -> list:
    num = {k: (None if row[k] is None or not math.isfinite(row[k]) else float(row[k]))
           for k in ("time_to_upright", "caught_at", "cart_clearance", "peak_ctrl")}
    r = {**row, **num}
    push = list(row.get("push") or ())
    when = repr(float(push[0][0])) if push else ""
    force = repr(float(sum(F for _, F in push)))
    st = row.get("settings") or {}
    return [sid, int(i), *[repr(float(v)) for v in start], when, force, repr(float(row.get("model_error", 1.0))),
            *[repr(float(st[k])) if k in st else "" for k in settings], bool(r["success"]), bool(r["replays"]),
            *[_cell(num[k]) for k in ("time_to_upright", "caught_at", "cart_clearance", "peak_ctrl")],
            failure(r), _cell(r["error"])]


def _parse(line: dict) -> dict:
    """A runner row (the keys :class:`cartpole.apps.sweep._Runner` returns) from one CSV row."""
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
    from cartpole.apps.sweep import SweepError

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


def sweep_axes(args) -> tuple:
    """The sweep description of the command line's axis options, in a fixed order (``--push-force``,
    ``--model-error``, ``--push-time``, each ``--start``, each ``--setting``): the first grid axis varies slowest and
    the first two swept axes are the success map's x and y.

    Raises
    ------
    SweepError
        Bad numbers for an axis (:func:`cartpole.apps.sweep.axis`).
    """
    from cartpole.apps.sweep import SweepError, axis

    axes = []
    for flag, name in (("push_force", "push_force"), ("model_error", "model_error"), ("push_time", "push_time")):
        values = getattr(args, flag, None)
        if values is not None:
            axes.append(axis(name, *values))
    for flag, prefix in (("start", "start:"), ("setting", "setting:")):
        for item in getattr(args, flag, None) or []:
            if len(item) < 2:
                raise SweepError(f"--{flag} takes a name, then V, LO HI or LO HI K; got {' '.join(item)}.")
            axes.append(axis(prefix + item[0], *item[1:]))
    return tuple(axes)


def _plan(args, params):
    """Validate everything before any run: the methods, n, workers, duration, axes and x0 for every method."""
    from cartpole.commands.swingup import check_duration
    from cartpole.apps.sweep import SweepError, _check, check_axes

    methods = list(dict.fromkeys(args.method if isinstance(args.method, list) else [args.method]))
    axes = sweep_axes(args)
    sampled = any(a.random for a in axes)
    if axes and not sampled and args.n is not None:
        cells = 1
        for a in axes:
            cells *= a.count
        raise SweepError(f"This sweep is a grid of {cells} run(s) and --n counts seeded draws; drop --n or give an "
                         "axis as LO HI to sample it.")
    if args.x0 is not None and not axes:
        raise SweepError("--x0 fixes the start of a sweep over axis options; without them the starts fill the start "
                         "box (give e.g. --push-force -20 20 5).")
    n = DEFAULT_N if args.n is None else args.n
    for m in methods:
        _check(m, n, args.workers, args.jitter, None, None)
        check_axes(axes, params, m)
    if args.stop_after is not None and args.stop_after < 1:
        raise SweepError(f"--stop-after needs at least 1 run (got {args.stop_after}).")
    duration = check_duration(args.duration, params)
    x0 = None
    if args.x0 is not None:
        from cartpole.apps.swingup import check_start
        x0 = check_start(args.x0, params)
    return methods, axes, n, duration, x0


def run(args) -> dict:
    """Run the sweep (one per ``--method``) and return the JSON document: for one method that of
    :func:`run_method`; for several ``mjcf``, ``methods``, ``sweeps`` (each method's document) and ``figure`` (the
    success maps side by side, :func:`cartpole.viz.sweep_plot.plot_comparison`)."""
    from cartpole.models import read_params

    params = read_params(args.mjcf)
    methods, axes, n, duration, x0 = _plan(args, params)
    docs, results = [], []
    for m in methods:
        doc, result = run_method(args, params, m, axes=axes, n=n, duration=duration, x0=x0)
        docs.append(doc)
        results.append(result)
    if len(methods) == 1:
        return docs[0]
    from cartpole.viz.sweep_plot import plot_comparison

    figure = plot_comparison(results, params, Path(args.out) / COMPARE)
    if not args.json:
        print(f"Success maps side by side: {Path(figure).resolve()}")
    return {"mjcf": params.mjcf, "methods": methods, "sweeps": docs, "figure": str(Path(figure).resolve())}


def run_method(args, params, method: str, *, axes=(), n: int = DEFAULT_N, duration=None, x0=None):
    """Run one method's sweep on ``params``, appending each finished run to the CSV results under ``args.out``, then
    rewrite it in run order and draw the success map; return ``(doc, SweepResult)``, the JSON document being:
    ``mjcf``, ``method``, ``n``, ``successes`` and the rest of :meth:`~cartpole.apps.sweep.SweepResult.summary`, ``rows``
    (one per run, in run order: ``run``, ``start``, ``push``, ``model_error``, ``settings``, ``success``,
    ``replays``, ``time_to_upright``, ``caught_at``, ``cart_clearance``, ``peak_ctrl``, ``error``, ``failure``),
    ``results`` (the CSV's absolute path), ``figure`` (the PNG's), ``sweep`` (the description's id) and ``resumed``
    (runs taken from the file)."""
    from cartpole._files import short, write_csv
    from cartpole.errors import CartPoleError
    from cartpole.apps.sweep import summary_line, swingup_sweep
    from cartpole.viz.sweep_plot import plot_success_map

    args.n = n
    sid = sweep_id(params, args, duration, method, axes, x0)
    settings = tuple(a.name[len("setting:"):] for a in axes if a.name.startswith("setting:"))
    head = header(params, settings)
    path = Path(args.out) / str(RESULTS).format(method=method)
    done = read_done(path, head, sid, MAX_READ) if args.resume else {}
    appender = []  # opened on the first finished run, so a sweep refused before any run writes nothing
    count = [0]

    def on_row(i, start, row):
        if not appender:
            appender.append(_Appender(path, head, fresh=not args.resume))
        appender[0].write(_csv_line(sid, i, start, row, settings))
        count[0] += 1
        if args.stop_after is not None and count[0] >= args.stop_after and \
                len(done) + count[0] < _total_runs(axes, n):
            raise KeyboardInterrupt

    try:
        result = swingup_sweep(params, method=method, n=n, seed=args.seed, workers=args.workers,
                               duration=duration, gain_jitter=args.jitter, address=args.address, done=done,
                               on_row=on_row, axes=axes, x0=x0)
        for a in appender:
            a.close()
        rows = result.rows()
        for r in rows:
            r["failure"] = failure(r)
        write_csv(path, head, [_csv_line(sid, r["run"], r["start"], r, settings) for r in rows])  # in run order
    except KeyboardInterrupt:
        for a in appender:
            a.close()
        try:  # what the file holds now is what a resume will keep
            finished = len(read_done(path, head, sid, MAX_READ))
        except CartPoleError:
            finished = len(done) + count[0]
        again = "the same command with --resume" if not args.resume else "the same command again"
        runs = _total_runs(axes, n)
        raise KeyboardInterrupt(f"interrupted after {finished} of {runs} runs, kept in {short(path)}; run "
                                f"{again} to finish the others.") from None
    finally:
        for a in appender:
            a.close()
    figure = plot_success_map(result, params, Path(args.out) / str(FIGURE).format(method=method))
    doc = {**result.summary(), "rows": rows, "results": str(path.resolve()), "figure": str(Path(figure).resolve()),
           "sweep": sid, "resumed": len(done)}
    if not args.json:
        print(summary_line(doc))
        for r in doc["rows"]:
            t = "never" if r["time_to_upright"] is None else f"{r['time_to_upright']:.3f} s"
            start = " ".join(f"{v:+.3f}" for v in r["start"])
            scenario = "".join(f", push {F:+g} N at {T:g} s" for T, F in r["push"]) + (
                f", model error {r['model_error']:g}" if r["model_error"] != 1.0 else "") + "".join(
                f", {k} {v:g}" for k, v in r["settings"].items())
            why = f" ({r['error']})" if r["error"] else (f" ({r['failure']})" if r["failure"] else "")
            print(f"  run {r['run']:3d}: start [{start}]{scenario}: {'success' if r['success'] else 'FAILED'}, "
                  f"time to upright {t}{why}")
        if done:
            print(f"Resumed: {len(done)} of {result.n} runs were already in the results file.")
        print(f"Results: {doc['results']}")
        print(f"Success map: {doc['figure']}")
    return doc, result


#: Largest run index read back from a results file (the sweep itself keeps only its own runs).
MAX_READ = 10**9


def _total_runs(axes, n: int) -> int:
    """Runs of a description (for the interrupt sentence): the grid's cells, times n with a sampled axis."""
    if not axes:
        return int(n)
    cells = 1
    for a in axes:
        if not a.random:
            cells *= a.count
    return cells * (int(n) if any(a.random for a in axes) else 1)
