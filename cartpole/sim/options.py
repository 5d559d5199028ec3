"""Settings as values: the shape every stage's options object shares, and the closed loop's own (:class:`LoopOptions`).

Each stage of a run takes its settings as one frozen dataclass: the planner :class:`~cartpole.planning.options.
PlanOptions`, the NMPC :class:`~cartpole.mpc.options.MPCOptions`, the MuJoCo closed loop :class:`LoopOptions`
(here, because the loop is the simulator's: its period, pushes and scenario, and later its sensors and delay). They
all derive from :class:`StageOptions`, which gives them

* ``options.replace(**changes)``: a copy with some fields changed, validated again; an unknown field name is one
  sentence listing the valid ones (what a sweep's ``setting:<name>`` axis uses to vary a field by its name);
* ``options.as_dict()``: a JSON-ready dict, one key per field (arrays as lists, functions by name);
* ``Options.names()`` (every field) and ``Options.scalar_names()`` (the fields a sweep may set to one number);
* equality and hashing by value (array fields compare element by element), so options can key a cache.

Array fields are stored as read-only numpy arrays and mappings as read-only mappings, so an options object cannot be
changed behind the back of a stage that holds it.
"""
from __future__ import annotations

import dataclasses
import json
import math
import types
from typing import ClassVar

import numpy as np

from cartpole._arrays import readonly
from cartpole.errors import CartPoleError


class OptionsError(CartPoleError, ValueError):
    """An options object given a field it does not have."""


class LoopError(OptionsError):
    """Bad closed-loop settings: a push that is not a pair of finite numbers, a model error that is not a scale in
    (0, 10], a duration or period that is not a positive number of seconds."""


def json_ready(value):
    """``value`` as plain JSON types: arrays and tuples as lists, mappings as dicts, numpy scalars as Python numbers,
    functions as ``"module:qualname"``, objects with a ``name`` (e.g. an :class:`~cartpole.ocp.objectives.Objective`)
    by that name; anything else by ``str``."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (tuple, list)):
        return [json_ready(v) for v in value]
    if isinstance(value, (dict, types.MappingProxyType)):
        return {str(k): json_ready(v) for k, v in value.items()}
    if callable(value) and hasattr(value, "__qualname__"):
        return f"{getattr(value, '__module__', '?')}:{value.__qualname__}"
    if isinstance(getattr(value, "name", None), str):
        return value.name
    return str(value)


class StageOptions:
    """Base of the frozen options dataclasses (see the module docstring); subclasses set :attr:`error`, the
    :class:`~cartpole.errors.CartPoleError` subclass their validation raises, and :attr:`SCALARS`."""

    #: The exception class of the stage (a CartPoleError subclass).
    error: ClassVar[type] = OptionsError
    #: Fields a sweep may set to a single number.
    SCALARS: ClassVar[tuple] = ()

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Every field's name, in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def scalar_names(cls) -> tuple[str, ...]:
        """The fields that take one number (what a sweep axis may vary)."""
        return tuple(cls.SCALARS)

    @classmethod
    def check_names(cls, names) -> None:
        """Raise :attr:`error` (one sentence, listing the valid names) when any of ``names`` is not a field."""
        unknown = [n for n in names if n not in cls.names()]
        if unknown:
            raise cls.error(f"{cls.__name__} has no field {', '.join(repr(n) for n in unknown)}; the fields are "
                            f"{', '.join(cls.names())}.")

    def replace(self, **changes):
        """A copy with ``changes`` (field name -> value) applied and validated again; ``self`` when there are none.

        Raises
        ------
        the class's :attr:`error`
            An unknown field name (the sentence lists the valid ones) or a value its validation refuses.
        """
        if not changes:
            return self
        self.check_names(changes)
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        """JSON-ready dict of every field (:func:`json_ready`): numbers, strings, None, lists, dicts."""
        return {f.name: json_ready(getattr(self, f.name)) for f in dataclasses.fields(self)}

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        for f in dataclasses.fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
                if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and np.array_equal(a, b)):
                    return False
            elif a != b:
                return False
        return True

    def __hash__(self):
        return hash((type(self).__name__, json.dumps(self.as_dict(), sort_keys=True)))

    # ---- helpers for the subclasses' __post_init__ -------------------------------------------------------------
    def set_field(self, name: str, value) -> None:
        """Store a normalised ``value`` in the frozen field ``name`` (for ``__post_init__``)."""
        object.__setattr__(self, name, value)

    def freeze_array(self, name: str) -> None:
        """Field ``name`` (None or array-like of finite numbers) as a read-only float array."""
        value = getattr(self, name)
        if value is None:
            return
        try:
            arr = readonly(value)
        except (TypeError, ValueError):
            raise self.error(f"{type(self).__name__}.{name} must be an array of numbers; got {value!r}.") from None
        if not np.all(np.isfinite(arr)):
            raise self.error(f"{type(self).__name__}.{name} must be finite; got {arr.tolist()}.")
        self.set_field(name, arr)

    def freeze_mapping(self, name: str) -> None:
        """Field ``name`` (None or a mapping) as a read-only mapping of a copy."""
        value = getattr(self, name)
        if value is None:
            return
        if not isinstance(value, (dict, types.MappingProxyType)):
            raise self.error(f"{type(self).__name__}.{name} must be a dict; got {value!r}.")
        self.set_field(name, types.MappingProxyType(dict(value)))

    def number(self, name: str, *, low: float = -math.inf, high: float = math.inf, low_open: bool = False,
               unit: str = "", optional: bool = False, integer: bool = False) -> None:
        """Field ``name`` as a float (or int) in ``[low, high]`` (``(low, high]`` with ``low_open``), else one
        sentence; None passes when ``optional``."""
        value = getattr(self, name)
        if value is None and optional:
            return
        what = f"{type(self).__name__}.{name}"
        try:
            v = float(value)
            if integer and v != int(v):
                raise ValueError
        except (TypeError, ValueError, OverflowError):
            kind = "a whole number" if integer else "a number"
            raise self.error(f"{what} must be {kind}; got {value!r}.") from None
        ok = math.isfinite(v) and (v > low if low_open else v >= low) and v <= high
        if not ok:
            if math.isinf(high):
                cond = f"{'>' if low_open else '>='} {low:g}"
            else:
                cond = f"in {'(' if low_open else '['}{low:g}, {high:g}]"
            raise self.error(f"{what} = {value!r} must be a finite number {cond}{' ' + unit if unit else ''}.")
        self.set_field(name, int(v) if integer else v)


#: Seconds each push lasts.
PUSH_SECONDS = 0.1


def check_push(push, params=None) -> tuple:
    """Validate pushes: a sequence of ``(T, F)`` pairs, ``T >= 0`` s and ``F`` N finite; the model (``params``, a
    :class:`~cartpole.models.CartPoleParams`, optional) must have a cart.

    Returns
    -------
    tuple of (float, float), sorted by time

    Raises
    ------
    LoopError
        Not pairs of finite numbers, a negative time, or a model without a slide joint to push.
    """
    if push is None:
        return ()
    try:
        pairs = [(float(T), float(F)) for T, F in push]
    except (TypeError, ValueError):
        raise LoopError(f"A push is a pair (T, F) of a start time in s and a force in N; got {push!r}.") from None
    for T, F in pairs:
        if not (np.isfinite(T) and np.isfinite(F) and T >= 0):
            raise LoopError(f"The push ({T:g} s, {F:g} N) needs a start time >= 0 s and a finite force; give "
                            "e.g. --push 1.5:20.")
    if pairs and params is not None and params.slide is None:
        raise LoopError("This MJCF has no slide joint, so there is no cart to push; drop the push.")
    return tuple(sorted(pairs))


def check_model_error(model_error) -> float:
    """The planning model's scale ``S`` (1.0 for None): a finite number, ``0 < S <= 10``.

    Raises
    ------
    LoopError
    """
    if model_error is None:
        return 1.0
    try:
        S = float(model_error)
    except (TypeError, ValueError):
        raise LoopError(f"The model error {model_error!r} is not a number; give a scale such as 0.8.") from None
    if not (np.isfinite(S) and 0 < S <= 10):
        raise LoopError(f"The model error {S:g} is not a scale in (0, 10] of the poles' masses and lengths; give "
                        "e.g. 1.2 for 20 % heavier and longer.")
    return S


def push_force(push, timestep: float):
    """``push`` pairs as the ``push(t) -> F`` callable :func:`~cartpole.sim.rollout.simulate` takes, or None.

    Each push acts on the physics steps ``k`` with ``round(T / h) <= k < round((T + PUSH_SECONDS) / h)``
    (``h = timestep``, s); overlapping pushes add."""
    pairs = check_push(push)
    if not pairs:
        return None
    h = float(timestep)
    spans = [(int(round(T / h)), int(round((T + PUSH_SECONDS) / h)), F) for T, F in pairs]

    def force(t: float) -> float:
        k = int(round(t / h))
        return float(sum(F for a, b, F in spans if a <= k < b))
    return force


@dataclasses.dataclass(frozen=True, eq=False)
class LoopOptions(StageOptions):
    """The MuJoCo closed loop's settings: how long it runs, at what control period, and the scenario it runs
    (pushes on the cart, a planning model that is wrong on purpose).

    Attributes
    ----------
    duration : float or None
        Simulated seconds; None: the caller's default (for ``run_swingup``: 10 s energy, 8 s mpc, the plan + 3 s
        trajopt).
    period : float or None
        Control period in s: each ctrl is held this long (MuJoCo still logs every physics step); None: the
        controller's own (the NMPC's period; every physics step for the others). A controller with a period of its
        own (the NMPC) re-plans at this one when its own is not given.
    push : tuple of (float, float)
        Pushes ``(T [s], F [N])``: a world-x force of F N on the cart body for :data:`PUSH_SECONDS` from time T s
        (:func:`push_force`), sorted by time; any sequence of pairs is accepted and normalised.
    model_error : float
        Scale S in (0, 10] of the *planning* model's pole masses and lengths (1: the MJCF's own); MuJoCo always
        runs the MJCF. The scenario the controller is designed for, kept with the loop it is tested in.

    Raises
    ------
    LoopError
        A duration or period that is not a positive number of seconds, a bad push or model error.
    """

    duration: float | None = None
    period: float | None = None
    push: tuple = ()
    model_error: float = 1.0

    error: ClassVar[type] = LoopError
    SCALARS: ClassVar[tuple] = ("duration", "period", "model_error")

    def __post_init__(self):
        for name in ("duration", "period"):
            v = getattr(self, name)
            if v is None:
                continue
            try:
                ok = math.isfinite(float(v)) and float(v) > 0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                flag = f"--{name}"
                raise LoopError(f"{name.capitalize()} {v} s is not a positive number of seconds; give e.g. {flag} "
                                f"{8 if name == 'duration' else 0.02}.")
            self.set_field(name, float(v))
        self.set_field("push", check_push(self.push))
        self.set_field("model_error", check_model_error(self.model_error))

    def push_force(self, timestep: float):
        """The pushes as the ``push(t) -> F`` (N) callable :func:`~cartpole.sim.rollout.simulate` takes at the
        physics step ``timestep`` (s), or None without pushes."""
        return push_force(self.push, timestep)
