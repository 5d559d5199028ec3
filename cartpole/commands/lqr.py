"""``cartpole lqr``: the day-5 LQR balance lab with its true numbers, figure, video and metrics row."""
from __future__ import annotations

import datetime
import subprocess
import sys
from pathlib import Path

import numpy as np

from cartpole._files import atomic_write

HELP = ("the LQR balance lab: K, settling times from 5 initial conditions in MuJoCo, figure, 10 s video "
        "and a metrics row")

FIGURE = Path("figures") / "day5_cartpole_lqr.png"
VIDEO = Path("videos") / "day5_cartpole.mp4"
METRICS = Path("metrics") / "metrics.csv"
VIDEO_SECONDS = 10.0

#: Columns of ``metrics.csv`` (the handout's row shape; the header is written only when the file is created).
METRICS_HEADER = "run_id,date,day,task,commit,seed,env,method,steps,runs,metric,value,notes"


def add_arguments(parser) -> None:
    """``--no-video`` and ``--discrete``."""
    parser.add_argument("--no-video", action="store_true", help="skip rendering the 10 s video")
    parser.add_argument("--discrete", action="store_true",
                        help="design K with dlqr on (Ad, Bd), one step of the MJCF's integrator, instead of "
                             "lqr on the continuous (A, B)")


def git_short_sha() -> str:
    """Short commit hash of the repository holding this package, or ``'nogit'``."""
    try:
        r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).resolve().parent,
                           capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "nogit"
    sha = r.stdout.strip()
    return sha if r.returncode == 0 and sha else "nogit"


def metrics_row(result, *, date: str | None = None, commit: str | None = None) -> str:
    """The lab's ``metrics.csv`` row for a :class:`~cartpole.lab.LabResult` (no newline).

    ``steps`` is the number of physics steps of one run; ``value`` the mean of the handout's settling time (s).
    """
    date = date or datetime.date.today().isoformat()
    commit = commit or git_short_sha()
    n = len(result.rollouts)
    return (f"day5_cartpole_lqr,{date},5,cartpole_lqr,{commit},0,cartpole,lqr,{result.steps},1,"
            f"settling_time_sec,{result.mean_settling_time_seed:.4f},{n}_ICs")


def append_metrics(path: Path, row: str) -> Path:
    """Append ``row`` to the CSV at ``path`` (header first when creating it); rewritten whole
    (:func:`~cartpole._files.atomic_write`)."""
    old = path.read_text() if path.exists() else METRICS_HEADER + "\n"
    if old and not old.endswith("\n"):
        old += "\n"
    return atomic_write(path, lambda fh: fh.write((old + row + "\n").encode()))


def _progress(label: str):
    def report(frac: float) -> None:
        end = "\n" if frac >= 1.0 else ""
        print(f"\r{label}: {frac:4.0%}", end=end, file=sys.stderr, flush=True)
    return report


def run(args) -> dict:
    """Run the lab on ``args.mjcf``, write its outputs under ``args.out`` and return the JSON document."""
    from cartpole.lab import run_lab
    from cartpole.sim import simulate
    from cartpole.viz import VideoUnavailable, plot_lab, render_video

    # Everything that can fail on bad input happens before the first file is written.
    result = run_lab(args.mjcf, discrete=args.discrete)
    out = Path(args.out)
    figure = plot_lab(result, out / FIGURE).resolve()
    video = None
    if not args.no_video:
        clip = simulate(result.params, result.controller(), result.x0s[0], VIDEO_SECONDS)
        try:
            video = render_video(result.params, clip, out / VIDEO,
                                 progress=_progress(f"rendering {VIDEO.as_posix()}")).resolve()
        except VideoUnavailable as exc:
            print(f"cartpole lqr: no video: {exc}", file=sys.stderr)
    metrics = append_metrics(out / METRICS, metrics_row(result)).resolve()

    ts_seed = result.settling_times_seed
    doc = {
        "mjcf": result.mjcf,
        "discrete": result.discrete,
        "A": result.A, "B": result.B,
        "K": result.K,
        "closed_loop_eigenvalues": {"real": result.E.real, "imag": result.E.imag},
        "x_eq": result.x_eq,
        "initial_conditions": result.x0s,
        "duration": result.duration,
        "settling_times_seed": ts_seed,
        "settling_times": result.settling_times,
        "settling_definition": ("settling_times_seed: t of the sample after the last with |theta| > 0.05 rad; "
                                "settling_times: first t after which |s-s*|, |theta|, |s_dot|, |theta_dot| all "
                                "stay <= 0.01 (m, rad, m/s, rad/s) to the end; null = never"),
        "mean_settling_time_seed": result.mean_settling_time_seed,
        "std_settling_time_seed": result.std_settling_time_seed,
        "settled": list(result.settled),
        "peak_ctrl": [m.peak_ctrl for m in result.metrics],
        "saturation_fraction": [m.saturation_fraction for m in result.metrics],
        "track_margin": [m.track_margin for m in result.metrics],
        "figure": str(figure),
        "video": None if video is None else str(video),
        "metrics": str(metrics),
    }
    if not args.json:
        _print_prose(result, doc)
    return doc


def _print_prose(result, doc) -> None:
    q = ", ".join(f"{v:g}" for v in np.diag(result.Q))
    r = ", ".join(f"{v:g}" for v in np.ravel(result.R))
    kind = "dlqr on (Ad, Bd), one MJCF integrator step" if result.discrete else "lqr on the continuous (A, B)"
    with np.printoptions(precision=4, suppress=True, linewidth=100):
        print(f"MJCF: {result.mjcf}")
        print("State x = [cart position (m), pole angle (rad), cart velocity (m/s), pole rate (rad/s)]; "
              "u = MuJoCo ctrl (force = gear * ctrl)")
        print("Linearized system at upright rest (exact, symbolic): x_dot = A x + B u")
        print("A =\n", result.A)
        print("B =\n", result.B)
        print(f"LQR ({kind}), Q = diag({q}), R = {r}, law u = -K (x - x*):")
        print("K =", result.K)
        print("Closed-loop eigenvalues:", result.E)
        print(f"Settling from {len(result.x0s)} initial conditions, {result.duration:g} s each in MuJoCo "
              "(handout's definition: |theta| stays <= 0.05 rad; strict: whole state within 0.01 of x*):")
        for i, (x0, ts, st, ok) in enumerate(zip(result.x0s, doc["settling_times_seed"], doc["settling_times"],
                                                 doc["settled"]), 1):
            print(f"  IC {i}: theta0 = {np.rad2deg(x0[1]):6.2f} deg, x0 = {x0[0]:+.2f} m: settling time "
                  f"{ts:.2f} s, strict {st:.2f} s, {'settled' if ok else 'NOT settled'}")
    print(f"Mean settling time: {result.mean_settling_time_seed:.2f} s ± {result.std_settling_time_seed:.2f} s "
          f"across {len(result.x0s)} initial conditions")
    print(f"Wrote {doc['figure']}")
    if doc["video"]:
        print(f"Wrote {doc['video']}")
    print(f"Appended a row to {doc['metrics']}")
