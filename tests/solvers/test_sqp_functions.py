"""The SQP's QP functions (cartpole.solvers.sqp_functions) against independent numpy references.

Layouts: every input and output is numpy's C-order block array, which is CasADi's column-major one with each block
transposed (J (N, nx, nv) is CasADi's (nv, nx N) of J_k'); outputs are read back as (N, rows, cols) the way
:meth:`cartpole.solvers.sqp.CollocationSQP._qp_step` and ``_daqp_step`` read them.
"""
import os
import resource
import subprocess
import sys

import numpy as np
import pytest

from cartpole.solvers import sqp_functions
from cartpole.ocp.bounds import OCPError
from cartpole.codegen import Buffered

REG = 1e-4


def _call(fn, *arrays):
    """``fn`` on numpy buffers as the SQP calls it; copies of the flat outputs (every output is dense: see
    test_every_output_is_dense_so_flat_buffers_reshape)."""
    return [o.copy() for o in Buffered(fn)(*arrays)]


def _data(nx, nu, N, seed, *, indefinite=False):
    """Seeded interval data: J (N, nx, nv) with J^b_x the identity plus small noise, H (N, nv, nv) symmetric
    (diagonally dominant positive definite, or indefinite), G (N, nv), D (N, nx)."""
    rng = np.random.default_rng(seed)
    nz = nx + nu
    nv = 2 * nz
    J = 0.3 * rng.standard_normal((N, nx, nv))
    J[:, :, nz:nz + nx] = np.eye(nx) + 0.1 * rng.standard_normal((N, nx, nx))
    S = rng.standard_normal((N, nv, nv))
    S = 0.5 * (S + S.transpose(0, 2, 1))
    H = 3.0 * S if indefinite else 5.0 * np.eye(nv) + 0.05 * S
    G = rng.standard_normal((N, nv))
    D = 0.1 * rng.standard_normal((N, nx))
    return J, H, G, D


def _stages(fns, nx, nu, N, J, H, G, D, lm):
    nz = nx + nu
    ny = nz + nu
    T, ct, Hy, gy, M = _call(fns[0], J, H, G, D, float(lm))
    return T.reshape(N, nz, ny), ct.reshape(N, nx), Hy.reshape(N, ny, ny), gy.reshape(N, ny), M.reshape(N, nx, nx)


def _stages_reference(nx, nu, J, H, G, D, lm):
    """M = inv(J^b_x), T = [[-M J^a, -M J^b_u], [0, I]], ct = -M d, Hy = P' H P + lm I, gy = P' (H_x ct + g)."""
    nz = nx + nu
    ny = nz + nu
    out = {"T": [], "ct": [], "Hy": [], "gy": [], "M": []}
    for Jk, Hk, gk, dk in zip(J, H, G, D):
        Ja, Jbx, Jbu = Jk[:, :nz], Jk[:, nz:nz + nx], Jk[:, nz + nx:]
        M = np.linalg.inv(Jbx)
        T = np.block([[-M @ Ja, -M @ Jbu], [np.zeros((nu, nz)), np.eye(nu)]])
        ct = -M @ dk
        P = np.vstack([np.hstack([np.eye(nz), np.zeros((nz, nu))]), T])
        out["T"].append(T)
        out["ct"].append(ct)
        out["Hy"].append(P.T @ Hk @ P + lm * np.eye(ny))
        out["gy"].append(P.T @ (Hk[:, nz:nz + nx] @ ct + gk))
        out["M"].append(M)
    return {k: np.array(v) for k, v in out.items()}


def _condensed_reference(nx, nu, T, ct, Hy, gy):
    """Brute-force dense condensing: G_k, g_k (k = 0..N) by the forward recursion, Hc = sum Y_k' Hy_k Y_k,
    fc = sum Y_k' (Hy_k c_k + gy_k)."""
    N = T.shape[0]
    nc = (N + 1) * nu
    Gk, gk = np.zeros((nx, nc)), np.zeros(nx)
    Gs, gs = [Gk], [gk]
    Hc, fc = np.zeros((nc, nc)), np.zeros(nc)
    for k in range(N):
        E = np.zeros((2 * nu, nc))
        E[:, k * nu:(k + 2) * nu] = np.eye(2 * nu)
        Y = np.vstack([Gk, E])
        c = np.r_[gk, np.zeros(2 * nu)]
        Hc += Y.T @ Hy[k] @ Y
        fc += Y.T @ (Hy[k] @ c + gy[k])
        A, Bw = T[k][:nx, :nx], T[k][:nx, nx:]
        Gk, gk = A @ Gk + Bw @ E, A @ gk + ct[k]
        Gs.append(Gk)
        gs.append(gk)
    return Hc, fc, np.array(Gs), np.array(gs)


def _assemble(nx, nu, N, outs):
    """Hc, fc and GT (N, nx, nc + 1) from sqp_condense's outputs, placed as the SQP places them."""
    return sqp_functions.assemble_condensed(outs, N, nx, nu)


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


SIZES = [(4, 1, 8), (6, 2, 6)]


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_stage_form_matches_numpy_reference(nx, nu, N):
    fns = sqp_functions.qp_functions(nx, nu, N, REG)
    J, H, G, D = _data(nx, nu, N, 1)
    lm = 0.01
    T, ct, Hy, gy, M = _stages(fns, nx, nu, N, J, H, G, D, lm)
    ref = _stages_reference(nx, nu, J, H, G, D, lm)
    for name, got in (("T", T), ("ct", ct), ("Hy", Hy), ("gy", gy), ("M", M)):
        assert _rel(got, ref[name]) < 1e-12, name


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_convexification_makes_indefinite_condensed_hessian_positive_definite(nx, nu, N):
    fns = sqp_functions.qp_functions(nx, nu, N, REG)
    J, H, G, D = _data(nx, nu, N, 2, indefinite=True)
    T, ct, Hy, gy, M = _stages(fns, nx, nu, N, J, H, G, D, 0.0)
    ref = _stages_reference(nx, nu, J, H, G, D, 0.0)
    raw, _, _, _ = _condensed_reference(nx, nu, T, ct, ref["Hy"], ref["gy"])
    assert np.linalg.eigvalsh(raw).min() < 0  # the test data really needs convexifying
    Hc, _, _ = _assemble(nx, nu, N, _call(fns[1], T, ct, Hy, gy))
    assert np.linalg.eigvalsh(0.5 * (Hc + Hc.T)).min() > 0
    # only the diagonal of the free input blocks moves: du_0 of the first stage and every stage's w = du_k+1
    nz = nx + nu
    shift = Hy - ref["Hy"]
    off = shift - np.array([np.diag(np.diag(s)) for s in shift])
    assert np.abs(off).max() < 1e-10 * np.abs(ref["Hy"]).max()
    assert np.abs(shift[:, :nx, :nx]).max() == pytest.approx(0, abs=1e-10 * np.abs(ref["Hy"]).max())
    assert np.abs(shift[1:, nx:nz, nx:nz]).max() == pytest.approx(0, abs=1e-10 * np.abs(ref["Hy"]).max())
    assert np.all(np.diagonal(shift, axis1=1, axis2=2) > -1e-10)
    assert np.abs(shift).max() > 0


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_positive_definite_hessian_is_left_unchanged(nx, nu, N):
    fns = sqp_functions.qp_functions(nx, nu, N, REG)
    J, H, G, D = _data(nx, nu, N, 3)
    _, _, Hy, _, _ = _stages(fns, nx, nu, N, J, H, G, D, 0.0)
    assert _rel(Hy, _stages_reference(nx, nu, J, H, G, D, 0.0)["Hy"]) < 1e-12


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_condensing_matches_brute_force_dense_condensing(nx, nu, N):
    fns = sqp_functions.qp_functions(nx, nu, N, REG)
    J, H, G, D = _data(nx, nu, N, 4, indefinite=True)  # any stage data: the condensing is exact
    T, ct, Hy, gy, _ = _stages(fns, nx, nu, N, J, H, G, D, 0.0)
    Hc, fc, GT = _assemble(nx, nu, N, _call(fns[1], T, ct, Hy, gy))
    Hr, fr, Gr, gr = _condensed_reference(nx, nu, T, ct, Hy, gy)
    assert _rel(Hc, Hr) < 1e-10
    assert _rel(fc, fr) < 1e-10
    nc = (N + 1) * nu
    assert _rel(GT[:, :, :nc], Gr[1:]) < 1e-10
    assert _rel(GT[:, :, nc], gr[1:]) < 1e-10


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_multipliers_match_numpy_reference(nx, nu, N):
    fns = sqp_functions.qp_functions(nx, nu, N, REG)
    nz = nx + nu
    J, H, G, D = _data(nx, nu, N, 5)
    T, ct, Hy, gy, M = _stages(fns, nx, nu, N, J, H, G, D, 0.0)
    rng = np.random.default_rng(6)
    dZ, nbx = rng.standard_normal((N + 1, nz)), rng.standard_normal((N + 1, nx))
    (lam,) = _call(fns[2], dZ, nbx, Hy, gy, T, H, G, M)
    lam = lam.reshape(N, nx)
    r = np.array([(Hy[k] @ np.r_[dZ[k], dZ[k + 1, nx:]])[:nx] + gy[k, :nx] + nbx[k] for k in range(N)])
    m = np.zeros((N, nx))
    m[N - 1] = nbx[N]
    for k in range(N - 1, 0, -1):
        m[k - 1] = T[k][:nx, :nx].T @ m[k] + r[k]
    ref = np.array([-M[k].T @ (m[k] + (H[k] @ np.r_[dZ[k], dZ[k + 1]] + G[k])[nz:nz + nx]) for k in range(N)])
    assert _rel(lam, ref) < 1e-12


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_stationarity_is_the_largest_lagrangian_gradient_entry_of_the_free_knot_variables(nx, nu, N):
    fns = sqp_functions.qp_functions(nx, nu, N, REG)
    nz = nx + nu
    J, _, G, _ = _data(nx, nu, N, 8)
    rng = np.random.default_rng(9)
    lam, nb = rng.standard_normal((N, nx)), rng.standard_normal((N + 1, nz))
    (kkt,) = _call(fns[3], J, G, lam, nb)
    gr = nb.copy()
    for k in range(N):  # interval k's defect and cost touch knots k and k+1
        share = J[k].T @ lam[k] + G[k]
        gr[k] += share[:nz]
        gr[k + 1] += share[nz:]
    gr[0, :nx] = gr[N, :nx] = 0.0  # pinned
    assert abs(float(kkt[0]) - np.abs(gr).max()) <= 1e-12 * np.abs(gr).max()


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_condensed_step_and_multipliers_solve_the_original_qp(nx, nu, N):
    """End to end, as _daqp_step uses them: the condensed equality QP (dx_0 = 0, dx_N = 0) gives a step on the
    linearised defects, and sqp_multipliers' defect multipliers make the original QP's Lagrangian stationary."""
    fns = sqp_functions.qp_functions(nx, nu, N, REG)
    nz = nx + nu
    J, H, G, D = _data(nx, nu, N, 7)
    T, ct, Hy, gy, M = _stages(fns, nx, nu, N, J, H, G, D, 0.0)
    Hc, fc, GT = _assemble(nx, nu, N, _call(fns[1], T, ct, Hy, gy))
    nc = (N + 1) * nu
    Gs, gs = GT[:, :, :nc], GT[:, :, nc]
    K = np.block([[Hc, Gs[-1].T], [Gs[-1], np.zeros((nx, nx))]])
    sol = np.linalg.solve(K, -np.r_[fc, gs[-1]])
    v, nu_N = sol[:nc], sol[nc:]
    dZ = np.empty((N + 1, nz))
    dZ[:, nx:] = v.reshape(N + 1, nu)
    dZ[0, :nx] = 0.0
    dZ[1:, :nx] = gs + Gs @ v
    dV = np.hstack([dZ[:-1], dZ[1:]])
    assert np.abs(D + (J @ dV[:, :, None])[:, :, 0]).max() < 1e-10  # on the linearised defects
    assert np.abs(dZ[N, :nx]).max() < 1e-10
    nbx = np.zeros((N + 1, nx))
    nbx[N] = nu_N
    (lam,) = _call(fns[2], dZ, nbx, Hy, gy, T, H, G, M)
    lam = lam.reshape(N, nx)
    grad = (H @ dV[:, :, None])[:, :, 0] + G
    gr = np.zeros((N + 1, nz))
    gr[:, :nx] = nbx
    gr[:-1] += grad[:, :nz] + (J[:, :, :nz].transpose(0, 2, 1) @ lam[:, :, None])[:, :, 0]
    gr[1:] += grad[:, nz:] + (J[:, :, nz:].transpose(0, 2, 1) @ lam[:, :, None])[:, :, 0]
    gr[0, :nx] = 0.0  # x_0 pinned: its multiplier is free
    assert np.abs(gr).max() < 1e-9 * max(1.0, np.abs(grad).max())


@pytest.mark.parametrize("nu", [1, 2])
def test_every_output_is_dense_so_flat_buffers_reshape(nu):
    for fn in sqp_functions.qp_functions(4, nu, 3, REG):
        for i in range(fn.n_out()):
            assert fn.sparsity_out(i).is_dense(), (fn.name(), fn.name_out(i))


@pytest.fixture(scope="module")
def compiled_small():
    nx, nu, N = 4, 1, 6
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("CARTPOLE_NO_COMPILE", raising=False)
        fns, lib = sqp_functions.compiled_qp_functions(nx, nu, N, REG)
    if lib is None:
        pytest.skip("no C compiler: the SQP's QP library could not be built")
    return (nx, nu, N), fns, lib


def test_compiled_functions_equal_virtual_machine(compiled_small):
    (nx, nu, N), cfns, lib = compiled_small
    vm = sqp_functions.qp_functions(nx, nu, N, REG)
    nz = nx + nu
    J, H, G, D = _data(nx, nu, N, 8, indefinite=True)  # the regularisation branches too
    outs = {}
    for key, fns in (("c", cfns), ("vm", vm)):
        st = _call(fns[0], J, H, G, D, 0.01)
        cond = _call(fns[1], *st[:4])
        rng = np.random.default_rng(9)
        dZ, nbx = rng.standard_normal((N + 1, nz)), rng.standard_normal((N + 1, nx))
        (lam,) = _call(fns[2], dZ, nbx, st[2], st[3], st[0], H, G, st[4])
        outs[key] = st + cond + [lam]
    assert len(outs["c"]) == 11
    for a, b in zip(outs["c"], outs["vm"]):
        assert _rel(a, b) < 1e-12


def test_no_compile_environment_gives_virtual_machine(monkeypatch):
    monkeypatch.setenv("CARTPOLE_NO_COMPILE", "1")
    fns, lib = sqp_functions.compiled_qp_functions(4, 1, 6, REG)
    assert lib is None
    assert [f.name() for f in fns] == ["sqp_stages", "sqp_condense", "sqp_multipliers", "sqp_stationarity"]


def test_single_interval_is_refused_in_one_sentence():
    with pytest.raises(OCPError, match="N >= 2"):
        sqp_functions.compiled_qp_functions(4, 1, 1, REG)


@pytest.mark.parametrize("nx,nu,N", SIZES)
def test_a_free_state_at_knot_0_condenses_as_one_more_unknown(nx, nu, N):
    """free_state_column (the minimum time's route to DAQP) against brute-force dense condensing in which knot 0's
    last state is an unknown before the inputs."""
    fns = sqp_functions.qp_functions(nx, nu, N, REG, n_free=1)
    J, H, G, D = _data(nx, nu, N, 6, indefinite=True)
    T, ct, Hy, gy, _ = _stages(fns, nx, nu, N, J, H, G, D, 0.0)
    Hc, fc, GT = _assemble(nx, nu, N, _call(fns[1], T, ct, Hy, gy))
    nc = (N + 1) * nu
    H1, f1, G1 = sqp_functions.free_state_column(T, Hy, gy, Hc, fc, GT[:, :, :nc], GT[:, :, nc])
    # reference: s_0 = (e_nx * p, du_0), v = (p, du_0 .. du_N)
    Gk, gk = np.zeros((nx, nc + 1)), np.zeros(nx)
    Gk[nx - 1, 0] = 1.0
    Gs = []
    Hr, fr = np.zeros((nc + 1, nc + 1)), np.zeros(nc + 1)
    for k in range(N):
        E = np.zeros((2 * nu, nc + 1))
        E[:, 1 + k * nu:1 + (k + 2) * nu] = np.eye(2 * nu)
        Y = np.vstack([Gk, E])
        c = np.r_[gk, np.zeros(2 * nu)]
        Hr += Y.T @ Hy[k] @ Y
        fr += Y.T @ (Hy[k] @ c + gy[k])
        Gk, gk = T[k][:nx, :nx] @ Gk + T[k][:nx, nx:] @ E, T[k][:nx, :nx] @ gk + ct[k]
        Gs.append(Gk)
    assert _rel(H1, Hr) < 1e-10 and _rel(f1, fr) < 1e-10
    assert _rel(G1, np.array(Gs)) < 1e-10


def test_the_compiled_librarys_key_is_its_recipe_with_the_builders_source_not_a_version_string(tmp_path, monkeypatch):
    """The library is found by its recipe (sizes, reg_min, n_free, CasADi's version and the digest of this builder's
    source file, cartpole.codegen.build_library's recipe_is_key): a new process finds it without building the
    Functions at all, and an edited builder (its source digest changed) builds a new library (no hand-bumped
    version string to forget)."""
    import casadi as ca

    from cartpole import codegen

    if codegen.compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("CARTPOLE_NO_COMPILE", raising=False)
    monkeypatch.setattr(codegen, "_BUILT", {})
    _, lib = sqp_functions.compiled_qp_functions(2, 1, 3, REG)
    original = sqp_functions.qp_functions

    def never(*args):
        raise AssertionError("the cached library's key needed the Functions built")

    monkeypatch.setattr(sqp_functions, "qp_functions", never)
    monkeypatch.setattr(codegen, "_BUILT", {})  # a new process
    _, again = sqp_functions.compiled_qp_functions(2, 1, 3, REG)
    assert lib is not None and again == lib

    def changed(*args):
        funcs = original(*args)
        last = funcs[-1]
        ins = [ca.MX.sym(last.name_in(i), last.sparsity_in(i)) for i in range(last.n_in())]
        funcs[-1] = ca.Function(last.name(), ins, [2 * o for o in last.call(ins)], last.name_in(), last.name_out())
        return funcs

    monkeypatch.setattr(sqp_functions, "qp_functions", changed)
    monkeypatch.setattr(sqp_functions, "_SOURCE_DIGEST", "edited-builder")  # what editing the file does
    monkeypatch.setattr(codegen, "_BUILT", {})  # a new process, the builder edited
    _, other = sqp_functions.compiled_qp_functions(2, 1, 3, REG)
    assert other is not None and other != lib


_BUILD_PEAK = """
import resource, sys
import casadi  # noqa: F401 - the interpreter and its libraries before the build
from cartpole.solvers import sqp_functions
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
sqp_functions.qp_functions(4, 1, int(sys.argv[1]), 1e-4)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before)
"""


def _build_peak_kb(N: int) -> int:
    """Peak resident memory (kB) that building the one-pole QP functions for ``N`` intervals adds, in a fresh
    interpreter whose address space is capped (a regression fails here instead of eating the machine)."""
    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-c", _BUILD_PEAK, str(N)], capture_output=True, text=True, timeout=120,
                          preexec_fn=cap, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return int(proc.stdout.split()[-1])


def test_building_the_qp_functions_costs_memory_linear_in_the_intervals():
    # one unnested mapaccum over N stages (the condensing's accumulator has N+2 rows) took CasADi superlinear memory
    # to build: 1.7 GB at N = 200, some 7 GB at the N = 315..499 of dm_control's swing-up (20 GB with the virtual
    # machine's second build); nested folds and an N-free stage keep it a few MB per 100 intervals
    small, large = _build_peak_kb(100), _build_peak_kb(400)
    assert large < 400 * 1024  # kB: what one N = 400 build may add
    assert large < 4 * max(small, 16 * 1024) * 2  # linear in N (4x the intervals), with slack for the allocator
