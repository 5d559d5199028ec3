"""Hand a swing-up over to an LQR catch inside a basin ``e' S e < rho``, with hysteresis.

Drake's acrobot swing-up does the same: the swing-up runs until the quadratic cost-to-go of the balancing LQR,
evaluated on the *wrapped* error from the upright equilibrium ``x_eq``, drops below a level ``rho`` that a basin
estimate (:func:`cartpole.validation.basin.estimate_basin`) found safe; the catch then holds the pole. The controller
goes back to the swing-up only when the cost exceeds ``release_factor * rho``, a much larger level, so noise
or the transient right after the catch cannot make it chatter between the two laws; ``release_factor = inf`` never
hands back (the catch holds once reached).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole.control.linear import LinearFeedback
from cartpole.errors import CartPoleError


class SwitchingError(CartPoleError):
    """Bad switching level (rho not positive, release factor not above 1, catch without S)."""


#: Input weight of the swing-up's catch on MuJoCo ctrl: ``LinearFeedback.for_model(plant, R=SWINGUP_CATCH_R)``.
#: The lab's R = 0.1 asks for more ctrl than the motor has as soon as the pole is a few degrees off, so the catch
#: saturates and its MuJoCo-verified basin is small (rho ~ 0.13 on the shipped asset); R = 1 keeps the catch inside
#: the ctrl range over a much larger set, and the same sampled estimate certifies rho ~ 0.64 (every model of the test
#: suite: 0.41 to 0.65).
SWINGUP_CATCH_R = 1.0


@dataclass(frozen=True)
class Switch:
    """One mode change: at time ``t`` (s) the controller switched to ``mode`` ("catch" or "swingup") with
    ``cost`` = ``e' S e`` at that state."""

    t: float
    mode: str
    cost: float


class SwitchingController:
    """Swing-up until ``e' S e < rho``, then the catch; back to swing-up only above ``release_factor * rho``.

    Parameters
    ----------
    swingup : callable
        ``(t, x) -> ctrl`` used outside the basin (e.g. :class:`EnergyShapingController`).
    catch : LinearFeedback
        The balancing law; must carry ``S`` (its :meth:`~LinearFeedback.cost_to_go` is the basin test: ``e' S e``
        on the error from its ``x_eq`` with the hinge-angle errors wrapped, so ``theta = 2 pi + 0.01`` counts as
        0.01 rad from upright).
    rho : float
        Catch level (dimensionless cost units of ``S``), e.g. ``BasinEstimate.rho``.
    release_factor : float
        Hysteresis: hand back to the swing-up only when ``e' S e > release_factor * rho`` (> 1; default 20).
        ``inf``: hold the catch once reached (never hand back).

    Attributes
    ----------
    mode : str
        "swingup" or "catch", the current law.
    switches : list of Switch
        Every mode change since the last reset.

    Notes
    -----
    The controller has state (its mode). It resets itself when called with a time earlier than the previous
    call (a new run), or explicitly with :meth:`reset`; either also resets the swing-up law when it has a
    ``reset()`` method (e.g. :class:`~cartpole.control.tvlqr.TVLQRController`), so a reused controller starts
    each run afresh.
    """

    def __init__(self, swingup, catch: LinearFeedback, rho: float, *, release_factor: float = 20.0):
        if getattr(catch, "S", None) is None:
            raise SwitchingError("The catch controller has no cost-to-go matrix S; build it with "
                                 "LinearFeedback(K, S=S) from lqr().")
        if not (np.isfinite(rho) and rho > 0):
            raise SwitchingError(f"The catch level rho = {rho} is not a positive number; estimate it with "
                                 "estimate_basin().")
        if isinstance(release_factor, bool) or not isinstance(release_factor, (int, float, np.integer, np.floating)) \
                or not release_factor > 1:  # NaN fails the comparison; inf passes (never hand back)
            raise SwitchingError(f"release_factor = {release_factor!r} must be a number above 1 (inf: hold the "
                                 "catch once reached) so the release level is above the catch level.")
        self.swingup = swingup
        self.catch = catch
        self.rho = float(rho)
        self.release_factor = float(release_factor)
        self._clear()

    def _clear(self) -> None:
        self.mode = "swingup"
        self.switches: list[Switch] = []
        self._last_t = -np.inf

    def reset(self) -> None:
        """Forget the mode and the switch log (start in swing-up mode), and reset the swing-up law when it has a
        ``reset()``."""
        self._clear()
        reset = getattr(self.swingup, "reset", None)
        if callable(reset):
            reset()

    @property
    def caught_at(self) -> float | None:
        """Time (s) of the last switch to the catch if the catch is still in charge, else None."""
        if self.mode == "catch" and self.switches:
            return self.switches[-1].t
        return None

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s) for state ``x`` (nx,), switching modes as the cost ``e' S e`` dictates."""
        t = float(t)
        if t < self._last_t:
            self.reset()
        self._last_t = t
        cost = self.catch.cost_to_go(x)
        if self.mode == "swingup" and cost < self.rho:
            self.mode = "catch"
            self.switches.append(Switch(t, "catch", cost))
        elif self.mode == "catch" and cost > self.release_factor * self.rho:
            self.mode = "swingup"
            self.switches.append(Switch(t, "swingup", cost))
        law = self.catch if self.mode == "catch" else self.swingup
        return np.atleast_1d(np.asarray(law(t, x), dtype=float))
