"""Hermite-Simpson interval functions compiled to C, for the fixed-time effort swing-up solved by IPOPT.

Why: with ``expand=True`` the NLP is one flat SX graph that CasADi's virtual machine interprets, and that
interpretation is most of a solve's time, the Hessian of the Lagrangian above all. The NLP is N copies of one
small interval function of ``2 (nx + nu)`` scaled variables ``v = (z_k, z_k+1)``, ``z = (x, u)`` (ten for one
pole). So only that interval's pieces are compiled: its defect and effort with their exact first derivatives,
and the Hessian block of its share of the Lagrangian (SX, derived by CasADi). For one pole their C source is
small and compiles in seconds; code-generating the assembled NLP functions instead kept gcc busy for minutes and
gigabytes. The interval source grows fast with the number of poles (megabytes for two and three), so large sources are compiled without optimisation (:data:`cartpole.codegen.LARGE_SOURCE`). The NLP's own functions (objective,
constraints, gradient, constraint Jacobian, Lagrangian Hessian) are small MX graphs that ``map`` the compiled
pieces over the N intervals and scatter the blocks into the NLP's sparse matrices; IPOPT gets them as
``grad_f``, ``jac_g`` and ``hess_lag``. Same NLP, same iterates, same solution as the SX formulation.

The shared library is cached in a user cache directory (:func:`cartpole.codegen.cache_dir`) under a hash of the model
(:func:`cartpole.codegen.model_key`: ``nx``, ``nu`` and every parameter), of the generated source (the scaling), the flags and the
CasADi version, so two models never share a library: it is compiled once per machine and model, never into the
package. Without a C compiler, or if the build fails, :func:`compiled_nlp` returns None (with a note on stderr)
and the caller keeps the SX formulation.
"""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from cartpole.codegen import build_library, compiled_or_none, digest, load_library, model_key
from cartpole.models import CartPoleModel
from cartpole.ocp import hermite_simpson
from cartpole.ocp.hermite_simpson import hs_interval_function, simpson_effort_terms



#: The names of the interval functions a compiled library holds (:func:`interval_functions`).
INTERVAL_FUNCTIONS = ("hs_d", "hs_e", "hs_dj", "hs_eg", "hs_hl")
#: The knot-shared functions (:func:`knot_functions`), mapped over N (:func:`knot_maps`).
KNOT_FUNCTIONS = ("hs_kf", "hs_mid1", "hs_mid2", "hs_kh")


@dataclass(frozen=True)
class CompiledNLP:
    """The NLP and its derivative functions built on the compiled interval functions.

    Attributes
    ----------
    nlp : dict
        ``{"x", "p", "f", "g"}`` for ``casadi.nlpsol`` (MX; ``x`` is ``[z_0, ..., z_N]`` ((nx + nu) (N+1),)
        scaled, ``p`` the duration T in s).
    options : dict
        ``grad_f``, ``jac_g``, ``hess_lag`` Functions for ``casadi.nlpsol('ipopt')``.
    library : str
        Path of the shared library in use.
    compiled_now : bool
        True when this call ran the compiler (False: found in the cache).
    """

    nlp: dict
    options: dict
    library: str
    compiled_now: bool


def interval_functions(f: ca.Function, sx: np.ndarray, su, eff_scale: float = 1.0, *,
                       running: ca.Function | None = None) -> list[ca.Function]:
    """SX functions of one Hermite-Simpson interval in scaled variables ``v = (x_k, u_k, x_k+1, u_k+1) / scale``.

    Every derivative is taken in ``(v, h)`` (``nv + 1`` entries, ``nv = 2 (nx + nu)``), the interval length
    ``h`` in s last: a free-final-time problem needs the ``h`` entries, a fixed-time one drops them.

    Parameters
    ----------
    f : casadi.Function
        Continuous dynamics ``x_dot = f(x (nx,), u (nu,))`` (sizes read from it).
    sx : (nx,) array
        State scales; ``su`` (nu,) the ctrl scales (a scalar for nu = 1); ``eff_scale`` divides the interval
        cost.
    running : casadi.Function, optional
        A running cost ``L(x (nx,), u (nu,)) -> scalar`` (SX): the interval cost is then its Simpson integral
        ``h (L_k + 4 L_c + L_k+1) / 6`` on the Hermite midpoint state and the first-order-hold midpoint input;
        default the effort ``integral u'u dt`` (ctrl^2 s).

    Returns
    -------
    list of casadi.Function
        ``hs_d(v, h) -> d`` (nx,) the defect divided by ``sx``; ``hs_e(v, h) -> e`` the interval cost
        divided by ``eff_scale``; ``hs_dj(v, h) -> (d, d(d)/d(v, h) (nx, nv + 1))``;
        ``hs_eg(v, h) -> (e, de/d(v, h) (nv + 1,))``; ``hs_hl(v, h, lam (nx,), sigma) ->`` upper triangle
        ((nv + 1) (nv + 2) / 2,) column-major of the Hessian of ``sigma e + lam' d`` in ``(v, h)``; and
        ``jac_hs_d``, ``jac_hs_e``, the Jacobians CasADi looks up by name when it differentiates an external
        function (it does once, for the final multipliers).
    """
    nx, nu = f.size1_in(0), f.size1_in(1)
    nz = nx + nu
    nv = 2 * nz
    su = ca.DM(np.broadcast_to(np.asarray(su, float), (nu,)))
    v = ca.SX.sym("v", nv)
    h = ca.SX.sym("h")
    vh = ca.vertcat(v, h)
    lam = ca.SX.sym("lam", nx)
    sigma = ca.SX.sym("sigma")
    xk, uk = v[0:nx] * ca.DM(sx), v[nx:nz] * su
    xk1, uk1 = v[nz:nz + nx] * ca.DM(sx), v[nz + nx:nv] * su
    defect, xc = hs_interval_function(f)(xk, uk, xk1, uk1, f(xk, uk), f(xk1, uk1), h)
    d = defect / ca.DM(sx)
    if running is None:
        e = h / 6 * ca.sum1(simpson_effort_terms(uk, uk1)) / eff_scale
    else:
        e = h / 6 * (running(xk, uk) + 4 * running(xc, 0.5 * (uk + uk1)) + running(xk1, uk1)) / eff_scale
    H = ca.densify(ca.hessian(sigma * e + ca.dot(lam, d), vh)[0])
    hess_triu = ca.vertcat(*[H[a, b] for b in range(nv + 1) for a in range(b + 1)])
    hs_d = ca.Function("hs_d", [v, h], [d])
    hs_e = ca.Function("hs_e", [v, h], [e])
    return [
        hs_d,
        hs_e,
        ca.Function("hs_dj", [v, h], [d, ca.densify(ca.jacobian(d, vh))]),
        ca.Function("hs_eg", [v, h], [e, ca.densify(ca.gradient(e, vh))]),
        ca.Function("hs_hl", [v, h, lam, sigma], [hess_triu]),
        hs_d.jacobian(),  # named jac_hs_d
        hs_e.jacobian(),
    ]


def knot_functions(f: ca.Function, sx: np.ndarray, su, *, running: ca.Function | None = None) -> list[ca.Function]:
    """The same fixed-duration derivatives as ``hs_dj``, ``hs_eg`` and ``hs_hl`` in ``v`` (:func:`interval_functions`),
    with every knot's dynamics and its curvature evaluated once instead of once per interval it touches (the SQP's
    evaluation; scaled variables as there, ``z = (x / sx, u / su)``):

    ``hs_kf(z (nz,)) -> (f (nx,), J (nx, nz))``
        A knot's ``f(x, u)`` and its Jacobian in ``z``.
    ``hs_mid1(z_k, z_k+1, f_k, f_k+1, J_k, J_k+1, h) -> (d (nx,), dd/dv (nx, nv), e, de/dv (nv,))``
        The interval's defect (over ``sx``) and cost, and their total derivatives in ``v = (z_k, z_k+1)``.
    ``hs_mid2(z_k, z_k+1, f_k, f_k+1, J_k, J_k+1, h, lam (nx,), sigma) -> (H (nv, nv), w_k (nx,), w_k+1 (nx,))``
        The Hessian of ``sigma e + lam' d`` in ``v`` but for the knots' own curvature, which is ``w_k' f`` at each
        knot: ``w_k = d(sigma e + lam' d)/d f_k`` (and ``w_k+1``), left to ``hs_kh``.
    ``hs_kh(z (nz,), w (nx,)) -> (nz, nz)``
        ``d^2 (w' f) / dz^2`` at a knot: with ``w`` the sum of its two intervals' weights, once per knot.

    Summed over the intervals, ``hs_mid2``'s blocks with each knot's ``hs_kh`` added (to either interval touching
    it) are the NLP Lagrangian's Hessian, equal to the sum of ``hs_hl``'s blocks (``tests/ocp/test_compiled_nlp.py``).
    """
    nx, nu = f.size1_in(0), f.size1_in(1)
    nz = nx + nu
    nv = 2 * nz
    sxd = ca.DM(np.asarray(sx, float).ravel())
    sud = ca.DM(np.broadcast_to(np.asarray(su, float).ravel(), (nu,)))
    z = ca.SX.sym("z", nz)
    fz = f(z[:nx] * sxd, z[nx:] * sud)
    w = ca.SX.sym("w", nx)
    hs_kf = ca.Function("hs_kf", [z], [fz, ca.densify(ca.jacobian(fz, z))], {"cse": True})
    hs_kh = ca.Function("hs_kh", [z, w], [ca.densify(ca.hessian(ca.dot(w, fz), z)[0])], {"cse": True})
    zk, zk1 = ca.SX.sym("zk", nz), ca.SX.sym("zk1", nz)
    fk, fk1 = ca.SX.sym("fk", nx), ca.SX.sym("fk1", nx)
    Jk, Jk1 = ca.SX.sym("Jk", nx, nz), ca.SX.sym("Jk1", nx, nz)
    h, lam, sigma = ca.SX.sym("h"), ca.SX.sym("lam", nx), ca.SX.sym("sigma")
    xk, uk = zk[:nx] * sxd, zk[nx:] * sud
    xk1, uk1 = zk1[:nx] * sxd, zk1[nx:] * sud
    defect, xc = hs_interval_function(f)(xk, uk, xk1, uk1, fk, fk1, h)
    d = defect / sxd
    if running is None:
        e = h / 6 * ca.sum1(simpson_effort_terms(uk, uk1))
    else:
        e = h / 6 * (running(xk, uk) + 4 * running(xc, 0.5 * (uk + uk1)) + running(xk1, uk1))
    v, g = ca.vertcat(zk, zk1), ca.vertcat(zk, zk1, fk, fk1)
    # dg/dv: the knots' f are functions of their own z
    Tg = ca.vertcat(ca.SX.eye(nv), ca.horzcat(Jk, ca.SX(nx, nz)), ca.horzcat(ca.SX(nx, nz), Jk1))
    jd = ca.mtimes(ca.jacobian(d, g), Tg)
    je = ca.mtimes(ca.jacobian(e, g), Tg)
    hs_mid1 = ca.Function("hs_mid1", [zk, zk1, fk, fk1, Jk, Jk1, h], [d, ca.densify(jd), e, ca.densify(je.T)],
                          {"cse": True})
    lag = sigma * e + ca.dot(lam, d)
    # The curvature of lag in v comes from three places: the knots' own f (left to hs_kh through w_k, w_k+1), the
    # midpoint's f and running cost (through z_c = (x_c, u_c), linear in g: Dc' Hc Dc below, Hc the midpoint terms'
    # Hessian in z_c alone, far cheaper than differentiating twice through g), and the cost's knot terms.
    uc = 0.5 * (uk + uk1)
    zc = ca.vertcat(xc, uc)
    Dc = ca.mtimes(ca.jacobian(zc, g), Tg)  # (nz, nv)
    zs = ca.SX.sym("zc", nz)
    mid = -4 * h / 6 * ca.dot(lam / sxd, f(zs[:nx], zs[nx:]))
    if running is None:
        knots_e = e  # the effort: quadratic in the knot inputs, u_c included
    else:
        mid += sigma * 4 * h / 6 * running(zs[:nx], zs[nx:])
        knots_e = h / 6 * (running(xk, uk) + running(xk1, uk1))
    Hc = ca.substitute(ca.hessian(mid, zs)[0], zs, zc)
    Hm = ca.mtimes([Dc.T, Hc, Dc]) + ca.hessian(sigma * knots_e, v)[0]
    wk, wk1 = ca.gradient(lag, fk), ca.gradient(lag, fk1)
    hs_mid2 = ca.Function("hs_mid2", [zk, zk1, fk, fk1, Jk, Jk1, h, lam, sigma],
                          [ca.densify(0.5 * (Hm + Hm.T)), ca.densify(wk), ca.densify(wk1)], {"cse": True})
    return [hs_kf, hs_mid1, hs_mid2, hs_kh]


def knot_maps(model: CartPoleModel | ca.Function, N: int, sx: np.ndarray, su, *, running: ca.Function | None = None,
              compiled: bool = True) -> tuple[dict[str, ca.Function], str | None]:
    """:func:`knot_functions` mapped over ``N`` intervals (``hs_kf`` and ``hs_kh`` over the N + 1 knots), by name,
    and the path of their library (None: the virtual machine). ``h`` and ``sigma`` are one scalar for all intervals.

    Compiled to C with the maps inside (one library per model, scaling, running cost and N, cached like the
    interval functions; a map generated into the C runs each instance about twice as fast as ``map`` over an
    external function); CasADi's virtual machine (same numbers) with ``compiled`` False, ``CARTPOLE_NO_COMPILE`` set
    or when the build fails (one line on stderr). Arguments as :func:`compiled_nlp`.
    """
    f = model if isinstance(model, ca.Function) else model.f
    sx, su = np.asarray(sx, float), np.asarray(su, float)
    N = int(N)

    # per function: how many instances (knots or intervals) and the inputs shared by all (h, sigma: scalars)
    layout = {"hs_kf": (N + 1, []), "hs_mid1": (N, [6]), "hs_mid2": (N, [6, 8]), "hs_kh": (N + 1, [])}

    def mapped():
        fns = dict(zip(KNOT_FUNCTIONS, knot_functions(f, sx, su, running=running)))
        return [fns[name].map(f"{name}_map", "serial", layout[name][0], layout[name][1], [])
                for name in KNOT_FUNCTIONS]

    def build():
        lib, _ = build_library(mapped, model_key(model), recipe=f"knots/{N}/" + recipe_key(f, sx, su, running),
                               recipe_is_key=True)
        ext = load_library(lib, [f"{name}_map" for name in KNOT_FUNCTIONS])
        return {name: ext[f"{name}_map"] for name in KNOT_FUNCTIONS}, lib

    built = compiled_or_none(build, "collocation knot functions", "using CasADi's virtual machine (same results)") \
        if compiled else None
    return built if built is not None else (dict(zip(KNOT_FUNCTIONS, mapped())), None)


#: The interval and knot functions' generators (this module and the Hermite-Simpson interval it builds on): part of
#: their libraries' recipe (:func:`recipe_key`), so an edited generator builds new libraries.
_SOURCE_DIGEST = hashlib.sha256(Path(__file__).read_bytes() + Path(hermite_simpson.__file__).read_bytes()
                                ).hexdigest()[:16]


def recipe_key(f: ca.Function, sx, su, running: ca.Function | None = None) -> str:
    """Hex digest of everything the interval functions are generated from: ``f``'s serialised expression graph,
    the scales ``sx``, ``su``, the running cost's graph (if any), the CasADi version, ``$CARTPOLE_CFLAGS`` and the
    source files of the generators (this module and :mod:`cartpole.ocp.hermite_simpson`, :data:`_SOURCE_DIGEST`).
    The compiled libraries are keyed by it (:func:`cartpole.codegen.build_library`'s ``recipe_is_key``): a cached
    library is found without generating its C source again."""
    h = hashlib.sha256()
    h.update((ca.__version__ + os.environ.get("CARTPOLE_CFLAGS", "") + _SOURCE_DIGEST).encode())
    h.update(f.serialize().encode())
    digest(np.asarray(sx, float), h)
    digest(np.asarray(su, float).ravel(), h)
    h.update(b"running:" + (running.serialize().encode() if running is not None else b"-"))
    return h.hexdigest()


def _assemble(ext: dict[str, ca.Function], N: int, nx: int, nu: int, *, free_time: bool = False,
              cost_weight: float = 1.0, time_weight: float = 0.0) -> tuple[dict, dict]:
    """The NLP (MX) and IPOPT's derivative Functions from the mapped interval functions.

    Objective ``time_weight T + cost_weight sum_k e_k``. Fixed time: variables ``[z_0 .. z_N]``, parameter T.
    Free time: variables ``[z_0 .. z_N, T]`` (T in s) and no parameter; T couples every interval (``h = T / N``),
    so the constraint Jacobian has one dense column and the Hessian one dense column (upper triangle), both
    assembled from the interval functions' ``h`` entries by the chain rule (``d/dT = d/dh / N``).
    """
    nz = nx + nu  # one knot
    nv = 2 * nz  # one interval's variables
    nvh = nv + 1  # and h
    ntri = nvh * (nvh + 1) // 2
    n_z = nz * (N + 1)
    n = n_z + int(free_time)
    w = ca.MX.sym("x", n)
    if free_time:
        p = ca.MX.sym("p", 0)
        T = w[n_z]
    else:
        p = ca.MX.sym("p", 1)
        T = p[0]
    h = T / N
    Z = ca.reshape(w[:n_z], nz, N + 1)
    V = ca.vertcat(Z[:, :-1], Z[:, 1:])  # (nv, N): interval k's variables in column k
    g = ca.vec(ext["hs_d"].map(N)(V, h))
    fobj = cost_weight * ca.sum2(ext["hs_e"].map(N)(V, h))
    if free_time and time_weight:
        fobj = fobj + time_weight * T
    nlp = {"x": w, "p": p, "f": fobj, "g": g}

    D, JD = ext["hs_dj"].map(N)(V, h)  # (nx, N), (nx, nvh N)
    E, GE = ext["hs_eg"].map(N)(V, h)  # (1, N), (nvh, N)
    GE = cost_weight * GE
    # gradient of f: knot k's nz entries get the right half of interval k-1 and the left half of interval k
    grad_f = ca.vec(ca.horzcat(GE[:nz, :], ca.DM.zeros(nz, 1)) + ca.horzcat(ca.DM.zeros(nz, 1), GE[nz:nv, :]))
    if free_time:
        grad_f = ca.vertcat(grad_f, time_weight + ca.sum2(GE[nv, :]) / N)

    # Jacobian of g: interval k's dense (nx x nv) block at rows nx k.., cols nz k.. (blocks do not overlap);
    # free time: its h column, divided by N, in the dense column of T
    nb = nvh if free_time else nv
    k, b, a = np.meshgrid(np.arange(N), np.arange(nb), np.arange(nx), indexing="ij")
    k, b, a = k.ravel(), b.ravel(), a.ravel()
    rows = nx * k + a
    cols = np.where(b < nv, nz * k + b, n_z)
    src = nx * nvh * k + nx * b + a
    fac = np.where(b < nv, 1.0, 1.0 / N)
    order = np.lexsort((rows, cols))  # CasADi's compressed-column order: by column, then row
    sp_j = ca.Sparsity.triplet(nx * N, n, rows.tolist(), cols.tolist())
    vals = ca.vec(JD)[src[order].tolist()]
    jac = ca.MX(sp_j, vals if not free_time else vals * ca.DM(fac[order]))

    # Hessian (upper triangle): the interval blocks summed where they overlap on the shared knots (and, free
    # time, every interval's h entries summed into T's column)
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", nx * N)
    HB = ext["hs_hl"].map(N)(V, h, ca.reshape(lam_g, nx, N), cost_weight * lam_f)  # (ntri, N)
    tri = [(a_, b_) for b_ in range(nvh) for a_ in range(b_ + 1)]
    keep = np.array([i for i, (a_, b_) in enumerate(tri) if free_time or b_ < nv])
    tri_a = np.array([tri[i][0] for i in keep])
    tri_b = np.array([tri[i][1] for i in keep])
    kk = np.arange(N)[:, None]

    def glob(c):
        return np.where(c[None, :] < nv, nz * kk + c[None, :], n_z + 0 * kk)

    h_rows, h_cols = glob(tri_a).ravel(), glob(tri_b).ravel()
    h_fac = ((tri_a < nv).astype(float) + (tri_a == nv) / N) * np.where(tri_b < nv, 1.0, 1.0 / N)
    h_fac = np.broadcast_to(h_fac[None, :], (N, keep.size)).ravel()
    h_src = (ntri * kk + keep[None, :]).ravel()  # entry of vec(HB)
    sp_h = ca.Sparsity.triplet(n, n, h_rows.tolist(), h_cols.tolist())  # duplicates merged
    # nonzero index in sp_h of each triplet, then one constant sparse matrix that sums the blocks into it
    colind, row = np.array(sp_h.colind()), np.array(sp_h.row())
    lookup = {}
    for c in range(n):
        for j in range(colind[c], colind[c + 1]):
            lookup[(int(row[j]), c)] = j
    dst = np.array([lookup[(int(r), int(c))] for r, c in zip(h_rows, h_cols)])
    scatter = ca.DM.triplet(dst.tolist(), h_src.tolist(), h_fac.tolist(), sp_h.nnz(), ntri * N)
    hess = ca.MX(sp_h, ca.mtimes(scatter, ca.vec(HB)))

    options = {
        "grad_f": ca.Function("hs_nlp_grad_f", [w, p], [fobj, grad_f], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("hs_nlp_jac_g", [w, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("hs_nlp_hess_l", [w, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"],
                                ["triu_hess_gamma_x_x"]),
    }
    return nlp, options


def compiled_nlp(model: CartPoleModel | ca.Function, N: int, sx: np.ndarray, su, eff_scale: float = 1.0, *,
                 free_time: bool = False, time_weight: float = 1.0, running: ca.Function | None = None
                 ) -> CompiledNLP | None:
    """The Hermite-Simpson NLP on compiled interval functions, or None where C cannot be built.

    Fixed time (default): objective ``cost / eff_scale``, variables ``[z_0 .. z_N]`` scaled, parameter T (s).
    Free time: objective ``time_weight T + cost / eff_scale``, variables ``[z_0 .. z_N, T]``, no parameter. The
    cost is the effort ``integral u'u dt`` (ctrl^2 s), or the integral of ``running`` when given. The library
    holds the interval functions only (:func:`interval_functions` with ``eff_scale = 1``): one library per
    model, scaling and running cost serves every N, T, ``eff_scale`` and both fixed and free time.

    Parameters
    ----------
    model : CartPoleModel or casadi.Function
        The model (its ``f``; its sizes and parameters key the cache, :func:`model_key`), or its continuous
        dynamics ``f(x (nx,), u (nu,)) -> x_dot (nx,)`` alone.
    N : int
        Number of intervals.
    sx : (nx,) array
        State scales (the NLP's variables are state / scale); ``su`` (nu,) the ctrl scales (a scalar for one
        input).
    eff_scale : float
        The cost is divided by it.
    free_time : bool
        T is the last variable (s) instead of the parameter.
    time_weight : float
        Weight of T in a free-time objective (1/s).
    running : casadi.Function, optional
        Running cost ``(x (nx,), u (nu,)) -> scalar`` (SX) integrated instead of the effort.

    Returns
    -------
    CompiledNLP or None
        None (with a note on stderr) when ``CARTPOLE_NO_COMPILE`` is set, there is no C compiler,
        or the build or load fails: the caller then uses the SX formulation, which gives the same numbers.
    """
    f = model if isinstance(model, ca.Function) else model.f
    nx, nu = f.size1_in(0), f.size1_in(1)
    sx, su = np.asarray(sx, float), np.asarray(su, float)

    def build():
        lib, now = build_library(lambda: interval_functions(f, sx, su, 1.0, running=running), model_key(model),
                                 recipe=recipe_key(f, sx, su, running), recipe_is_key=True)
        return lib, now, load_library(lib, INTERVAL_FUNCTIONS)

    built = compiled_or_none(build, "collocation functions", "using the slower SX formulation (same results)")
    if built is None:
        return None
    lib, now, ext = built
    nlp, options = _assemble(ext, int(N), nx, nu, free_time=free_time, cost_weight=1.0 / float(eff_scale),
                             time_weight=float(time_weight) if free_time else 0.0)
    return CompiledNLP(nlp=nlp, options=options, library=lib, compiled_now=now)
