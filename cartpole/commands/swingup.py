"""``cartpole swingup``: swing the pole up and hold it (energy shaping + LQR catch, or trajopt + TVLQR), in MuJoCo."""
from __future__ import annotations

import math
import sys

HELP = "swing the pole up and hold it upright in MuJoCo (energy shaping + LQR catch, or trajopt + TVLQR)"


def add_arguments(parser) -> None:
    """``--method``, ``--x0``, ``--duration``, ``--no-video``."""
    parser.add_argument("--method", choices=("energy", "trajopt"), default="energy",
                        help="energy shaping with an LQR catch (default) or direct collocation + TVLQR")
    parser.add_argument("--x0", nargs="+", type=float, default=None, metavar="V",
                        help="start state [qpos, qvel], 2 nq numbers in MuJoCo's joint order: every joint's "
                             "position (m or rad, 0 = upright as built), then every joint's rate; one pole: "
                             "X TH XD THD; default every pole hanging at rest (0 pi 0 0 for one pole)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="simulated seconds (default 10 for energy, plan + 3 for trajopt)")
    parser.add_argument("--no-video", action="store_true", help="do not render videos/swingup_<method>.mp4")


def _progress(stage: str, fraction: float) -> None:
    print(f"\rswingup: {stage} {100 * fraction:5.1f} %", end="" if fraction < 1 else "\n", file=sys.stderr,
          flush=True)


def run(args) -> dict:
    """Validate the input, run the swing-up, write the figure (and video) and return the JSON document."""
    from pathlib import Path

    from cartpole.models import build_model
    from cartpole.swingup import SwingupError, check_start, run_swingup
    from cartpole.viz import plot_swingup

    # Everything is validated before anything is computed or written.
    model = build_model(args.mjcf)
    params = model.params
    x0 = check_start(model.x_hanging if args.x0 is None else args.x0, params)
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise SwingupError(f"Duration {args.duration} s is not a positive number of seconds; give e.g. "
                           "--duration 8.")
    out = Path(args.out)

    res = run_swingup(model, method=args.method, x0=x0, duration=args.duration, progress=_progress)
    fig = plot_swingup(res.rollout, params, out / "figures" / f"swingup_{args.method}.png", plan=res.plan,
                       caught_at=res.caught_at, model=model,
                       title=f"Swing-up ({args.method}) in MuJoCo: {'success' if res.success else 'FAILED'}")
    video = None
    if not args.no_video:
        from cartpole.viz import VideoUnavailable, render_video
        try:
            video = render_video(params, res.rollout, out / "videos" / f"swingup_{args.method}.mp4",
                                 progress=lambda f: _progress("video", f))
        except VideoUnavailable as exc:
            print(f"cartpole swingup: no video ({exc})", file=sys.stderr)
    m = res.metrics
    doc = {"mjcf": params.mjcf, "method": args.method, "success": res.success, "caught_at": res.caught_at,
           "rollout": res.rollout.to_dict(), "time_to_upright": m["time_to_upright"],
           "figure": str(fig.resolve()), "video": None if video is None else str(Path(video).resolve()),
           "metrics": {k: v for k, v in m.items()}, "basin": None if res.basin is None else res.basin.summary()}
    if not args.json:
        def fmt(v, unit):
            return "never" if v is None else f"{v:.3f} {unit}"
        print(f"MJCF: {params.mjcf}")
        print(f"Swing-up ({args.method}) from x0 = {list(map(float, x0))}: "
              f"{'SUCCESS' if res.success else 'FAILED'} (upright and at rest for the last 1 s, cart off its "
              "limits, ctrl in range)")
        print(f"Caught at: {fmt(res.caught_at, 's')}; time to upright (every |theta_i| < 0.05 rad for good): "
              f"{fmt(m['time_to_upright'], 's')}")
        print(f"Peak |ctrl|: {m['peak_ctrl']:.3f}; cart range used: [{m['cart_min']:.3f}, {m['cart_max']:.3f}] m "
              f"(closest to a limit: {m['cart_clearance']:.3f} m)")
        if res.basin is not None:
            print(f"Catch basin: e' S e < rho = {res.basin.rho:.4f} ({res.basin.n} MuJoCo samples, seed "
                  f"{res.basin.seed}, safety factor {res.basin.safety_factor})")
        print(f"Figure: {fig}")
        print(f"Video: {video if video is not None else 'not written'}")
    return doc
