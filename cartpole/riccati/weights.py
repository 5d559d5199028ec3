"""The default LQR weights for any cart with a chain of poles.

:func:`default_weights` weighs each slide (cart) position 1, each hinge angle 10, each joint rate 0.1 and each input
(MuJoCo ctrl) 0.1: for one pole ``Q = diag(1, 10, 0.1, 0.1)``, ``R = 0.1`` (the balance lab's weights,
:data:`cartpole.apps.lab.Q_LAB`, :data:`cartpole.apps.lab.R_LAB`).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np


#: Weight of a slide (cart) position, m^-2.
SLIDE_WEIGHT = 1.0
#: Weight of a hinge angle, rad^-2.
HINGE_WEIGHT = 10.0
#: Weight of every joint rate (m/s or rad/s)^-2.
RATE_WEIGHT = 0.1
#: Weight of every input, per (MuJoCo ctrl)^2.
INPUT_WEIGHT = 0.1


def default_weights(model) -> tuple[np.ndarray, np.ndarray]:
    """The default weights for ``model``: ``Q`` on the state ``[qpos, qvel]`` and ``R`` on the inputs.

    Parameters
    ----------
    model : object
        Anything with ``nq`` (number of joint positions; ``nx // 2`` is used when it only has ``nx``, as every
        joint is one-DOF so ``nv = nq``), ``nu`` (number of inputs) and, optionally, ``slides`` and ``hinges``:
        tuples of the qpos indices of the slide and hinge joints. Without them index 0 is the slide (the
        cart) and every other index a hinge.

    Returns
    -------
    Q : (2 nq, 2 nq) array
        Diagonal: 1 for each slide position, 10 for each hinge angle, 0.1 for each of the ``nq`` rates.
    R : (nu, nu) array
        ``0.1 * I(nu)``.

    For one pole, ``nq = 2``, ``nu = 1``: ``Q = diag(1, 10, 0.1, 0.1)`` and ``R = [[0.1]]``. The arrays are new
    and writable.
    """
    nq = int(model.nq) if hasattr(model, "nq") else int(model.nx) // 2
    nu = int(model.nu)
    slides = tuple(getattr(model, "slides", (0,)))
    hinges = tuple(getattr(model, "hinges", range(1, nq)))
    q = np.zeros(nq)
    q[list(slides)] = SLIDE_WEIGHT
    q[list(hinges)] = HINGE_WEIGHT
    Q = np.diag(np.concatenate([q, np.full(nq, RATE_WEIGHT)]))
    R = INPUT_WEIGHT * np.eye(nu)
    return Q, R


#: A model's shape with one pole on a cart: ``nq = 2`` joints, ``nu = 1`` input (the argument of
#: :func:`default_weights` for the single-pole weights).
ONE_POLE = SimpleNamespace(nq=2, nu=1)
