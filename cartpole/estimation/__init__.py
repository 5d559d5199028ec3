"""State estimation for a rig that measures, not an oracle: sensors (encoders, noise, quantisation, bias), the
Kalman filter (LQG), the extended Kalman filter and moving-horizon estimation, and prediction over a known delay."""
from cartpole.estimation.base import EstimationError, Estimator
from cartpole.estimation.mhe import MovingHorizonEstimator, bench_mhe, horizon_periods

__all__ = ["EstimationError", "Estimator", "MovingHorizonEstimator", "bench_mhe", "horizon_periods"]
