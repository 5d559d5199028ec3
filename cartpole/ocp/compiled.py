"""Hermite-Simpson interval functions compiled to C, for the fixed-time effort swing-up solved by IPOPT.

Why: with ``expand=True`` the NLP is one flat SX graph that CasADi's virtual machine interprets; at N = 100
that costs about 30 of a solve's 50 ms, most of it the Hessian of the Lagrangian. The NLP is N copies of one
small interval function of ``2 (nx + nu)`` scaled variables ``v = (z_k, z_k+1)``, ``z = (x, u)`` (ten for one
pole). So only that interval's pieces are compiled: its defect and effort with their exact first derivatives,
and the Hessian block of its share of the Lagrangian (SX, derived by CasADi). For one pole their C source is
small and compiles in about a second; code-generating the assembled NLP functions instead kept gcc busy for
minutes at 2.5 GB. The interval source grows fast with the number of poles (1.1 MB for two, 5.2 MB for three),
so large sources are compiled without optimisation (:data:`LARGE_SOURCE`). The NLP's own functions (objective,
constraints, gradient, constraint Jacobian, Lagrangian Hessian) are small MX graphs that ``map`` the compiled
pieces over the N intervals and scatter the blocks into the NLP's sparse matrices; IPOPT gets them as
``grad_f``, ``jac_g`` and ``hess_lag``. Same NLP, same iterates, same solution as the SX formulation.

The shared library is cached in a user cache directory (:func:`cache_dir`) under a hash of the model
(:func:`model_key`: ``nx``, ``nu`` and every parameter), of the generated source (the scaling), the flags and the
CasADi version, so two models never share a library: it is compiled once per machine and model, never into the
package. Without a C compiler, or if the build fails, :func:`compiled_nlp` returns None (with a note on stderr)
and the caller keeps the SX formulation.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from cartpole._files import atomic_write
from cartpole.models import CartPoleModel
from cartpole.ocp.hermite_simpson import hs_interval_function, simpson_effort_terms

#: Flags for the C compiler; -O2 is as fast as -O3 here and compiles quicker.
CFLAGS = ("-O2", "-fPIC", "-shared")
#: Generated C longer than this (characters) is compiled with :data:`LARGE_CFLAGS`: gcc's optimiser is superlinear
#: in the size of one function and the interval Hessian grows fast with the number of poles. Measured (gcc, one
#: core): one pole 0.16 MB, -O2 2.4 s; two poles 1.1 MB, -O2 43 s, -O1 20 s, -O0 1.3 s (solves at -O0 still 3.4x
#: faster than the SX virtual machine, at -O1 8x); three poles 5.2 MB, -O1 340 s, -O0 6 s.
LARGE_SOURCE = 400_000
#: Flags for large generated sources (see :data:`LARGE_SOURCE`).
LARGE_CFLAGS = ("-O0", "-fPIC", "-shared")
_LIB_VERSION = "hs-interval-v3"  # bump when the generated functions change meaning


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


def cache_dir() -> Path:
    """``$CARTPOLE_CACHE_DIR``, else ``$XDG_CACHE_HOME/cartpole``, else ``~/.cache/cartpole``."""
    env = os.environ.get("CARTPOLE_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "cartpole"


def _cflags(src: str) -> tuple:
    """Compiler flags for generated C ``src``: ``$CARTPOLE_CFLAGS`` (e.g. ``-O2`` to optimise a large model once
    and for all) with ``-fPIC -shared``, else :data:`CFLAGS` or, above :data:`LARGE_SOURCE`, :data:`LARGE_CFLAGS`."""
    env = os.environ.get("CARTPOLE_CFLAGS")
    if env:
        return (*env.split(), "-fPIC", "-shared")
    return CFLAGS if len(src) < LARGE_SOURCE else LARGE_CFLAGS


def _compiler() -> str | None:
    cc = os.environ.get("CC") or "gcc"
    return shutil.which(cc) or shutil.which("cc")


def _digest(obj, h) -> None:
    """Feed a canonical, exact serialisation of ``obj`` (dataclasses, arrays, numbers, strings, sequences) to ``h``."""
    if dataclasses.is_dataclass(obj):
        h.update(type(obj).__name__.encode())
        for fld in dataclasses.fields(obj):
            h.update(fld.name.encode())
            _digest(getattr(obj, fld.name), h)
    elif isinstance(obj, np.ndarray):
        arr = np.ascontiguousarray(obj)
        h.update(f"{arr.dtype.str}{arr.shape}".encode() + arr.tobytes())
    elif isinstance(obj, (tuple, list)):
        h.update(f"[{len(obj)}".encode())
        for item in obj:
            _digest(item, h)
    else:
        h.update(f"{type(obj).__name__}:{obj!r};".encode())  # repr of a float is exact


def model_key(model: CartPoleModel | ca.Function) -> str:
    """Hex digest of what makes a model's interval functions: ``nx``, ``nu`` and every parameter it was built from
    (all joints, bodies, actuators, gravity, integrator...; not the MJCF's path). For a bare CasADi Function:
    its sizes and serialised expression graph."""
    h = hashlib.sha256()
    if isinstance(model, ca.Function):
        h.update(f"f{model.size1_in(0)}x{model.size1_in(1)}:".encode() + model.serialize().encode())
    else:
        h.update(f"model{model.nx}x{model.nu}:".encode())
        params = dataclasses.replace(model.params, mjcf="")
        _digest(params, h)
    return h.hexdigest()


def interval_functions(f: ca.Function, sx: np.ndarray, su, eff_scale: float) -> list[ca.Function]:
    """SX functions of one Hermite-Simpson interval in scaled variables ``v = (x_k, u_k, x_k+1, u_k+1) / scale``.

    Parameters
    ----------
    f : casadi.Function
        Continuous dynamics ``x_dot = f(x (nx,), u (nu,))`` (sizes read from it).
    sx : (nx,) array
        State scales; ``su`` (nu,) the ctrl scales (a scalar for nu = 1); ``eff_scale`` divides the effort
        (ctrl^2 s).

    Returns
    -------
    list of casadi.Function
        With ``nv = 2 (nx + nu)``: ``hs_d(v, h) -> d`` (nx,) the defect divided by ``sx``; ``hs_e(v, h) -> e``
        the interval's effort ``integral u'u dt / eff_scale``; ``hs_dj(v, h) -> (d, dd/dv (nx, nv))``;
        ``hs_eg(v, h) -> (e, de/dv (nv,))``; ``hs_hl(v, h, lam (nx,), sigma) ->`` upper triangle
        (nv (nv + 1) / 2,) column-major of the Hessian of ``sigma e + lam' d`` in ``v``; and ``jac_hs_d``,
        ``jac_hs_e``, the Jacobians CasADi looks up by name when it differentiates an external function (it
        does once, for the final multipliers).
    """
    nx, nu = f.size1_in(0), f.size1_in(1)
    nz = nx + nu
    nv = 2 * nz
    su = ca.DM(np.broadcast_to(np.asarray(su, float), (nu,)))
    v = ca.SX.sym("v", nv)
    h = ca.SX.sym("h")
    lam = ca.SX.sym("lam", nx)
    sigma = ca.SX.sym("sigma")
    xk, uk = v[0:nx] * ca.DM(sx), v[nx:nz] * su
    xk1, uk1 = v[nz:nz + nx] * ca.DM(sx), v[nz + nx:nv] * su
    defect, _ = hs_interval_function(f)(xk, uk, xk1, uk1, f(xk, uk), f(xk1, uk1), h)
    d = defect / ca.DM(sx)
    e = h / 6 * ca.sum1(simpson_effort_terms(uk, uk1)) / eff_scale
    H = ca.densify(ca.hessian(sigma * e + ca.dot(lam, d), v)[0])
    hess_triu = ca.vertcat(*[H[a, b] for b in range(nv) for a in range(b + 1)])
    hs_d = ca.Function("hs_d", [v, h], [d])
    hs_e = ca.Function("hs_e", [v, h], [e])
    return [
        hs_d,
        hs_e,
        ca.Function("hs_dj", [v, h], [d, ca.densify(ca.jacobian(d, v))]),
        ca.Function("hs_eg", [v, h], [e, ca.densify(ca.gradient(e, v))]),
        ca.Function("hs_hl", [v, h, lam, sigma], [hess_triu]),
        hs_d.jacobian(),  # named jac_hs_d
        hs_e.jacobian(),
    ]


def _build_library(funcs: list[ca.Function], model_digest: str = "") -> tuple[str, bool]:
    """C source of ``funcs`` compiled to a cached shared library; returns (path, compiled_now).

    The library's name is a hash of ``model_digest`` (:func:`model_key`), the source, the flags (:func:`_cflags`)
    and the CasADi version.
    """
    gen = ca.CodeGenerator("hs_interval.c", {"with_header": False, "casadi_real": "double"})
    for fn in funcs:
        gen.add(fn)
    src = gen.dump()
    flags = _cflags(src)
    key = hashlib.sha256((_LIB_VERSION + model_digest + " ".join(flags) + ca.__version__ + src).encode()
                         ).hexdigest()[:20]
    target = cache_dir()
    lib = target / f"hs_interval_{key}.so"
    if lib.exists():
        return str(lib), False
    cc = _compiler()
    if cc is None:
        raise RuntimeError("no C compiler (gcc or cc) on PATH")
    target.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="cartpole-cc-") as tmp:
        c_file = Path(tmp) / f"hs_interval_{key}.c"
        c_file.write_text(src)
        out = Path(tmp) / lib.name
        proc = subprocess.run([cc, *flags, str(c_file), "-o", str(out), "-lm"], capture_output=True, text=True,
                              timeout=120)
        if proc.returncode != 0:
            last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
            raise RuntimeError(f"{Path(cc).name} failed: {last}")
        # atomic: a concurrent process sees the whole library or none
        atomic_write(lib, lambda fh: fh.write(out.read_bytes()))
    return str(lib), True


def _assemble(ext: dict[str, ca.Function], N: int, nx: int, nu: int) -> tuple[dict, dict]:
    """The NLP (MX) and IPOPT's derivative Functions from the mapped interval functions."""
    nz = nx + nu  # one knot
    nv = 2 * nz  # one interval's variables
    ntri = nv * (nv + 1) // 2
    n = nz * (N + 1)
    w = ca.MX.sym("x", n)
    p = ca.MX.sym("p", 1)
    h = p[0] / N
    Z = ca.reshape(w, nz, N + 1)
    V = ca.vertcat(Z[:, :-1], Z[:, 1:])  # (nv, N): interval k's variables in column k
    g = ca.vec(ext["hs_d"].map(N)(V, h))
    fobj = ca.sum2(ext["hs_e"].map(N)(V, h))
    nlp = {"x": w, "p": p, "f": fobj, "g": g}

    D, JD = ext["hs_dj"].map(N)(V, h)  # (nx, N), (nx, nv N)
    E, GE = ext["hs_eg"].map(N)(V, h)  # (1, N), (nv, N)
    # gradient of f: knot k's nz entries get the right half of interval k-1 and the left half of interval k
    grad_f = ca.vec(ca.horzcat(GE[:nz, :], ca.DM.zeros(nz, 1)) + ca.horzcat(ca.DM.zeros(nz, 1), GE[nz:, :]))

    # Jacobian of g: interval k's dense (nx x nv) block at rows nx k.., cols nz k.. (blocks do not overlap)
    k, b, a = np.meshgrid(np.arange(N), np.arange(nv), np.arange(nx), indexing="ij")
    rows, cols, src = (nx * k + a).ravel(), (nz * k + b).ravel(), (nx * nv * k + nx * b + a).ravel()
    order = np.lexsort((rows, cols))  # CasADi's compressed-column order: by column, then row
    sp_j = ca.Sparsity.triplet(nx * N, n, rows.tolist(), cols.tolist())
    jac = ca.MX(sp_j, ca.vec(JD)[src[order].tolist()])

    # Hessian (upper triangle): the interval blocks summed where they overlap on the shared knots
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", nx * N)
    HB = ext["hs_hl"].map(N)(V, h, ca.reshape(lam_g, nx, N), lam_f)  # (ntri, N)
    tri_a, tri_b = zip(*[(a_, b_) for b_ in range(nv) for a_ in range(b_ + 1)])
    tri_a, tri_b = np.array(tri_a), np.array(tri_b)
    h_rows = (nz * np.arange(N)[:, None] + tri_a[None, :]).ravel()
    h_cols = (nz * np.arange(N)[:, None] + tri_b[None, :]).ravel()
    sp_h = ca.Sparsity.triplet(n, n, h_rows.tolist(), h_cols.tolist())  # duplicates merged
    # nonzero index in sp_h of each triplet, then one constant sparse matrix that sums the blocks into it
    nz_idx = np.full((n, n), -1, dtype=np.int64)
    colind, row = np.array(sp_h.colind()), np.array(sp_h.row())
    for c in range(n):
        nz_idx[row[colind[c]:colind[c + 1]], c] = np.arange(colind[c], colind[c + 1])
    dst = nz_idx[h_rows, h_cols]
    scatter = ca.DM(ca.Sparsity.triplet(sp_h.nnz(), ntri * N, dst.tolist(), list(range(ntri * N))), 1.0)
    hess = ca.MX(sp_h, ca.mtimes(scatter, ca.vec(HB)))

    options = {
        "grad_f": ca.Function("hs_nlp_grad_f", [w, p], [fobj, grad_f], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("hs_nlp_jac_g", [w, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("hs_nlp_hess_l", [w, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"],
                                ["triu_hess_gamma_x_x"]),
    }
    return nlp, options


def compiled_nlp(model: CartPoleModel | ca.Function, N: int, sx: np.ndarray, su, eff_scale: float
                 ) -> CompiledNLP | None:
    """The fixed-time effort NLP on compiled interval functions, or None where C cannot be built.

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
        The objective is ``integral u'u dt / eff_scale``.

    Returns
    -------
    CompiledNLP or None
        None (with a note on stderr) when ``CARTPOLE_NO_COMPILE`` is set, there is no C compiler,
        or the build or load fails: the caller then uses the SX formulation, which gives the same numbers.
    """
    if os.environ.get("CARTPOLE_NO_COMPILE"):
        return None
    f = model if isinstance(model, ca.Function) else model.f
    nx, nu = f.size1_in(0), f.size1_in(1)
    try:
        funcs = interval_functions(f, np.asarray(sx, float), np.asarray(su, float), float(eff_scale))
        lib, now = _build_library(funcs, model_key(model))
        ext = {name: ca.external(name, lib) for name in ("hs_d", "hs_e", "hs_dj", "hs_eg", "hs_hl")}
    except Exception as exc:  # noqa: BLE001 - any failure here means: keep the SX path
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[-1]
        print(f"cartpole: compiled collocation functions unavailable ({reason}); using the slower SX "
              "formulation (same results).", file=sys.stderr)
        return None
    nlp, options = _assemble(ext, int(N), nx, nu)
    return CompiledNLP(nlp=nlp, options=options, library=lib, compiled_now=now)
