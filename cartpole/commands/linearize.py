"""``cartpole linearize``: exact continuous and discrete linearisation at upright rest."""
from __future__ import annotations

import numpy as np

from cartpole.commands._rig import smoothed_friction_sentence
from cartpole.commands._state import state_sentence
from cartpole.errors import CartPoleError
from cartpole.models import build_model, friction_treatment, linearize, steps_per_period

HELP = ("exact A, B (continuous) and Ad, Bd (one step of the MJCF's integrator) at the computed upright "
        "equilibrium x_eq, u_eq")


#: linearize prints and writes no files, so it takes no --out (an old --out is accepted, ignored, with a note).
WRITES_FILES = False


def add_arguments(parser) -> None:
    """``--period``: Ad, Bd over a control period of whole MJCF steps with the ctrl held."""
    parser.add_argument("--period", type=float, default=None, metavar="S",
                        help="give Ad, Bd over this control period (a whole number of MJCF steps, the ctrl held): "
                             "the exact discrete model a sampled controller sees; default one MJCF step")


def run(args) -> dict:
    """Build the symbolic model from ``args.mjcf`` and return/print the linearisation at ``(x_eq, u_eq)``.

    JSON: ``mjcf``, ``dt`` (s), ``integrator``, ``x_eq`` (2 nq,), ``u_eq`` (nu,), ``A`` (2 nq, 2 nq), ``B``
    (2 nq, nu), ``Ad``, ``Bd`` (one step of the MJCF's integrator, or with ``--period`` the held steps of the
    period), ``period`` (s), ``steps`` (MJCF steps per period), ``smoothed_friction`` (one entry per joint with
    ``frictionloss``, which the symbolic model holds as the smooth ``-frictionloss tanh(qvel / width)``:
    :func:`cartpole.models.friction_treatment`; empty without friction) and ``model`` {``contacts``: the file's geom
    pairs by whether they can touch, :meth:`cartpole.models.ContactReport.to_dict`}.
    """
    model = build_model(args.mjcf)
    steps = steps_per_period(getattr(args, "period", None), model.dt)
    lin = {"x_eq": model.x_eq, "u_eq": model.u_eq, "dt": model.dt, "integrator": model.integrator}
    lin["A"], lin["B"] = linearize(model)
    lin["Ad"], lin["Bd"] = linearize(model, period=steps * model.dt)
    bad = [k for k in ("x_eq", "u_eq", "A", "B", "Ad", "Bd") if not np.all(np.isfinite(lin[k]))]
    if bad:
        raise CartPoleError(f"The linearisation has NaN or inf entries in {', '.join(bad)}: the MJCF holds a number "
                            "that is not finite (a damping, mass, gear, armature or time step); fix it.")
    doc = {"mjcf": model.params.mjcf, "dt": lin["dt"], "integrator": lin["integrator"], "x_eq": lin["x_eq"],
           "u_eq": lin["u_eq"], "A": lin["A"], "B": lin["B"], "Ad": lin["Ad"], "Bd": lin["Bd"],
           "period": steps * lin["dt"], "steps": steps,
           "smoothed_friction": friction_treatment(model.params, width=model.friction_width),
           "model": {"contacts": model.contacts.to_dict()}}
    if not args.json:
        with np.printoptions(precision=6, suppress=True, linewidth=100):
            print(f"MJCF: {doc['mjcf']}")
            print(state_sentence(model.params))
            print(model.contacts.summary())
            print("Upright equilibrium (computed): x_eq =", lin["x_eq"], " u_eq =", lin["u_eq"])
            print("Continuous, at upright rest: d(x - x_eq)/dt = A (x - x_eq) + B (u - u_eq)")
            print("A =\n", lin["A"])
            print("B =\n", lin["B"])
            if steps > 1:
                print(f"Discrete, over a control period of {steps * lin['dt']:g} s ({steps} {lin['integrator']} "
                      f"steps of {lin['dt']} s, the ctrl held): x[k+1] - x_eq = Ad (x[k] - x_eq) + Bd (u[k] - u_eq)")
            else:
                print(f"Discrete, one {lin['integrator']} step of dt = {lin['dt']} s: "
                      "x[k+1] - x_eq = Ad (x[k] - x_eq) + Bd (u[k] - u_eq)")
            print("Ad =\n", lin["Ad"])
            print("Bd =\n", lin["Bd"])
        smoothed = smoothed_friction_sentence(doc["smoothed_friction"], what="this linearisation")
        if smoothed:
            print(smoothed + " A, B, Ad, Bd are the smooth model's, not MuJoCo's sticking joint's.")
    return doc
