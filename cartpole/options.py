"""Settings as values: the shape every stage's options object shares (:class:`StageOptions`).

Each stage of a run takes its settings as one frozen dataclass: the planner :class:`~cartpole.planning.options.
PlanOptions`, the NMPC :class:`~cartpole.mpc.options.MPCOptions`, the MuJoCo closed loop :class:`~cartpole.sim.options.
LoopOptions`. They
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


def json_ready(value):
    """``value`` as plain JSON types: arrays and tuples as lists, mappings as dicts, numpy scalars as Python numbers,
    functions as ``"module:qualname"``, objects with a ``name`` (e.g. an :class:`~cartpole.ocp.objectives.Objective`)
    by that name, other dataclasses as dicts of their fields; anything else by ``str``."""
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
    if dataclasses.is_dataclass(value) and not isinstance(value, type):  # e.g. a knockdown: its fields
        return {f.name: json_ready(getattr(value, f.name)) for f in dataclasses.fields(value)}
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
               unit: str = "", optional: bool = False, integer: bool = False, hint: str = "") -> None:
        """Field ``name`` as a float (or int) in ``[low, high]`` (``(low, high]`` with ``low_open``), else one
        sentence; None passes when ``optional``.

        Parameters
        ----------
        name : str
            The field.
        low, high : float
            Its bounds, in ``unit``; ``low`` excluded when ``low_open``.
        low_open : bool
            Whether ``low`` itself is refused.
        unit : str
            The unit the sentence states after the bounds (e.g. ``"s"``).
        optional : bool
            Whether None is allowed (kept as None).
        integer : bool
            Whether the value must be a whole number (stored as an int).
        hint : str
            What to do, ending the sentence after a semicolon (e.g. ``"give e.g. `duration=5`, or None for ..."``;
            an argument in backquotes is what the command line names by its option); default: none.

        Raises
        ------
        the class's :attr:`error`
            The value is not a (whole) number, not finite or out of its bounds.
        """
        value = getattr(self, name)
        if value is None and optional:
            return
        what = f"{type(self).__name__}.{name}"
        then = f"; {hint}." if hint else "."
        try:
            v = float(value)
            if integer and v != int(v):
                raise ValueError
        except (TypeError, ValueError, OverflowError):
            kind = "a whole number" if integer else "a number"
            raise self.error(f"{what} must be {kind}; got {value!r}{then}") from None
        ok = math.isfinite(v) and (v > low if low_open else v >= low) and v <= high
        if not ok:
            if math.isinf(high):
                cond = f"{'>' if low_open else '>='} {low:g}"
            else:
                cond = f"in {'(' if low_open else '['}{low:g}, {high:g}]"
            raise self.error(f"{what} = {value!r} must be a finite number {cond}{' ' + unit if unit else ''}{then}")
        self.set_field(name, int(v) if integer else v)
