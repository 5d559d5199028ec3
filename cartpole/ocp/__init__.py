"""Trajectory optimisation problems for any cart-pole model (any nq, nu): Hermite-Simpson direct collocation
(:mod:`~cartpole.ocp.collocation`) with bounds from the MJCF (:mod:`~cartpole.ocp.bounds`), objectives
(:mod:`~cartpole.ocp.objectives`), initial guesses (:mod:`~cartpole.ocp.guess`), the :class:`Trajectory` a solve
returns and the records of each solve (:mod:`~cartpole.ocp.records`). Solvers beyond IPOPT and fatrop are in
:mod:`cartpole.solvers`; the swing-up planner that uses both in :mod:`cartpole.planning`."""
from cartpole.ocp.bounds import OCPBounds, bounds_from_model, bounds_from_params
from cartpole.ocp.collocation import CollocationOptions, DirectCollocation, OCPError, OCPInfeasible, OCPNotSolved
from cartpole.ocp.objectives import Objective, Reward, make_objective, reward
from cartpole.ocp.records import Attempt, SolveInfo
from cartpole.ocp.trajectory import Trajectory, TrajectoryError

__all__ = ["OCPBounds", "bounds_from_model", "bounds_from_params", "DirectCollocation", "OCPError", "OCPInfeasible",
           "OCPNotSolved", "CollocationOptions", "Attempt", "SolveInfo", "Trajectory", "TrajectoryError", "Objective",
           "Reward", "make_objective", "reward"]
