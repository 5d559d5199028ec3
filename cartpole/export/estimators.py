"""The estimator parts of an export (:class:`cartpole.export.program.CPart`): the C file of ``cartpole/csrc`` that
implements ``cp_est_start(y, x)`` (the first estimate from the first measurement) and ``cp_est_update(y, U, x)``
(one period, ``U`` the ctrl of each physics step since the last sample, column-major ``(nu, m)``), with tables
taken from the Python estimator's own matrices so the C computes what :mod:`cartpole.estimation` computes.

=========  ===============  ==========================================================================
estimator  C file           Python class it reproduces
=========  ===============  ==========================================================================
none       ``cp_state.c``   the state itself (``y = [qpos, qvel]``)
kf         ``cp_kf.c``      :class:`~cartpole.estimation.kalman.KalmanFilter` (steady-state gain)
ekf        ``cp_ekf.c``     :class:`~cartpole.estimation.ekf.ExtendedKalmanFilter`
=========  ===============  ==========================================================================
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from cartpole.errors import CartPoleError
from cartpole.estimation import measurement_function
from cartpole.estimation.sensors import KINDS
from cartpole.export.csource import table
from cartpole.export.program import CPart


class ExportError(CartPoleError):
    """An export that cannot be made: a method or estimator the C cannot reproduce at these settings, a plan that
    does not exist, an output folder that is not an earlier export, no C compiler."""


def state_part() -> CPart:
    """Estimator ``none`` (``cp_state.c``): the measurement is the state ``[qpos, qvel]``."""
    return CPart(sources=("cp_state.c",))


def first_state_rows(model, spec) -> np.ndarray:
    """For each joint, the row of ``y`` whose ``jointpos`` sensor gives the first estimate (-1: from
    ``model.x_hanging``), as :func:`cartpole.estimation.initial_state` does.

    Parameters
    ----------
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    (nq,) int array

    Raises
    ------
    ExportError
        A joint without an encoder that other position sensors (frame positions, axes) would solve for: that
        Gauss-Newton fit is not exported.
    """
    nq = int(model.nq)
    rows = np.full(nq, -1, dtype=int)
    other = False
    start = 0
    for s in spec.sensors:
        if s.kind == "jointpos":
            if rows[s.target] < 0:
                rows[s.target] = start
        elif KINDS[s.kind][1] == "position":
            other = True
        start += s.dim
    if other and np.any(rows < 0):
        raise ExportError("The first estimate of a joint without an encoder comes from a Gauss-Newton fit of the "
                          "frame sensors, which the export does not generate; put a jointpos sensor on every joint.")
    return rows


def first_state_data(model, spec, base) -> tuple:
    """The tables ``EST_ROW`` (:func:`first_state_rows`) and ``EST_BASE`` (``base`` with zero rates) of the rig's
    first estimate (``cp_first_state`` of ``cartpole/csrc/cp_common.c``: encoder positions, ``base``'s elsewhere,
    zero rates).

    Parameters
    ----------
    model : CartPoleModel
    spec : SensorSpec
    base : (nx,) array
        Where the unmeasured positions come from.

    Returns
    -------
    tuple of (name, ctype, values)
    """
    rows = first_state_rows(model, spec)
    base = np.array(base, dtype=float).ravel()
    base[int(model.nq):] = 0.0
    return (("EST_ROW", "int", rows), ("EST_BASE", "cp_real", base))


def reset_code(model, spec, base) -> tuple[str, str]:
    """For a part written as C text: the ``static const`` tables of :func:`first_state_data`; the code is empty
    (``first_state(y, x)`` is a macro of ``src/cp_legacy.c`` calling ``cp_first_state`` on them).

    Parameters
    ----------
    model : CartPoleModel
    spec : SensorSpec
    base : (nx,) array

    Returns
    -------
    (str, str)
    """
    return "".join(table(n, v, c) for n, c, v in first_state_data(model, spec, base)), ""


def kalman_part(kf, model, spec) -> CPart:
    """The steady-state Kalman filter ``kf`` (:class:`cartpole.estimation.kalman.KalmanFilter`) as ``cp_kf.c``: its
    ``A``, ``B``, ``C``, ``D``, ``L`` and operating point as tables; ``h`` at a copy of the operating point a whole
    turn away is generated (``cp_h``).

    Parameters
    ----------
    kf : KalmanFilter
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    CPart
    """
    x, u = ca.SX.sym("x", kf.nx), ca.SX.sym("u", kf.nu)
    h = ca.Function("cp_h", [x, u], [ca.densify(measurement_function(model, spec)(x, u))])
    data = first_state_data(model, spec, model.x_hanging) + tuple(
        (f"KF_{n}", "cp_real", getattr(kf, a)) for n, a in (("A", "A"), ("B", "B"), ("C", "C"), ("D", "D"),
                                                          ("L", "L"), ("XOP", "x_op"), ("UOP", "u_op"),
                                                          ("YOP", "y_op")))
    return CPart(sources=("cp_kf.c",), data=data, functions=(h,))


#: Kept for the parts written as C text: the linear algebra is ``cartpole/csrc/cp_linalg.c`` (``cp_linalg.h``,
#: included by ``src/cp_legacy.c``), so nothing is added to their code.
LINALG = ""


def ekf_part(ekf, model, spec) -> CPart:
    """The extended Kalman filter ``ekf`` (:class:`cartpole.estimation.ekf.ExtendedKalmanFilter`) as ``cp_ekf.c``:
    the prediction over the period and its Jacobian (``model.hold(m)``) and the measurement and its Jacobian
    CasADi-generated (``cp_ekf_predict``, ``cp_ekf_measure``), the covariance update in the Joseph form with
    ``P`` symmetrised, a prediction that is not finite kept at the last estimate with ``P + W``, as the Python
    filter does.

    Parameters
    ----------
    ekf : ExtendedKalmanFilter
    model : CartPoleModel
    spec : SensorSpec

    Returns
    -------
    CPart
    """
    nx, nu, m = ekf.nx, ekf.nu, ekf.steps
    hold = model.hold(m)
    x, U = ca.SX.sym("x", nx), ca.SX.sym("U", nu, m)
    predict = ca.Function("cp_ekf_predict", [x, U], [ca.densify(hold.step_inputs(x, U)),
                                                      ca.densify(hold.ABd_inputs(x, U)[0])], {"cse": True})
    u = ca.SX.sym("u", nu)
    y = measurement_function(model, spec)(x, u)
    measure = ca.Function("cp_ekf_measure", [x, u], [ca.densify(y), ca.densify(ca.jacobian(y, x))], {"cse": True})
    data = first_state_data(model, spec, model.x_hanging) + (
        ("EKF_W", "cp_real", ekf.W), ("EKF_V", "cp_real", ekf.V), ("EKF_P0", "cp_real", ekf.P0))
    return CPart(sources=("cp_ekf.c",), data=data, functions=(predict, measure))
