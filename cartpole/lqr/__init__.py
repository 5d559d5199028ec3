"""Linear-quadratic regulators: infinite-horizon ``lqr``/``dlqr`` (:mod:`~cartpole.lqr.riccati`), finite-horizon
TVLQR (:mod:`~cartpole.lqr.tvlqr`) and the lab's default weights (:mod:`~cartpole.lqr.weights`)."""
from cartpole.lqr.riccati import LQRError, LQRResult, check_weights, dlqr, lqr
from cartpole.lqr.tvlqr import TVLQRGains, tvlqr
from cartpole.lqr.weights import Q_LAB, R_LAB, lab_weights

__all__ = ["LQRError", "LQRResult", "check_weights", "dlqr", "lqr", "TVLQRGains", "tvlqr", "Q_LAB", "R_LAB",
           "lab_weights"]
