"""Robustness sweep of the energy swing-up: many seeded starts (and optionally jittered gains), one summary.

Each run is :func:`cartpole.swingup.run_swingup` (energy shaping + LQR catch, in MuJoCo on the MJCF), so a sweep
measures exactly what ``cartpole swingup`` does. A run counts as a success when
:func:`~cartpole.validation.metrics.swingup_success` holds (upright and at rest over the last second,
cart never at its limit, every ctrl in range) *and* its log replays exactly with ``mj_step``
(:func:`~cartpole.sim.rollout.replays_exactly`). The basin estimate is computed once per model and reused
(:class:`~cartpole.validation.basin.BasinCache`).

Starts: ``center + U(-half_widths, half_widths)`` per state from ``numpy.random.default_rng(seed)``, default
around hanging at rest with half-widths ``(0.3 m, 0.3 rad, 0.3 m/s, 1 rad/s)``. Gain jitter (``gain_jitter = j``)
multiplies each dimensionless setting in :data:`JITTERED` by an independent ``U(1 - j, 1 + j)`` factor per run
(``energy_accel`` is capped at 1), drawn from the same generator after the starts.

Example (the before/after numbers of the README)::

    python -m cartpole.sweep --n 20 --seed 0
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from cartpole._arrays import readonly
from cartpole.control.energy import DEFAULT_SCALING
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleParams, read_params
from cartpole.sim import replays_exactly
from cartpole.swingup import run_swingup
from cartpole.validation.basin import BasinCache

#: Default start box: centre (hanging at rest) and half-widths [m, rad, m/s, rad/s].
HANGING = (0.0, np.pi, 0.0, 0.0)
HALF_WIDTHS = (0.3, 0.3, 0.3, 1.0)
#: Dimensionless energy-shaping settings that ``gain_jitter`` perturbs.
JITTERED = ("energy_gain", "overshoot", "energy_accel", "centring_frequency", "centring_damping",
            "damping_softening", "centring_band")


class SweepError(CartPoleError):
    """Bad sweep settings (no runs, negative widths, jitter outside [0, 1))."""


@dataclass(frozen=True)
class SweepResult:
    """What a robustness sweep found; arrays are read-only, one entry per run.

    Attributes
    ----------
    mjcf : str
        The MJCF every run used.
    starts : (n, 4) array
        Start states [m, rad, m/s, rad/s].
    success : (n,) bool array
        ``swingup_success`` of the MuJoCo rollout and the rollout replays exactly.
    time_to_upright : (n,) array
        s (``time_to_upright`` of :func:`~cartpole.validation.metrics.swingup_metrics`); NaN where the run failed.
    caught_at : (n,) array
        s, when the LQR catch took over for good; NaN if it never did.
    cart_clearance : (n,) array
        m, smallest distance to a cart limit over each run.
    peak_ctrl : (n,) array
        Largest |ctrl| of each run.
    options : tuple of dict
        The energy-shaping keyword arguments of each run (jittered settings), as passed to the controller.
    rho : float
        Catch level used (the basin estimate's).
    seed : int
    duration : float
        Simulated seconds per run.
    half_widths : (4,) array
    gain_jitter : float
    """

    mjcf: str
    starts: np.ndarray
    success: np.ndarray
    time_to_upright: np.ndarray
    caught_at: np.ndarray
    cart_clearance: np.ndarray
    peak_ctrl: np.ndarray
    options: tuple
    rho: float
    seed: int
    duration: float
    half_widths: np.ndarray
    gain_jitter: float
    base_options: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("starts", "time_to_upright", "caught_at", "cart_clearance", "peak_ctrl", "half_widths"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        object.__setattr__(self, "success", readonly(self.success, bool))

    @property
    def n(self) -> int:
        """Number of runs."""
        return int(len(self.success))

    @property
    def success_rate(self) -> float:
        """Fraction of runs that succeeded."""
        return float(np.mean(self.success)) if self.n else 0.0

    def _t(self):
        return self.time_to_upright[self.success]

    @property
    def t_median(self) -> float:
        """Median time to upright (s) over the successful runs (NaN if none)."""
        t = self._t()
        return float(np.median(t)) if t.size else float("nan")

    @property
    def t_max(self) -> float:
        """Largest time to upright (s) over the successful runs (NaN if none)."""
        t = self._t()
        return float(np.max(t)) if t.size else float("nan")

    def summary(self) -> dict:
        """JSON-ready summary: ``mjcf``, ``n``, ``successes``, ``success_rate``, ``time_to_upright_median``,
        ``time_to_upright_max``, ``caught_at_median``, ``min_cart_clearance``, ``max_peak_ctrl``, ``failed`` (start
        states of the failures), ``seed``, ``duration``, ``half_widths``, ``gain_jitter``, ``rho``."""
        nan = lambda v: None if not np.isfinite(v) else float(v)  # noqa: E731
        ca_ok = self.caught_at[self.success]
        return {"mjcf": self.mjcf, "n": self.n, "successes": int(self.success.sum()),
                "success_rate": self.success_rate, "time_to_upright_median": nan(self.t_median),
                "time_to_upright_max": nan(self.t_max),
                "caught_at_median": nan(float(np.median(ca_ok)) if ca_ok.size else np.nan),
                "min_cart_clearance": float(self.cart_clearance.min()),
                "max_peak_ctrl": float(self.peak_ctrl.max()),
                "failed": self.starts[~self.success].tolist(), "seed": self.seed, "duration": self.duration,
                "half_widths": self.half_widths.tolist(), "gain_jitter": self.gain_jitter, "rho": self.rho}


def _draw_starts(rng, n: int, center, half_widths) -> np.ndarray:
    return np.asarray(center, float) + rng.uniform(-1, 1, (int(n), 4)) * np.asarray(half_widths, float)


def sweep_starts(n: int, *, seed: int = 0, center=HANGING, half_widths=HALF_WIDTHS) -> np.ndarray:
    """Seeded start states (n, 4): ``center + U(-half_widths, half_widths)`` (the starts :func:`swingup_sweep`
    draws first from the same seed)."""
    return _draw_starts(np.random.default_rng(seed), n, center, half_widths)


def swingup_sweep(mjcf=None, *, n: int = 20, seed: int = 0, center=HANGING, half_widths=HALF_WIDTHS,
                  gain_jitter: float = 0.0, energy_options: dict | None = None, duration: float | None = None,
                  catch_weights: tuple | None = None, basin_cache=None, progress=None) -> SweepResult:
    """Run the energy swing-up from ``n`` seeded starts (optionally with jittered gains) and summarise.

    Parameters
    ----------
    mjcf : path or CartPoleParams or None
        The cart-pole (None = shipped asset).
    n : int
        Number of runs.
    seed : int
        Seed of ``numpy.random.default_rng`` for the starts (and the gain jitter).
    center : (4,) array
        Centre of the start box, default hanging at rest.
    half_widths : (4,) array
        Half-widths of the start box [m, rad, m/s, rad/s]; default ``(0.3, 0.3, 0.3, 1.0)``.
    gain_jitter : float
        In [0, 1): relative jitter of the settings in :data:`JITTERED` (0 = the gains as given).
    energy_options : dict, optional
        Energy-shaping settings (``EnergyShapingController`` keywords / ``default_gains`` scalings) every run
        starts from; default the package defaults.
    duration : float, optional
        Simulated seconds per run (default that of :func:`~cartpole.swingup.run_swingup`, 10 s).
    catch_weights : (Q, R), optional
        LQR weights of the catch (default :func:`~cartpole.control.switching.swingup_catch`'s), passed to
        :func:`~cartpole.swingup.run_swingup`.
    basin_cache : BasinCache, optional
        Reuse basin estimates across sweeps.
    progress : callable, optional
        ``progress(fraction)`` after each run.

    Returns
    -------
    SweepResult
    """
    if int(n) < 1 or not (0 <= gain_jitter < 1) or np.any(np.asarray(half_widths, float) < 0):
        raise SweepError(f"A sweep needs n >= 1, half-widths >= 0 and 0 <= gain_jitter < 1 (got n = {n}, "
                         f"half_widths = {half_widths}, gain_jitter = {gain_jitter}).")
    params = mjcf if isinstance(mjcf, CartPoleParams) else read_params(mjcf)
    cache = BasinCache() if basin_cache is None else basin_cache
    rng = np.random.default_rng(seed)
    starts = _draw_starts(rng, n, center, half_widths)
    lo, hi = params.cart_range
    starts[:, 0] = np.clip(starts[:, 0], lo + 1e-3, hi - 1e-3)
    base = dict(energy_options or {})
    opts = []
    for _ in range(int(n)):
        o = dict(base)
        if gain_jitter > 0:
            f = rng.uniform(1 - gain_jitter, 1 + gain_jitter, len(JITTERED))
            for k, fk in zip(JITTERED, f):
                v = float(o.get(k, DEFAULT_SCALING[k])) * fk
                o[k] = min(v, 1.0) if k == "energy_accel" else v
        opts.append(o)
    ok = np.zeros(n, bool)
    tu, ca, clr, pk = (np.full(n, np.nan) for _ in range(4))
    rho = np.nan
    for i, x0 in enumerate(starts):
        res = run_swingup(params, method="energy", x0=x0, duration=duration, basin_cache=cache,
                          energy_options=opts[i], catch_weights=catch_weights)
        m = res.metrics
        rho = res.basin.rho
        ok[i] = bool(res.success and replays_exactly(res.rollout, params))
        tu[i] = m["time_to_upright"] if (ok[i] and m["time_to_upright"] is not None) else np.nan
        ca[i] = np.nan if res.caught_at is None else res.caught_at
        clr[i], pk[i] = m["cart_clearance"], m["peak_ctrl"]
        if progress is not None:
            progress((i + 1) / n)
    return SweepResult(mjcf=params.mjcf, starts=starts, success=ok, time_to_upright=tu, caught_at=ca,
                       cart_clearance=clr, peak_ctrl=pk, options=tuple(opts), rho=float(rho), seed=int(seed),
                       duration=float(10.0 if duration is None else duration),
                       half_widths=np.asarray(half_widths, float), gain_jitter=float(gain_jitter),
                       base_options=base)


def _bar(label):
    def f(frac):
        print(f"\r{label}: {100 * frac:5.1f} %", end="" if frac < 1 else "\n", file=sys.stderr, flush=True)
    return f


def _seconds(value) -> str:
    """``'2.810 s'``, or ``'n/a'`` when no run reached upright (the summary holds None)."""
    return "n/a" if value is None else f"{value:.3f} s"


def main(argv=None) -> int:
    """``python -m cartpole.sweep [--mjcf P ...] [--n N] [--seed S] [--jitter J] [--options JSON] [--json]``: one
    summary line (or JSON) per model."""
    import argparse
    import json

    ap = argparse.ArgumentParser(prog="python -m cartpole.sweep", description=main.__doc__)
    ap.add_argument("--mjcf", nargs="*", default=[None], help="MJCF files (default: the shipped asset)")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jitter", type=float, default=0.0, help="relative gain jitter (0 = none)")
    ap.add_argument("--options", default="{}", help="JSON dict of energy-shaping settings")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    opts = json.loads(a.options)
    out = []
    for path in a.mjcf:
        r = swingup_sweep(path, n=a.n, seed=a.seed, gain_jitter=a.jitter, energy_options=opts,
                          progress=_bar(str(path or "shipped")))
        s = r.summary()
        out.append(s)
        if not a.json:
            print(f"{s['mjcf']}: success {s['successes']}/{s['n']}, time to upright median "
                  f"{_seconds(s['time_to_upright_median'])}, max {_seconds(s['time_to_upright_max'])}, "
                  f"min clearance {s['min_cart_clearance']:.3f} m, peak |ctrl| {s['max_peak_ctrl']:.3f}")
    if a.json:
        print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
