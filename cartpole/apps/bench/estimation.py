"""The estimators' step times for ``cartpole bench``: MHE (one Gauss-Newton step a period, the compiled C the loop
runs, beside its Python reference step and the naive IPOPT re-solve of the whole window in the same process) and EKF
on the cart's encoders at a 10 ms period (medians of many updates, wall time; construction and compiles not timed)."""
from __future__ import annotations

from cartpole.estimation import measurement_function, sensor_spec
from cartpole.estimation.ekf import bench_ekf
from cartpole.estimation.mhe import bench_mhe
from cartpole.models import plant_model, steps_per_period

#: Control period (s) and MHE window (s) the benchmark uses: 50 periods of 10 ms.
PERIOD = 0.01
MHE_HORIZON = 0.5
#: Runs of the MHE's timed updates (the figure is the median of their medians), Python reference updates timed,
#: and windows the IPOPT baseline re-solves.
MHE_REPEATS, MHE_PYTHON, MHE_BASELINE = 3, 100, 30


def estimation_benchmark(plant=None, *, quick: bool = False) -> dict:
    """``{"period", "mhe": {step_ms_median, step_ms_max, ...}, "ekf": {median_us, p90_us, updates}}`` on ``mjcf``
    (default the shipped cart), its encoders as sensors (positions only).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
    quick : bool
        Fewer updates (for the test suite).

    Returns
    -------
    dict
        ``period`` (s); ``mhe`` from :func:`~cartpole.estimation.mhe.bench_mhe` (ms; with ``python``, ``ipopt``
        and ``speedup``); ``ekf`` from
        :func:`~cartpole.estimation.ekf.bench_ekf` (microseconds).
    """
    model = plant_model(plant)
    steps = steps_per_period(PERIOD, model.dt)
    spec = sensor_spec(model, encoder_cpr=4096, encoder_resolution=0.0005, noise_std=0.001)
    n = 100 if quick else 2000
    mhe = bench_mhe(model, horizon=MHE_HORIZON, period=PERIOD, n=n, repeats=MHE_REPEATS,
                    python=10 if quick else MHE_PYTHON, baseline=3 if quick else MHE_BASELINE)
    ekf = bench_ekf(model, steps, measurement_function(model, spec), spec.measurement_covariance(), updates=n)
    return {"period": PERIOD, "mhe": mhe, "ekf": ekf}


def print_estimation_table(doc: dict) -> None:
    """The estimators' step times as two lines."""
    m, e = doc["mhe"], doc["ekf"]
    print(f"Estimation at a {doc['period'] * 1e3:g} ms period from encoders: MHE ({m['N']} periods, one "
          f"Gauss-Newton step{' in C' if m.get('c_step') else ''}) median {m['step_ms_median'] * 1e3:.1f} us, max "
          f"{m['step_ms_max']:.3f} ms a step; EKF median {e['median_us']:.1f} us")
    if "python" in m:
        print(f"  MHE Python reference step median {m['python']['step_ms_median']:.2f} ms (max difference "
              f"{m['python']['max_diff']:.1e})")
    if "ipopt" in m:
        print(f"  MHE window re-solved by IPOPT median {m['ipopt']['step_ms_median']:.1f} ms: the C step "
              f"{m['speedup']:.0f}x faster")
