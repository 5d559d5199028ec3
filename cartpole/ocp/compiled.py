"""Hermite-Simpson interval functions compiled to C, for the fixed-time effort swing-up solved by IPOPT.

Why: with ``expand=True`` the NLP is one flat SX graph that CasADi's virtual machine interprets; at N = 100
that costs about 30 of a solve's 50 ms, most of it the Hessian of the Lagrangian. The NLP is N copies of one
small interval function of ten scaled variables ``v = (z_k, z_k+1)``, ``z = (x, u)``. So only that interval's
pieces are compiled: its defect and effort with their exact first derivatives, and the Hessian block of its
share of the Lagrangian (SX, derived by CasADi). Their C source is small and compiles in about a second;
code-generating the assembled NLP functions instead kept gcc busy for minutes at 2.5 GB. The NLP's own
functions (objective, constraints, gradient, constraint Jacobian, Lagrangian Hessian) are small MX graphs
that ``map`` the compiled pieces over the N intervals and scatter the blocks into the NLP's sparse matrices;
IPOPT gets them as ``grad_f``, ``jac_g`` and ``hess_lag``. Same NLP, same iterates, same solution as the SX
formulation.

The shared library is cached in a user cache directory (:func:`cache_dir`) under a hash of its generated
source, so the model's parameters, the scaling and the CasADi version are all in the key: it is compiled once
per machine and model, never into the package. Without a C compiler, or if the build fails,
:func:`compiled_nlp` returns None (with a note on stderr) and the caller keeps the SX formulation.
"""
from __future__ import annotations

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
from cartpole.ocp.hermite_simpson import hs_interval_function, simpson_effort_terms

#: Flags for the C compiler; -O2 is as fast as -O3 here and compiles quicker.
CFLAGS = ("-O2", "-fPIC", "-shared")
_LIB_VERSION = "hs-interval-v2"  # bump when the generated functions change meaning


@dataclass(frozen=True)
class CompiledNLP:
    """The NLP and its derivative functions built on the compiled interval functions.

    Attributes
    ----------
    nlp : dict
        ``{"x", "p", "f", "g"}`` for ``casadi.nlpsol`` (MX; ``x`` is ``[z_0, ..., z_N]`` (5 (N+1),) scaled,
        ``p`` the duration T in s).
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


def _compiler() -> str | None:
    cc = os.environ.get("CC") or "gcc"
    return shutil.which(cc) or shutil.which("cc")


def interval_functions(f: ca.Function, sx: np.ndarray, su: float, eff_scale: float) -> list[ca.Function]:
    """SX functions of one Hermite-Simpson interval in scaled variables ``v = (x_k, u_k, x_k+1, u_k+1) / scale``.

    Parameters
    ----------
    f : casadi.Function
        Continuous dynamics ``x_dot = f(x (4,), u (1,))``.
    sx : (4,) array
        State scales; ``su`` the ctrl scale; ``eff_scale`` divides the effort (ctrl^2 s).

    Returns
    -------
    list of casadi.Function
        ``hs_d(v, h) -> d`` (4,) the defect divided by ``sx``; ``hs_e(v, h) -> e`` the interval's effort;
        ``hs_dj(v, h) -> (d, dd/dv (4, 10))``; ``hs_eg(v, h) -> (e, de/dv (10,))``;
        ``hs_hl(v, h, lam (4,), sigma) -> `` upper triangle (55,) column-major of the Hessian of
        ``sigma e + lam' d`` in ``v``; and ``jac_hs_d``, ``jac_hs_e``, the Jacobians CasADi looks up by name
        when it differentiates an external function (it does once, for the final multipliers).
    """
    v = ca.SX.sym("v", 10)
    h = ca.SX.sym("h")
    lam = ca.SX.sym("lam", 4)
    sigma = ca.SX.sym("sigma")
    xk, uk = v[0:4] * ca.DM(sx), v[4] * su
    xk1, uk1 = v[5:9] * ca.DM(sx), v[9] * su
    defect, _ = hs_interval_function(f)(xk, uk, xk1, uk1, f(xk, uk), f(xk1, uk1), h)
    d = defect / ca.DM(sx)
    e = h / 6 * simpson_effort_terms(uk, uk1) / eff_scale
    H = ca.densify(ca.hessian(sigma * e + ca.dot(lam, d), v)[0])
    hess_triu = ca.vertcat(*[H[a, b] for b in range(10) for a in range(b + 1)])
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


def _build_library(funcs: list[ca.Function]) -> tuple[str, bool]:
    """C source of ``funcs`` compiled to a cached shared library; returns (path, compiled_now)."""
    gen = ca.CodeGenerator("hs_interval.c", {"with_header": False, "casadi_real": "double"})
    for fn in funcs:
        gen.add(fn)
    src = gen.dump()
    key = hashlib.sha256((_LIB_VERSION + " ".join(CFLAGS) + ca.__version__ + src).encode()).hexdigest()[:20]
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
        proc = subprocess.run([cc, *CFLAGS, str(c_file), "-o", str(out), "-lm"], capture_output=True, text=True,
                              timeout=120)
        if proc.returncode != 0:
            last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
            raise RuntimeError(f"{Path(cc).name} failed: {last}")
        # atomic: a concurrent process sees the whole library or none
        atomic_write(lib, lambda fh: fh.write(out.read_bytes()))
    return str(lib), True


def _assemble(ext: dict[str, ca.Function], N: int) -> tuple[dict, dict]:
    """The NLP (MX) and IPOPT's derivative Functions from the mapped interval functions."""
    n = 5 * (N + 1)
    w = ca.MX.sym("x", n)
    p = ca.MX.sym("p", 1)
    h = p[0] / N
    Z = ca.reshape(w, 5, N + 1)
    V = ca.vertcat(Z[:, :-1], Z[:, 1:])  # (10, N): interval k's variables in column k
    g = ca.vec(ext["hs_d"].map(N)(V, h))
    fobj = ca.sum2(ext["hs_e"].map(N)(V, h))
    nlp = {"x": w, "p": p, "f": fobj, "g": g}

    D, JD = ext["hs_dj"].map(N)(V, h)  # (4, N), (4, 10 N)
    E, GE = ext["hs_eg"].map(N)(V, h)  # (1, N), (10, N)
    # gradient of f: knot k's 5 entries get the right half of interval k-1 and the left half of interval k
    grad_f = ca.vec(ca.horzcat(GE[:5, :], ca.DM.zeros(5, 1)) + ca.horzcat(ca.DM.zeros(5, 1), GE[5:, :]))

    # Jacobian of g: interval k's dense (4 x 10) block at rows 4k.., cols 5k.. (blocks do not overlap)
    k, b, a = np.meshgrid(np.arange(N), np.arange(10), np.arange(4), indexing="ij")
    rows, cols, src = (4 * k + a).ravel(), (5 * k + b).ravel(), (40 * k + 4 * b + a).ravel()
    order = np.lexsort((rows, cols))  # CasADi's compressed-column order: by column, then row
    sp_j = ca.Sparsity.triplet(4 * N, n, rows.tolist(), cols.tolist())
    jac = ca.MX(sp_j, ca.vec(JD)[src[order].tolist()])

    # Hessian (upper triangle): the interval blocks summed where they overlap on the shared knots
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", 4 * N)
    HB = ext["hs_hl"].map(N)(V, h, ca.reshape(lam_g, 4, N), lam_f)  # (55, N)
    tri_a, tri_b = zip(*[(a_, b_) for b_ in range(10) for a_ in range(b_ + 1)])
    tri_a, tri_b = np.array(tri_a), np.array(tri_b)
    h_rows = (5 * np.arange(N)[:, None] + tri_a[None, :]).ravel()
    h_cols = (5 * np.arange(N)[:, None] + tri_b[None, :]).ravel()
    sp_h = ca.Sparsity.triplet(n, n, h_rows.tolist(), h_cols.tolist())  # duplicates merged
    # nonzero index in sp_h of each triplet, then one constant sparse matrix that sums the blocks into it
    nz = np.full((n, n), -1, dtype=np.int64)
    colind, row = np.array(sp_h.colind()), np.array(sp_h.row())
    for c in range(n):
        nz[row[colind[c]:colind[c + 1]], c] = np.arange(colind[c], colind[c + 1])
    dst = nz[h_rows, h_cols]
    scatter = ca.DM(ca.Sparsity.triplet(sp_h.nnz(), 55 * N, dst.tolist(), list(range(55 * N))), 1.0)
    hess = ca.MX(sp_h, ca.mtimes(scatter, ca.vec(HB)))

    options = {
        "grad_f": ca.Function("hs_nlp_grad_f", [w, p], [fobj, grad_f], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("hs_nlp_jac_g", [w, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("hs_nlp_hess_l", [w, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"],
                                ["triu_hess_gamma_x_x"]),
    }
    return nlp, options


def compiled_nlp(f: ca.Function, N: int, sx: np.ndarray, su: float, eff_scale: float) -> CompiledNLP | None:
    """The fixed-time effort swing-up NLP on compiled interval functions, or None where C cannot be built.

    Parameters
    ----------
    f : casadi.Function
        Continuous dynamics ``f(x (4,), u (1,)) -> x_dot (4,)``.
    N : int
        Number of intervals.
    sx : (4,) array
        State scales (the NLP's variables are state / scale); ``su`` the ctrl scale.
    eff_scale : float
        The objective is ``integral u^2 dt / eff_scale``.

    Returns
    -------
    CompiledNLP or None
        None (with a note on stderr) when ``CARTPOLE_NO_COMPILE`` is set, there is no C compiler,
        or the build or load fails: the caller then uses the SX formulation, which gives the same numbers.
    """
    if os.environ.get("CARTPOLE_NO_COMPILE"):
        return None
    try:
        funcs = interval_functions(f, np.asarray(sx, float), float(su), float(eff_scale))
        lib, now = _build_library(funcs)
        ext = {name: ca.external(name, lib) for name in ("hs_d", "hs_e", "hs_dj", "hs_eg", "hs_hl")}
    except Exception as exc:  # noqa: BLE001 - any failure here means: keep the SX path
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[-1]
        print(f"cartpole: compiled collocation functions unavailable ({reason}); using the slower SX "
              "formulation (same results).", file=sys.stderr)
        return None
    nlp, options = _assemble(ext, int(N))
    return CompiledNLP(nlp=nlp, options=options, library=lib, compiled_now=now)
