"""Library errors name Python arguments; the command line names its options: the one place that maps the first to
the second.

A library sentence names an argument in single backticks: ``ctrl_noise`` or ``method='trajopt'`` (an argument and
its value), each between two backtick characters. :func:`as_flags` rewrites each one the command line sets as its
option (``--ctrl-noise``, ``--method trajopt``) and leaves every other backticked word as it is; :func:`flag_words` does it to the
:class:`~cartpole.errors.CartPoleError` a command's work raises, so the person at the terminal reads the options they
can type.
"""
from __future__ import annotations

import re
from contextlib import contextmanager

from cartpole.errors import CartPoleError

#: The option that sets each Python argument (or options field) a library error may name, for every command.
FLAGS = {
    "method": "--method", "x0": "--x0", "ctrl_noise": "--ctrl-noise", "time_budget": "--time-budget",
    "workers": "--workers", "solver": "--solver", "seed": "--seed", "duration": "--duration",
    "push_force": "--push-force", "address": "--address", "resume": "--resume", "n": "--n", "gain_jitter": "--jitter",
    "results": "--out",
    "mpc": "--horizon, --mpc-solver", "plan": "--objective, --solver", "path": "--plan-mjcf",
    "seed_plan=False": "--no-seed-plan", "MPCOptions(objective=...)": "--objective",
}

#: A backticked argument, alone (``name``) or with its value (``name='value'``).
_NAMED = re.compile(r"`([^`=]+)(?:=([^`]*))?`")


def as_flags(text: str, flags: dict | None = None) -> str:
    """``text`` with every backticked argument the command line sets (``flags``, default :data:`FLAGS`) written as
    its option: ``method='trajopt'`` -> ``--method trajopt``, ``ctrl_noise`` -> ``--ctrl-noise`` (each in
    backticks in ``text``).

    Parameters
    ----------
    text : str
        A library sentence.
    flags : dict, optional
        Argument (or whole backticked text) -> option.

    Returns
    -------
    str
    """
    flags = FLAGS if flags is None else flags

    def option(m: re.Match) -> str:
        whole = m.group(0)[1:-1]
        if whole in flags:
            return flags[whole]
        name, value = m.group(1), m.group(2)
        if name not in flags:
            return m.group(0)
        return flags[name] if value is None else f"{flags[name]} {value.strip(chr(39))}"

    return _NAMED.sub(option, text)


@contextmanager
def flag_words(flags: dict | None = None):
    """Within it, a :class:`~cartpole.errors.CartPoleError` raised is re-raised (the same object) with its sentence
    in the command line's words (:func:`as_flags`).

    Parameters
    ----------
    flags : dict, optional
        As for :func:`as_flags`.
    """
    try:
        yield
    except CartPoleError as exc:
        if exc.args and isinstance(exc.args[0], str):
            exc.args = (as_flags(exc.args[0], flags),) + exc.args[1:]
        raise
