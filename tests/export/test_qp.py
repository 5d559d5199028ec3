"""The export's dense dual active-set QP solver in C against DAQP (the NMPC's Python solver) on random strictly
convex QPs with bounds and general rows, and against the KKT conditions."""
import ctypes
import subprocess

import numpy as np
import pytest

from cartpole.export.build import STRICT_CFLAGS, find_compiler
from cartpole.codegen import qp_fields, qp_source

NZ, NR = 12, 8


@pytest.fixture(scope="module")
def qp_lib(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("qp")
    fields = "\n".join(f"    {f}" for f in qp_fields(NZ, NR))
    src = f"""#include <math.h>
typedef double cp_real;
#define CP_REAL_IS_FLOAT 0
static struct {{
{fields}
}} S;
{qp_source(NZ, NR)}
int solve(cp_real* H, const cp_real* h, const cp_real* A, const cp_real* lba, const cp_real* uba,
          const cp_real* lbx, const cp_real* ubx, cp_real* z)
{{
    return qp_solve(H, h, A, lba, uba, lbx, ubx, z);
}}
"""
    (tmp / "qp.c").write_text(src)
    lib = tmp / "qp.so"
    subprocess.run([find_compiler(), *STRICT_CFLAGS, "-O2", "-fPIC", "-shared", str(tmp / "qp.c"), "-o", str(lib),
                    "-lm"], check=True, capture_output=True)
    return ctypes.CDLL(str(lib))


def _c_solve(lib, H, h, A, lba, uba, lbx, ubx):
    dbl = ctypes.POINTER(ctypes.c_double)
    arrs = [np.ascontiguousarray(a, dtype=float) for a in (H.copy(), h, A, lba, uba, lbx, ubx)]
    z = np.zeros(NZ)
    code = lib.solve(*[a.ctypes.data_as(dbl) for a in arrs], z.ctypes.data_as(dbl))
    return code, z


@pytest.mark.parametrize("seed", range(25))
def test_c_qp_equals_daqp_and_satisfies_kkt(qp_lib, seed):
    daqp = pytest.importorskip("daqp")
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(NZ, NZ))
    H = M @ M.T + 0.1 * np.eye(NZ)
    h = rng.normal(size=NZ) * 5
    A = rng.normal(size=(NR, NZ))
    lbx, ubx = -rng.uniform(0.1, 1, NZ), rng.uniform(0.1, 1, NZ)
    lbx[::5], ubx[1::6] = -np.inf, np.inf  # some bounds absent
    lba, uba = -rng.uniform(0.2, 1, NR), rng.uniform(0.2, 1, NR)
    lba[::3] = -np.inf
    code, z = _c_solve(qp_lib, H, h, A, lba, uba, lbx, ubx)
    assert code == 0
    up = np.minimum(np.r_[ubx, uba], 1e30)
    lo = np.maximum(np.r_[lbx, lba], -1e30)
    zd, _, flag, _ = daqp.solve(H, h, A, up, lo, np.zeros(NZ + NR, dtype=np.int32))
    assert flag == 1
    np.testing.assert_allclose(z, zd, atol=1e-9)
    # KKT: feasible, and the gradient is a non-negative combination of the active constraints' normals
    tol = 1e-9
    assert np.all(z >= lbx - tol) and np.all(z <= ubx + tol)
    assert np.all(A @ z >= lba - tol) and np.all(A @ z <= uba + tol)
    g = H @ z + h
    normals = []
    for i in range(NZ):
        if abs(z[i] - lbx[i]) < 1e-9:
            normals.append(np.eye(NZ)[i])
        if abs(z[i] - ubx[i]) < 1e-9:
            normals.append(-np.eye(NZ)[i])
    for r in range(NR):
        if abs(A[r] @ z - lba[r]) < 1e-9:
            normals.append(A[r])
        if abs(A[r] @ z - uba[r]) < 1e-9:
            normals.append(-A[r])
    if normals:
        N = np.array(normals).T
        lam, *_ = np.linalg.lstsq(N, g, rcond=None)
        assert np.all(lam >= -1e-8) and np.linalg.norm(N @ lam - g) < 1e-7 * max(1, np.linalg.norm(g))
    else:
        assert np.linalg.norm(g) < 1e-8


def test_infeasible_qp_says_so(qp_lib):
    H, h = np.eye(NZ), np.zeros(NZ)
    A = np.zeros((NR, NZ))
    A[0, 0] = 1.0
    lba, uba = np.full(NR, -np.inf), np.full(NR, np.inf)
    lba[0] = 2.0  # z_0 >= 2 and z_0 <= 1
    lbx, ubx = np.full(NZ, -1.0), np.full(NZ, 1.0)
    code, _ = _c_solve(qp_lib, H, h, A, lba, uba, lbx, ubx)
    assert code == 2
