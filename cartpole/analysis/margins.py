"""Stability margins of a loop broken at the plant input (:mod:`cartpole.analysis.loops`), read from its frequency
response with python-control and made safe for loops that are unstable open loop, as every cart-pole's is.

For ``1 + k L`` (a gain ``k > 0`` at the break) a closed-loop pole crosses the stability boundary only at a
frequency where ``k L = -1``, i.e. where ``L`` is real and negative (a *phase crossover*, ``k = -1 / L``), at
``w = 0`` or, for a sampled loop, at the Nyquist frequency ``pi / T``. Those gains cut ``(0, inf)`` into intervals
inside which stability cannot change; the closed-loop eigenvalues at one gain inside each decide it
(an open-loop-unstable ``L`` is stable for ``k`` in a band, not below a single number, which is why a margin
read off a Bode plot alone misleads). The **gain margin** is the stable band around ``k = 1``:
``(low, high)``, ``low = 0`` or ``high = inf`` where it is unbounded; continuous LQR guarantees
``low <= 1/2`` and ``high = inf``.

At each *gain crossover* ``|L(jw_c)| = 1`` the phase distance to ``-1`` is ``phi_c = angle(L) + pi`` (wrapped);
the **phase margin** is the smallest ``|phi_c|`` (LQR guarantees 60 degrees), and the **delay margin** is the
smallest delay ``tau`` whose rotation ``e^(-j w tau)`` brings a crossover onto ``-1``: ``min_c (phi_c mod 2 pi) /
w_c`` (s). For a sampled loop ``w`` runs to ``pi / T`` and a delay that is not a whole number of periods is read
the same way (the continuous-delay reading of a sampled loop). ``Ms = max |1 / (1 + L)|`` and ``Mt = max |L / (1 +
L)|`` over the same frequencies; ``1 / Ms`` is the smallest distance of the Nyquist curve to ``-1``.

Crossovers are found on a dense logarithmic sweep of python-control's ``frequency_response`` and refined by
Brent's method on ``L`` itself; the tests check them against ``control.stability_margins`` and the gain band
against the closed-loop eigenvalues.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from cartpole._arrays import readonly
from cartpole.analysis.loops import Loop, AnalysisError

#: Points per decade of the frequency sweep (then refined to round-off).
POINTS_PER_DECADE = 400
#: Decades below the slowest and above the fastest pole the sweep covers (continuous loops).
DECADES_AROUND = 3.0


@dataclass(frozen=True)
class Margins:
    """The margins of one :class:`~cartpole.analysis.loops.Loop` (see the module doc for the definitions).

    Attributes
    ----------
    name, description, channel : str
        From the loop.
    period : float or None
        Sample time of the loop in s (None: continuous).
    delay : float
        Delay already inside the loop, s.
    gain_margin : (2,) array
        ``[low, high]``: the loop stays stable for every gain ``k`` at the break strictly between them (ratio; 0 and
        inf where unbounded).
    phase_margin_deg : float
        Smallest phase distance of a gain crossover to -1, degrees (inf without gain crossover).
    delay_margin_s : float
        Smallest added delay that destabilises the loop, s (inf without gain crossover).
    ms, mt : float
        Peaks of the sensitivity ``|S|`` and the complementary sensitivity ``|T|``.
    ms_frequency, mt_frequency : float
        Where they peak, rad/s (inf or 0 where the peak is the limit at infinite or zero frequency).
    gain_crossovers : (n,) array
        Frequencies where ``|L| = 1``, rad/s.
    crossover_phases_deg : (n,) array
        ``angle(L) + 180`` wrapped to (-180, 180] at each, degrees.
    phase_crossovers : (m,) array
        Frequencies where ``L`` is real and negative (the gains ``-1 / L`` there bound the stable band), rad/s.
    """

    name: str
    description: str
    channel: str
    period: float | None
    delay: float
    gain_margin: np.ndarray
    phase_margin_deg: float
    delay_margin_s: float
    ms: float
    mt: float
    ms_frequency: float
    mt_frequency: float
    gain_crossovers: np.ndarray
    crossover_phases_deg: np.ndarray
    phase_crossovers: np.ndarray

    def __post_init__(self):
        for name in ("gain_margin", "gain_crossovers", "crossover_phases_deg", "phase_crossovers"):
            object.__setattr__(self, name, readonly(getattr(self, name)))

    @property
    def crossover(self) -> float | None:
        """The gain crossover that sets the delay margin, rad/s (None without one)."""
        if self.gain_crossovers.size == 0:
            return None
        rot = np.mod(np.radians(self.crossover_phases_deg), 2 * np.pi) / self.gain_crossovers
        return float(self.gain_crossovers[int(np.argmin(rot))])

    def to_dict(self) -> dict:
        """JSON-ready: ``gain_margin`` ``[low, high]`` (ratio, null where unbounded), ``phase_margin_deg``,
        ``delay_margin_s`` (null where infinite), ``ms``, ``mt``, ``gain_crossover_rad_s`` (the one setting the delay
        margin), ``gain_crossovers_rad_s``, ``phase_crossovers_rad_s``, ``ms_rad_s``, ``mt_rad_s`` (null at 0 or infinity),
        ``period``,
        ``delay``, ``channel``, ``description``."""
        def num(v):
            return None if v is None or not math.isfinite(v) or v == 0 else float(v)

        low, high = (float(v) for v in self.gain_margin)
        return {"description": self.description, "channel": self.channel, "period": self.period,
                "delay": self.delay, "gain_margin": [None if low == 0 else low, num(high)],
                "phase_margin_deg": num(self.phase_margin_deg), "delay_margin_s": num(self.delay_margin_s),
                "ms": float(self.ms), "mt": float(self.mt), "ms_rad_s": num(self.ms_frequency),
                "mt_rad_s": num(self.mt_frequency), "gain_crossover_rad_s": self.crossover,
                "gain_crossovers_rad_s": [float(w) for w in self.gain_crossovers],
                "phase_crossovers_rad_s": [float(w) for w in self.phase_crossovers]}


def _value(L, w: float) -> complex:
    """``L`` at ``s = j w`` (continuous) or ``z = e^(j w T)`` (sampled), w in rad/s."""
    s = 1j * w if L.dt == 0 else np.exp(1j * w * L.dt)
    return complex(np.asarray(L(s)).ravel()[0])


def frequency_grid(L) -> np.ndarray:
    """The logarithmic sweep the margins are read on, rad/s: :data:`DECADES_AROUND` decades around the loop's poles
    (continuous; zero poles ignored) or from there up to the Nyquist frequency ``pi / T`` (sampled, included).

    Parameters
    ----------
    L : control.StateSpace

    Returns
    -------
    (n,) array
        Increasing frequencies, rad/s, :data:`POINTS_PER_DECADE` per decade.
    """
    lam = np.linalg.eigvals(np.asarray(L.A, float))
    if L.dt:
        lam = np.log(lam[np.abs(lam) > 1e-12].astype(complex)) / L.dt
    mag = np.abs(lam)
    mag = mag[mag > 1e-9]
    lo = (mag.min() if mag.size else 1.0) * 10 ** -DECADES_AROUND
    hi = math.pi / L.dt if L.dt else (mag.max() if mag.size else 1.0) * 10 ** DECADES_AROUND
    lo = min(lo, hi * 1e-6)
    n = int(np.ceil(np.log10(hi / lo) * POINTS_PER_DECADE)) + 1
    return np.logspace(np.log10(lo), np.log10(hi), n)


def response(L, omega) -> np.ndarray:
    """``L`` along ``omega`` (rad/s) through python-control's ``frequency_response``: a complex (n,) array."""
    import control  # python-control takes seconds to import: only loop users pay for it

    return np.asarray(control.frequency_response(L, np.asarray(omega, float)).complex).reshape(-1)


def closed_loop_stable(L, k: float = 1.0) -> bool:
    """Whether ``1 + k L`` is stable: every eigenvalue of ``A - k B (1 + k D)^-1 C`` in the open left half plane
    (continuous) or inside the unit circle (sampled), with a margin of 1e-9."""
    A, B, C, D = (np.asarray(M, float) for M in (L.A, L.B, L.C, L.D))
    lam = np.linalg.eigvals(A - k * B @ np.linalg.solve(np.eye(D.shape[0]) + k * D, C))
    return bool(np.abs(lam).max() < 1 - 1e-9) if L.dt else bool(lam.real.max() < -1e-9)


def _roots(f, w, values) -> list[float]:
    """Roots of ``f(w)`` (real) between sign changes of ``values`` on the grid ``w``, refined by Brent in log w."""
    out = []
    for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0):
        a, b = np.log(w[i]), np.log(w[i + 1])
        out.append(float(np.exp(scipy.optimize.brentq(lambda lw: f(np.exp(lw)), a, b, xtol=1e-14, rtol=1e-14))))
    return out


def _peak(g, w, values) -> tuple[float, float]:
    """The maximum of ``g`` over the grid, refined between the neighbours of the best grid point."""
    i = int(np.argmax(values))
    best, at = float(values[i]), float(w[i])
    if 0 < i < w.size - 1:
        res = scipy.optimize.minimize_scalar(lambda lw: -g(np.exp(lw)), bounds=(np.log(w[i - 1]), np.log(w[i + 1])),
                                             method="bounded", options={"xatol": 1e-12})
        if -res.fun > best:
            best, at = float(-res.fun), float(np.exp(res.x))
    return best, at


def gain_band(L, candidates) -> tuple[float, float]:
    """The stable band of gains around ``k = 1``: the candidate gains (where a pole can cross) cut ``(0, inf)``
    into intervals; stability at each interval's middle (closed-loop eigenvalues) decides it, and adjacent stable
    intervals merge.

    Parameters
    ----------
    L : control.StateSpace
        A loop whose nominal closed loop (``k = 1``) is stable.
    candidates : sequence of float
        Positive gains where ``k L = -1`` at some frequency.

    Returns
    -------
    (low, high)
        0 and inf where unbounded.
    """
    ks = sorted({float(k) for k in candidates if k > 0 and math.isfinite(k)})
    edges = [0.0] + ks + [math.inf]

    def mid(a, b):
        if b == math.inf:
            return 2 * a if a > 0 else 1.0
        return 0.5 * b if a == 0 else math.sqrt(a * b)

    stable = [closed_loop_stable(L, mid(a, b)) for a, b in zip(edges[:-1], edges[1:])]
    j = int(np.searchsorted(edges, 1.0, side="right")) - 1  # the interval holding k = 1
    if 1.0 in ks:  # nominal on a boundary: not robust
        return 1.0, 1.0
    lo_i = hi_i = j
    while lo_i > 0 and stable[lo_i - 1]:
        lo_i -= 1
    while hi_i < len(stable) - 1 and stable[hi_i + 1]:
        hi_i += 1
    return edges[lo_i], edges[hi_i + 1]


def loop_margins(loop: Loop) -> Margins:
    """Gain, phase and delay margins, ``Ms`` and ``Mt`` of a loop (see the module doc).

    Parameters
    ----------
    loop : Loop
        SISO, its nominal closed loop stable.

    Returns
    -------
    Margins

    Raises
    ------
    AnalysisError
        A loop whose nominal closed loop is not stable (it has no margins to give).
    """
    L = loop.L
    if L.ninputs != 1 or L.noutputs != 1:
        raise AnalysisError(f"Margins are read on one loop at a time; this one has {L.ninputs} inputs and "
                        f"{L.noutputs} outputs.")
    if not closed_loop_stable(L):
        raise AnalysisError(f"The closed loop of '{loop.name}' ({loop.description}) is not stable, so it has no "
                        "margins; fix the design first.")
    w = frequency_grid(L)
    H = response(L, w)
    inner = slice(0, w.size - 1) if L.dt else slice(0, w.size)  # the Nyquist point is handled exactly
    wi, Hi = w[inner], H[inner]
    gains = _roots(lambda x: math.log(abs(_value(L, x))), wi, np.log(np.abs(Hi)))
    phases = [x for x in _roots(lambda x: _value(L, x).imag, wi, Hi.imag) if _value(L, x).real < 0]
    candidates = [-1.0 / _value(L, x).real for x in phases]
    if L.dt:
        end = _value(L, math.pi / L.dt)
        if end.real < 0:
            candidates.append(-1.0 / end.real)
            phases.append(math.pi / L.dt)
    dc = _dc_gain(L)
    if dc is not None and dc < 0:
        candidates.append(-1.0 / dc)
    ms, ms_w = _peak(lambda x: 1.0 / abs(1.0 + _value(L, x)), w, 1.0 / np.abs(1.0 + H))
    mt, mt_w = _peak(lambda x: abs(_value(L, x) / (1.0 + _value(L, x))), w, np.abs(H / (1.0 + H)))
    if not L.dt and not np.any(np.asarray(L.D)) and ms < 1.0:
        ms, ms_w = 1.0, math.inf  # |S| -> 1 as w -> inf for a strictly proper continuous loop: the supremum
    t0 = 1.0 if dc is None else abs(dc / (1.0 + dc))  # |T| at w = 0 (1 with an integrator in the loop)
    if t0 > mt:
        mt, mt_w = t0, 0.0
    low, high = gain_band(L, candidates)
    phi = np.array([math.remainder(np.angle(_value(L, x)) + math.pi, 2 * math.pi) for x in gains])
    wc = np.array(gains)
    pm = float(np.degrees(np.abs(phi)).min()) if phi.size else math.inf
    dm = float((np.mod(phi, 2 * np.pi) / wc).min()) if phi.size else math.inf
    return Margins(loop.name, loop.description, loop.channel, loop.period, loop.delay, np.array([low, high]),
                   pm, dm, ms, mt, ms_w, mt_w, wc, np.degrees(phi), np.array(phases))


def _dc_gain(L) -> float | None:
    """``L`` at ``w = 0`` when it is finite (no pole at s = 0 or z = 1), else None."""
    A = np.asarray(L.A, float)
    M = (np.eye(A.shape[0]) - A) if L.dt else -A
    if np.linalg.cond(M) > 1e12:
        return None
    return float((np.asarray(L.C) @ np.linalg.solve(M, np.asarray(L.B)) + np.asarray(L.D)).ravel()[0])
