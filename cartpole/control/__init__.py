"""Controllers with one call shape, ``u = controller(t, x)``: linear feedback, energy shaping, switching."""
from cartpole.control.linear import FeedbackError, LinearFeedback

__all__ = ["FeedbackError", "LinearFeedback"]
from cartpole.control.model_rollout import model_rollout  # noqa: E402

__all__ += ["model_rollout"]
from cartpole.control.tvlqr import TVLQRController  # noqa: E402

__all__ += ["TVLQRController"]
from cartpole.control.energy import (EnergyGains, EnergyShapingController, EnergyShapingModelError,  # noqa: E402
                                     energy_rollout)
from cartpole.control.switching import SWINGUP_CATCH_R, Switch, SwitchingController  # noqa: E402

__all__ += ["EnergyGains", "EnergyShapingController", "EnergyShapingModelError", "energy_rollout",
            "SWINGUP_CATCH_R", "Switch", "SwitchingController"]
from cartpole.control.pid import CascadedPID, PIDError, PIDGains, tune_pid  # noqa: E402

__all__ += ["CascadedPID", "PIDError", "PIDGains", "tune_pid"]
from cartpole.control.friction import FrictionCompensation  # noqa: E402

__all__ += ["FrictionCompensation"]
from cartpole.control.drain import EnergyDrain, EnergyDrainError  # noqa: E402

__all__ += ["EnergyDrain", "EnergyDrainError"]
