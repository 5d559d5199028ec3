"""Number lists on the command line (``--x0``, ``--Q``, ``--R``, ``--u-max``), written as a person writes them:
separated by spaces (``--Q 1 10 0.1 0.1``), by commas (``--Q 1,10,0.1,0.1``, as copied from Python or a paper), or
both."""
from __future__ import annotations

import argparse


class Numbers(argparse.Action):
    """``nargs="+"`` action that stores a list of floats, splitting each token on commas; a token that is not a
    number is refused by argparse's own error (exit status 2, one line)."""

    def __init__(self, option_strings, dest, nargs="+", **kwargs):
        super().__init__(option_strings, dest, nargs=nargs, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        out = []
        for token in values:
            for part in filter(None, (p.strip() for p in token.split(","))):
                try:
                    out.append(float(part))
                except ValueError:
                    raise argparse.ArgumentError(self, f"'{part}' is not a number; give numbers separated by "
                                                       "spaces or commas") from None
        if not out:
            raise argparse.ArgumentError(self, "needs at least one number")
        setattr(namespace, self.dest, out)
