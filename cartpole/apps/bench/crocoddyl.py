"""Side by side with Crocoddyl: its own double-pendulum swing-up example solved by its FDDP and by the toolkit's DDP.

Crocoddyl's ``examples/double_pendulum_fwddyn.py`` (3.2.1): the example-robot-data double pendulum, a torque on the
first joint, Euler at ``dt = 0.01`` s over ``N = 100`` steps from ``x0 = (3.14, 0, 0, 0)`` (hanging), running cost
``1e-4 / dt * |u|^2 / 2 + 1e-5 / dt * r' W r / 2`` (integrated: times ``dt``) and terminal ``100 r' W r / 2`` with
the soft goal residual ``r = (sin q1, sin q2, 1 - cos q1, 1 - cos q2, v1, v2)``, ``W = diag(1, 1, 1, 1, 0.1, 0.1)``.
The toolkit solves the same problem on the same model, converted by MuJoCo's URDF import
(``cartpole/assets/examples/crocoddyl_double_pendulum.xml``): its exact Euler step (MuJoCo's semi-implicit Euler,
which is Crocoddyl's ``IntegratedActionModelEuler``), the same costs as CasADi Functions, the box-DDP of
:mod:`cartpole.solvers.ddp`.

Crocoddyl's cart-pole example (its notebook ``02_optimizing_a_cartpole_swingup.ipynb``, the action model a user writes
in Python, the way that notebook teaches it): a 1 kg cart, a 0.1 kg point mass 0.5 m up the pole, the force on the
cart unbounded, semi-implicit Euler at ``dt = 0.05`` s over ``N = 50`` nodes from ``x0 = (0, 0, 1, 0.5)`` (upright,
moving), the per-node cost ``|w * (sin th, 1 - cos th, y, ydot, thdot, f)|^2 / 2`` with ``w = (1, 1, 0.1, 0.001,
0.001, 1)`` (not times ``dt``: the model is discrete) and the terminal the same without ``f``. Ours runs on the MJCF
of it (``cartpole/assets/examples/crocoddyl_cartpole.xml``, MuJoCo's Euler step equal to the notebook's update to
1e-8 relative, the 1e-12 kg m^2 inertia MuJoCo needs of the point mass) with the force bounded at 1000 N, which no
solution reaches (the box-DDP needs finite bounds). Crocoddyl's side is an action model written here from the
notebook's equations, its values and derivatives from one CasADi Function (the notebook's own model is
hand-differentiated numpy: the same Python callback per node). Crocoddyl starts from its default guess (every
node's state upright at rest), ours, a single-shooting DDP that takes no state guess, from the ctrl of the upright
LQR run from ``x0``: from zero force its pole falls and it settles in a local minimum (``zero_guess``).

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

from cartpole.control.linear import LinearFeedback
from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.solvers.ddp import DDP, DDPOptions, DDPProblem

#: The example's settings.
DT, N, X0 = 0.01, 100, (3.14, 0.0, 0.0, 0.0)
U_WEIGHT, X_WEIGHT, TERMINAL_WEIGHT = 1e-4, 1e-5, 100.0
RESIDUAL_WEIGHTS = (1.0, 1.0, 1.0, 1.0, 0.1, 0.1)


def _residual(x):
    return ca.vertcat(ca.sin(x[0]), ca.sin(x[1]), 1 - ca.cos(x[0]), 1 - ca.cos(x[1]), x[2], x[3])


def example_model(name: str, model=None):
    """``model`` when given, else the shipped example MJCF ``cartpole/assets/examples/NAME`` built."""
    return build_model(SHIPPED_MJCF.parent / "examples" / name) if model is None else model


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
    model = example_model("crocoddyl_double_pendulum.xml", model)
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    r = _residual(x)
    goal = 0.5 * ca.dot(ca.DM(RESIDUAL_WEIGHTS) * r, r)
    running = ca.Function("croc_running", [x, u], [U_WEIGHT / DT * 0.5 * ca.dot(u, u) + X_WEIGHT / DT * goal])
    terminal = ca.Function("croc_terminal", [x], [TERMINAL_WEIGHT * goal])
    lo, hi = np.asarray(model.params.ctrl_range, float).T
    problem = DDPProblem(u_low=lo, u_high=hi, running=running, terminal=terminal, hinges=model.hinges)
    ddp = DDP(model.step, DT, N, problem, options=DDPOptions(tolerance=1e-9, compiled=compiled))
    return ddp, np.array(X0)


#: Crocoddyl's cart-pole example: step, nodes, start, residual weights, and the force bound ours needs (never reached).
CP_DT, CP_N, CP_X0 = 0.05, 50, (0.0, 0.0, 1.0, 0.5)
CP_WEIGHTS = (1.0, 1.0, 0.1, 0.001, 0.001, 1.0)
CP_FORCE_BOUND = 1000.0


def _cartpole_cost(x, u):
    """``|w * r|^2 / 2`` of the cart-pole example's residual ``r = (sin th, 1 - cos th, y, ydot, thdot, f)``."""
    r = ca.DM(CP_WEIGHTS) * ca.vertcat(ca.sin(x[1]), 1 - ca.cos(x[1]), x[0], x[2], x[3], u)
    return 0.5 * ca.dot(r, r)


def cartpole_ddp(model=None, *, compiled: bool = True):
    """The toolkit's :class:`~cartpole.solvers.ddp.DDP` of Crocoddyl's cart-pole example (see the module doc): the
    per-node cost divided by ``dt`` (the DDP sums ``dt L``), the terminal cost the same residual without the force.

    Parameters
    ----------
    model : CartPoleModel, optional
        Default ``cartpole/assets/examples/crocoddyl_cartpole.xml``.
    compiled : bool

    Returns
    -------
    (DDP, x0 (4,) array)
    """
    model = example_model("crocoddyl_cartpole.xml", model)
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    running = ca.Function("croc_cp_running", [x, u], [_cartpole_cost(x, u) / CP_DT])
    terminal = ca.Function("croc_cp_terminal", [x], [_cartpole_cost(x, 0)])
    problem = DDPProblem(u_low=-CP_FORCE_BOUND, u_high=CP_FORCE_BOUND, running=running, terminal=terminal,
                         hinges=model.hinges)
    ddp = DDP(model.step, CP_DT, CP_N, problem, options=DDPOptions(tolerance=1e-9, compiled=compiled))
    return ddp, np.array(CP_X0)


def _crocoddyl_cartpole_problem():
    """Crocoddyl's cart-pole example as a :class:`crocoddyl.ActionModelAbstract` in Python (the notebook's
    equations: point-mass cart-pole, the angle from upright positive toward -x, semi-implicit Euler)."""
    import crocoddyl

    x, u = ca.SX.sym("x", 4), ca.SX.sym("u", 1)
    M, m, length, g = 1.0, 0.1, 0.5, 9.81
    s, c, thd = ca.sin(x[1]), ca.cos(x[1]), x[3]
    mu = M + m * s * s
    ydd = (u[0] + m * g * c * s - m * length * s * thd ** 2) / mu
    thdd = (u[0] * c / length + (M + m) * g * s / length - m * c * s * thd ** 2) / mu
    vel = ca.vertcat(x[2] + CP_DT * ydd, x[3] + CP_DT * thdd)
    xn = ca.vertcat(x[0] + CP_DT * vel[0], x[1] + CP_DT * vel[1], vel)
    cost = _cartpole_cost(x, u)
    z = ca.vertcat(x, u)
    fun = ca.Function("croc_cp", [x, u], [xn, cost, ca.jacobian(xn, x), ca.jacobian(xn, u), ca.gradient(cost, z),
                                          ca.hessian(cost, z)[0]])
    term = _cartpole_cost(x, 0)
    tfun = ca.Function("croc_cp_t", [x], [term, ca.gradient(term, x), ca.hessian(term, x)[0]])

    class CartpoleModel(crocoddyl.ActionModelAbstract):
        def __init__(self, terminal: bool):
            crocoddyl.ActionModelAbstract.__init__(self, crocoddyl.StateVector(4), 1, 6)
            self.is_terminal = terminal

        def calc(self, data, x, u=None):
            if u is None or self.is_terminal:
                data.xnext[:] = x
                data.cost = float(tfun(x)[0])
            else:
                xn, cost = fun(x, u)[:2]
                data.xnext[:] = np.asarray(xn).ravel()
                data.cost = float(cost)

        def calcDiff(self, data, x, u=None):
            if u is None or self.is_terminal:
                _, gx, hx = tfun(x)
                data.Fx[:, :] = np.eye(4)
                data.Lx[:] = np.asarray(gx).ravel()
                data.Lxx[:, :] = np.asarray(hx)
            else:
                _, _, fx, fu, gz, hz = (np.asarray(v) for v in fun(x, u))
                data.Fx[:, :] = fx
                data.Fu[:] = fu.reshape(np.shape(data.Fu))
                data.Lx[:], data.Lu[:] = gz.ravel()[:4], gz.ravel()[4:]
                data.Lxx[:, :] = hz[:4, :4]
                data.Lxu[:] = hz[:4, 4:].reshape(np.shape(data.Lxu))
                data.Luu[:] = hz[4:, 4:].reshape(np.shape(data.Luu))

    return crocoddyl.ShootingProblem(np.array(CP_X0), [CartpoleModel(False)] * CP_N, CartpoleModel(True))


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


def _side_by_side(ddp, x0, problem, N: int, dt: float, repeats: int, *, U0=None, crocoddyl_guess=True) -> dict:
    """Our DDP from the ctrl guess ``U0`` (default zeros) and Crocoddyl's FDDP (``crocoddyl_guess``: zero ctrl with
    every state ``x0``; False: Crocoddyl's own default, its state's zero at every node, as ``solver.solve()``) on one
    problem, ``repeats`` timed solves each (ours compiled and warm first); the keys of :func:`crocoddyl_benchmark`."""
    U0 = np.zeros((N, ddp.nu)) if U0 is None else np.asarray(U0, float)
    ddp.solve(x0, U0)  # compiled and warm; every timed solve starts again from the same guess
    times, res = [], None
    for _ in range(max(1, int(repeats))):
        t = time.perf_counter()
        res = ddp.solve(x0, U0)
        times.append(1e3 * (time.perf_counter() - t))
    ours = {"ms_median": statistics.median(times), "ms_all": times, "iterations": res.iterations,
            "cost": res.cost, "status": res.status, "final_state": res.x[-1].tolist(),
            "peak_ctrl": float(np.abs(res.u).max())}
    out = {"ours": ours, "crocoddyl": None, "speedup": None, "cost_gap": None, "N": N, "dt": dt}
    try:
        import crocoddyl
    except ImportError as exc:
        out["crocoddyl_missing"] = f"{exc.name or exc}: pip install crocoddyl 'pin==4.0.0' example-robot-data"
        return out
    times, solver = [], None
    for _ in range(max(1, int(repeats))):
        solver = crocoddyl.SolverFDDP(problem())
        t = time.perf_counter()
        if crocoddyl_guess:
            solver.solve([np.asarray(x0, float)] * (N + 1), [np.zeros(ddp.nu)] * N, 1000)
        else:
            solver.solve([], [], 1000)
        times.append(1e3 * (time.perf_counter() - t))
    theirs = {"ms_median": statistics.median(times), "ms_all": times, "iterations": int(solver.iter),
              "cost": float(solver.cost), "status": "converged" if solver.isFeasible else "infeasible",
              "final_state": np.asarray(solver.xs[-1]).tolist(),
              "peak_ctrl": float(np.abs(np.asarray(solver.us)).max())}
    out.update(crocoddyl=theirs, speedup=theirs["ms_median"] / ours["ms_median"],
               cost_gap=ours["cost"] - theirs["cost"])
    return out


def crocoddyl_benchmark(*, repeats: int = 3) -> dict:
    """Solve Crocoddyl's double-pendulum example, and its cart-pole example, with Crocoddyl's FDDP and with the
    toolkit's DDP, same guess.

    Parameters
    ----------
    repeats : int
        Timed solves of each (the first, building call of ours is not timed: its functions are compiled once).

    Returns
    -------
    dict
        The double pendulum's ``ours`` {``ms_median``, ``ms_all``, ``iterations``, ``cost``, ``status``,
        ``final_state``, ``peak_ctrl``}, ``crocoddyl`` (the same keys, or None when it is not installed, with
        ``crocoddyl_missing`` the reason), ``speedup`` (Crocoddyl's median over ours) and ``cost_gap`` (ours minus
        Crocoddyl's), ``N``, ``dt``; and ``cartpole``, the same keys for the cart-pole example (ours from
        :func:`cartpole_lqr_guess`, Crocoddyl from its default guess), with ``guess`` and ``zero_guess`` (ours from
        zero force: ``cost``, ``iterations``, ``status``, ``final_state``).
    """
    ddp, x0 = double_pendulum_ddp()
    out = _side_by_side(ddp, x0, _crocoddyl_problem, N, DT, repeats)
    ddp, x0 = cartpole_ddp()
    # Crocoddyl as its notebook calls it (every node's state guess upright at rest); ours, a single-shooting DDP,
    # cannot take a state guess: from zero force the pole falls and its DDP settles in a local minimum that swings the
    # pole round once (reported as zero_guess), so its ctrl guess is the upright LQR's rollout, the guess a control
    # engineer makes for "stay up"
    cp = _side_by_side(ddp, x0, _crocoddyl_cartpole_problem, CP_N, CP_DT, repeats, U0=cartpole_lqr_guess(),
                       crocoddyl_guess=False)
    zero = ddp.solve(x0, np.zeros((CP_N, ddp.nu)))
    cp["guess"] = "upright LQR rollout"
    cp["zero_guess"] = {"cost": zero.cost, "iterations": zero.iterations, "status": zero.status,
                        "final_state": zero.x[-1].tolist()}
    out["cartpole"] = cp
    return out


def cartpole_lqr_guess(model=None) -> np.ndarray:
    """(N, 1) ctrl of the upright LQR (:meth:`~cartpole.control.linear.LinearFeedback.for_model`, the lab's
    weights) run from the cart-pole example's start on its exact step: the ctrl guess of ours there."""
    model = example_model("crocoddyl_cartpole.xml", model)
    ctl = LinearFeedback.for_model(model)
    x, U = np.array(CP_X0), []
    for k in range(CP_N):
        u = np.asarray(ctl(k * CP_DT, x), float).ravel()
        U.append(u)
        x = np.asarray(model.step(x, u), float).ravel()
    return np.array(U)


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
    cp = doc.get("cartpole")
    if cp is not None:
        o, c = cp["ours"], cp["crocoddyl"]
        w(f"Crocoddyl's cart-pole example (N = {cp['N']}, dt = {cp['dt']} s, a Python action model): ours "
          f"(from the LQR's rollout; from zero force a local minimum of cost {cp['zero_guess']['cost']:.3f}) "
          f"{o['ms_median']:.1f} ms, {o['iterations']} iterations, cost {o['cost']:.6f}")
        w("\n" if c is None else f"; Crocoddyl FDDP {c['ms_median']:.1f} ms, {c['iterations']} iterations, cost "
          f"{c['cost']:.6f}; {cp['speedup']:.1f}x\n")
