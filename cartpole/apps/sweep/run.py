"""Running a sweep: :func:`swingup_sweep` (plan the runs, read each planning model's basin once, hand the runs to an
executor, gather the rows in run order) and :func:`recorded_sweep` (the same, each finished run appended to a CSV
results file, resumable, then the file rewritten in run order and the success map drawn): what ``cartpole sweep``
does."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from cartpole.errors import CartPoleError, first_line
from cartpole.models import CartPoleParams, build_model, plant_params
from cartpole.ocp.dmc import episode_starts, is_task
from cartpole.progress import stage
from cartpole.apps.swingup import (ENERGY_DURATION, MPC_DURATION, SUPERVISOR_DURATION, check_plan_size,
                                   start_state)
from cartpole.validation.basin import BasinCache
from cartpole.apps.forkserver import start_server
from cartpole.apps.sweep.executors import Runner, check_address, mpc_fields, run_dask, run_here, run_pool
from cartpole.apps.sweep.plan import (MAX_SHARED_BASINS, SweepError, check_axes, check_settings, default_half_widths,
                                      plan_runs, total_runs)
from cartpole.apps.sweep.results import (ResultsFile, SweepResult, csv_row, failure, header, read_done,
                                         results_lock, sweep_id)


def swingup_sweep(plant=None, *, method: str = "energy", n: int = 20, seed: int = 0, center=None,
                  half_widths=None, gain_jitter: float = 0.0, energy_options: dict | None = None,
                  duration: float | None = None, catch_weights: tuple | None = None, basin_cache=None,
                  progress=None, workers: int = 1, address: str | None = None, done: dict | None = None,
                  on_row=None, axes=(), x0=None, loop=None, objective: str | None = None,
                  mpc: dict | None = None) -> SweepResult:
    """Run the swing-up over a sweep description (``axes``; without: ``n`` seeded starts in a box, optionally with
    jittered gains) and summarise.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (None = shipped asset).
    method : {"energy", "trajopt", "mpc"}
        Swing-up of every run (:func:`~cartpole.apps.swingup.run_swingup`).
    n : int
        Number of runs (1 to :data:`~cartpole.apps.sweep.plan.MAX_RUNS`) without axes; with axes, the number of
        draws per grid cell when any axis is sampled (ignored for a pure grid, whose size is the product of the
        counts).
    axes : sequence of Axis
        The sweep description (:class:`~cartpole.apps.sweep.plan.Axis`, :func:`~cartpole.apps.sweep.plan.axis`):
        grids and seeded samples over start components, the push, the model error and controller settings.
    x0 : (2 nq,) array, optional
        With axes: the start of every run where no start axis sets a component (default the hanging rest).
    seed : int
        Seed of ``numpy.random.default_rng`` for the starts (and the gain jitter).
    center : (2 nq,) array, optional
        Centre of the start box, default the model's hanging rest ``x_hanging``.
    half_widths : (2 nq,) array, optional
        Half-widths of the start box [m, rad, m/s, rad/s]; default
        :func:`~cartpole.apps.sweep.plan.default_half_widths` (one pole: ``(0.3, 0.3, 0.3, 1.0)``).
    gain_jitter : float
        In [0, 1): relative jitter of the settings in :data:`~cartpole.apps.sweep.plan.JITTERED` (0 = the gains
        as given); energy only.
    energy_options : dict, optional
        Energy-shaping settings (``EnergyShapingController`` keywords / ``default_gains`` scalings) every run
        starts from; default the package defaults.
    duration : float, optional
        Simulated seconds per run (default that of :func:`~cartpole.apps.swingup.run_swingup`).
    catch_weights : (Q, R), optional
        LQR weights of the catch (default the lab's ``Q`` and :data:`~cartpole.control.switching.SWINGUP_CATCH_R`),
        passed to :func:`~cartpole.apps.swingup.run_swingup`.
    basin_cache : BasinCache, optional
        Reuse basin estimates across sweeps.
    progress : callable, optional
        ``progress(fraction)`` after each run (the sweep is also a :func:`cartpole.progress.stage`).
    workers : int
        Processes to spread the runs over (1 = this process; ``W``: this process and ``W - 1`` workers,
        :func:`~cartpole.apps.sweep.executors.run_pool`); the rows are the same for any number.
    address : str, optional
        A running Dask distributed scheduler (``tcp://host:port``): the runs go to its workers instead (one model
        per worker process, built on its first run there); ``workers`` is then ignored. Same rows, bit for bit.
    done : dict, optional
        ``{run index: row}`` of runs already finished (a resumed sweep): they are not run again, their rows (the
        keys :meth:`~cartpole.apps.sweep.executors.Runner.run` returns) are used as given.
    on_row : callable, optional
        ``on_row(index, start, row)`` as each run finishes, in the order they finish (the command appends it to the
        results file); ``row`` also carries the run's ``push``, ``model_error`` and ``settings``. An exception it
        raises (KeyboardInterrupt, say) stops the sweep; finished rows stay reported.

    loop : LoopOptions, optional
        The rig every run has (period, delay, sensors, estimator; :class:`~cartpole.sim.options.LoopOptions`); a
        ``setting:<loop field>`` axis varies one of its fields per run.
    objective : str, optional
        trajopt: what every plan optimises; mpc: what the MPC minimises, run by the DDP MPC (``MPCOptions(solver=
        'ddp', objective=...)``, the MPC that takes any running objective), its seed plan the same (a name of :data:`cartpole.ocp.objectives.NAMED` or
        MODULE:FUNCTION). A dm_control task (``dmc_cartpole_swingup``, ...) makes the sweep dm_control's
        evaluation: the ``n`` starts are its first ``n`` episodes' with ``task_kwargs={'random': seed}``
        (:func:`cartpole.ocp.dmc.episode_starts`, instead of the start box; no axes), every run lasts at least the
        episode, and the result holds each run's ``return`` (the summary their mean).
    mpc : dict, optional
        mpc: fields of :class:`~cartpole.mpc.options.MPCOptions` every run has, by name (``horizon``; ``seed_plan``
        False: the DDP MPC without its offline seed plan, finding the swing-up itself in the loop, which needs an
        ``objective``); refused with the other methods.

    Returns
    -------
    SweepResult

    Raises
    ------
    SweepError
        Bad settings. Errors of the model (an MJCF that is not a cart-pole, energy on a chain) are raised before
        any run; a run that raises on its own start is a failed row instead.
    """
    check_settings(method, n, workers, gain_jitter, half_widths, energy_options, seed=seed)
    if address:
        check_address(address)  # a malformed address before any work; an unreachable one when the runs start
    n, workers = int(n), int(workers)
    # the pool's fork server imports the toolkit while this process reads the model, plans, finds the basins and
    # starts its own share of the runs
    context = start_server(method) if workers > 1 and not address else None
    params = plant_params(plant)
    model = build_model(params)
    try:
        check_plan_size(model, method)
    except CartPoleError as exc:
        raise SweepError(first_line(exc) + ".") from None
    nx = 2 * params.nq
    mpc = dict(mpc or {})
    dmc_task = _check_objective(model, method, objective, axes, center, half_widths, mpc)
    axes = check_axes(axes, params, method, duration=duration if duration is not None else
                      {"energy": ENERGY_DURATION, "mpc": MPC_DURATION, "supervisor": SUPERVISOR_DURATION}.get(method))
    if x0 is not None and not axes:
        raise SweepError("A fixed start x0 is for a sweep over axes; without axes the starts fill the start box.")
    fixed = None  # the runs' start where no axis sets one, and the start box's default centre
    if x0 is not None or axes or center is None:  # x0 checked, else the hanging rest on a range's edge (said)
        try:
            fixed, _ = start_state(x0, params, default=model.x_hanging)
        except CartPoleError as exc:
            raise SweepError(first_line(exc) + ".") from None
    center = fixed if center is None else np.asarray(center, float)
    half_widths = default_half_widths(params) if half_widths is None else np.asarray(half_widths, float)
    if center.shape != (nx,) or half_widths.shape != (nx,):
        raise SweepError(f"The start box needs {nx} centre values and {nx} half-widths for this model (got "
                         f"{center.size} and {half_widths.size}).")
    base = dict(energy_options or {})
    if method == "energy":  # refuse a model energy shaping cannot drive before anything runs
        from cartpole.control.energy import DEFAULT_SCALING, EnergyShapingController
        EnergyShapingController(model, **base)
        for a in axes:  # and an energy setting whose ends no controller takes (every run would only fail)
            key = a.name[len("setting:"):]
            if a.name.startswith("setting:") and key in DEFAULT_SCALING:
                for v in (a.low, a.high):
                    try:
                        EnergyShapingController(model, **{**base, key: v})
                    except CartPoleError as exc:
                        raise SweepError(f"The sweep axis {a.name} reaches {v:g}: {first_line(exc)}.") from None
    runs = plan_runs(params, center if fixed is None else fixed, axes, n, seed, center=center,
                     half_widths=half_widths, gain_jitter=gain_jitter, base_options=base)
    if dmc_task:  # dm_control's own episodes: its initialize_episode from RandomState(seed)
        runs = replace(runs, starts=episode_starts(model, objective, n, seed))
    starts = runs.starts
    n = len(starts)
    jobs = [runs.job(i) for i in range(n)]
    out: list = [None] * n
    for i, row in (done or {}).items():
        if 0 <= int(i) < n:
            out[int(i)] = row
    todo = [i for i in range(n) if out[i] is None]
    workers = min(workers, max(len(todo), 1))
    cache = BasinCache.on_disk() if basin_cache is None else basin_cache
    runner = Runner(params, method, duration, catch_weights, cache, model=model, loop=loop, objective=objective,
                    mpc=mpc)
    # each planning model's basin once, here, before the runs (and shipped to the workers in the cache); a sampled
    # model error has a planning model per run: those runs estimate their own basin where they run (in parallel)
    scales = sorted(set(runs.model_errors.tolist()))
    rhos = {}
    for S in (scales if len(scales) <= MAX_SHARED_BASINS else [1.0]):
        b = runner.basin(S)
        rhos[S] = math.nan if b is None else float(b.rho)
    rho = rhos.get(1.0, rhos[scales[0]] if scales[0] in rhos else math.nan)
    where = f" on {address}" if address else (f" on {workers} workers" if workers > 1 else "")
    size = f"{len(todo)} runs" + (f" of {n}" if len(todo) < n else "") + where
    with stage(f"{method} swing-ups", size=size, callback=progress) as tick:
        counter = [0]

        def finished(i, row):
            out[i] = row
            counter[0] += 1
            if on_row is not None:
                on_row(i, starts[i], {**row, "push": runs.pushes[i], "model_error": float(runs.model_errors[i]),
                                      "settings": dict(runs.settings[i])})
            tick(counter[0] / len(todo))

        if not todo:
            pass
        elif address:
            run_dask(address, runner, jobs, todo, finished)
        elif workers == 1:
            run_here(runner, jobs, todo, finished)
        else:
            run_pool(runner, jobs, workers, todo, finished, context=context)
    return SweepResult(mjcf=params.mjcf, starts=starts, success=np.array([r["success"] for r in out], bool),
                       time_to_upright=np.array([r["time_to_upright"] for r in out], float),
                       caught_at=np.array([r["caught_at"] for r in out], float),
                       cart_clearance=np.array([r["cart_clearance"] for r in out], float),
                       peak_ctrl=np.array([r["peak_ctrl"] for r in out], float), options=runs.options, rho=rho,
                       seed=int(seed), duration=float(duration) if duration is not None else (
                           {"energy": ENERGY_DURATION, "mpc": MPC_DURATION, "supervisor": SUPERVISOR_DURATION}.get(method)),
                       half_widths=half_widths, gain_jitter=float(gain_jitter), base_options=base, method=method,
                       replays=np.array([r["replays"] for r in out], bool),
                       diverged_at=np.array([r.get("diverged_at", math.nan) for r in out], float),
                       errors=tuple(r["error"] for r in out), workers=1 if address else workers,
                       address=address or None, pushes=runs.pushes, model_errors=runs.model_errors,
                       settings=runs.settings, axes=axes, objective=objective, mpc=mpc,
                       returns=np.array([r["return"] for r in out], float) if dmc_task else None,
                       return_steps=np.array([r["return_steps"] for r in out], float) if dmc_task else None,
                       **_knocked_arrays(out))


def _knocked_arrays(out: list) -> dict:
    """``uptime``, ``knockdowns``, ``swingups`` arrays of a knocked sweep's rows (each row has them), else none."""
    if not out or "uptime" not in out[0]:
        return {}
    return {k: np.array([r.get(k, np.nan) for r in out], float) for k in ("uptime", "knockdowns", "swingups")}


def _check_objective(model, method: str, objective, axes, center, half_widths, mpc: dict | None = None) -> bool:
    """Refuse an objective (or MPC settings) the sweep cannot run (one sentence, :class:`SweepError`); True for a
    dm_control task."""
    mpc = dict(mpc or {})
    if mpc and method != "mpc":
        raise SweepError(f"--horizon and --no-seed-plan are the MPC's settings; use them with --method mpc (not "
                         f"{method}).")
    if objective is not None and method not in ("trajopt", "mpc"):
        raise SweepError(f"--objective chooses what the trajectory optimisation (or the DDP MPC) optimises; sweep it "
                         f"with --method trajopt or mpc (not {method}).")
    if method == "mpc" and not mpc.get("seed_plan", True) and objective is None:
        raise SweepError("--no-seed-plan runs the DDP MPC, which needs an objective to find the swing-up by itself; "
                         "give --objective (e.g. dmc_acrobot_swingup).")
    if method == "mpc" and (mpc or objective is not None):  # the MPC's own refusals (time is not a running cost)
        from cartpole.mpc.options import MPCOptions

        try:
            MPCOptions(**mpc_fields(objective, mpc))
        except CartPoleError as exc:
            raise SweepError(first_line(exc) + ".") from None
    if objective is None:
        return False
    from cartpole.ocp.objectives import make_objective

    try:
        make_objective(model, objective)
    except CartPoleError as exc:
        raise SweepError(first_line(exc) + ".") from None
    if not is_task(objective):
        return False
    if axes or center is not None or half_widths is not None:
        raise SweepError(f"The {objective} sweep starts where dm_control's episodes start (seeded by --seed); drop "
                         "the axes and the start box.")
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


def recorded_sweep(params: CartPoleParams, *, method: str, n: int, seed: int, results: Path, figure: Path,
                   workers: int = 1, duration: float | None = None, gain_jitter: float = 0.0,
                   address: str | None = None, axes=(), x0=None, resume: bool = False,
                   stop_after: int | None = None, loop=None, objective: str | None = None,
                   mpc: dict | None = None) -> RecordedSweep:
    """:func:`swingup_sweep` with a results file: each finished run is appended to the CSV ``results`` (columns
    :func:`~cartpole.apps.sweep.results.header`) as it finishes, so an interrupt or a crash keeps it; with
    ``resume`` the runs of this sweep already in the file are kept and only the others run. At the end the file
    is rewritten in run order and the success map drawn to ``figure``. Nothing is written before the first run
    finishes.

    Parameters
    ----------
    params : CartPoleParams
    method, n, seed, workers, duration, gain_jitter, address, axes, x0, loop, objective, mpc
        As for :func:`swingup_sweep` (``duration`` in s; ``x0`` (2 nq,)); a dm_control task's sweep adds the
        ``return`` and ``return_steps`` columns.
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
    with results_lock(results):
        return _recorded_sweep(params, method=method, n=n, seed=seed, results=results, figure=figure,
                               workers=workers, duration=duration, gain_jitter=gain_jitter, address=address,
                               axes=axes, x0=x0, resume=resume, stop_after=stop_after, loop=loop,
                               objective=objective, mpc=mpc)


def _recorded_sweep(params, *, method, n, seed, results, figure, workers, duration, gain_jitter, address, axes, x0,
                    resume, stop_after, loop, objective=None, mpc=None) -> RecordedSweep:
    from cartpole._files import write_csv
    from cartpole.viz.sweep_plot import plot_success_map

    results, figure = Path(results), Path(figure)
    sid = sweep_id(params, method=method, n=n, seed=seed, duration=duration, jitter=gain_jitter, axes=axes, x0=x0,
                   loop=loop, objective=objective, mpc=mpc)
    settings = tuple(a.name[len("setting:"):] for a in axes if a.name.startswith("setting:"))
    returns = is_task(objective)
    knocked = loop is not None and loop.disturbed
    head = header(params, settings, returns=returns, knocked=knocked)
    total = total_runs(axes, n)
    done = read_done(results, head, sid, total) if resume else {}
    opened = []  # opened on the first finished run, so a sweep refused before any run writes nothing
    count = [0]

    def on_row(i, start, row):
        if not opened:
            opened.append(ResultsFile(results, head, fresh=not resume))
        opened[0].write(csv_row(sid, i, start, row, settings, returns=returns, knocked=knocked))
        count[0] += 1
        if stop_after is not None and count[0] >= stop_after and len(done) + count[0] < total:
            raise KeyboardInterrupt

    figure_ready = _preload_figure() if (workers > 1 or address) else None
    try:
        result = swingup_sweep(params, method=method, n=n, seed=seed, workers=workers, duration=duration,
                               gain_jitter=gain_jitter, address=address, done=done, on_row=on_row, axes=axes,
                               x0=x0, loop=loop, objective=objective, mpc=mpc)
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
    drawn = plot_success_map(result, params, figure)
    return RecordedSweep(result=result, rows=rows, sweep=sid, results=results, figure=Path(drawn),
                         resumed=len(done))


def _preload_figure():
    """A thread running :func:`cartpole.viz.sweep_plot.preload` (started; returned to be joined on every way out of the
    sweep, refused and interrupted ones included): while the runs go on worker processes, this process's share waits
    on the GIL for a moment less than the plot's imports would cost after the last run. Only for sweeps with workers
    elsewhere: with one worker nothing runs beside it. A failure there is left to the real import, which raises it
    where the figure is drawn."""
    import threading

    from cartpole.viz.sweep_plot import preload

    def run():
        try:
            preload()
        except Exception:  # noqa: BLE001 - the figure's own import and drawing report it
            pass

    thread = threading.Thread(target=run, name="cartpole-sweep-figure")
    thread.start()
    return thread
