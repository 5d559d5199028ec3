"""Controllers with one call shape, ``u = controller(t, x)``: linear feedback, energy shaping, switching."""
from cartpole.control.linear import LinearFeedback, state_error

__all__ = ["LinearFeedback", "state_error"]
from cartpole.control.tvlqr import TVLQRController  # noqa: E402

__all__ += ["TVLQRController"]
from cartpole.control.energy import EnergyGains, EnergyShapingController, energy_guess, energy_rollout  # noqa: E402
from cartpole.control.switching import Switch, SwitchingController, lab_catch  # noqa: E402

__all__ += ["EnergyGains", "EnergyShapingController", "energy_guess", "energy_rollout", "Switch",
            "SwitchingController", "lab_catch"]
from cartpole.control.pid import CascadedPID, PIDError, PIDGains, tune_pid  # noqa: E402

__all__ += ["CascadedPID", "PIDError", "PIDGains", "tune_pid"]
