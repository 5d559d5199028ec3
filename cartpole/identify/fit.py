"""The fit: multiple-shooting least squares over logged runs, the parameters as decision variables.

Each run is cut into shooting segments of ``segment`` samples. The decision variables are the parameters ``theta =
nominal + scale * delta`` (:class:`~cartpole.identify.parameters.Parameter`) and the full state ``[qpos, qvel]`` at
every segment's first sample (the rates are states of the fit, never differentiated data). The model
(:func:`~cartpole.identify.parameters.sample_step`, the MJCF's integrator with the logged ctrl held over each
sample, MuJoCo's friction-loss constraint solved exactly) runs each segment from its node; the residuals are the
measured positions (and rates, where a log has them) minus the simulated ones, each joint weighted by its
measurement spread, and ``sqrt(W) delta`` pulling toward the nominal (``W`` the regularisation weight); continuity
of the segments is an equality constraint. Gauss-Newton on the constrained problem (a dense KKT solve per iteration,
a backtracking line search on an exact-penalty merit), bounds on the parameters kept by fixing those that would
cross them. After convergence each joint's weight is re-set to its residual spread and the fit polished, so the
covariance ``s^2 (J'J + W)^-1`` (the parameter block of the inverse KKT matrix) has a reduced chi-square of one;
standard errors and correlations follow, and directions of the data-only information the runs hardly see are named
in one sentence (:func:`identifiability_warnings`).
"""
from __future__ import annotations

import dataclasses
import hashlib
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import cartpole.codegen as codegen
from cartpole._arrays import readonly
from cartpole.codegen import compiled_or_none
from cartpole.errors import CartPoleError
from cartpole.identify.parameters import sample_step
from cartpole.models import DEFAULT_FRICTION_WIDTH, CartPoleParams

#: Default regularisation weight W: a parameter one scale (its nominal size) off the nominal costs as much as one
#: sample one measurement spread off, so it decides only what the data cannot.
DEFAULT_REGULARIZATION = 1.0
#: Default shooting segment, s (rounded to whole samples): short enough that an upright pole run open loop on a
#: wrong model stays near the data, long enough to keep the problem small.
DEFAULT_SEGMENT_S = 0.1
#: Prior measurement spread before the first pass re-weights it: m on slides, rad on hinges; m/s, rad/s for rates.
PRIOR_STD = 1e-3
PRIOR_RATE_STD = 1e-2
#: A direction of the parameters (relative to their scales) whose data-only standard error exceeds this is not
#: identifiable from the runs; two parameters correlated beyond CORRELATION_WARN are named as a combination.
UNIDENTIFIABLE_STD = 0.2
CORRELATION_WARN = 0.99
#: The fit has converged when one iteration lowers the objective by less than this fraction (measurement noise
#: decides the last digits; a smooth-friction fit cannot match a sticking joint exactly).
REL_TOL = 1e-6


class FitError(CartPoleError):
    """A fit that cannot be set up or does not converge."""


@dataclass(frozen=True)
class FitResult:
    """What the fit found.

    Attributes
    ----------
    parameters : tuple of Parameter
    fitted : (np,) array
        Fitted values, SI units.
    std : (np,) array
        Standard errors, SI units.
    correlation : (np, np) array
    warnings : tuple of str
        One sentence each: combinations the runs do not identify, parameters on a bound.
    fit_rms : (nq,) array
        RMS of the position residuals over the fitted runs per joint, m or rad (multiple shooting: each segment
        from its fitted node).
    iterations : int
    solve_s : float
        Wall time of the fit, s (building the functions included).
    residual_std : (nq,) array
        The per-joint spread the final weights used, m or rad.
    """

    parameters: tuple
    fitted: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    warnings: tuple
    fit_rms: np.ndarray
    iterations: int
    solve_s: float
    residual_std: np.ndarray

    @property
    def names(self) -> tuple:
        """Parameter names in order."""
        return tuple(q.name for q in self.parameters)

    @property
    def nominal(self) -> np.ndarray:
        """(np,) nominal values."""
        return readonly([q.nominal for q in self.parameters])

    def as_dict(self) -> dict:
        """name -> {nominal, fitted, std} (the JSON ``parameters`` object)."""
        return {q.name: {"nominal": q.nominal, "fitted": float(v), "std": float(s)}
                for q, v, s in zip(self.parameters, self.fitted, self.std)}


def segment_function(p: CartPoleParams, params, sample_time: float, length: int, *,
                     friction_width: float = DEFAULT_FRICTION_WIDTH, exact_friction: bool = True) -> ca.Function:
    """One shooting segment and its Jacobians:
    ``(x0 (nx,), U (nu, L), theta (np,)) -> (X (nx, L), x_end (nx,), dX/d[x0, theta] (nx L, nx + np),
    dx_end/d[x0, theta] (nx, nx + np))``, ``X[:, k]`` the state at the segment's sample ``k`` (``X[:, 0] = x0``).

    Parameters
    ----------
    p : CartPoleParams
    params : sequence of Parameter
    sample_time : float
        s.
    length : int
        Samples per segment L (a count, no unit: the segment lasts ``length * sample_time`` s).
    friction_width : float
        m/s or rad/s (the smooth friction's, with ``exact_friction=False``).
    exact_friction : bool
        MuJoCo's friction constraint solved exactly (:func:`~cartpole.identify.parameters.sample_step`).

    Returns
    -------
    casadi.Function
    """
    F = sample_step(p, params, sample_time, friction_width=friction_width, exact_friction=exact_friction)
    nx, nu, npar = 2 * p.nq, p.nu, len(params)
    x0, U, th = ca.SX.sym("x0", nx), ca.SX.sym("U", nu, length), ca.SX.sym("theta", npar)
    xs = [x0]
    for k in range(length):
        xs.append(F(xs[-1], U[:, k], th))
    X = ca.hcat(xs[:-1])
    z = ca.vertcat(x0, th)
    Xv = ca.vec(X)
    # no common-subexpression elimination: on the two-pole cart it halves an evaluation but takes seconds to build,
    # more than a whole fit's evaluations save
    return ca.Function("segment", [x0, U, th], [X, xs[-1], ca.jacobian(Xv, z), ca.jacobian(xs[-1], z)],
                       ["x0", "U", "theta"], ["X", "x_end", "dX", "dx_end"])


def _values_only(seg: ca.Function) -> ca.Function:
    """The segment's ``(X, x_end)`` without the Jacobians (line searches and residual spreads need no more)."""
    x0, U, th = (ca.SX.sym(n, seg.size_in(i)) for i, n in enumerate(("x0", "U", "theta")))
    X, xe = seg(x0, U, th)[:2]
    return ca.Function("segment_values", [x0, U, th], [X, xe])


@dataclass
class _Run:
    """One log cut into segments (mutable working data of the fit)."""

    S: int
    L: int
    fun: object
    values: object
    U: np.ndarray        # (nu, L S)
    meas: np.ndarray     # (nx, L S + 1): positions, rates (NaN where not measured)
    nodes: np.ndarray    # (nx, S + 1)


def _initial_rates(t, qpos) -> np.ndarray:
    """Rates from positions for the first guess of the nodes only (central differences over +-2 samples)."""
    v = np.gradient(qpos, t, axis=0)
    k = 5
    ker = np.ones(k) / k
    return np.column_stack([np.convolve(np.pad(v[:, j], k // 2, mode="edge"), ker, "valid") for j in range(v.shape[1])])


#: Part of a compiled segment library's key: bump when segment_function changes meaning for the same inputs.
SEGMENT_RECIPE = "identify-segment-v1"


def compiled_segment(p: CartPoleParams, params, sample_time: float, length: int, *,
                     friction_width: float = DEFAULT_FRICTION_WIDTH, exact_friction: bool = True) -> tuple:
    """:func:`segment_function` and its values-only twin compiled to C through :mod:`cartpole.codegen` (``-O0``:
    gcc's optimiser is superlinear in these long straight-line functions), cached by a key of everything they are
    built from: the first call per model, parameters, sample time and length compiles, later ones load.

    Parameters
    ----------
    p, params, sample_time, length, friction_width, exact_friction
        As :func:`segment_function` (s; samples; m/s or rad/s).

    Returns
    -------
    (casadi.Function, casadi.Function)
        The segment (as :func:`segment_function`) and its ``(X, x_end)``.
    """
    h = hashlib.sha256(SEGMENT_RECIPE.encode())
    codegen.digest([dataclasses.replace(p, mjcf=""), list(params), float(sample_time), int(length),
                    float(friction_width), bool(exact_friction)], h)

    def funcs():
        seg = segment_function(p, params, sample_time, length, friction_width=friction_width,
                               exact_friction=exact_friction)
        return [seg, _values_only(seg)]

    lib, _ = codegen.build_library(funcs, "identify", recipe=h.hexdigest(), cflags=("-O0",))
    f = codegen.load_library(lib, ["segment", "segment_values"])
    return f["segment"], f["segment_values"]


def _prepare(p, params, logs, segment_s, friction_width, exact, compiled=False) -> list:
    nq, nx = p.nq, 2 * p.nq
    runs, funcs = [], {}
    for log in logs:
        Ts = log.sample_time
        L = max(2, round(segment_s / Ts))
        S = (log.n - 1) // L
        if S < 1:
            L, S = log.n - 1, 1
        key = (round(Ts, 12), L)
        if key not in funcs and compiled:  # the toolkit's one rule: C when it builds, else the virtual machine
            funcs[key] = compiled_or_none(lambda: compiled_segment(p, params, Ts, L, friction_width=friction_width,
                                                                   exact_friction=exact), "fit segments")
        if funcs.get(key) is None:
            seg = segment_function(p, params, Ts, L, friction_width=friction_width, exact_friction=exact)
            funcs[key] = (seg, _values_only(seg))
        n = S * L
        meas = np.full((nx, n + 1), np.nan)
        meas[:nq] = log.qpos[:n + 1].T
        if log.qvel is not None:
            meas[nq:] = log.qvel[:n + 1].T
        rates = _initial_rates(log.t, log.qpos)[:n + 1].T
        guess = np.vstack([meas[:nq], np.where(np.isfinite(meas[nq:]), meas[nq:], rates)])
        runs.append(_Run(S=S, L=L, fun=funcs[key][0], values=funcs[key][1], U=log.ctrl[:n].T.copy(), meas=meas,
                         nodes=guess[:, ::L].copy()))
    return runs


def _evaluate(runs, theta, w, np_, want_jac=True):
    """Residuals, constraint values and their Jacobian blocks for every run at ``theta`` and the runs' nodes."""
    out = []
    for run in runs:
        nx = run.nodes.shape[0]
        if want_jac:
            X, xe, dX, dxe = run.fun(run.nodes[:, :-1], run.U, theta)
        else:
            X, xe = run.values(run.nodes[:, :-1], run.U, theta)
        X = np.asarray(X)
        pred = np.hstack([X, run.nodes[:, -1:]])
        wmat = np.where(np.isfinite(run.meas), w[:, None], 0.0)
        r = (wmat * np.nan_to_num(run.meas - pred)).T  # (L S + 1, nx)
        c = (run.nodes[:, 1:] - np.asarray(xe)).T     # (S, nx)
        jac = None
        if want_jac:
            dX = np.asarray(dX).reshape(nx * run.L, run.S, nx + np_)
            dxe = np.asarray(dxe).reshape(nx, run.S, nx + np_)
            jac = (dX, dxe, wmat)
        out.append((r, c, jac))
    return out


def _merit(evals, delta, W, mu) -> tuple[float, float]:
    ssr = sum(float(np.sum(r ** 2)) for r, _, _ in evals) + W * float(delta @ delta)
    viol = sum(float(np.sum(np.abs(c))) for _, c, _ in evals)
    return 0.5 * ssr + mu * viol, viol


def _kkt(runs, evals, W, np_, scale, *, fixed=None):
    """The GN KKT matrix and right-hand side in z = [delta, nodes of every run]."""
    nx = runs[0].nodes.shape[0]
    sizes = [(run.S + 1) * nx for run in runs]
    nz = np_ + sum(sizes)
    ncon = sum(run.S * nx for run in runs)
    H = np.zeros((nz, nz))
    g = np.zeros(nz)
    C = np.zeros((ncon, nz))
    c = np.zeros(ncon)
    H[:np_, :np_] += W * np.eye(np_)
    off, row = np_, 0
    for run, (r, cval, (dX, dxe, wmat)), size in zip(runs, evals, sizes):
        L, S = run.L, run.S
        for s in range(S):
            # residual rows of segment s: samples s L .. s L + L - 1, rows (k, i) ordered as vec(X) (i fastest)
            w = wmat[:, s * L:(s + 1) * L].T.reshape(-1)        # (L nx,) in (k, i) order
            Js = dX[:, s, :] * w[:, None]                          # d(pred)/dz weighted; residual = meas - pred
            rs = r[s * L:(s + 1) * L].reshape(-1)
            Jx, Jt = Js[:, :nx], Js[:, nx:] * scale[None, :]
            ix = slice(off + s * nx, off + (s + 1) * nx)
            H[ix, ix] += Jx.T @ Jx
            H[ix, :np_] += Jx.T @ Jt
            H[:np_, ix] += Jt.T @ Jx
            H[:np_, :np_] += Jt.T @ Jt
            g[ix] -= Jx.T @ rs
            g[:np_] -= Jt.T @ rs
            # continuity: nodes[s+1] - x_end(nodes[s], theta) = 0
            rr = slice(row + s * nx, row + (s + 1) * nx)
            C[rr, off + (s + 1) * nx: off + (s + 2) * nx] = np.eye(nx)
            C[rr, ix] = -dxe[:, s, :nx]
            C[rr, :np_] = -dxe[:, s, nx:] * scale[None, :]
            c[rr] = cval[s]
        # the last node is measured directly
        wl = wmat[:, -1]
        il = slice(off + S * nx, off + (S + 1) * nx)
        H[il, il] += np.diag(wl ** 2)
        g[il] -= wl * r[-1]
        off += size
        row += S * nx
    for i, move in (fixed or {}).items():  # a parameter stopped at its bound: an extra equality dz_i = move
        C = np.vstack([C, np.eye(1, nz, i)])
        c = np.append(c, -move)
    return H, g, C, c


def _kkt_matrix(H, C):
    """The sparse KKT matrix ``[[H, C'], [C, 0]]`` (block-banded: segments couple only to their neighbours and to
    the parameters)."""
    Hs, Cs = sp.csc_matrix(H), sp.csc_matrix(C)
    return sp.bmat([[Hs, Cs.T], [Cs, None]], format="csc")


def _solve_kkt(H, g, C, c):
    """GN step ``dz`` and multipliers from the KKT system, by a sparse LU (a dense solve of the same matrix is about
    a hundred times slower at 20 s of 5 ms data)."""
    nz = H.shape[0]
    K = _kkt_matrix(H, C)
    rhs = -np.concatenate([g, c])
    try:
        lu = spla.splu(K)
        sol = lu.solve(rhs)
    except RuntimeError:  # singular: a least-squares step
        lu = None
        sol = spla.lsqr(K, rhs)[0]
    return sol[:nz], sol[nz:], lu


def _gauss_newton(runs, params, delta, w, W, *, max_iter, tol):
    np_ = len(params)
    scale = np.array([q.scale for q in params])
    nominal = np.array([q.nominal for q in params])
    lo = np.array([(q.lower - q.nominal) / q.scale for q in params])
    hi = np.array([(q.upper - q.nominal) / q.scale for q in params])
    with np.errstate(invalid="ignore"):  # strictly inside: a zero mass is not physical
        lo = np.where(np.isfinite(lo), lo + 1e-9 * (1 + np.abs(lo)), lo)
    mu = 1e3
    lm = 0.0  # Levenberg-Marquardt damping on diag(H): zero while plain Gauss-Newton steps succeed
    it = 0
    for it in range(1, max_iter + 1):
        theta = nominal + scale * delta
        evals = _evaluate(runs, theta, w, np_)
        H0, g0, _, _ = _kkt(runs, evals, W, np_, scale)
        g0[:np_] += W * delta
        dH = np.maximum(np.diag(H0), 1e-12)
        accepted = False
        for trial in range(16):
            alpha = 1.0 if trial < 6 else 0.5 ** (trial - 5)  # damping alone cannot shorten the constraint step
            fixed: dict[int, float] = {}
            for _ in range(np_ + 1):
                H, g, C, c = _kkt(runs, evals, W, np_, scale, fixed=fixed)
                g[:np_] += W * delta
                H[np.diag_indices_from(H)] += lm * dH
                dz, lam, _ = _solve_kkt(H, g, C, c)
                cross = [i for i in range(np_) if i not in fixed and not (lo[i] <= delta[i] + dz[i] <= hi[i])]
                if not cross:
                    break
                for i in cross:  # stop these parameters on the bound they would cross (this iteration)
                    fixed[i] = (lo[i] if delta[i] + dz[i] < lo[i] else hi[i]) - delta[i]
            mu = max(mu, 2 * float(np.max(np.abs(lam))) if lam.size else mu)
            phi0, viol0 = _merit(evals, delta, W, mu)
            pred = -(float(g @ dz) + 0.5 * float(dz @ (H0 @ dz))) + mu * viol0  # GN model's decrease
            dz = alpha * dz
            pred = alpha * pred
            d_try = np.clip(delta + dz[:np_], lo, hi)
            saved = [run.nodes.copy() for run in runs]
            off = np_
            for run in runs:
                n = run.nodes.size
                run.nodes += dz[off:off + n].reshape(run.S + 1, -1).T
                off += n
            phi, _ = _merit(_evaluate(runs, nominal + scale * d_try, w, np_, want_jac=False), d_try, W, mu)
            if np.isfinite(phi) and phi0 - phi >= 1e-4 * max(pred, 0.0) and phi <= phi0:
                delta[:] = d_try
                accepted = True
                ratio = (phi0 - phi) / pred if pred > 0 else 1.0
                lm *= max(1 / 3, 1 - (2 * min(ratio, 1.0) - 1) ** 3)  # Nielsen's update
                lm = 0.0 if lm < 1e-9 else lm
                break
            for run, s0 in zip(runs, saved):
                run.nodes[:] = s0
            lm = max(4 * lm, 1e-4) if trial < 6 else lm
        step = float(np.max(np.abs(dz[:np_]))) if np_ else 0.0
        if not accepted:
            return it, viol0 < 1e-6 and pred <= tol * max(1.0, phi0)
        if viol0 < 1e-8 and (step < tol or (phi0 - phi) <= REL_TOL * phi0):
            return it, True
    return it, False


def fit(p: CartPoleParams, params, logs, *, regularization: float = DEFAULT_REGULARIZATION,
        segment_s: float = DEFAULT_SEGMENT_S, friction_width: float = DEFAULT_FRICTION_WIDTH,
        exact_friction: bool = True, compiled: bool = False, max_iter: int = 60, tol: float = 1e-7) -> FitResult:
    """Fit ``params`` to the logged runs (module docstring).

    Parameters
    ----------
    p : CartPoleParams
        The nominal model.
    params : sequence of Parameter
        What to fit (:func:`~cartpole.identify.parameters.parse_parameters`).
    logs : sequence of RunLog
        The runs to fit (:func:`~cartpole.identify.logs.read_log`).
    regularization : float
        Weight W >= 0 of ``sum(((theta - nominal) / scale)^2)`` against the data's squared weighted residuals.
    segment_s : float
        Shooting segment length, s.
    friction_width : float
        The smooth friction's velocity scale, m/s or rad/s (with ``exact_friction=False``).
    exact_friction : bool
        Fit with MuJoCo's friction constraint solved exactly (default), else with the smooth ``tanh`` friction
        reached by continuation from wider widths.
    compiled : bool
        Evaluate the segments in compiled C (:func:`compiled_segment`, cached) instead of CasADi's virtual machine:
        worth it only when the library is already cached (docs/identify.md, Speed).
    max_iter : int
        Gauss-Newton iterations per pass.
    tol : float
        Step size (relative to the parameters' scales) at which the fit has converged.

    Returns
    -------
    FitResult

    Raises
    ------
    FitError
        No runs, no parameters, a negative weight, or no convergence.
    """
    t0 = time.perf_counter()
    params = tuple(params)
    if not logs:
        raise FitError("No run to fit; give at least one log in `logs`.")
    if not params:
        raise FitError("No parameter to fit; give `params` (parse_parameters of names like mass:pole, or all).")
    if not (np.isfinite(regularization) and regularization >= 0):
        raise FitError(f"The regularisation weight {regularization:g} is not a non-negative number; give e.g. 1.")
    nq, np_ = p.nq, len(params)
    w = np.concatenate([np.full(nq, 1 / PRIOR_STD), np.full(nq, 1 / PRIOR_RATE_STD)])
    delta = np.zeros(np_)
    iters = 0
    runs = None
    with_friction = not exact_friction and (p.has_friction or any(q.kind == "frictionloss" for q in params))
    # Friction: continuation from a wider, smoother friction down to the model's (each fit warm-starts the next),
    # as Gauss-Newton from the nominal on the steep one crawls.
    for width in ((8 * friction_width, 4 * friction_width, 2 * friction_width) if with_friction else ()):
        nodes = None if runs is None else [run.nodes.copy() for run in runs]
        runs = _prepare(p, params, logs, segment_s, width, False)
        for run, n0 in zip(runs, nodes or []):
            run.nodes[:] = n0
        it, _ = _gauss_newton(runs, params, delta, w, regularization, max_iter=max_iter, tol=tol)
        iters += it
    nodes = None if runs is None else [run.nodes.copy() for run in runs]
    runs = _prepare(p, params, logs, segment_s, friction_width, exact_friction, compiled)
    for run, n0 in zip(runs, nodes or []):
        run.nodes[:] = n0
    for _ in range(2):  # fit, then re-weight each joint by its residual spread and polish
        it, ok = _gauss_newton(runs, params, delta, w, regularization, max_iter=max_iter, tol=tol)
        iters += it
        if not ok:
            raise FitError(f"The fit did not converge in {max_iter} Gauss-Newton iterations; fit fewer "
                           "parameters, raise `regularization`, or give a more exciting run.")
        theta = np.array([q.nominal + q.scale * d for q, d in zip(params, delta)])
        res = _residual_std(runs, theta, w, np_)
        floor = 1e-3 / w  # a spread below a thousandth of the prior's is rounding, not noise
        w_new = np.where(np.isfinite(res), 1 / np.maximum(res, floor), w)
        if np.allclose(w_new, w, rtol=0.05):
            w = w_new
            break
        w = w_new
    theta = np.array([q.nominal + q.scale * d for q, d in zip(params, delta)])
    std, corr, warn = _uncertainty(runs, params, theta, w, regularization)
    res = _residual_std(runs, theta, w, np_)
    return FitResult(parameters=params, fitted=readonly(theta), std=readonly(std), correlation=readonly(corr),
                     warnings=tuple(warn), fit_rms=readonly(res[:nq]), iterations=iters,
                     solve_s=time.perf_counter() - t0, residual_std=readonly(res[:nq]))


def _uncertainty(runs, params, theta, w, regularization: float) -> tuple:
    """``(std, correlation, warnings)`` of the fitted ``theta``: the standard deviations in the parameters' units
    from the KKT system at the optimum (the residuals' variance per degree of freedom, at least 1), their
    correlation matrix, and the identifiability and bound warnings."""
    np_ = len(params)
    evals = _evaluate(runs, theta, w, np_)
    scale = np.array([q.scale for q in params])
    H, g, C, c = _kkt(runs, evals, regularization, np_, scale)
    n_data = sum(int(np.sum(np.isfinite(run.meas))) for run in runs)
    ssr = sum(float(np.sum(r ** 2)) for r, _, _ in evals)
    dof = max(1, n_data - np_ - sum(run.nodes.size - run.S * run.nodes.shape[0] for run in runs))
    s2 = max(ssr / dof, 1.0)  # the weights are the residual spreads, so about 1; never below (floored spreads)
    _, _, lu = _solve_kkt(H, g, C, c)
    if lu is None:
        raise FitError("The fit's information matrix is singular at the optimum; fit fewer parameters or raise "
                       "`regularization`.")
    E = np.zeros((H.shape[0] + C.shape[0], np_))
    E[:np_, :np_] = np.eye(np_)
    cov_rel = s2 * lu.solve(E)[:np_, :np_]
    cov_rel = 0.5 * (cov_rel + cov_rel.T)
    std = np.sqrt(np.maximum(np.diag(cov_rel), 0)) * scale
    d = np.sqrt(np.maximum(np.diag(cov_rel), 1e-300))
    corr = cov_rel / np.outer(d, d)
    info_data = np.linalg.inv(cov_rel / s2) - regularization * np.eye(np_)
    warn = identifiability_warnings(params, 0.5 * (info_data + info_data.T) / s2, corr)
    warn += _bound_warnings(params, theta)
    return std, corr, warn


def _residual_std(runs, theta, w, np_) -> np.ndarray:
    """RMS of the unweighted residual per state entry (nx,) over every run (NaN where never measured)."""
    evals = _evaluate(runs, theta, w, np_, want_jac=False)
    sq = np.zeros(len(w))
    cnt = np.zeros(len(w))
    for run, (r, _, _) in zip(runs, evals):
        m = np.isfinite(run.meas).T
        sq += np.sum(np.where(m, (r / w[None, :]) ** 2, 0), axis=0)
        cnt += m.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(sq / cnt)


def identifiability_warnings(params, info, corr) -> list:
    """One sentence per combination of parameters the runs hardly determine.

    Parameters
    ----------
    params : sequence of Parameter
    info : (np, np) array
        Data-only information matrix of ``delta`` (parameters relative to their scales).
    corr : (np, np) array
        Correlation of the fitted parameters.

    Returns
    -------
    list of str
    """
    out = []
    names = [q.name for q in params]
    evals, evecs = np.linalg.eigh(info)
    involved = set()
    for lam, v in zip(evals, evecs.T):
        std = np.inf if lam <= 0 else 1 / np.sqrt(lam)
        if std <= UNIDENTIFIABLE_STD:
            continue
        order = np.argsort(-np.abs(v))
        who = [names[i] for i in order if abs(v[i]) >= 0.15]
        involved.update(names[i] for i in order if abs(v[i]) >= 0.05)
        if len(who) == 1:
            out.append(f"{who[0]} is not identifiable from these runs (data-only standard error {_pct(std)}; it "
                       "stays near the nominal by the regularisation): give a run that moves it, or leave it out of "
                       "--fit.")
        else:
            out.append(f"{', '.join(who[:-1])} and {who[-1]} are identifiable only as a combination from these runs "
                       f"(e.g. a ratio; data-only standard error of the combination {_pct(std)}, held near the "
                       "nominal by the regularisation): fix one of them (weigh it) or give runs that separate them.")
    n = len(names)
    pairs = [(names[i], names[j], corr[i, j]) for i in range(n) for j in range(i + 1, n)
             if abs(corr[i, j]) >= CORRELATION_WARN and not {names[i], names[j]} <= involved]
    if pairs:
        listed = "; ".join(f"{a} and {b} ({c:+.3f})" for a, b, c in pairs[:4])
        more = f" and {len(pairs) - 4} more pairs" if len(pairs) > 4 else ""
        out.append(f"Strongly correlated in these runs, so the data fix mainly their combination (e.g. a ratio): "
                   f"{listed}{more}; fix one of each pair or give runs that separate them.")
    return out


def _pct(x: float) -> str:
    return "unbounded" if not np.isfinite(x) or x > 1e6 else f"{100 * x:.0f} % of the scale"


def _bound_warnings(params, theta) -> list:
    out = []
    for q, v in zip(params, theta):
        if q.kind in ("mass", "inertia", "gear") and np.isfinite(q.lower) and v <= q.lower + 1e-6 * q.scale:
            out.append(f"{q.name} ended on its bound {q.lower:g}: the data push it below what is physical; check "
                       "the log's sign conventions and units.")
    return out


@dataclass(frozen=True)
class Simulation:
    """A model run open loop on a log's ctrl from the state estimated at its start.

    Attributes
    ----------
    t : (N,) array, s
    x : (N, nx) array
        Simulated states.
    rms : (nq,) array
        RMS of measured minus simulated positions per joint, m or rad.
    """

    t: np.ndarray
    x: np.ndarray
    rms: np.ndarray


def simulate_log(p: CartPoleParams, params, theta, log, *, start_s: float = 0.5,
                 friction_width: float = DEFAULT_FRICTION_WIDTH, exact_friction: bool = True) -> Simulation:
    """Simulate the model with parameter values ``theta`` on a log's ctrl: the start state (rates included) is
    fitted to the log's first ``start_s`` seconds with the parameters held (Gauss-Newton), then the model runs open
    loop over the whole log. What the held-out check compares (a hanging run; an open-loop unstable run grows
    apart under any model).

    Parameters
    ----------
    p : CartPoleParams
    params : sequence of Parameter
    theta : (np,) array, SI units
    log : RunLog
    start_s : float
        Seconds of data that fix the start state.
    friction_width : float
        m/s or rad/s (the smooth friction's, with ``exact_friction=False``).
    exact_friction : bool
        MuJoCo's friction constraint solved exactly.

    Returns
    -------
    Simulation
    """
    theta = np.asarray(theta, float)
    nq = p.nq
    Ts = log.sample_time
    L = int(min(log.n - 1, max(2, round(start_s / Ts))))
    seg = segment_function(p, params, Ts, L, friction_width=friction_width, exact_friction=exact_friction)
    x0 = np.concatenate([log.qpos[0], _initial_rates(log.t, log.qpos)[0]])
    meas = log.qpos[:L].T
    for _ in range(20):
        X, _, dX, _ = seg(x0, log.ctrl[:L].T, theta)
        r = (meas - np.asarray(X)[:nq]).T.reshape(-1)
        J = np.asarray(dX)[:, :2 * nq].reshape(L, 2 * nq, 2 * nq)[:, :nq, :].reshape(-1, 2 * nq)
        dx = np.linalg.lstsq(J, r, rcond=None)[0]
        x0 = x0 + dx
        if np.max(np.abs(dx)) < 1e-10:
            break
    step = sample_step(p, params, Ts, friction_width=friction_width, exact_friction=exact_friction)
    run = step.mapaccum(log.n - 1)
    xs = np.asarray(run(x0, log.ctrl[:-1].T, theta)).T
    x = np.vstack([x0, xs])
    with np.errstate(over="ignore", invalid="ignore"):
        rms = np.sqrt(np.mean((log.qpos - x[:, :nq]) ** 2, axis=0))
    return Simulation(t=readonly(log.t), x=readonly(x), rms=readonly(rms))
