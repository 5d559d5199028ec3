"""How far the two- and three-pole trajopt + TVLQR swing-up holds: planning-model pole masses off, starts off.

Measures the robustness sentence of the "More poles" page with the protocol of ``tests/apps/test_robustness.py``
(the chain tests there cover 5 % and 0.03 rad): plan on the file's model (or on one whose pole masses are scaled),
run MuJoCo on the file from hanging rest (or from hanging with every hinge offset: all one way, all the other, first
and last opposed) for the plan plus 8 s, success by ``swingup_metrics`` over the last 3 s on a log that replays
exactly. Prints one JSON document::

    python tests/chain_robustness.py --poles 2 3 --mass 0.9 1.1 --offset 0.05
    {"two_pole": {"mass": {"0.9": true, ...}, "offset": {"0.05": [true, true, true]}, ...}, ...}
"""
from __future__ import annotations

import argparse
import json

import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.metrics import swingup_metrics

HOLD = 3.0  # s at the end that must be upright and at rest
AFTER = 8.0  # s simulated after the plan: the catch brings the cart back to rest, then the hold
CARTS = {2: "two_pole", 3: "three_pole"}


def offset_starts(model, d: float) -> list[np.ndarray]:
    """Hanging rest with every hinge offset by ``d`` rad: all +, all -, first + and last - (each (2 nq,))."""
    hinges = list(model.hinges)
    patterns = [np.full(len(hinges), d), np.full(len(hinges), -d), np.zeros(len(hinges))]
    patterns[2][0], patterns[2][-1] = d, -d
    starts = []
    for p in patterns:
        x0 = np.array(model.x_hanging, dtype=float)
        x0[hinges] += p
        starts.append(x0)
    return starts


def held(params, plan, x0) -> bool:
    """True when the plan's TVLQR run from ``x0`` in MuJoCo swings up and holds, its log replaying exactly."""
    ro = simulate(params, plan.controller, x0, plan.T + AFTER)
    return bool(replays_exactly(ro, params) and swingup_metrics(ro, build_model(params), hold=HOLD)["success"])


def chain_robustness(poles: int, mass_factors=(), offsets=()) -> dict:
    """``{"mass": {factor: success}, "offset": {d: [success per sign pattern]}}`` for the shipped cart with
    ``poles`` poles; factors scale the planning model's pole masses, offsets are rad on every hinge."""
    params = read_params(SHIPPED_MJCF.with_name(f"cartpole_{CARTS[poles]}.xml"))
    model = build_model(params)
    out = {"mass": {}, "offset": {}}
    for f in mass_factors:
        plan = trajopt_swingup(params, plan_model=build_model(params.scaled_pole(f, 1.0)))
        out["mass"][repr(float(f))] = held(params, plan, model.x_hanging)
    if offsets:
        plan = trajopt_swingup(params)  # planned from hanging rest; TVLQR absorbs the offset
        for d in offsets:
            out["offset"][repr(float(d))] = [held(params, plan, x0) for x0 in offset_starts(model, d)]
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poles", type=int, nargs="+", choices=sorted(CARTS), default=sorted(CARTS))
    ap.add_argument("--mass", type=float, nargs="*", default=[0.9, 1.1], help="planning-model pole mass factors")
    ap.add_argument("--offset", type=float, nargs="*", default=[0.05], help="start offsets on every hinge (rad)")
    args = ap.parse_args(argv)
    print(json.dumps({CARTS[n]: chain_robustness(n, args.mass, args.offset) for n in args.poles}))


if __name__ == "__main__":
    main()
