"""The moving-horizon estimator's part (:class:`cartpole.export.program.CPart`): the window of
:class:`cartpole.estimation.mhe.MovingHorizonEstimator` in C, one Gauss-Newton step a period.

The C is the one the MuJoCo loop runs: ``cartpole/csrc/mhe.c.jinja`` rendered by
:func:`cartpole.estimation.mhe_c.mhe_source` for this estimator (the window's stages and measurements with their
Jacobians CasADi-generated; the Riccati recursion over the window; the bounded fallback by the dual active-set solver
of ``cartpole/csrc/qp_dual.c``; the window's slide with its arrival-cost update). Only the first estimate's tables
(:func:`cartpole.export.estimators.reset_code`) are the export's own.
"""
from __future__ import annotations

from cartpole.estimation import measurement_function
from cartpole.estimation.mhe_c import mhe_source
from cartpole.export.estimators import reset_code
from cartpole.export.program import CPart


def mhe_part(mhe, model, spec) -> CPart:
    """The MHE ``mhe`` (just built) on ``model`` with sensors ``spec`` as an estimator part.

    Parameters
    ----------
    mhe : MovingHorizonEstimator
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    CPart
    """
    src = mhe_source(mhe, model, measurement_function(model, spec))
    rtab, rcode = reset_code(model, spec, model.x_hanging)
    return CPart(tables=rtab, code=rcode + src.code, fields=src.fields, reset="    mh_reset();\n",
                 functions=src.functions)
