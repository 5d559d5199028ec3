"""The exact discrete model over a control period: ``m`` steps of the MJCF's integrator with the ctrl held.

A controller that runs every ``m`` physics steps and holds its ctrl in between (a zero-order hold, as a real rig
and Gymnasium's ``frame_skip`` do) sees the plant ``x+ = step^m(x, u)``, not one physics step and not the
continuous dynamics. :class:`HoldModel` composes the symbolic one-step map of
:class:`~cartpole.models.symbolic.CartPoleModel` (which reproduces ``mj_step``) ``m`` times in CasADi SX, so the
map and its Jacobians ``Ad``, ``Bd`` over the hold are exact, at any state, and agree with ``m`` calls of
``mj_step`` (a test checks them by central differences). The same composition with a different ctrl in every
physics step (``(x, U (nu, m)) -> x+``) serves an estimator whose delayed ctrl changes inside a period.

Note that ``m`` steps of size ``h`` are not one step of size ``m h``: the integrators are not exact, and MuJoCo's
semi-implicit Euler treats damping implicitly per step, so :meth:`CartPoleModel.rebuilt` with ``dt = m h`` is an
approximation of what MuJoCo does over a period; this is not.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from cartpole.errors import CartPoleError

#: Relative tolerance with which a period must be a whole number of physics steps.
#: Longest control period accepted, s (a hold of thousands of steps would also take long to build).
MAX_PERIOD = 1.0
_WHOLE = 1e-6


class PeriodError(CartPoleError, ValueError):
    """A control period that is not a positive whole number of the MJCF's physics steps."""


def steps_per_period(period: float | None, timestep: float) -> int:
    """Physics steps ``m`` in a control period (None: one step).

    Parameters
    ----------
    period : float or None
        Control period in s.
    timestep : float
        The MJCF's physics step ``h`` in s.

    Returns
    -------
    int
        ``m = period / h`` (>= 1).

    Raises
    ------
    PeriodError
        A period that is not finite and positive, or not a whole number of physics steps (within 1e-6 relative).
    """
    if period is None:
        return 1
    try:
        T = float(period)
    except (TypeError, ValueError):
        raise PeriodError(f"The control period {period!r} is not a number of seconds; give e.g. `period` "
                          f"{5 * timestep:g}.") from None
    if not (math.isfinite(T) and T > 0):
        raise PeriodError(f"The control period {T:g} s is not a positive number of seconds; give a whole number of "
                          f"the MJCF's {timestep:g} s steps, e.g. `period` {5 * timestep:g}.")
    if T > MAX_PERIOD:
        raise PeriodError(f"The control period {T:g} s is longer than the {MAX_PERIOD:g} s limit (no cart-pole is "
                          f"balanced that slowly); give a whole number of the MJCF's {timestep:g} s steps below it.")
    m = round(T / timestep)
    if m < 1 or abs(m * timestep - T) > _WHOLE * T:
        lo, hi = max(1, math.floor(T / timestep)), max(1, math.ceil(T / timestep))
        near = sorted({lo * timestep, hi * timestep})
        raise PeriodError(f"The control period {T:g} s is not a whole number of the MJCF's {timestep:g} s physics "
                          f"steps; give {' or '.join(f'{v:g}' for v in near)} s.")
    return int(m)


@dataclass(frozen=True)
class HoldModel:
    """``steps`` physics steps of a :class:`~cartpole.models.symbolic.CartPoleModel` with the ctrl held: the plant a
    sampled controller at period ``steps * model.dt`` sees. CasADi Functions, built once.

    Attributes
    ----------
    model : CartPoleModel
        The one-step model (its ``dt`` is the physics step).
    steps : int
        Physics steps per period ``m``.
    step : casadi.Function
        ``(x (nx,), u (nu,)) -> x+ (nx,)``: the state one period later with ``u`` held (ctrl units; SI states).
    ABd : casadi.Function
        ``(x, u) -> (Ad (nx, nx), Bd (nx, nu))``: its exact Jacobians.
    step_inputs : casadi.Function
        ``(x (nx,), U (nu, m)) -> x+ (nx,)``: the same map with ctrl ``U[:, j]`` during physics step ``j``.
    ABd_inputs : casadi.Function
        ``(x, U) -> (d x+/dx (nx, nx), d x+/dU (nx, nu m))``, the last in column-major order of ``U``.
    """

    model: object
    steps: int
    step: ca.Function
    ABd: ca.Function
    step_inputs: ca.Function
    ABd_inputs: ca.Function

    @property
    def period(self) -> float:
        """The control period in s (``steps`` times the physics step)."""
        return self.steps * float(self.model.dt)

    @property
    def nx(self) -> int:
        """Number of states."""
        return self.model.nx

    @property
    def nu(self) -> int:
        """Number of inputs."""
        return self.model.nu

    def step_np(self, x, u) -> np.ndarray:
        """The state (nx,) one period after ``x`` (nx,) with ctrl ``u`` (nu,) held."""
        return np.asarray(self.step(np.asarray(x, float), np.atleast_1d(u).astype(float))).ravel()

    def linearize(self, x=None, u=None) -> tuple[np.ndarray, np.ndarray]:
        """``(Ad (nx, nx), Bd (nx, nu))`` over the period at ``x`` (nx,), ``u`` (nu,) (default the model's upright
        equilibrium ``x_eq``, ``u_eq``)."""
        x = self.model.x_eq if x is None else np.asarray(x, float)
        u = self.model.u_eq if u is None else np.atleast_1d(u).astype(float)
        Ad, Bd = self.ABd(x, u)
        return np.asarray(Ad), np.asarray(Bd)


def hold_model(model, steps: int) -> HoldModel:
    """The exact discrete model of ``model`` over ``steps`` physics steps with the ctrl held (see module doc).

    Parameters
    ----------
    model : CartPoleModel
        One physics step (``model.dt`` s) of the MJCF's integrator.
    steps : int
        Physics steps per control period, >= 1.

    Returns
    -------
    HoldModel
        For ``steps == 1`` its ``step`` and ``ABd`` equal the model's own.
    """
    m = int(steps)
    if m < 1 or m != steps:
        raise PeriodError(f"A hold of {steps} physics steps is not a whole number >= 1.")
    nx, nu = model.nx, model.nu
    opts = {"cse": True}
    x = ca.SX.sym("x", nx)
    u = ca.SX.sym("u", nu)
    U = ca.SX.sym("U", nu, m)
    xh, xs = x, x
    for j in range(m):
        xh = model.step(xh, u)
        xs = model.step(xs, U[:, j])
    step = ca.Function("hold_step", [x, u], [xh], ["x", "u"], ["x_next"], opts)
    ABd = ca.Function("hold_ABd", [x, u], [ca.jacobian(xh, x), ca.jacobian(xh, u)], ["x", "u"], ["Ad", "Bd"], opts)
    step_inputs = ca.Function("hold_step_inputs", [x, U], [xs], ["x", "U"], ["x_next"], opts)
    ABd_inputs = ca.Function("hold_ABd_inputs", [x, U], [ca.jacobian(xs, x), ca.jacobian(xs, ca.vec(U))],
                             ["x", "U"], ["Ad", "BU"], opts)
    return HoldModel(model=model, steps=m, step=step, ABd=ABd, step_inputs=step_inputs, ABd_inputs=ABd_inputs)
