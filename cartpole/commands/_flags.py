"""The command line's words for the library's: an error raised below the command layer names the Python argument
in backquotes (```u_max```, ```method='trajopt'```, ```video=False```); the command line prints the option that
sets it (``--u-max``, ``--method trajopt``, ``--no-video``). Only the backquoted arguments listed in :data:`FLAGS`
change; any other text is printed as raised. The table is one for every command, so a backquoted argument name means
the same option wherever the library raises it (a new error naming an argument the command line sets adds its line
here). :func:`as_flags` rewrites a sentence; :func:`flag_words` rewrites the
:class:`~cartpole.errors.CartPoleError` a command's work raises.
"""
from __future__ import annotations

import re
from contextlib import contextmanager

from cartpole.errors import CartPoleError

#: A Python argument (or options field, or a whole ``argument=value``) as library errors write it between backquotes
#: -> the command line's option.
FLAGS = {
    "accel_std": "--process-noise",
    "actuated_joints": "--actuated-joint",
    "address": "--address",
    "amplitude": "--amplitude",
    "cart_max": "--cart-max",
    "controller='lqr'": "--controller lqr",
    "controller='tvlqr'": "--controller tvlqr",
    "ctrl_noise": "--ctrl-noise",
    "delay": "--delay",
    "dry_run": "--dry-run",
    "duration": "--duration",
    "encoder_cpr": "--encoder-cpr",
    "encoder_resolution": "--encoder-resolution",
    "estimator": "--estimator",
    "gain_jitter": "--jitter",
    "horizon": "--horizon",
    "lab_margins": "--margins",
    "logs": "--log",
    "mass_error": "--mass-error",
    "mcu": "--mcu",
    "method": "--method",
    "mode='hanging'": "--mode hanging",
    "mpc": "--horizon, --mpc-solver",
    "MPCOptions(objective=...)": "--objective",
    "MPCOptions(solver='ddp')": "--mpc-solver ddp",
    "n": "--n",
    "names": "--fit",
    "objective": "--objective",
    "out": "--out",
    "params": "--fit",
    "path": "--plan-mjcf",
    "period": "--period",
    "pid=True": "--compare-pid",
    "plan": "--objective, --solver",
    "plant": "--mjcf",
    "push=[(1.5, 20)]": "--push 1.5:20",
    "push_force": "--push-force",
    "regularization": "--regularization",
    "results": "--out",
    "resume": "--resume",
    "seed": "--seed",
    "search_s=None": "--search-s inf",
    "seed_plan=False": "--no-seed-plan",
    "solver": "--solver",
    "time_budget": "--time-budget",
    "u_max": "--u-max",
    "video=False": "--no-video",
    "workers": "--workers",
    "x0": "--x0",
}

#: A backquoted argument, alone (```name```) or with its value (```name='value'```).
_NAMED = re.compile(r"`([^`=\n]+)(?:=([^`\n]*))?`")


def as_flags(text: str, flags: dict | None = None) -> str:
    """``text`` with every backquoted argument the command line sets written as its option.

    Parameters
    ----------
    text : str
        A library error's sentence.
    flags : dict, optional
        Argument (or whole backquoted text) -> option; default :data:`FLAGS`.

    Returns
    -------
    str
        The same sentence for a person at the command line: ```u_max``` -> ``--u-max``, ```method='trajopt'``` ->
        ``--method trajopt``; backquoted text that is not in ``flags`` is left as it is.
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
