"""Objectives of the swing-up OCP: what a user picks, as one small object the transcription integrates.

Sign convention: **an objective is a cost, minimised**. A running *reward* ``r(x, u)`` (higher is better) is
given by wrapping it, :func:`reward`, which the transcription minimises as ``-r``; every reported value is in the
user's own sign (a reward's integral is reported as the reward's integral, positive when the reward is).

* ``effort``: ``integral u'u dt`` over a fixed T (ctrl^2 s), Simpson's rule on the first-order-hold input (exact);
* ``time``: the final time T (free) plus a small effort term that makes the bang-bang answer unique;
* ``tracking``: ``integral (d' Q d + (u - u*)' R (u - u*)) dt`` toward the upright equilibrium ``x*``, ``u*``
  with ``Q``, ``R`` diagonal (default :func:`cartpole.riccati.default_weights`). The wrapped
  hinge-angle error is not smooth at +-pi, so for each hinge ``d_i^2`` is ``2 (1 - cos e_i)`` (``e_i = theta_i -
  theta_i*``): equal to ``e_i^2`` up to ``O(e_i^4)`` near upright, smooth and 2 pi-periodic everywhere;
  the other entries are the plain errors;
* the dm_control suite's tasks (:mod:`cartpole.ocp.dmc`, :data:`DMC`): ``dmc_cartpole_swingup`` (alias
  ``dmc_swingup``), ``dmc_cartpole_swingup_sparse``, ``dmc_cartpole_balance``, ``dmc_pendulum_swingup``,
  ``dmc_acrobot_swingup``, ``dmc_acrobot_swingup_sparse``: each task's reward, maximised (a smooth surrogate of
  it where dm_control's is sparse, :func:`cartpole.ocp.dmc.reward_expression`);
* any Python function ``(x, u) -> scalar`` of CasADi symbols (``x`` (nx,) SX, ``u`` (nu,) SX): a running cost, or
  a running reward when wrapped with :func:`reward`. On the command line ``--objective MODULE:FUNCTION`` imports
  it with :mod:`importlib` (:func:`load_objective`).

A running cost ``L`` is integrated with Simpson's rule on every collocation interval, using the Hermite
midpoint state and the first-order-hold midpoint input: ``h (L_k + 4 L_c + L_k+1) / 6``.
"""
from __future__ import annotations

import importlib
import re
from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from cartpole.errors import FOREIGN_WIDTH, first_line
from cartpole.ocp import dmc
from cartpole.ocp.bounds import OCPError
from cartpole.riccati import default_weights

#: The dm_control suite's tasks, by objective name, and the alias ``dmc_swingup``.
DMC = tuple(dmc.TASKS) + tuple(dmc.ALIASES)

NAMED = ("effort", "time", "tracking") + DMC


class Reward:
    """A running reward ``(x, u) -> scalar`` to be maximised (see :func:`reward`)."""

    def __init__(self, fn: Callable, name: str | None = None):
        self.fn = fn
        self.name = name or getattr(fn, "__name__", "reward")

    def __call__(self, x, u):
        return self.fn(x, u)


def reward(fn: Callable) -> Reward:
    """Mark ``fn(x, u) -> scalar`` as a reward: the OCP maximises its integral (minimises ``-integral``).

    Usable as a decorator in a module given to ``--objective MODULE:FUNCTION``::

        from cartpole.ocp.objectives import reward

        @reward
        def upright(x, u):
            return casadi.cos(x[1])
    """
    return fn if isinstance(fn, Reward) else Reward(fn)


@dataclass(frozen=True)
class Objective:
    """One objective of the swing-up OCP.

    Attributes
    ----------
    name : str
        ``effort``, ``time``, ``tracking``, a dm_control task of :data:`DMC` or the user function's name.
    running : casadi.Function or None
        ``(x (nx,), u (nu,)) -> cost`` per second, already signed as a cost (a reward negated); None for ``effort``
        and ``time``, which the transcription builds itself.
    is_reward : bool
        The user's quantity is a reward: reported values are ``-cost``.
    free_time : bool
        The final time is a decision variable (``time`` only).
    """

    name: str
    running: ca.Function | None = None
    is_reward: bool = False
    free_time: bool = False

    @property
    def kind(self) -> str:
        """``effort``, ``time`` or ``running``."""
        return self.name if self.name in ("effort", "time") else "running"


def dmc_swingup_reward(model, x, u, *, clip_control: bool = False):
    """dm_control's smooth cart-pole swing-up reward as a CasADi expression of ``x`` (nx,) and ``u`` (nu,): the
    task ``dmc_cartpole_swingup`` of :func:`cartpole.ocp.dmc.reward_expression` (``dm_control/suite/cartpole.py``,
    ``Balance._get_reward(sparse=False)``).

    ``clip_control`` False (what the OCP optimises): the quadratic control tolerance unclipped, ``1 - u_0^2``
    (smooth; equal inside ``|u_0| <= 1``); True: dm_control's exact value for any ctrl. The reward is in [0, 1]
    with ``clip_control``.
    """
    return dmc.reward_expression(model, "dmc_cartpole_swingup", x, u, exact=clip_control)


def dmc_swingup_function(model, *, clip_control: bool = False) -> ca.Function:
    """:func:`dmc_swingup_reward` as a CasADi Function ``(x (nx,), u (nu,)) -> reward`` (scalar), built once per
    model and form (:func:`cartpole.ocp.dmc.reward_function`)."""
    return dmc.reward_function(model, "dmc_cartpole_swingup", exact=clip_control)


def tracking_cost(model, x, u, Q=None, R=None):
    """The tracking running cost toward ``x*``, ``u*`` (see the module notes) as a CasADi expression.

    ``Q`` (nx,) or diagonal (nx, nx), ``R`` (nu,) or diagonal (nu, nu); default
    :func:`cartpole.riccati.default_weights`.
    """
    Q0, R0 = default_weights(model)
    q = np.diag(Q0) if Q is None else (np.diag(Q) if np.ndim(Q) == 2 else np.asarray(Q, float))
    r = np.diag(np.atleast_2d(R0)) if R is None else (np.diag(R) if np.ndim(R) == 2 else np.atleast_1d(R))
    x_eq, u_eq = np.asarray(model.x_eq, float), np.asarray(model.u_eq, float)
    hinges = set(model.hinges)
    J = 0
    for i in range(model.nx):
        e = x[i] - x_eq[i]
        J = J + q[i] * (2 * (1 - ca.cos(e)) if i in hinges else e**2)
    for j in range(model.nu):
        J = J + r[j] * (u[j] - u_eq[j]) ** 2
    return J


def _short(exc: BaseException) -> str:
    """The first line of an exception's message, without a final period (user code's errors can be long)."""
    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()]
    return first_line(lines[0], FOREIGN_WIDTH) if lines else type(exc).__name__


def _from_function(model, fn: Callable, label: str) -> Objective:
    """Check a user's ``(x, u) -> scalar`` on SX symbols and wrap it (a :class:`Reward` is negated)."""
    is_rew = isinstance(fn, Reward)
    name = fn.name if is_rew else getattr(fn, "__name__", "objective")
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    try:
        val = fn(x, u)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - any failure of user code is reported in one sentence
        raise OCPError(f"The objective {label} failed on CasADi symbols ({type(exc).__name__}: "
                       f"{_short(exc)}); write it with casadi "
                       f"operations (casadi.cos, casadi.exp, ...) of x ({model.nx},) and u ({model.nu},).") \
            from None
    try:
        val = ca.SX(val) if not isinstance(val, ca.SX) else val
    except Exception:  # noqa: BLE001
        raise OCPError(f"The objective {label} returned {type(val).__name__}, not a CasADi expression; "
                       "return one scalar expression of x and u.") from None
    if val.shape != (1, 1):
        raise OCPError(f"The objective {label} returned a {val.shape[0]}x{val.shape[1]} expression, not a "
                       "scalar; return one number per (x, u), e.g. a sum.")
    fname = re.sub(r"_+", "_", re.sub(r"\W", "_", name)).strip("_")  # CasADi: a letter, then no "__"
    fname = fname if re.match(r"[A-Za-z]", fname) else f"objective_{fname}".rstrip("_")
    try:
        f = ca.Function(fname, [x, u], [-val if is_rew else val], ["x", "u"], ["cost"])
    except RuntimeError as exc:
        why = ("depends on CasADi symbols other than x and u; build it from the two arguments only"
               if "free" in str(exc).lower() else
               f"cannot be made a CasADi Function ({first_line(exc, FOREIGN_WIDTH)})")
        raise OCPError(f"The objective {label} {why}.") from None
    v = float(f(model.x_eq, model.u_eq))
    if not np.isfinite(v):
        raise OCPError(f"The objective {label} is {v} at the upright equilibrium, not a finite number (math or "
                       "numpy functions turn a CasADi symbol into nan); write it with casadi operations "
                       "(casadi.cos, casadi.exp, ...) and keep it finite there.")
    return Objective(name=name, running=f, is_reward=is_rew)


def make_objective(model, objective=None, *, free_time: bool = False, Q=None, R=None) -> Objective:
    """The :class:`Objective` for ``objective``: a name of :data:`NAMED`, an :class:`Objective`, a callable
    ``(x, u) -> scalar`` cost or a :func:`reward`; None is ``time`` when ``free_time`` else ``effort``.

    ``Q``, ``R`` weight ``tracking`` (diagonal; default the lab's pattern).
    """
    if objective is None:
        objective = "time" if free_time else "effort"
    if isinstance(objective, Objective):
        return objective
    if isinstance(objective, str):
        if objective == "effort":
            return Objective("effort")
        if objective == "time":
            return Objective("time", free_time=True)
        x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
        if objective == "tracking":
            return Objective("tracking", ca.Function("tracking", [x, u], [tracking_cost(model, x, u, Q, R)],
                                                     ["x", "u"], ["cost"]))
        if dmc.is_task(objective):  # the planner's form of the task's reward (a surrogate where it is sparse)
            r = dmc.reward_expression(model, objective, x, u, exact=False)
            return Objective(objective, ca.Function(objective, [x, u], [-r], ["x", "u"], ["cost"]), is_reward=True)
        if ":" in objective:
            return _from_function(model, load_objective(objective), f"'{objective}'")
        raise OCPError(f"Objective '{objective}' is not known; choose one of {', '.join(NAMED)} or give "
                       "MODULE:FUNCTION.")
    if callable(objective):
        return _from_function(model, objective, f"'{getattr(objective, '__name__', 'function')}'")
    raise OCPError(f"Objective {objective!r} is neither a name ({', '.join(NAMED)}) nor a function (x, u) -> scalar.")


def load_objective(spec: str) -> Callable:
    """Import ``MODULE:FUNCTION`` with :mod:`importlib` and return the function (checked later on SX symbols).

    Raises
    ------
    OCPError
        Not of the form MODULE:FUNCTION, the module cannot be imported, or it has no such callable.
    """
    mod_name, _, fn_name = spec.partition(":")
    if not mod_name or not fn_name:
        raise OCPError(f"The objective '{spec}' is not of the form MODULE:FUNCTION (e.g. mycosts:upright).")
    try:
        mod = importlib.import_module(mod_name)
    except ModuleNotFoundError as exc:
        if exc.name != mod_name.split(".")[0] and exc.name != mod_name:  # the module itself imports a missing one
            raise OCPError(f"The objective module '{mod_name}' cannot be imported: it raised ModuleNotFoundError "
                           f"({_short(exc)}); fix that module.") from None
        raise OCPError(f"The objective module '{mod_name}' cannot be imported: it is not found; make it a module "
                       "on PYTHONPATH (the installed cartpole script does not search the current directory: run "
                       "with PYTHONPATH=. for a file mymodule.py there).") from None
    except SystemExit as exc:  # the user's module called sys.exit / raise SystemExit while imported
        raise OCPError(f"The objective module '{mod_name}' cannot be imported: it called SystemExit({exc.code!r}) "
                       "at import; remove the exit from the module's top level (guard it with if __name__ == "
                       "'__main__').") from None
    except Exception as exc:  # noqa: BLE001 - an error inside the user's module
        raise OCPError(f"The objective module '{mod_name}' cannot be imported: it raised {type(exc).__name__} "
                       f"({_short(exc)}) at import; fix that module.") from None
    fn = getattr(mod, fn_name, None)
    if fn is None or not callable(fn):
        raise OCPError(f"The objective module '{mod_name}' has no function '{fn_name}'; give MODULE:FUNCTION of "
                       "a function (x, u) -> scalar.")
    return fn
