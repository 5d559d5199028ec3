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
import functools
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

#: Flags for the C compiler: the generated functions are straight-line arithmetic that gcc vectorises for the
#: machine's own instruction set (one pole, N = 100 intervals mapped: exact Hessian blocks 0.148 ms at -O2, 0.116 at
#: -O3 -march=native; defect Jacobians 0.066 and 0.039 ms; same compile time, 1.9 s). A library is keyed by the CPU
#: (:func:`cpu_key`), so a cache shared between machines stays correct; where the compiler refuses
#: ``-march=native`` the library is built with :data:`PORTABLE_CFLAGS`.
CFLAGS = ("-O3", "-march=native", "-fPIC", "-shared")
#: The fallback of :data:`CFLAGS`.
PORTABLE_CFLAGS = ("-O2", "-fPIC", "-shared")
#: Generated C longer than this (characters) is compiled with :data:`LARGE_CFLAGS`: gcc's optimiser is superlinear
#: in the size of one function and the interval Hessian grows fast with the number of poles. Measured (gcc, one
#: core): one pole 0.16 MB, -O2 2.4 s; two poles 1.1 MB, -O2 43 s, -O1 20 s, -O0 1.3 s (solves at -O0 still 3.4x
#: faster than the SX virtual machine, at -O1 8x); three poles 5.2 MB, -O1 340 s, -O0 6 s.
LARGE_SOURCE = 400_000
#: Flags for large generated sources (see :data:`LARGE_SOURCE`).
LARGE_CFLAGS = ("-O0", "-fPIC", "-shared")
_LIB_VERSION = "hs-interval-v5"  # bump when the generated functions change meaning


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


@functools.lru_cache(maxsize=None)
def cpu_key() -> str:
    """The machine's architecture, CPU model and feature flags (Linux ``/proc/cpuinfo``, its first processor),
    hashed: what code compiled with ``-march=native`` depends on. Read once per process."""
    import platform

    h = hashlib.sha256(platform.machine().encode())
    try:
        seen = set()
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if not line.strip() and seen:  # the end of the first processor's block
                break
            name = line.split(":", 1)[0].strip()
            if name in ("model name", "flags", "Features", "CPU part") and name not in seen:
                seen.add(name)
                h.update(line.encode())
    except OSError:
        h.update(platform.processor().encode())
    return h.hexdigest()[:16]


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


def recipe_key(f: ca.Function, sx, su, running: ca.Function | None = None) -> str:
    """Hex digest of everything the interval functions are generated from: ``f``'s serialised expression graph,
    the scales ``sx``, ``su``, the running cost's graph (if any), :data:`_LIB_VERSION`, the CasADi version and
    ``$CARTPOLE_CFLAGS``. A library found under it is used without generating its C source again."""
    h = hashlib.sha256()
    h.update((_LIB_VERSION + ca.__version__ + os.environ.get("CARTPOLE_CFLAGS", "")).encode())
    h.update(f.serialize().encode())
    _digest(np.asarray(sx, float), h)
    _digest(np.asarray(su, float).ravel(), h)
    h.update(b"running:" + (running.serialize().encode() if running is not None else b"-"))
    return h.hexdigest()


def _build_library(funcs, model_digest: str = "", recipe: str | None = None, *,
                   cflags: tuple | None = None) -> tuple[str, bool]:
    """C source of ``funcs`` compiled to a cached shared library; returns (path, compiled_now).

    ``funcs`` is a list of Functions or a callable returning it. Without ``recipe`` the library's name is a hash
    of ``model_digest`` (:func:`model_key`), the source, the flags (:func:`_cflags`) and the CasADi version; with
    ``recipe`` (:func:`recipe_key`) a hash of ``model_digest`` and ``recipe``, looked up before any source is
    generated (generating the three-pole cart's source takes about half a second); both with :func:`cpu_key`.
    ``cflags``: the compiler flags (``-fPIC -shared`` added) instead of :func:`_cflags`'s choice, unless
    ``$CARTPOLE_CFLAGS`` is set. Flags with ``-march=native`` that the compiler refuses are retried as
    :data:`PORTABLE_CFLAGS`.
    """
    target = cache_dir()
    cpu = cpu_key()
    if recipe is not None:
        key = "r" + hashlib.sha256((model_digest + recipe + cpu).encode()).hexdigest()[:20]
        lib = target / f"hs_interval_{key}.so"
        if lib.exists():
            return str(lib), False
    gen = ca.CodeGenerator("hs_interval.c", {"with_header": False, "casadi_real": "double"})
    for fn in (funcs() if callable(funcs) else funcs):
        gen.add(fn)
    src = gen.dump()
    if cflags is not None and not os.environ.get("CARTPOLE_CFLAGS"):
        flags = (*cflags, "-fPIC", "-shared")
    else:
        flags = _cflags(src)
    if recipe is None:
        key = hashlib.sha256((_LIB_VERSION + model_digest + " ".join(flags) + ca.__version__ + cpu + src).encode()
                             ).hexdigest()[:20]
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
        if proc.returncode != 0 and "-march=native" in flags:
            proc = subprocess.run([cc, *PORTABLE_CFLAGS, str(c_file), "-o", str(out), "-lm"], capture_output=True,
                                  text=True, timeout=120)
        if proc.returncode != 0:
            last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
            raise RuntimeError(f"{Path(cc).name} failed: {last}")
        # atomic: a concurrent process sees the whole library or none
        atomic_write(lib, lambda fh: fh.write(out.read_bytes()))
    return str(lib), True


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


_LOADED: dict[str, dict[str, ca.Function]] = {}


def _load(lib: str) -> dict[str, ca.Function]:
    """The interval functions of the shared library ``lib`` (loaded once per process)."""
    if lib not in _LOADED:
        _LOADED[lib] = {name: ca.external(name, lib) for name in ("hs_d", "hs_e", "hs_dj", "hs_eg", "hs_hl")}
    return _LOADED[lib]


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
    if os.environ.get("CARTPOLE_NO_COMPILE"):
        return None
    f = model if isinstance(model, ca.Function) else model.f
    nx, nu = f.size1_in(0), f.size1_in(1)
    try:
        sx, su = np.asarray(sx, float), np.asarray(su, float)
        recipe = recipe_key(f, sx, su, running)
        lib, now = _build_library(lambda: interval_functions(f, sx, su, 1.0, running=running), model_key(model),
                                  recipe=recipe)
        ext = _load(lib)
    except Exception as exc:  # noqa: BLE001 - any failure here means: keep the SX path
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[-1]
        print(f"cartpole: compiled collocation functions unavailable ({reason}); using the slower SX "
              "formulation (same results).", file=sys.stderr)
        return None
    nlp, options = _assemble(ext, int(N), nx, nu, free_time=free_time, cost_weight=1.0 / float(eff_scale),
                             time_weight=float(time_weight) if free_time else 0.0)
    return CompiledNLP(nlp=nlp, options=options, library=lib, compiled_now=now)


class _Buffered:
    """A CasADi Function evaluated on numpy buffers (no DM conversions): call with C-contiguous float arrays laid
    out as CasADi's column-major inputs; returns its outputs as flat arrays, overwritten by the next call."""

    def __init__(self, fun: ca.Function):
        self._buf, self._eval = fun.buffer()
        self._n_in = fun.n_in()
        self.out = [np.zeros(fun.nnz_out(i)) for i in range(fun.n_out())]
        for i, o in enumerate(self.out):
            self._buf.set_res(i, memoryview(o))

    def __call__(self, *args):
        keep = [np.ascontiguousarray(a, dtype=float) for a in args]
        for i, a in enumerate(keep):
            self._buf.set_arg(i, memoryview(a))
        self._eval()
        return self.out
