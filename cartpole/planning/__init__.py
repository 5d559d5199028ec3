"""The swing-up planner: minimum time, then the chosen objective, from named guesses and several starts, the plan
re-solved on the exact discrete step where tracking needs it, and TVLQR gains along it with the hand-over LQR
(:mod:`~cartpole.planning.trajopt`), its settings as one value (:class:`~cartpole.planning.options.PlanOptions`).
It sits above :mod:`cartpole.ocp` (the problems) and :mod:`cartpole.solvers` (the SQP), below :mod:`cartpole.mpc`
(whose swing-up starts from a plan)."""
from cartpole.planning.options import PlanOptions, PlanOptionsError
from cartpole.planning.trajopt import SwingupPlan, handover_catch, minimum_time, trajopt_swingup

__all__ = ["PlanOptions", "PlanOptionsError", "SwingupPlan", "handover_catch", "minimum_time", "trajopt_swingup"]
