"""The command line's words for the library's: an error raised below the command layer names the Python argument
(in backquotes, ```u_max```, ```video=False```); the command line prints the option that sets it (``--u-max``,
``--no-video``). Only the backquoted spans listed in :data:`FLAGS` change; any other text is printed as raised.
The table is one for every command, so a backquoted argument name means the same option wherever the library
raises it (a new error naming an argument the command line sets adds its line here).
"""
from __future__ import annotations

import re

#: A Python argument (or argument=value) as library errors write it between backquotes -> the command line's option.
FLAGS = {
    "accel_std": "--process-noise",
    "actuated_joints": "--actuated-joint",
    "amplitude": "--amplitude",
    "cart_max": "--cart-max",
    "controller='lqr'": "--controller lqr",
    "controller='tvlqr'": "--controller tvlqr",
    "delay": "--delay",
    "dry_run": "--dry-run",
    "duration": "--duration",
    "encoder_cpr": "--encoder-cpr",
    "encoder_resolution": "--encoder-resolution",
    "estimator": "--estimator",
    "estimator='kf'": "--estimator kf",
    "estimator='none'": "--estimator none",
    "logs": "--log",
    "mcu": "--mcu",
    "names": "--fit",
    "params": "--fit",
    "mode='hanging'": "--mode hanging",
    "out": "--out",
    "period": "--period",
    "plant": "--mjcf",
    "push=[(1.5, 20)]": "--push 1.5:20",
    "regularization": "--regularization",
    "u_max": "--u-max",
    "video=False": "--no-video",
    "x0": "--x0",
}

_SPAN = re.compile(r"`([^`\n]+)`")


def in_flags(text: str) -> str:
    """``text`` with each backquoted Python argument of :data:`FLAGS` replaced by its command-line option.

    Parameters
    ----------
    text : str
        A library error's sentence.

    Returns
    -------
    str
        The same sentence for a person at the command line: ```u_max``` -> ``--u-max``; backquoted text that is
        not in :data:`FLAGS` is left as it is.
    """
    return _SPAN.sub(lambda m: FLAGS.get(m.group(1), m.group(0)), text)
