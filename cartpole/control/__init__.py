"""Controllers with one call shape, ``u = controller(t, x)``: linear feedback, energy shaping, switching."""
from cartpole.control.linear import LinearFeedback, state_error

__all__ = ["LinearFeedback", "state_error"]
