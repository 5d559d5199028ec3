"""State estimation for a rig that measures, not an oracle: sensors (encoders, noise, quantisation, bias), the
Kalman filter (LQG), the extended Kalman filter and moving-horizon estimation, and prediction over a known delay."""
from cartpole.estimation.base import EstimationError, Estimator
from cartpole.estimation.ekf import ExtendedKalmanFilter, bench_ekf
from cartpole.estimation.kalman import (
    KalmanFilter,
    KalmanGain,
    kalman_gain,
    state_names,
)
from cartpole.estimation.measurement import initial_state, measurement_function
from cartpole.estimation.mhe import MHEOptions, MovingHorizonEstimator, bench_mhe, horizon_periods
from cartpole.estimation.sensors import (
    KINDS,
    Sensor,
    SensorError,
    SensorFrame,
    SensorSampler,
    SensorSpec,
    sensor_spec,
)

__all__ = [
    "KINDS",
    "EstimationError",
    "Estimator",
    "ExtendedKalmanFilter",
    "KalmanFilter",
    "KalmanGain",
    "MHEOptions",
    "MovingHorizonEstimator",
    "Sensor",
    "SensorError",
    "SensorFrame",
    "SensorSampler",
    "SensorSpec",
    "bench_ekf",
    "bench_mhe",
    "horizon_periods",
    "initial_state",
    "kalman_gain",
    "measurement_function",
    "sensor_spec",
    "state_names",
]
