"""Excitation signals for identification: an open-loop multisine around the hanging pendulum's natural frequencies,
sized so the cart stays inside its rail and the ctrl inside its range.

The multisine ``u(t) = a sum_k sin(w_k t + phi_k) / sqrt(K)`` has ``K`` frequencies spread evenly over
``[0.7 w_min, 2.5 w_max]`` (``w`` the hanging modes' natural frequencies, from the exact linearisation at hanging
rest) with Schroeder phases ``phi_k = -pi k (k - 1) / K`` (a low crest factor), a raised-cosine fade in and out of
one second, and ``a`` shrunk until the nominal model's run of it keeps the cart within :data:`RAIL_FRACTION` of
its rail. The ctrl is held over each sample, so the same CSV can be played on a rig.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole._arrays import readonly
from cartpole.errors import CartPoleError

#: The cart is kept within this fraction of each rail end (nominal model).
RAIL_FRACTION = 0.6
#: Number of sines.
N_SINES = 8
#: Fade in and out, s.
FADE_S = 1.0


class ExciteError(CartPoleError):
    """An excitation that cannot be designed (no hanging oscillation, a duration too short)."""


@dataclass(frozen=True)
class Excitation:
    """A designed excitation.

    Attributes
    ----------
    t : (N,) array, s
        Sample times from 0.
    ctrl : (N, nu) array
        Ctrl held from ``t[k]`` to ``t[k+1]``.
    frequencies : (K,) array, rad/s
    amplitude : float
        Peak of the multisine's envelope as a fraction of the ctrl range's half-width.
    natural_frequencies : (m,) array, rad/s
        The hanging modes' natural frequencies.
    """

    t: np.ndarray
    ctrl: np.ndarray
    frequencies: np.ndarray
    amplitude: float
    natural_frequencies: np.ndarray


def natural_frequencies(model) -> np.ndarray:
    """Undamped natural frequencies (rad/s) of the hanging rest's oscillating modes, ascending: the square roots of
    the positive eigenvalues of ``M^-1 d2V/dq2`` there (damping and friction left out).

    Parameters
    ----------
    model : CartPoleModel

    Returns
    -------
    (m,) array
    """
    x = np.asarray(model.x_hanging, float)
    M = np.asarray(model.mass_matrix(x))
    H = np.asarray(model.rest_potential(x[:model.nq])[1])  # stiffness of gravity, springs and actuator bias
    ev = np.linalg.eigvals(np.linalg.solve(M, H)).real
    w = np.sort(np.sqrt(ev[ev > 1e-9]))
    if not w.size:
        raise ExciteError("The hanging rest of this model does not oscillate, so there is no natural frequency to "
                          "excite around; check the MJCF's gravity and poles.")
    return w


def multisine(model, duration: float, sample_time: float, *, amplitude: float | None = None,
              seed: int = 0) -> Excitation:
    """Design the excitation (module docstring) for ``model`` on its first actuator.

    Parameters
    ----------
    model : CartPoleModel
        The nominal model (used to size the amplitude).
    duration : float
        s (at least three seconds).
    sample_time : float
        Ctrl hold and log step, s (a whole number of the model's steps).
    amplitude : float, optional
        Envelope peak as a fraction (0, 1] of the ctrl half-range; default the largest, up to 0.8, that keeps the
        cart inside :data:`RAIL_FRACTION` of its rail on the nominal model.
    seed : int
        Shifts the frequencies slightly (another informative run for a held-out check).

    Returns
    -------
    Excitation

    Raises
    ------
    ExciteError
        A duration under 3 s, a sample time that is not a whole number of steps, an amplitude outside (0, 1].
    """
    if not (np.isfinite(duration) and duration >= 3):
        raise ExciteError(f"The excitation's duration {duration:g} s is too short; give a `duration` of at least 3 s.")
    steps = round(sample_time / model.dt)
    if steps < 1 or abs(steps * model.dt - sample_time) > 1e-9:
        raise ExciteError(f"The sample time {sample_time:g} s is not a whole number of MJCF steps ({model.dt:g} s); "
                          "give a multiple of the step.")
    if amplitude is not None and not (0 < amplitude <= 1):
        raise ExciteError(f"The amplitude {amplitude:g} is not in (0, 1]; give a fraction of the ctrl range.")
    wn = natural_frequencies(model)
    rng = np.random.default_rng(seed)
    w = np.linspace(0.7 * wn[0], 2.5 * wn[-1], N_SINES) * (1 + 0.03 * rng.uniform(-1, 1, N_SINES) * (seed != 0))
    k = np.arange(1, N_SINES + 1)
    phi = -np.pi * k * (k - 1) / N_SINES
    n = round(duration / sample_time)
    t = np.arange(n + 1) * sample_time
    s = np.sin(np.outer(t, w) + phi).sum(axis=1) / np.sqrt(N_SINES)
    fade = np.clip(np.minimum(t, t[-1] - t) / FADE_S, 0, 1)
    s = s * 0.5 * (1 - np.cos(np.pi * fade)) / np.max(np.abs(s))
    lo, hi = model.u_low[0], model.u_high[0]
    mid, half = (0.5 * (lo + hi), 0.5 * (hi - lo)) if np.isfinite(hi - lo) else (0.0, 1.0)
    ctrl = np.zeros((n + 1, model.nu))
    hold = model.hold(steps) if steps > 1 else None
    rail = model.params.cart_range
    a = 0.8 if amplitude is None else float(amplitude)
    for _ in range(12):
        ctrl[:, 0] = mid + a * half * s
        if amplitude is not None or model.slide is None or not np.all(np.isfinite(rail)):
            break
        reach = _cart_reach(model, hold, ctrl)
        limit = RAIL_FRACTION * 0.5 * (rail[1] - rail[0])
        if reach <= limit:
            break
        a *= 0.9 * limit / reach
    return Excitation(t=readonly(t), ctrl=readonly(ctrl), frequencies=readonly(w), amplitude=float(a),
                      natural_frequencies=readonly(wn))


def _cart_reach(model, hold, ctrl) -> float:
    """Largest cart excursion from the rail's middle on the nominal model from hanging rest, m."""
    step = hold.step if hold is not None else model.step
    run = step.mapaccum(ctrl.shape[0] - 1)
    xs = np.asarray(run(model.x_hanging, ctrl[:-1].T)).T
    mid = 0.5 * float(np.sum(model.params.cart_range))
    reach = np.max(np.abs(xs[:, model.slide] - mid))
    return float(reach) if np.isfinite(reach) else np.inf
