"""Trajectory optimisation for any cart-pole model (any nq, nu): Hermite-Simpson direct collocation with bounds
from the MJCF, the Trajectory it returns, and the collocation -> TVLQR swing-up pipeline."""
from cartpole.ocp.bounds import OCPBounds, bounds_from_model, bounds_from_params
from cartpole.ocp.collocation import DirectCollocation, OCPError, OCPInfeasible, SolveInfo
from cartpole.ocp.objectives import Objective, Reward, make_objective, reward
from cartpole.ocp.pipeline import SwingupPlan, handover_catch, minimum_time, trajopt_swingup
from cartpole.ocp.trajectory import Trajectory, TrajectoryError

__all__ = ["OCPBounds", "bounds_from_model", "bounds_from_params", "DirectCollocation", "OCPError", "OCPInfeasible",
           "SolveInfo", "SwingupPlan", "handover_catch", "minimum_time", "trajopt_swingup", "Trajectory", "TrajectoryError",
           "Objective", "Reward", "make_objective", "reward"]
from cartpole.ocp.nmpc import NMPCController, NMPCError, nmpc_swingup  # noqa: E402
__all__ += ["NMPCController", "NMPCError", "nmpc_swingup"]
