"""The swing-up planner: minimum time, then the chosen objective, from named guesses and several starts, the plan
re-solved on the exact discrete step where tracking needs it, and TVLQR gains along it with the hand-over LQR
(:mod:`~cartpole.planning.trajopt`), its settings as one value (:class:`~cartpole.planning.options.PlanOptions`).
When no guess converges, a search for swing-ups that pump at the chain's slowest hanging mode
(:mod:`~cartpole.planning.pumping`), and the refusal: infeasible only with the proof of the energy ceiling
(:mod:`~cartpole.planning.energy_ceiling`), else "no swing-up found". It sits above :mod:`cartpole.ocp` (the problems)
and :mod:`cartpole.solvers` (the SQP), below :mod:`cartpole.mpc` (whose swing-up starts from a plan). For a pendulum
driven at its hinge, the optimal policy over its whole state plane by value iteration
(:mod:`~cartpole.planning.value_iteration`)."""
from cartpole.planning.energy_ceiling import EnergyCeiling, energy_ceiling
from cartpole.planning.options import PlanOptions, PlanOptionsError
from cartpole.planning.pumping import hanging_mode, pumping_search
from cartpole.planning.trajopt import SwingupPlan, handover_catch, minimum_time, trajopt_swingup
from cartpole.planning.value_iteration import (BandReward, DMCReward, HingeValues, ValueIterationOptions, ValuePolicy,
                                               cached_hinge_values, hinge_values)

__all__ = ["EnergyCeiling", "PlanOptions", "PlanOptionsError", "SwingupPlan", "energy_ceiling", "handover_catch",
           "hanging_mode", "minimum_time", "pumping_search", "trajopt_swingup", "BandReward", "DMCReward", "HingeValues",
           "ValueIterationOptions", "ValuePolicy", "cached_hinge_values", "hinge_values"]
