"""Side by side with Crocoddyl: its own double-pendulum swing-up example solved by its FDDP and by the toolkit's DDP.

Crocoddyl's ``examples/double_pendulum_fwddyn.py`` (3.2.1): the example-robot-data double pendulum, a torque on the
first joint, Euler at ``dt = 0.01`` s over ``N = 100`` steps from ``x0 = (3.14, 0, 0, 0)`` (hanging), running cost
``1e-4 / dt * |u|^2 / 2 + 1e-5 / dt * r' W r / 2`` (integrated: times ``dt``) and terminal ``100 r' W r / 2`` with
the soft goal residual ``r = (sin q1, sin q2, 1 - cos q1, 1 - cos q2, v1, v2)``, ``W = diag(1, 1, 1, 1, 0.1, 0.1)``.
The toolkit solves the same problem on the same model, converted by MuJoCo's URDF import
(``cartpole/assets/examples/crocoddyl_double_pendulum.xml``): its exact Euler step (MuJoCo's semi-implicit Euler,
which is Crocoddyl's ``IntegratedActionModelEuler``), the same costs as CasADi Functions, the box-DDP of
:mod:`cartpole.solvers.ddp`.

Both start from the same guess: zero torque from ``x0`` (Crocoddyl: ``solve([x0] * (N + 1), [0] * N)``, its states
the hanging rest it starts from). Crocoddyl is optional (the ``crocoddyl`` extra: ``crocoddyl`` with ``pin==4.0.0``;
``pin`` 4.1 makes Crocoddyl 3.2.1 compute wrong dynamics without an error, DESIGN.md); without it the row holds the
toolkit's numbers and ``crocoddyl`` None.
"""
from __future__ import annotations

import statistics
import sys
import time

import casadi as ca
import numpy as np

#: The example's settings.
DT, N, X0 = 0.01, 100, (3.14, 0.0, 0.0, 0.0)
U_WEIGHT, X_WEIGHT, TERMINAL_WEIGHT = 1e-4, 1e-5, 100.0
RESIDUAL_WEIGHTS = (1.0, 1.0, 1.0, 1.0, 0.1, 0.1)


def _residual(x):
    return ca.vertcat(ca.sin(x[0]), ca.sin(x[1]), 1 - ca.cos(x[0]), 1 - ca.cos(x[1]), x[2], x[3])


def double_pendulum_ddp(model=None, *, compiled: bool = True):
    """The toolkit's :class:`~cartpole.solvers.ddp.DDP` of Crocoddyl's double-pendulum example (see the module doc).

    Parameters
    ----------
    model : CartPoleModel, optional
        Default the shipped conversion, ``cartpole/assets/examples/crocoddyl_double_pendulum.xml``.
    compiled : bool

    Returns
    -------
    (DDP, x0 (4,) array)
    """
    from cartpole.models import SHIPPED_MJCF, build_model
    from cartpole.solvers.ddp import DDP, DDPOptions

    model = build_model(SHIPPED_MJCF.parent / "examples" / "crocoddyl_double_pendulum.xml") if model is None else model
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    r = _residual(x)
    goal = 0.5 * ca.dot(ca.DM(RESIDUAL_WEIGHTS) * r, r)
    running = ca.Function("croc_running", [x, u], [U_WEIGHT / DT * 0.5 * ca.dot(u, u) + X_WEIGHT / DT * goal])
    terminal = ca.Function("croc_terminal", [x], [TERMINAL_WEIGHT * goal])
    lo, hi = np.asarray(model.params.ctrl_range, float).T
    ddp = DDP(model.step, DT, N, running=running, terminal=terminal, u_low=lo, u_high=hi, hinges=model.hinges,
              options=DDPOptions(tolerance=1e-9), compiled=compiled)
    return ddp, np.array(X0)


def _crocoddyl_problem():
    import crocoddyl
    import example_robot_data
    from crocoddyl.utils.pendulum import ActuationModelDoublePendulum, CostModelDoublePendulum

    pend = example_robot_data.load("double_pendulum")
    state = crocoddyl.StateMultibody(pend.model)
    actuation = ActuationModelDoublePendulum(state, actLink=1)
    nu = actuation.nu
    running, terminal = crocoddyl.CostModelSum(state, nu), crocoddyl.CostModelSum(state, nu)
    x_goal = CostModelDoublePendulum(state, crocoddyl.ActivationModelWeightedQuad(np.array(RESIDUAL_WEIGHTS)), nu)
    u_reg = crocoddyl.CostModelResidual(state, crocoddyl.ResidualModelControl(state, nu))
    running.addCost("uReg", u_reg, U_WEIGHT / DT)
    running.addCost("xGoal", x_goal, X_WEIGHT / DT)
    terminal.addCost("xGoal", x_goal, TERMINAL_WEIGHT)

    def integrated(costs):
        return crocoddyl.IntegratedActionModelEuler(
            crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, costs), DT)

    return crocoddyl.ShootingProblem(np.array(X0), [integrated(running)] * N, integrated(terminal))


def crocoddyl_benchmark(*, repeats: int = 3) -> dict:
    """Solve Crocoddyl's double-pendulum example with Crocoddyl's FDDP and with the toolkit's DDP, same guess.

    Parameters
    ----------
    repeats : int
        Timed solves of each (the first, building call of ours is not timed: its functions are compiled once).

    Returns
    -------
    dict
        ``ours`` {``ms_median``, ``ms_all``, ``iterations``, ``cost``, ``status``, ``final_state``}, ``crocoddyl``
        (the same keys, or None when it is not installed, with ``crocoddyl_missing`` the reason), ``speedup``
        (Crocoddyl's median over ours) and ``cost_gap`` (ours minus Crocoddyl's), ``N``, ``dt``.
    """
    ddp, x0 = double_pendulum_ddp()
    U0 = np.zeros((N, ddp.nu))
    ddp.solve(x0, U0)  # compiled and warm; every timed solve starts again from the same guess
    times, res = [], None
    for _ in range(max(1, int(repeats))):
        t = time.perf_counter()
        res = ddp.solve(x0, U0)
        times.append(1e3 * (time.perf_counter() - t))
    ours = {"ms_median": statistics.median(times), "ms_all": times, "iterations": res.iterations,
            "cost": res.cost, "status": res.status, "final_state": res.x[-1].tolist()}
    out = {"ours": ours, "crocoddyl": None, "speedup": None, "cost_gap": None, "N": N, "dt": DT}
    try:
        import crocoddyl
    except ImportError as exc:
        out["crocoddyl_missing"] = f"{exc.name or exc}: pip install crocoddyl 'pin==4.0.0' example-robot-data"
        return out
    times, solver = [], None
    for _ in range(max(1, int(repeats))):
        solver = crocoddyl.SolverFDDP(_crocoddyl_problem())
        t = time.perf_counter()
        solver.solve([np.array(X0)] * (N + 1), [np.zeros(1)] * N, 1000)
        times.append(1e3 * (time.perf_counter() - t))
    theirs = {"ms_median": statistics.median(times), "ms_all": times, "iterations": int(solver.iter),
              "cost": float(solver.cost), "status": "converged" if solver.isFeasible else "infeasible",
              "final_state": np.asarray(solver.xs[-1]).tolist()}
    out.update(crocoddyl=theirs, speedup=theirs["ms_median"] / ours["ms_median"],
               cost_gap=ours["cost"] - theirs["cost"])
    return out


def print_crocoddyl(doc: dict, file=None) -> None:
    """Prose lines of a :func:`crocoddyl_benchmark` document."""
    w = (sys.stdout if file is None else file).write
    o, c = doc["ours"], doc["crocoddyl"]
    w(f"\nCrocoddyl's double-pendulum example (N = {doc['N']}, dt = {doc['dt']} s, from hanging, zero torque): ours "
      f"{o['ms_median']:.1f} ms, {o['iterations']} iterations, cost {o['cost']:.6f}")
    if c is None:
        w(f"; Crocoddyl not installed ({doc.get('crocoddyl_missing')})\n")
    else:
        w(f"; Crocoddyl FDDP {c['ms_median']:.1f} ms, {c['iterations']} iterations, cost {c['cost']:.6f}; "
          f"{doc['speedup']:.1f}x\n")
