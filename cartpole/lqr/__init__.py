"""Linear-quadratic regulators: infinite-horizon ``lqr``/``dlqr`` (:mod:`~cartpole.lqr.riccati`), finite-horizon
TVLQR (:mod:`~cartpole.lqr.tvlqr`) and the lab's default weights (:mod:`~cartpole.lqr.weights`)."""
from cartpole.lqr.riccati import (LQRError, LQRResult, check_weights, dlqr, is_controllable, lqr,
                                  uncontrollable_modes)
from cartpole.lqr.tvlqr import TVLQRGains, riccati_backward, tvlqr
from cartpole.lqr.weights import Q_LAB, R_LAB, lab_weights

__all__ = ["LQRError", "LQRResult", "check_weights", "dlqr", "is_controllable", "lqr", "uncontrollable_modes",
           "TVLQRGains", "riccati_backward", "tvlqr", "Q_LAB", "R_LAB", "lab_weights"]
