"""Trajectory optimisation: Hermite-Simpson direct collocation, the Trajectory it returns, and the
collocation -> TVLQR swing-up pipeline."""
from cartpole.ocp.collocation import DirectCollocation, OCPError, OCPInfeasible, SolveInfo
from cartpole.ocp.pipeline import SwingupPlan, minimum_time, trajopt_swingup
from cartpole.ocp.trajectory import Trajectory, TrajectoryError

__all__ = ["DirectCollocation", "OCPError", "OCPInfeasible", "SolveInfo", "SwingupPlan", "minimum_time",
           "trajopt_swingup", "Trajectory", "TrajectoryError"]
