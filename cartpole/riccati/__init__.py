"""Riccati equations: infinite-horizon LQR, continuous and discrete (``lqr``/``dlqr``, the algebraic equations, in
:mod:`~cartpole.riccati.algebraic`), finite-horizon TVLQR (the Riccati recursion, :mod:`~cartpole.riccati.tvlqr`) and
the default weights (:mod:`~cartpole.riccati.weights`).

Named for the mathematics it solves (as :func:`scipy.linalg.solve_continuous_are`), so that the subpackage does not
share its name with the function ``cartpole.lqr``."""
from cartpole.riccati.algebraic import (LQRError, LQRResult, check_weights, dlqr, is_controllable, lqr,
                                        uncontrollable_modes)
from cartpole.riccati.tvlqr import TVLQRGains, riccati_backward, tvlqr
from cartpole.riccati.weights import ONE_POLE, default_weights

__all__ = ["LQRError", "LQRResult", "check_weights", "dlqr", "is_controllable", "lqr", "uncontrollable_modes",
           "TVLQRGains", "riccati_backward", "tvlqr", "ONE_POLE", "default_weights"]
