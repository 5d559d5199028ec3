"""``cartpole linearize``: exact continuous and discrete linearisation at upright rest."""
from __future__ import annotations

import numpy as np

HELP = "exact A, B (continuous) and Ad, Bd (one step of the MJCF's integrator) at upright rest"


def add_arguments(parser) -> None:
    """No options beyond the common --mjcf/--out/--json."""


def run(args) -> dict:
    """Build the symbolic model from ``args.mjcf`` and return/print the linearisation."""
    from cartpole.models import build_model, linearize

    model = build_model(args.mjcf)
    lin = linearize(model)
    doc = {"mjcf": model.params.mjcf, "dt": lin["dt"], "integrator": lin["integrator"],
           "A": lin["A"], "B": lin["B"], "Ad": lin["Ad"], "Bd": lin["Bd"]}
    if not args.json:
        with np.printoptions(precision=6, suppress=True, linewidth=100):
            print(f"MJCF: {doc['mjcf']}")
            print("State x = [cart position (m), pole angle (rad), cart velocity (m/s), pole rate (rad/s)];"
                  " input u = MuJoCo ctrl")
            print("Continuous, at upright rest: x_dot = A x + B u")
            print("A =\n", lin["A"])
            print("B =\n", lin["B"])
            print(f"Discrete, one {lin['integrator']} step of dt = {lin['dt']} s: x[k+1] = Ad x[k] + Bd u[k]")
            print("Ad =\n", lin["Ad"])
            print("Bd =\n", lin["Bd"])
    return doc
