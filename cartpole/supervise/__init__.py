"""A controller that recovers from any state for as long as it runs (:mod:`~cartpole.supervise.supervisor`): the
catch inside its basin, the energy law or a brake and a planner outside it, TVLQR along each new plan."""
from cartpole.supervise.supervisor import (Decision, PassiveBrake, Supervisor, SupervisorError, SupervisorOptions,
                                           supervisor_for)

__all__ = ["Decision", "PassiveBrake", "Supervisor", "SupervisorError", "SupervisorOptions", "supervisor_for"]
