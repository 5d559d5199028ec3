"""A plan warm-started from the library against a cold one (``cartpole bench``'s ``plan_library`` rows).

Per model: a library built from :func:`~cartpole.planning.library.library_starts` (cold plans, not timed here), then
from each of ``probes`` starts near a stored one (its first hinge moved by 0.15 to 0.35 rad either way, every hinge
rate by up to 1.5 rad/s, the cart by up to 0.2 m; seeded) the planner
(:func:`~cartpole.planning.trajopt.trajopt_swingup`) twice, alternating: cold (no guess: the minimum-time search,
every guess it tries, the effort stage, TVLQR) and warm (the nearest stored plan as ``guess``: the effort stage from
it, TVLQR). The figure is the median over the probes of each probe's ratio ``warm / cold`` of wall times; ``warm_hits``
counts the probes whose warm start converged (the others went on cold, their time included). On dm_control's
acrobot, driven at its elbow (:func:`~cartpole.supervise.supervisor.hinge_driven`), as its supervisor plans: from
states near the knots of the plan from hanging (where a knocked acrobot is once its damping has calmed it), warm
from the nearest knot's tail. Both include the same tail (TVLQR, its predicted tracking, the catch's Riccati): the
ratio is of whole plans, as the supervisor waits for
them.
"""
from __future__ import annotations

import time

import numpy as np

from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.planning.library import build_plan_library, library_starts, mirrored
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.supervise.supervisor import KNOT_ENERGY_WEIGHT, KNOT_MIN_TAIL, hinge_driven

#: Default models: the shipped one- and two-pole carts and dm_control's acrobot (its cold plans take minutes on a
#: shared machine: its row is the bench's longest).
LIBRARY_MODELS = (("1 pole", "cartpole.xml"), ("2 poles", "cartpole_two_pole.xml"), ("acrobot", "dmc_acrobot.xml"))


def knot_probes(model, trajectories, count: int, seed: int = 0) -> np.ndarray:
    """``count`` starts near knots of the stored plans (k of them, cycled), as a calmed acrobot meets them: the
    state at a fraction ``(i + 1) / (count + 1)`` of a plan's duration, every second one mirrored through upright
    (:func:`~cartpole.planning.library.mirrored`), every hinge moved by up to 0.1 rad and its rate by up to
    0.5 rad/s (seeded by ``seed``). Shape (count, nx)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(int(count)):
        tr = trajectories[i % len(trajectories)]
        if i % 2:
            tr = mirrored(model, tr)
        x = np.array(tr.state(float(tr.t[0]) + (i + 1) / (int(count) + 1) * tr.duration), dtype=float)
        for j in model.hinges:
            x[j] += rng.uniform(-0.1, 0.1)
            x[model.nq + j] += rng.uniform(-0.5, 0.5)
        out.append(x)
    return np.array(out)


def probe_starts(model, stored, count: int, seed: int = 0) -> np.ndarray:
    """``count`` starts near the ``stored`` starts (k, nx), cycling through them: the first hinge moved by 0.15 to
    0.35 rad either way, every hinge rate by up to 1.5 rad/s, the cart by up to 0.2 m (seeded by ``seed``).
    Shape (count, nx)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(int(count)):
        x = np.array(stored[i % len(stored)], dtype=float)
        h = model.hinges[0]
        x[h] += rng.choice([-1.0, 1.0]) * rng.uniform(0.15, 0.35)
        for j in model.hinges:
            x[model.nq + j] += rng.uniform(-1.5, 1.5)
        if model.slide is not None:
            x[model.slide] += rng.uniform(-0.2, 0.2)
        out.append(x)
    return np.array(out)


def plan_library_benchmark(models=None, *, angles: int = 3, probes: int = 3, seed: int = 0, progress=None
                           ) -> list[dict]:
    """One row per model: cold and warm-started plans from the same starts near the library's.

    On a model driven at a hinge (:func:`~cartpole.supervise.supervisor.hinge_driven`: the acrobot) as its
    supervisor plans: the library is the one plan from hanging, the probes are near its knots (:func:`knot_probes`),
    the warm start is the nearest knot's tail (:meth:`~cartpole.planning.library.PlanLibrary.knot_guesses`, by pose
    and energy as the supervisor chooses) and no plan is re-solved on the exact discrete step.

    Parameters
    ----------
    models : sequence of (label, MJCF path), optional
        Default :data:`LIBRARY_MODELS` (paths relative to the shipped assets).
    angles : int
        Starts of the library's grid (:func:`~cartpole.planning.library.library_starts`).
    probes : int
        Starts planned from, both ways.
    seed : int
        Seed of the probes.
    progress : callable, optional
        ``progress(message)`` as each measurement starts.

    Returns
    -------
    list of dict
        ``model``, ``mjcf``, ``library_plans``, ``library_build_s`` (s, the library's cold plans), ``probes``,
        ``cold_s`` and ``warm_s`` (s, per probe; None where that plan failed), ``cold_s_median``, ``warm_s_median``,
        ``fraction_median`` (median of ``warm / cold`` over the probes both planned), ``warm_hits`` (warm starts
        that converged), ``warm_from`` (``"start"``: the nearest stored start's plan; ``"knot"``: the nearest knot's
        tail).
    """
    if models is None:
        models = [(label, str(SHIPPED_MJCF.parent / name)) for label, name in LIBRARY_MODELS]
    rows = []
    for label, path in models:
        params = read_params(path)
        model = build_model(params)
        knots = hinge_driven(model)
        starts = library_starts(model, angles=1 if knots else angles)
        opts = PlanOptions(exact_discrete=False) if knots else None
        if progress is not None:
            progress(f"plan library: {label}: {len(starts)} cold plans for the library")
        tic = time.perf_counter()
        lib = build_plan_library(params, model, starts, options=opts)
        build_s = time.perf_counter() - tic
        row = {"model": label, "mjcf": str(path), "library_plans": len(lib), "library_build_s": build_s,
               "probes": int(probes), "cold_s": [], "warm_s": [], "warm_hits": 0,
               "warm_from": "knot" if knots else "start"}
        if len(lib):
            if progress is not None:
                progress(f"plan library: {label}: {probes} starts, cold and warm")
            probe = (knot_probes(model, [p.trajectory for p in lib.plans], probes, seed) if knots else
                     probe_starts(model, [p.x0 for p in lib.plans], probes, seed))
            for x in probe:
                for way in ("cold", "warm"):
                    guess = None
                    if way == "warm":
                        guess = (lib.knot_guesses(model, x, count=1, energy_weight=KNOT_ENERGY_WEIGHT,
                                                  min_tail=KNOT_MIN_TAIL)[0][0] if knots else lib.guess_for(model, x))
                    tic = time.perf_counter()
                    try:
                        plan = trajopt_swingup(params, x0=tuple(x), plan_model=model, guess=guess, options=opts)
                    except CartPoleError:  # a failed plan is a row's None, not the bench's end
                        row[f"{way}_s"].append(None)
                        continue
                    row[f"{way}_s"].append(time.perf_counter() - tic)
                    if way == "warm":
                        row["warm_hits"] += int(any(a.chosen and a.stage.startswith("warm effort")
                                                    for a in plan.solve_info.attempts))
        both = [(c, w) for c, w in zip(row["cold_s"], row["warm_s"]) if c is not None and w is not None]
        row["cold_s_median"] = float(np.median([c for c, _ in both])) if both else None
        row["warm_s_median"] = float(np.median([w for _, w in both])) if both else None
        row["fraction_median"] = float(np.median([w / c for c, w in both])) if both else None
        rows.append(row)
    return rows


def print_plan_library_table(rows: list[dict]) -> None:
    """The rows as a table: model, library plans, probes, cold and warm medians (s), warm/cold, warm hits."""
    print("Plan library: a plan warm-started from the nearest stored plan vs a cold plan, same starts")
    print(f"  {'model':<10} {'plans':>5} {'probes':>6} {'cold s':>8} {'warm s':>8} {'warm/cold':>9} {'hits':>5}")
    for r in rows:
        def f(v, fmt):
            return "-" if v is None else format(v, fmt)
        print(f"  {r['model']:<10} {r['library_plans']:>5} {r['probes']:>6} {f(r['cold_s_median'], '8.2f')} "
              f"{f(r['warm_s_median'], '8.2f')} {f(r['fraction_median'], '9.2f')} {r['warm_hits']:>5}")
