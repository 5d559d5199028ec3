"""``--u-max`` and ``--cart-max``: the bounds every command that plans a swing-up plans within, where the MJCF
leaves its motor or rail unlimited (or to narrow them); see :func:`cartpole.models.planning_limits`."""
from __future__ import annotations

from cartpole.commands._numbers import Numbers


def add_limit_arguments(parser) -> None:
    """Add ``--u-max U`` and ``--cart-max M`` to a command that plans."""
    parser.add_argument("--u-max", action=Numbers, default=None, metavar="U",
                        help="largest |ctrl| the swing-up plans and runs with, one number or one per actuator "
                             "(default each actuator's ctrlrange; without one, the ctrl whose force accelerates "
                             "everything the cart carries at 1 g, or on a hinge holds its load horizontal: "
                             "said in the output and the JSON 'limits')")
    parser.add_argument("--cart-max", type=float, default=None, metavar="M",
                        help="the cart keeps |x - centre| <= M m during the swing-up (default the slide's range; "
                             "an unlimited slide gets 3 chain lengths, said in the output and the JSON 'limits')")


def limit_keywords(args) -> dict:
    """``u_max`` and ``cart_max`` for :func:`cartpole.models.planning_limits` (and the apps that take them)."""
    u = getattr(args, "u_max", None)
    return {"u_max": None if u is None else (u[0] if len(u) == 1 else list(u)),
            "cart_max": getattr(args, "cart_max", None)}


def limit_lines(limits: dict | None, moves=()) -> list[str]:
    """The prose sentences of a ``limits`` JSON object (defaults used) and of the start moves (``start_moved``)."""
    out = list((limits or {}).get("notes", ()))
    out += [m["note"] for m in moves or ()]
    return out
