"""The NMPC's controller part (:class:`cartpole.export.program.CPart`): the real-time iteration the MuJoCo loop runs,
``cartpole/csrc/nmpc.c.jinja`` with the dual active-set QP of ``cartpole/csrc/qp_dual.c``, rendered by
:func:`cartpole.mpc.nmpc_c.nmpc_source` with this controller's tables (its first iterate and offline plan as
``static const`` tables here; the loop's library takes them at run time). See that template for the equations:
shift, the stages' exact linearisations through the CasADi-generated ``cp_nmpc_lin``, the condensing (plain or
pre-stabilised), the QP, the safe action (``CP_FALLBACK``); each solve counted and timed (``cp_clock.c``) and read
back by ``cp_nmpc_state`` (:class:`cartpole.export.inloop.CompiledNMPCLaw`).
"""
from __future__ import annotations

import numpy as np

from cartpole.export.program import CPart
from cartpole.mpc.nmpc import NMPCController
from cartpole.mpc.nmpc_c import nmpc_source
from cartpole.mpc.options import MPCOptions
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup


#: Files of ``cartpole/csrc`` the NMPC part carries beside its rendered C: the clock that times each solve.
NMPC_FILES = ("cp_clock.c", "cp_clock.h")


def nmpc_part(ctl, plan) -> CPart:
    """``ctrl_eval`` of an :class:`~cartpole.mpc.nmpc.NMPCController` (just reset) whose offline plan is ``plan``:
    :func:`cartpole.mpc.nmpc_c.nmpc_source` with its tables, the C the controller runs in the MuJoCo loop.

    Parameters
    ----------
    ctl : NMPCController
        Plain or pre-stabilised condensing (``ctl.prestabilize``).
    plan : Trajectory or None
        The offline plan whose inputs extend the shifted tail (the controller's guess).

    Returns
    -------
    CPart
    """
    src = nmpc_source(ctl, plan)
    return CPart(sources=NMPC_FILES, code=src.code, fields=src.fields, reset=src.reset, functions=src.functions)


def nmpc_design(model, x0, period: float):
    """The Python NMPC the export reproduces and its offline plan: ``(controller, plan)``, as
    :func:`cartpole.mpc.nmpc.nmpc_swingup` builds it (the plan by trajectory optimisation from ``x0``, the first
    iterate converged for ``x0``).

    Parameters
    ----------
    model : CartPoleModel
    x0 : (nx,) array
    period : float
        Control period, s.

    Returns
    -------
    (NMPCController, Trajectory)
    """

    options = MPCOptions(period=float(period))
    x0 = np.asarray(x0, dtype=float).ravel()
    sp = trajopt_swingup(model.params, x0=x0, plan_model=model, options=PlanOptions(cart_margin=options.cart_margin))
    ctl = NMPCController(model, model.params, options=options, guess=sp.trajectory, x0=x0)
    return ctl, sp.trajectory
