"""Linear-quadratic regulators: infinite-horizon ``lqr``/``dlqr`` (and finite-horizon TVLQR in ``tvlqr``)."""
from cartpole.lqr.lqr import LQRError, LQRResult, check_weights, dlqr, lqr

__all__ = ["LQRError", "LQRResult", "check_weights", "dlqr", "lqr"]
from cartpole.lqr.tvlqr import TVLQRGains, tvlqr  # noqa: E402

__all__ += ["TVLQRGains", "tvlqr"]
