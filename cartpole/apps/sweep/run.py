"""Running a sweep: :func:`swingup_sweep` (plan the runs, read each planning model's basin once, hand the runs to an
executor, gather the rows in run order) and :func:`recorded_sweep` (the same, each finished run appended to a CSV
results file, resumable, then the file rewritten in run order and the success map drawn): what ``cartpole sweep``
does."""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from cartpole._files import write_csv
from cartpole.control.energy import DEFAULT_SCALING, EnergyOptions, EnergyShapingController, energy_options
from cartpole.errors import CartPoleError, first_line
from cartpole.models import CartPoleParams, build_model, plant_params
from cartpole.mpc.options import MPCOptions
from cartpole.ocp.dmc import episode_starts, is_task
from cartpole.ocp.objectives import make_objective
from cartpole.progress import stage
from cartpole.apps.swingup import METHOD_CLASSES, SwingupOptions, check_plan_size, start_state
from cartpole.validation.basin import BasinCache
from cartpole.viz.sweep_plot import plot_success_map, preload
from cartpole.apps.forkserver import start_server
from cartpole.apps.sweep.executors import Runner, check_address, run_dask, run_here, run_pool
from cartpole.apps.sweep.plan import (MAX_SHARED_BASINS, SweepError, SweepRuns, check_axes, check_settings,
                                      default_half_widths, plan_runs, total_runs)
from cartpole.apps.sweep.results import (ResultsFile, SweepResult, csv_row, failure, header, read_done,
                                         results_lock, sweep_id)


def swingup_sweep(plant=None, method: str = "energy", options: SwingupOptions | None = None, *,
                  runs: SweepRuns | None = None, workers: int = 1, address: str | None = None, basin_cache=None,
                  progress=None, done: dict | None = None, on_row=None) -> SweepResult:
    """Run the swing-up over a sweep description (``runs``: ``n`` seeded starts in a box, optionally with jittered
    gains, or the grid and samples of its axes), each run with the same options as a single run, and summarise.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (None = shipped asset).
    method : {"energy", "trajopt", "mpc", "supervisor"}
        Swing-up of every run (:func:`~cartpole.apps.swingup.run_swingup`).
    options : SwingupOptions, optional
        The settings every run starts from, as for :func:`~cartpole.apps.swingup.run_swingup`: ``loop`` (the rig,
        the duration, s: default the method's own; a ``setting:<loop field>`` axis varies one of its fields per run,
        a push or model-error axis its push and model error), ``energy`` (jittered by ``runs.gain_jitter``, its
        scalings varied by ``setting:`` axes), ``plan`` (trajopt: its ``objective`` and fields), ``mpc`` (mpc:
        :class:`~cartpole.mpc.options.MPCOptions`; ``solver="ddp"`` with an ``objective`` runs the DDP MPC on it,
        ``seed_plan=False`` without its offline seed plan), ``catch_weights``. A dm_control task as objective
        (``dmc_cartpole_swingup``, ...) makes the sweep dm_control's evaluation: the ``n`` starts are its first
        ``n`` episodes' with ``task_kwargs={'random': seed}`` (:func:`cartpole.ocp.dmc.episode_starts`, instead of
        the start box; no axes), every run lasts at least the episode, and the result holds each run's ``return``.
    runs : SweepRuns, optional
        Which runs (:class:`~cartpole.apps.sweep.plan.SweepRuns`); default ``SweepRuns()`` (20 starts, seed 0).
    workers : int
        Processes to spread the runs over (1 = this process; ``W``: this process and ``W - 1`` workers,
        :func:`~cartpole.apps.sweep.executors.run_pool`); the rows are the same for any number.
    address : str, optional
        A running Dask distributed scheduler (``tcp://host:port``): the runs go to its workers instead (one model
        per worker process, built on its first run there); ``workers`` is then ignored. Same rows, bit for bit.
    basin_cache : BasinCache, optional
        Reuse basin estimates across sweeps.
    progress : callable, optional
        ``progress(fraction)`` after each run (the sweep is also a :func:`cartpole.progress.stage`).
    done : dict, optional
        ``{run index: row}`` of runs already finished (a resumed sweep): they are not run again, their rows (the
        keys :meth:`~cartpole.apps.sweep.executors.Runner.run` returns) are used as given.
    on_row : callable, optional
        ``on_row(index, start, row)`` as each run finishes, in the order they finish (the command appends it to the
        results file); ``row`` also carries the run's ``push``, ``model_error`` and ``settings``. An exception it
        raises (KeyboardInterrupt, say) stops the sweep; finished rows stay reported.

    Returns
    -------
    SweepResult

    Raises
    ------
    SweepError
        Bad settings. Errors of the model (an MJCF that is not a cart-pole, energy on a chain) are raised before
        any run; a run that raises on its own start is a failed row instead.
    """
    options = SwingupOptions() if options is None else options
    runs = SweepRuns() if runs is None else runs
    base = energy_changes(options.energy)
    check_settings(method, runs.n, workers, runs.gain_jitter, runs.half_widths, base, seed=runs.seed)
    if address:
        check_address(address)  # a malformed address before any work; an unreachable one when the runs start
    workers = int(workers)
    # the pool's fork server imports the toolkit while this process reads the model, plans, finds the basins and
    # starts its own share of the runs
    context = start_server(method) if workers > 1 and not address else None
    params = plant_params(plant)
    model = build_model(params)
    try:
        check_plan_size(model, method)
    except CartPoleError as exc:
        raise SweepError(first_line(exc) + ".") from None
    objective = sweep_objective(method, options)
    dmc_task = _check_objective(model, method, options, runs)
    duration = options.loop.duration
    axes = check_axes(runs.axes, params, method, duration=own_seconds(method, duration))
    center, half_widths, fixed = _start_box(params, model, runs)
    if method == "energy":
        _check_energy(model, base, axes)
    planned = plan_runs(params, center if fixed is None else fixed, axes, runs.n, runs.seed, center=center,
                        half_widths=half_widths, gain_jitter=runs.gain_jitter, base_options=base)
    if dmc_task:  # dm_control's own episodes: its initialize_episode from RandomState(seed)
        planned = replace(planned, starts=episode_starts(model, objective, runs.n, runs.seed))
    cache = BasinCache.on_disk() if basin_cache is None else basin_cache
    runner = Runner(params, method, options, cache, model=model)
    rho = _shared_rho(runner, planned)  # before the runs: the workers get the basins in the cache
    out, workers = _run_all(runner, planned, workers=workers, address=address, done=done, on_row=on_row,
                            progress=progress, context=context)
    return SweepResult(mjcf=params.mjcf, starts=planned.starts, success=_column(out, "success", bool),
                       time_to_upright=_column(out, "time_to_upright"), caught_at=_column(out, "caught_at"),
                       cart_clearance=_column(out, "cart_clearance"), peak_ctrl=_column(out, "peak_ctrl"),
                       options=planned.options, rho=rho, seed=int(runs.seed),
                       duration=own_seconds(method, duration), half_widths=half_widths,
                       gain_jitter=float(runs.gain_jitter), base_options=base, method=method,
                       replays=_column(out, "replays", bool),
                       diverged_at=np.array([r.get("diverged_at", math.nan) for r in out], float),
                       errors=tuple(r["error"] for r in out), workers=1 if address else workers,
                       address=address or None, pushes=planned.pushes, model_errors=planned.model_errors,
                       settings=planned.settings, axes=axes, objective=objective, mpc=mpc_changes(options.mpc),
                       returns=_column(out, "return") if dmc_task else None,
                       return_steps=_column(out, "return_steps") if dmc_task else None, **_knocked_arrays(out))


def own_seconds(method: str, duration: float | None) -> float | None:
    """s each run lasts: ``duration``, else the method's own (None for trajopt, known after each plan)."""
    if duration is not None:
        return float(duration)
    return None if method == "trajopt" else METHOD_CLASSES[method].duration


def energy_changes(energy) -> dict:
    """The energy-shaping settings (field -> value) of ``energy`` (EnergyOptions, a dict or None) that differ from
    the defaults: what every run's energy shaping starts from (and the gain jitter perturbs)."""
    if energy is None:
        return {}
    given, default = energy_options(energy).as_dict(), EnergyOptions().as_dict()
    return {k: v for k, v in given.items() if v != default[k]}


def mpc_changes(mpc: MPCOptions | None) -> dict:
    """The MPC settings (field -> value) of ``mpc`` that differ from the defaults, besides its objective and the DDP
    solver an objective implies: the ``mpc`` of a sweep's summary and id."""
    if mpc is None:
        return {}
    given, default = mpc.as_dict(), MPCOptions().as_dict()
    implied = ("objective", "solver") if mpc.objective is not None and mpc.solver == "ddp" else ("objective",)
    return {k: v for k, v in given.items() if v != default[k] and k not in implied}


def sweep_objective(method: str, options: SwingupOptions):
    """What every run optimises: the plan's objective (trajopt), the MPC's (mpc), else None."""
    stage = {"trajopt": options.plan, "mpc": options.mpc}.get(method)
    if stage is None:  # energy or the supervisor: an objective given is refused by _check_objective
        stage = options.plan or options.mpc
    return None if stage is None else stage.objective


def _start_box(params: CartPoleParams, model, runs: SweepRuns) -> tuple:
    """``(center, half_widths, fixed)``: the start box and the runs' start where no axis sets one (None for a start
    box around a given centre), the hanging rest on a range's edge unless ``runs.x0`` is given."""
    nx = 2 * params.nq
    if runs.x0 is not None and not runs.axes:
        raise SweepError("A fixed start x0 is for a sweep over axes; without axes the starts fill the start box.")
    fixed = None
    if runs.x0 is not None or runs.axes or runs.center is None:  # x0 checked, else the hanging rest (said)
        try:
            fixed, _ = start_state(runs.x0, params, default=model.x_hanging)
        except CartPoleError as exc:
            raise SweepError(first_line(exc) + ".") from None
    center = fixed if runs.center is None else np.asarray(runs.center, float)
    half_widths = default_half_widths(params) if runs.half_widths is None else np.asarray(runs.half_widths, float)
    if center.shape != (nx,) or half_widths.shape != (nx,):
        raise SweepError(f"The start box needs {nx} centre values and {nx} half-widths for this model (got "
                         f"{center.size} and {half_widths.size}).")
    return center, half_widths, fixed


def _check_energy(model, base: dict, axes: tuple) -> None:
    """Refuse a model energy shaping cannot drive, and an energy setting axis whose ends no controller takes (every
    run would only fail), before anything runs."""
    EnergyShapingController(model, energy_options(base))
    for a in axes:
        key = a.name[len("setting:"):]
        if a.name.startswith("setting:") and key in DEFAULT_SCALING:
            for v in (a.low, a.high):
                try:
                    EnergyShapingController(model, energy_options({**base, key: v}))
                except CartPoleError as exc:
                    raise SweepError(f"The sweep axis {a.name} reaches {v:g}: {first_line(exc)}.") from None


def _shared_rho(runner: Runner, planned) -> float:
    """Each planning model's basin once, here, before the runs (and shipped to the workers in the cache); a sampled
    model error has a planning model per run: those runs estimate their own basin where they run (in parallel).
    The level ``rho`` of the file's own planning model (NaN without a catch)."""
    scales = sorted(set(planned.model_errors.tolist()))
    rhos = {}
    for S in (scales if len(scales) <= MAX_SHARED_BASINS else [1.0]):
        b = runner.basin(S)
        rhos[S] = math.nan if b is None else float(b.rho)
    return rhos.get(1.0, rhos[scales[0]] if scales[0] in rhos else math.nan)


def _run_all(runner: Runner, planned, *, workers: int, address, done, on_row, progress, context) -> tuple:
    """``(rows, workers)``: every run's row, in run order (those in ``done`` as given, the others run here, on a
    pool or on Dask), and the local processes used (no more than the runs to do)."""
    starts = planned.starts
    n = len(starts)
    jobs = [planned.job(i) for i in range(n)]
    out: list = [None] * n
    for i, row in (done or {}).items():
        if 0 <= int(i) < n:
            out[int(i)] = row
    todo = [i for i in range(n) if out[i] is None]
    workers = min(workers, max(len(todo), 1))
    where = f" on {address}" if address else (f" on {workers} workers" if workers > 1 else "")
    size = f"{len(todo)} runs" + (f" of {n}" if len(todo) < n else "") + where
    with stage(f"{runner.method} swing-ups", size=size, callback=progress) as tick:
        counter = [0]

        def finished(i, row):
            out[i] = row
            counter[0] += 1
            if on_row is not None:
                on_row(i, starts[i], {**row, "push": planned.pushes[i],
                                      "model_error": float(planned.model_errors[i]),
                                      "settings": dict(planned.settings[i])})
            tick(counter[0] / len(todo))

        if not todo:
            pass
        elif address:
            run_dask(address, runner, jobs, todo, finished)
        elif workers == 1:
            run_here(runner, jobs, todo, finished)
        else:
            run_pool(runner, jobs, workers, todo, finished, context=context)
    return out, workers


def _column(out: list, key: str, dtype=float) -> np.ndarray:
    """One key of every row as an array."""
    return np.array([r[key] for r in out], dtype)


def _knocked_arrays(out: list) -> dict:
    """``uptime``, ``knockdowns``, ``swingups`` arrays of a knocked sweep's rows (each row has them), else none."""
    if not out or "uptime" not in out[0]:
        return {}
    return {k: np.array([r.get(k, np.nan) for r in out], float) for k in ("uptime", "knockdowns", "swingups")}


def _check_objective(model, method: str, options: SwingupOptions, runs: SweepRuns) -> bool:
    """Refuse an objective (or MPC settings) the sweep cannot run (one sentence, :class:`SweepError`); True for a
    dm_control task."""
    if options.mpc is not None and method != "mpc":
        raise SweepError(f"`mpc` options are the MPC's settings; use them with `method='mpc'` (not '{method}').")
    if options.plan is not None and method not in ("trajopt", "mpc", "supervisor"):
        raise SweepError(f"`plan` options set the trajectory optimisation; sweep them with `method='trajopt'` or "
                         f"`method='mpc'` (not '{method}').")
    objective = sweep_objective(method, options)
    if objective is None:
        if method == "mpc" and options.mpc is not None and not options.mpc.seed_plan:
            raise SweepError("An MPC without its seed plan (`seed_plan=False`) is the DDP MPC, which needs an "
                             "objective to find the swing-up by itself; give `MPCOptions(objective=...)` (e.g. "
                             "dmc_acrobot_swingup).")
        return False
    try:
        make_objective(model, objective)
    except CartPoleError as exc:
        raise SweepError(first_line(exc) + ".") from None
    if not is_task(objective):
        return False
    if runs.axes or runs.center is not None or runs.half_widths is not None:
        raise SweepError(f"The {objective} sweep starts where dm_control's episodes start (seeded by its `seed`); "
                         "drop the axes and the start box.")
    return True


class SweepInterrupted(KeyboardInterrupt):
    """A recorded sweep stopped by Ctrl-C (or SIGTERM during a pool sweep): ``finished`` of ``total`` runs are in
    the results file ``path``, which a resumed sweep goes on from."""

    def __init__(self, finished: int, total: int, path: Path, signum: int | None = None):
        super().__init__(f"interrupted after {finished} of {total} runs")
        self.finished, self.total, self.path = int(finished), int(total), Path(path)
        self.signum = signum  # the signal that stopped it (SIGTERM: cartpole.errors.Terminated), None for Ctrl-C


@dataclass(frozen=True)
class RecordedSweep:
    """A sweep run by :func:`recorded_sweep`.

    Attributes
    ----------
    result : SweepResult
    rows : list of dict
        :meth:`SweepResult.rows` with each row's ``failure`` (:func:`~cartpole.apps.sweep.results.failure`).
    sweep : str
        The description's id (:func:`~cartpole.apps.sweep.results.sweep_id`), the results file's ``sweep`` column.
    results : Path
        The CSV results file, rewritten in run order.
    figure : Path
        The success map (:func:`cartpole.viz.sweep_plot.plot_success_map`).
    resumed : int
        Runs taken from the results file instead of run again.
    """

    result: SweepResult
    rows: list
    sweep: str
    results: Path
    figure: Path
    resumed: int


def recorded_sweep(params: CartPoleParams, method: str, options: SwingupOptions | None = None, *,
                   runs: SweepRuns | None = None, results: Path, figure: Path, workers: int = 1,
                   address: str | None = None, resume: bool = False, stop_after: int | None = None) -> RecordedSweep:
    """:func:`swingup_sweep` with a results file: each finished run is appended to the CSV ``results`` (columns
    :func:`~cartpole.apps.sweep.results.header`) as it finishes, so an interrupt or a crash keeps it; with
    ``resume`` the runs of this sweep already in the file are kept and only the others run. At the end the file
    is rewritten in run order and the success map drawn to ``figure``. Nothing is written before the first run
    finishes.

    Parameters
    ----------
    params : CartPoleParams
    method, options, runs, workers, address
        As for :func:`swingup_sweep`; a dm_control task's sweep adds the ``return`` and ``return_steps`` columns.
    results, figure : Path
        The CSV results file and the PNG success map.
    resume : bool
        Keep this sweep's runs found in ``results`` (another sweep's file is refused).
    stop_after : int, optional
        For tests: stop as Ctrl-C would once this many runs have finished here (if runs remain).

    Raises
    ------
    SweepInterrupted
        Ctrl-C (or ``stop_after``): how many runs the results file holds now.
    SweepError
        Bad settings, or a results file that cannot be resumed from.
    LockedError
        Another sweep is writing the same results file (:func:`~cartpole.apps.sweep.results.results_lock`).
    """
    options = SwingupOptions() if options is None else options
    runs = SweepRuns() if runs is None else runs
    with results_lock(results):
        return _recorded_sweep(params, method, options, runs, _Record(Path(results), Path(figure), resume, stop_after),
                               workers=workers, address=address)


@dataclass(frozen=True)
class _Record:
    """Where and how a recorded sweep keeps its rows: the results file, the figure, whether to resume, and the
    test's ``stop_after``."""

    results: Path
    figure: Path
    resume: bool
    stop_after: int | None


def _recorded_sweep(params, method: str, options: SwingupOptions, runs: SweepRuns, record: _Record, *, workers,
                    address) -> RecordedSweep:
    """:func:`recorded_sweep` inside its lock."""
    results = record.results
    objective = sweep_objective(method, options)
    sid = sweep_id(params, method=method, runs=runs, loop=options.loop, objective=objective,
                   mpc=mpc_changes(options.mpc))
    settings = tuple(a.name[len("setting:"):] for a in runs.axes if a.name.startswith("setting:"))
    returns = is_task(objective)
    knocked = options.loop.disturbed
    head = header(params, settings, returns=returns, knocked=knocked)
    total = total_runs(runs.axes, runs.n)
    done = read_done(results, head, sid, total) if record.resume else {}
    opened = []  # opened on the first finished run, so a sweep refused before any run writes nothing
    count = [0]

    def on_row(i, start, row):
        if not opened:
            opened.append(ResultsFile(results, head, fresh=not record.resume))
        opened[0].write(csv_row(sid, i, start, row, settings, returns=returns, knocked=knocked))
        count[0] += 1
        if record.stop_after is not None and count[0] >= record.stop_after and len(done) + count[0] < total:
            raise KeyboardInterrupt

    figure_ready = _preload_figure() if (workers > 1 or address) else None
    try:
        result = swingup_sweep(params, method, options, runs=runs, workers=workers, address=address, done=done,
                               on_row=on_row)
        for f in opened:
            f.close()
        rows = result.rows()
        for r in rows:
            r["failure"] = failure(r)
        write_csv(results, head, [csv_row(sid, r["run"], r["start"], r, settings, returns=returns,
                                          knocked=knocked) for r in rows])  # in run order
    except KeyboardInterrupt as stop:
        for f in opened:
            f.close()
        try:  # what the file holds now is what a resume will keep
            kept = len(read_done(results, head, sid, total))
        except CartPoleError:
            kept = len(done) + count[0]
        raise SweepInterrupted(kept, total, results, getattr(stop, "signum", None)) from None
    finally:
        for f in opened:
            f.close()
        if figure_ready is not None:  # never left importing at exit: a thread inside a C extension's import when
            figure_ready.join()       # the interpreter finalises aborts the process
    drawn = plot_success_map(result, params, record.figure)
    return RecordedSweep(result=result, rows=rows, sweep=sid, results=results, figure=Path(drawn),
                         resumed=len(done))


def _preload_figure():
    """A thread running :func:`cartpole.viz.sweep_plot.preload` (started; returned to be joined on every way out of the
    sweep, refused and interrupted ones included): while the runs go on worker processes, this process's share waits
    on the GIL for a moment less than the plot's imports would cost after the last run. Only for sweeps with workers
    elsewhere: with one worker nothing runs beside it. A failure there is left to the real import, which raises it
    where the figure is drawn."""
    def run():
        try:
            preload()
        except Exception:  # noqa: BLE001 - the figure's own import and drawing report it
            pass

    thread = threading.Thread(target=run, name="cartpole-sweep-figure")
    thread.start()
    return thread
