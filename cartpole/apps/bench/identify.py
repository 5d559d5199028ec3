"""System identification's fit times for ``cartpole bench``: the multiple-shooting Gauss-Newton fit
(:func:`cartpole.identify.fit.fit`) of ``all`` to 20 s of 5 ms data on the shipped one- and two-pole carts, logged by
``excite`` from a variant of each (gear +20 %, damping of every joint +30 %) through quantised encoders, against
IPOPT through CasADi (exact Hessian) on the same multiple-shooting least squares in the same process (wall time,
functions built inside both)."""
from __future__ import annotations

import re
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

import cartpole.apps.excite as excite_app
from cartpole.identify.fit import PRIOR_STD, fit
from cartpole.identify.parameters import parse_parameters, sample_step
from cartpole.models import SHIPPED_MJCF, read_params

#: Logged seconds per fit (``quick``: 5).
SECONDS = 20.0


def _variant(src: Path, dst: Path) -> Path:
    text = src.read_text()
    text = text.replace('gear="20"', 'gear="24"')
    text = re.sub(r'damping="([0-9.]+)"', lambda m: f'damping="{1.3 * float(m.group(1)):g}"', text)
    dst.write_text(text)
    return dst


def ipopt_fit(p, params, log, *, segment_s: float = 0.1, regularization: float = 1.0) -> dict:
    """The baseline: the multiple-shooting problem of :func:`cartpole.identify.fit.fit` (its first pass: the prior
    weights) as one NLP for IPOPT (exact Hessian), built and solved here.

    Parameters
    ----------
    p : CartPoleParams
    params : sequence of Parameter
    log : RunLog
    segment_s : float
        Shooting segment, s.
    regularization : float
        Weight toward the nominal.

    Returns
    -------
    dict
        ``solve_s`` (s, build included), ``iterations``, ``status``, ``fitted`` (SI units).
    """
    t0 = time.perf_counter()
    nq, nx, np_ = p.nq, 2 * p.nq, len(params)
    Ts = log.sample_time
    L = max(2, round(segment_s / Ts))
    S = (log.n - 1) // L
    F = sample_step(p, params, Ts)
    x0, U, th = ca.SX.sym("x0", nx), ca.SX.sym("U", p.nu, L), ca.SX.sym("theta", np_)
    xs = [x0]
    for k in range(L):
        xs.append(F(xs[-1], U[:, k], th))
    seg = ca.Function("seg", [x0, U, th], [ca.hcat(xs[:-1])[:nq, :], xs[-1]])
    scale = np.array([q.scale for q in params])
    nominal = np.array([q.nominal for q in params])
    delta = ca.MX.sym("delta", np_)
    nodes = ca.MX.sym("nodes", nx, S + 1)
    theta = ca.DM(nominal) + ca.DM(scale) * delta
    Y, xe = seg.map(S)(nodes[:, :-1], ca.DM(log.ctrl[:S * L].T), theta)
    meas = log.qpos[:S * L + 1].T
    r = ca.vec((ca.DM(meas[:, :-1]) - Y) / PRIOR_STD)
    r_last = (ca.DM(meas[:, -1]) - nodes[:nq, -1]) / PRIOR_STD
    f = 0.5 * (ca.sumsqr(r) + ca.sumsqr(r_last) + regularization * ca.sumsqr(delta))
    g = ca.vec(nodes[:, 1:] - xe)
    w = ca.veccat(delta, nodes)
    lo = np.array([(q.lower - q.nominal) / q.scale for q in params])
    hi = np.array([(q.upper - q.nominal) / q.scale for q in params])
    solver = ca.nlpsol("ipopt_fit", "ipopt", {"x": w, "f": f, "g": g},
                       {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.max_iter": 300,
                        "ipopt.tol": 1e-8})
    v = np.gradient(log.qpos, log.t, axis=0)
    guess = np.vstack([log.qpos.T, v.T])[:, ::L][:, :S + 1]
    sol = solver(x0=np.concatenate([np.zeros(np_), guess.T.ravel()]), lbg=0, ubg=0,
                 lbx=np.concatenate([np.maximum(lo, -1e19), np.full(nx * (S + 1), -np.inf)]),
                 ubx=np.concatenate([np.minimum(hi, 1e19), np.full(nx * (S + 1), np.inf)]))
    stats = solver.stats()
    d = np.asarray(sol["x"]).ravel()[:np_]
    return {"solve_s": time.perf_counter() - t0, "iterations": int(stats.get("iter_count", -1)),
            "status": str(stats.get("return_status")), "fitted": (nominal + scale * d).tolist()}


#: Timed fits per cart (medians).
REPEATS = 3


def identify_benchmark(*, quick: bool = False, baseline: bool = True) -> dict:
    """``{"seconds", "rows": [{model, samples, parameters, fit_s, iterations, max_rel_error, ipopt_s,
    ipopt_iterations, ipopt_status, speedup, compiled_first_s, compiled_s, compiled_speedup}]}`` on the shipped
    one- and two-pole carts (``quick``: one pole, 5 s, one fit, nothing compiled). ``fit_s`` and ``compiled_s``
    are medians of :data:`REPEATS` fits (VM, and compiled C from the cache); ``compiled_first_s`` the first
    compiled fit, the compiler's run included unless the library was cached.

    Parameters
    ----------
    quick : bool
    baseline : bool
        Also time IPOPT.

    Returns
    -------
    dict
        Times in s; ``max_rel_error`` the largest relative error of a fitted parameter against the variant's
        truth (those with a nonzero truth).
    """
    seconds = 5.0 if quick else SECONDS
    carts = [SHIPPED_MJCF] if quick else [SHIPPED_MJCF, SHIPPED_MJCF.parent / "cartpole_two_pole.xml"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="cartpole-bench-identify-") as tmp:
        for src in carts:
            truth = _variant(src, Path(tmp) / f"truth_{src.stem}.xml")
            experiment = excite_app.ExciteOptions(duration=seconds, encoder_cpr=2048, encoder_resolution=1e-4)
            log = excite_app.run_excite(truth, tmp, experiment, csv_name=f"{src.stem}.csv").log
            p = read_params(src)
            names = ["gear:motor"] + [f"damping:{j}" for j in p.joint_names]
            params = parse_parameters(p, names)
            tv = np.array([q.nominal for q in parse_parameters(read_params(truth), names)])
            runs = [fit(p, params, [log]) for _ in range(1 if quick else REPEATS)]
            res = runs[0]
            fit_s = float(np.median([r.solve_s for r in runs]))
            row = {"model": src.stem, "samples": log.n, "sample_time": log.sample_time, "parameters": list(names),
                   "fit_s": fit_s, "iterations": res.iterations,
                   "max_rel_error": float(np.max(np.abs(res.fitted - tv) / np.abs(tv)))}
            if not quick:  # the segments compiled to C: the first fit pays the compiler unless cached
                first = fit(p, params, [log], compiled=True)
                cc = float(np.median([fit(p, params, [log], compiled=True).solve_s for _ in range(REPEATS)]))
                row.update(compiled_first_s=first.solve_s, compiled_s=cc, compiled_speedup=fit_s / cc)
            if baseline:
                b = ipopt_fit(p, params, log)
                row.update(ipopt_s=b["solve_s"], ipopt_iterations=b["iterations"], ipopt_status=b["status"],
                           ipopt_max_rel_error=float(np.max(np.abs(np.array(b["fitted"]) - tv) / np.abs(tv))),
                           speedup=b["solve_s"] / fit_s)
            rows.append(row)
    return {"seconds": seconds, "rows": rows}


def print_identify_table(doc: dict) -> None:
    """One line per cart."""
    for r in doc["rows"]:
        base = (f"; IPOPT on the same problem {r['ipopt_s']:.2f} s ({r['ipopt_iterations']} iterations, "
                f"{r['speedup']:.1f}x)" if "ipopt_s" in r else "")
        print(f"Identify {r['model']}: {len(r['parameters'])} parameters from {doc['seconds']:g} s of "
              f"{1e3 * r['sample_time']:g} ms data in {r['fit_s']:.2f} s ({r['iterations']} Gauss-Newton "
              f"iterations, largest error {100 * r['max_rel_error']:.2f} %){base}")
        if "compiled_s" in r:
            print(f"  compiled C: {r['compiled_s']:.2f} s from the cache ({r['compiled_speedup']:.1f}x the VM), "
                  f"first fit {r['compiled_first_s']:.2f} s with the compile")
