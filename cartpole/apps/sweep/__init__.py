"""Robustness sweeps of the swing-up: one description, many runs, one row per run, one summary.

Three jobs, one module each:

- :mod:`~cartpole.apps.sweep.plan`: the description and its runs. Axes (:class:`Axis`, :func:`axis`), each a
  grid (``linspace(low, high, count)``) or a seeded uniform sample (``U(low, high)`` per run) of one input: a
  start-state component (``start:<joint>`` or ``start:<joint>_rate``), a push (``push_force`` N and ``push_time``
  s: one push of :data:`~cartpole.apps.swingup.PUSH_SECONDS`), the planning model's error ``model_error`` (pole
  masses and lengths scaled, :meth:`~cartpole.models.CartPoleParams.scaled_pole`) or a controller setting
  (``setting:<name>``: an energy-shaping scaling of :data:`~cartpole.control.energy.DEFAULT_SCALING` for
  ``energy``, ``period`` or ``horizon`` for ``mpc``). The runs are the Cartesian product of the grid axes (the
  first axis varies slowest), repeated ``n`` times with fresh draws when any axis is sampled; every input not on
  an axis is fixed (the start at the model's hanging rest, no push, no model error, the controller's own
  settings). Without axes a sweep is the classic start box: ``center + U(-half_widths, half_widths)`` per state,
  default around the hanging rest with half-widths 0.3 m per slide, 0.3 rad per hinge, 0.3 m/s per slide rate and
  1 rad/s per hinge rate, cart positions kept 1 mm inside the rail; gain jitter (``gain_jitter = j``, energy only)
  multiplies each setting in :data:`JITTERED` by an independent ``U(1 - j, 1 + j)``. Every run's inputs are drawn
  before any run starts, from ``numpy.random.default_rng(seed)`` in a fixed order, so a description and a seed
  give the same runs in any order and on any number of workers.
- :mod:`~cartpole.apps.sweep.executors`: where the runs run: this process, this process beside worker processes
  forked from a fork server that has the toolkit imported (one model per worker, built once), or a Dask
  distributed cluster (one model per worker process, built on its first run). Same rows, bit for bit.
- :mod:`~cartpole.apps.sweep.results`: what was found and how it is kept: :class:`SweepResult`, the sweep's id,
  the CSV results file (appended as each run finishes, read back to resume).

:mod:`~cartpole.apps.sweep.run` ties them: :func:`swingup_sweep` and :func:`recorded_sweep` (what ``cartpole
sweep`` does). Each run is :func:`cartpole.apps.swingup.run_swingup` (``method="energy"``: energy shaping + LQR
catch, ``"trajopt"``: collocation + TVLQR, or ``"mpc"``: nonlinear MPC) in MuJoCo on the MJCF, so a sweep measures
exactly what ``cartpole swingup`` does. A run counts as a success when
:func:`~cartpole.validation.metrics.swingup_success` holds (upright and at rest over the last second, cart never
at its limit, every ctrl in range) *and* its log replays exactly with ``mj_step``
(:func:`~cartpole.sim.rollout.replays_exactly`). A run that raises a :class:`~cartpole.errors.CartPoleError` (an
infeasible plan from that start, say) is a failure whose row carries the sentence as ``error``. The catch basin is
estimated once per planning model, before the runs, found on disk when an earlier run estimated it
(:meth:`~cartpole.validation.basin.BasinCache.on_disk`), and handed to every run.

Examples::

    cartpole sweep --n 20 --seed 0 --workers 2
    cartpole sweep --method trajopt --push-force -20 20 5 --model-error 0.8 1.2 5 --push-time 0.5
"""
from cartpole.apps.sweep.executors import Runner, runners_built
from cartpole.apps.sweep.plan import (DEFAULT_PUSH_TIME, HALF_WIDTHS, HANGING, HINGE_HALF_WIDTHS, JITTERED,
                                      MAX_RUNS, MAX_SHARED_BASINS, MAX_WORKERS, METHODS, SETTINGS,
                                      SLIDE_HALF_WIDTHS, Axis, PlannedRuns, SweepError, SweepRuns, axis, check_axes,
                                      check_settings, default_half_widths, plan_runs, start_index, sweep_starts,
                                      total_runs)
from cartpole.apps.sweep.results import (ResultsFile, SweepResult, csv_row, failure, header, read_done,
                                         summary_line, sweep_id)
from cartpole.apps.sweep.run import RecordedSweep, SweepInterrupted, recorded_sweep, swingup_sweep

__all__ = [
    "Axis", "DEFAULT_PUSH_TIME", "HALF_WIDTHS", "HANGING", "HINGE_HALF_WIDTHS", "JITTERED", "MAX_RUNS",
    "MAX_SHARED_BASINS", "MAX_WORKERS", "METHODS", "PlannedRuns", "RecordedSweep", "ResultsFile", "Runner",
    "SETTINGS", "SLIDE_HALF_WIDTHS", "SweepError", "SweepInterrupted", "SweepRuns", "SweepResult", "axis", "check_axes",
    "check_settings", "csv_row", "default_half_widths", "failure", "header", "plan_runs", "read_done",
    "recorded_sweep", "runners_built", "start_index", "summary_line", "sweep_id", "sweep_starts", "swingup_sweep",
    "total_runs",
]
