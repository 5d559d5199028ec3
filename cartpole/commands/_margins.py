"""``cartpole lqr --margins``: the frequency-domain margins of the lab's linear designs on the rig the other
options describe (:mod:`cartpole.apps.margins`), printed as a table and drawn as Bode, Nyquist and sensitivity
figures under ``--out``."""
from __future__ import annotations

from pathlib import Path

from cartpole.apps.margins import lab_margins, loops_and_margins, mujoco_margins, noise_limited_R
from cartpole.progress import stage
from cartpole.viz.loop_plot import plot_loops

#: Where the figures go under --out.
FIGURES = Path("figures")


def add_margins_argument(parser) -> None:
    """``--margins`` on ``cartpole lqr``."""
    parser.add_argument("--margins", action="store_true",
                        help="instead of the lab: the loop of the LQR (with --estimator kf also the LQG, with "
                             "--compare-pid the PID) on this rig (--period, --delay) broken at the plant input: gain, "
                             "phase and delay margins, Ms, Mt and crossovers (python-control); prints a table and "
                             "writes figures/margins_bode.png, margins_nyquist.png, margins_sensitivity.png")
    parser.add_argument("--margins-mujoco", action="store_true",
                        help="--margins, and measure them in MuJoCo on this rig beside the predictions: the delay "
                             "margin of each design (whole physics steps) and the gain band of those on the true "
                             "state (LQR, PID; bisected to 1 %%); JSON margins_mujoco")
    parser.add_argument("--ctrl-noise", type=float, default=None, metavar="FRACTION",
                        help="design for the sensors: raise R (doubling it) until the ctrl's standard deviation that "
                             "the sensors' noise and quantisation cause through the LQG loop, predicted at upright, "
                             "is below FRACTION of the ctrl range (needs an estimator and encoders); JSON ctrl_noise")


def ctrl_noise_weights(args, model, loop, Q, R):
    """``--ctrl-noise FRACTION``: ``(R, doc)`` with ``R`` raised until the ctrl noise the sensors cause stays below
    the fraction of the ctrl range (:func:`cartpole.apps.margins.noise_limited_R`) and ``doc`` the JSON
    ``ctrl_noise`` {``fraction``, ``factor``, ``R``, ``predicted_std``, ``predicted_fraction``}; ``(R, None)``
    without the option. Prints one line unless ``--json``."""
    fraction = getattr(args, "ctrl_noise", None)
    if fraction is None:
        return R, None

    found = noise_limited_R(model, Q, R, loop, fraction, discrete=args.discrete)
    doc = {"fraction": found["fraction"], "factor": found["factor"], "R": found["R"].tolist(),
           "predicted_std": found["predicted_std"].tolist(), "predicted_fraction": found["predicted_fraction"].tolist()}
    if not args.json:
        print(f"--ctrl-noise {fraction:g}: R x {found['factor']:g}, predicted ctrl noise "
              f"{', '.join(f'{100 * v:.2g} %' for v in found['predicted_fraction'])} of the ctrl range")
    return found["R"], doc


def _fmt(v, scale: float = 1.0, digits: str = ".3g") -> str:
    return "inf" if v is None else format(v * scale, digits)


def run_margins(args, model, loop, Q, R) -> dict:
    """The ``--margins`` document: ``mjcf``, ``period`` (s), ``rig``, ``margins`` (design key -> its margins:
    ``gain_margin`` [low, high] ratio with null where unbounded, ``phase_margin_deg``, ``delay_margin_s``, ``ms``,
    ``mt``, crossovers in rad/s), ``figures`` (kind -> path); prints a table unless ``--json``."""
    check = getattr(args, "margins_mujoco", False)
    found = lab_margins(model, Q=Q, R=R, discrete=args.discrete, loop=loop, pid=args.compare_pid)
    figures = plot_loops(loops_and_margins(found), Path(args.out) / FIGURES)
    period = model.dt if loop.period is None else loop.period
    doc = {"mjcf": model.params.mjcf, "period": float(period), "rig": loop.as_dict(), "margins": found.to_dict(),
           "figures": {k: str(Path(p).resolve()) for k, p in figures.items()}}
    if check:
        tilt = 1e-3 if loop.estimator_for("balance") == "none" else 0.02  # well above the encoders' counts
        with stage("margins in MuJoCo", size="a gain bisection and a delay search per design"):
            doc["margins_mujoco"] = mujoco_margins(model, found, loop=loop, tilt=tilt)
    if not args.json:
        print(f"{'design':16s} {'gain margin':>18s} {'phase (deg)':>11s} {'delay (ms)':>10s} {'Ms':>6s} {'Mt':>6s} "
              f"{'crossover (rad/s)':>17s}")
        for key, m in doc["margins"].items():
            lo, hi = m["gain_margin"]
            print(f"{key:16s} {'[' + _fmt(lo) + ', ' + _fmt(hi) + ']':>18s} {_fmt(m['phase_margin_deg'], 1, '.1f'):>11s} "
                  f"{_fmt(m['delay_margin_s'], 1e3, '.1f'):>10s} {m['ms']:6.3f} {m['mt']:6.3f} "
                  f"{_fmt(m['gain_crossover_rad_s'], 1, '.1f'):>17s}")
        for key, m in doc["margins"].items():
            print(f"  {key}: {m['description']}")
            if "ctrl_noise_std" in m:
                print(f"    ctrl noise from the sensors (predicted): std {', '.join(f'{v:.3g}' for v in m['ctrl_noise_std'])}"
                      f" ({', '.join(f'{100 * v:.2g} %' for v in m['ctrl_noise_fraction'])} of the ctrl range)")
        if check:
            print("Measured in MuJoCo (from a small tilt; stable = decays or, with encoders, the ctrl off its limits):")
            for key, mj in doc["margins_mujoco"].items():
                if key == "rel":
                    continue
                line = (f"  {key}: delay margin {_fmt(mj['delay_margin_s'], 1e3, '.3g')} ms (predicted "
                        f"{_fmt(mj['delay_margin_predicted_s'], 1e3, '.3g')} ms in whole steps)")
                if "ctrl_noise_std" in mj:
                    line += (f"; ctrl noise std {', '.join(f'{v:.3g}' for v in mj['ctrl_noise_std'])} (predicted "
                             f"{', '.join(f'{v:.3g}' for v in mj['ctrl_noise_std_predicted'])})")
                if "gain_margin" in mj:
                    lo, hi = mj["gain_margin"]
                    plo, phi = mj["gain_margin_predicted"]
                    line += (f"; gain band [{lo:.4g}, {_fmt(hi, 1, '.4g')}] (predicted [{plo:.4g}, "
                             f"{_fmt(phi, 1, '.4g')}])")
                print(line)
        for p in doc["figures"].values():
            print(f"Wrote {p}")
    return doc
