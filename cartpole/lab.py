"""The day-5 LQR balance lab as one function call: design K, run five initial conditions in MuJoCo, measure.

``run_lab()`` reproduces the lab handout's experiment on any cart-pole MJCF the toolkit reads: the exact
linearisation at upright rest (continuous ``A, B`` from the symbolic model, or ``Ad, Bd`` of one step of the
MJCF's integrator with ``discrete=True``), LQR with the lab's weights, and five 6 s MuJoCo runs of
``u = u* - K (x - x*)`` (ctrl clipped to ``ctrlrange`` by MuJoCo) from the lab's five starts, each logged every
physics step so it replays exactly. The settling statistics are those of
:mod:`cartpole.validation.metrics` (the handout's definition and a strict one).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import CartPoleParams, read_params
from cartpole._arrays import readonly

#: The handout's five starts ``[s (m), theta (rad), s_dot, theta_dot]``: 5, -5 and 8 degrees at the centre,
#: 3 degrees with the cart at 0.2 m, -4 degrees with the cart at -0.3 m.
LAB_INITIAL_CONDITIONS = np.array([
    [0.0, np.deg2rad(5.0), 0.0, 0.0],
    [0.0, -np.deg2rad(5.0), 0.0, 0.0],
    [0.0, np.deg2rad(8.0), 0.0, 0.0],
    [0.2, np.deg2rad(3.0), 0.0, 0.0],
    [-0.3, np.deg2rad(-4.0), 0.0, 0.0],
])
LAB_INITIAL_CONDITIONS.setflags(write=False)

#: Seconds each lab run lasts (the handout's ``SIM_TIME_S``).
LAB_DURATION = 6.0

#: Fraction of the room to a joint limit that a start may use (the rest is left for the transient).
_ROOM = 0.5


class LabError(CartPoleError):
    """The lab cannot be run on this model (e.g. its joint ranges exclude upright rest)."""


def lab_equilibrium(params: CartPoleParams) -> np.ndarray:
    """Upright rest ``x* = [s*, 0, 0, 0]`` (4,), ``s*`` the middle of the slide range (0 for a symmetric or
    unlimited rail).

    Raises
    ------
    LabError
        When the hinge range excludes the upright angle 0.
    """
    lo, hi = (float(v) for v in params.cart_range)
    if np.isfinite(lo) and np.isfinite(hi):
        s_eq = 0.5 * (lo + hi)
    elif np.isfinite(lo):  # a rail limited on one side only: start 1 m clear of that end
        s_eq = max(0.0, lo + 1.0)
    elif np.isfinite(hi):
        s_eq = min(0.0, hi - 1.0)
    else:
        s_eq = 0.0
    hlo, hhi = params.hinge_range
    if not hlo < 0.0 < hhi:
        raise LabError(f"The hinge range [{hlo:g}, {hhi:g}] rad does not contain the upright angle 0; "
                       "the lab balances the pole upright, so widen the hinge range.")
    return readonly([s_eq, 0.0, 0.0, 0.0])


def lab_initial_conditions(params: CartPoleParams) -> np.ndarray:
    """The lab's five starts (5, 4), moved to the model's equilibrium and scaled into its joint ranges.

    The handout's starts (:data:`LAB_INITIAL_CONDITIONS`) are offsets from ``x*`` (:func:`lab_equilibrium`).
    When a cart offset uses more than half of the room to a slide limit, every cart offset is scaled by one
    factor so the largest uses exactly half; the same for the pole angles and the hinge range. So on the
    shipped MJCF (track +-1.5 m, free hinge) they are the handout's starts unchanged.

    Returns
    -------
    (5, 4) read-only array, ``[s (m), theta (rad), s_dot (m/s), theta_dot (rad/s)]`` per row.
    """
    x_eq = lab_equilibrium(params)
    offsets = np.array(LAB_INITIAL_CONDITIONS)
    for col, (lo, hi) in ((0, params.cart_range), (1, params.hinge_range)):
        room = _ROOM * min(x_eq[col] - lo, hi - x_eq[col])
        need = np.abs(offsets[:, col]).max()
        if need > room:
            offsets[:, col] *= room / need
    return readonly(x_eq + offsets)


@dataclass(frozen=True)
class LabResult:
    """Everything the lab computed; arrays are read-only.

    Attributes
    ----------
    mjcf : str
        Absolute path of the MJCF run.
    params : CartPoleParams
    discrete : bool
        True when K came from ``dlqr(Ad, Bd)`` at the MJCF's time step, else ``lqr(A, B)``.
    A, B : (4, 4), (4, 1) arrays
        Continuous linearisation at upright rest (1/s; state derivative per unit ctrl).
    Ad, Bd : (4, 4), (4, 1) arrays
        One step of the MJCF's integrator there.
    Q, R : (4, 4), (1, 1) arrays
        LQR weights used.
    K : (1, 4) array
        Gain, ctrl per [m, rad, m/s, rad/s]; the law is ``u = u* - K (x - x*)`` (python-control's sign).
    S : (4, 4) array
        Riccati solution (cost-to-go ``e' S e``).
    E : (4,) complex array
        Closed-loop eigenvalues of ``A - B K`` (or ``Ad - Bd K``).
    x_eq : (4,) array
        Equilibrium ``x*``.
    x0s : (5, 4) array
        Initial conditions run.
    duration : float, s
    rollouts : tuple of Rollout
        One MuJoCo run per start, every physics step logged.
    metrics : tuple of RunMetrics
        Per run (see :mod:`cartpole.validation.metrics`).
    """

    mjcf: str
    params: CartPoleParams
    discrete: bool
    A: np.ndarray
    B: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    K: np.ndarray
    S: np.ndarray
    E: np.ndarray
    x_eq: np.ndarray
    x0s: np.ndarray
    duration: float
    rollouts: tuple
    metrics: tuple

    @property
    def settling_times_seed(self) -> np.ndarray:
        """(5,) s, the handout's definition per start."""
        return np.array([m.settling_time_seed for m in self.metrics])

    @property
    def settling_times(self) -> np.ndarray:
        """(5,) s, the strict whole-state definition per start (``inf`` if never)."""
        return np.array([m.settling_time_strict for m in self.metrics])

    @property
    def mean_settling_time_seed(self) -> float:
        """Mean over the starts of the handout's settling time, s."""
        return float(np.mean(self.settling_times_seed))

    @property
    def std_settling_time_seed(self) -> float:
        """Population standard deviation (``np.std``, as the handout) of the handout's settling time, s."""
        return float(np.std(self.settling_times_seed))

    @property
    def settled(self) -> tuple:
        """Per start: strict settling time finite and the cart never reached its limit."""
        return tuple(m.settled for m in self.metrics)

    @property
    def steps(self) -> int:
        """Physics steps per run."""
        return int(self.rollouts[0].ctrl.shape[0])

    def controller(self):
        """The lab's feedback law as a :class:`~cartpole.control.linear.LinearFeedback`."""
        from cartpole.control.linear import LinearFeedback

        return LinearFeedback(self.K, self.x_eq, 0.0, S=self.S)


def design(model, Q, R, *, discrete: bool = False):
    """LQR at upright rest of a :class:`~cartpole.models.CartPoleModel`.

    Returns ``(LQRResult, (A, B, Ad, Bd))``; ``discrete`` picks ``dlqr(Ad, Bd)`` over ``lqr(A, B)``.
    """
    from cartpole.lqr import dlqr, lqr

    A, B = model.linearize()
    Ad, Bd = model.linearize(discrete=True)
    res = dlqr(Ad, Bd, Q, R) if discrete else lqr(A, B, Q, R)
    return res, (A, B, Ad, Bd)


def run_lab(mjcf: str | Path | CartPoleParams | None = None, *, Q=None, R=None, discrete: bool = False,
            duration: float = LAB_DURATION, progress: Callable[[float], None] | None = None) -> LabResult:
    """Run the LQR balance lab on a cart-pole MJCF.

    Parameters
    ----------
    mjcf : path or CartPoleParams, optional
        Cart-pole to balance (default the shipped asset).
    Q : (4, 4) array, optional
        State weights (default the lab's ``diag(1, 10, 0.1, 0.1)``).
    R : (1, 1) array or float, optional
        ctrl weight (default the lab's 0.1).
    discrete : bool
        Design on the exact discrete model ``(Ad, Bd)`` at the MJCF's time step (``dlqr``) instead of ``(A, B)``.
    duration : float, s
        Length of each MuJoCo run (default 6 s, the handout's).
    progress : callable, optional
        Called with the fraction of runs done (0..1).

    Returns
    -------
    LabResult

    Raises
    ------
    MJCFError, LQRError, LabError
        Bad MJCF, weights, or a model the lab cannot balance.
    """
    from cartpole.lqr import Q_LAB, R_LAB
    from cartpole.models import build_model
    from cartpole.control.linear import LinearFeedback
    from cartpole.validation.metrics import summarize
    from cartpole.sim import simulate

    params = mjcf if isinstance(mjcf, CartPoleParams) else read_params(mjcf)
    Q = Q_LAB if Q is None else Q
    R = R_LAB if R is None else R
    model = build_model(params)
    res, (A, B, Ad, Bd) = design(model, Q, R, discrete=discrete)
    x_eq = lab_equilibrium(params)
    x0s = lab_initial_conditions(params)
    ctrl = LinearFeedback(res.K, x_eq, 0.0, S=res.S)
    runs, mets = [], []
    for i, x0 in enumerate(x0s):
        run = simulate(params, ctrl, x0, duration)
        runs.append(run)
        mets.append(summarize(run, x_eq=x_eq, ctrl_range=params.ctrl_range, cart_range=params.cart_range))
        if progress is not None:
            progress((i + 1) / len(x0s))
    return LabResult(mjcf=params.mjcf, params=params, discrete=bool(discrete), A=readonly(A), B=readonly(B),
                     Ad=readonly(Ad), Bd=readonly(Bd), Q=readonly(np.atleast_2d(Q)), R=readonly(np.atleast_2d(R)),
                     K=readonly(res.K), S=readonly(res.S),
                     E=readonly(res.E, complex), x_eq=x_eq, x0s=x0s, duration=float(duration), rollouts=tuple(runs),
                     metrics=tuple(mets))
