"""C literals, tables and CasADi code generation of an export: exact numbers, strict-clean C."""
import subprocess

import casadi as ca
import numpy as np
import pytest

from cartpole.export.build import STRICT_CFLAGS, find_compiler
from cartpole.export.csource import (
    float_maths,
    generate,
    literal,
    silence_unused,
    table,
)


def test_literal_round_trips_every_double_exactly():
    rng = np.random.default_rng(1)
    values = np.concatenate([rng.normal(size=200) * 10.0 ** rng.integers(-300, 300, size=200),
                             [0.0, -0.0, 1.0, 1e-320, np.pi, -np.inf, np.inf]])
    for v in values:
        text = literal(v)
        back = {"INFINITY": np.inf, "-INFINITY": -np.inf}.get(text)
        assert (float(text) if back is None else back) == v


def test_literal_refuses_nan():
    with pytest.raises(ValueError):
        literal(float("nan"))


def test_table_is_row_major_and_refuses_empty():
    text = table("T", np.array([[1.0, 2.0], [3.0, 4.0]]))
    assert text.index("2.0") < text.index("3.0") and "T[4]" in text
    with pytest.raises(ValueError):
        table("E", [])


def test_float_maths_renames_libm_calls_only():
    assert float_maths("a=cos(b)+casadi_sq(c)+fabs(d); x.sin(y);") == "a=cosf(b)+casadi_sq(c)+fabsf(d); x.sin(y);"


def test_silence_unused_voids_every_parameter():
    out = silence_unused("static int f(const double** arg, double* w, int mem) {\n  return 0;\n}\n")
    assert "(void)arg; (void)w; (void)mem;" in out


@pytest.mark.parametrize("real", ["double", "float"])
def test_generated_functions_compile_under_the_strict_flags_and_compute_casadi_values(tmp_path, real):
    import ctypes

    x = ca.SX.sym("x", 3)
    fn = ca.Function("cp_test", [x], [ca.vertcat(ca.sin(x[0]) * x[1], ca.exp(x[2]), x[0] ** 2)])
    src, hdr = generate([fn], real)
    (tmp_path / "cp_generated.c").write_text(src)
    (tmp_path / "cp_generated.h").write_text(hdr)
    lib = tmp_path / "lib.so"
    subprocess.run([find_compiler(), *STRICT_CFLAGS, "-fPIC", "-shared", str(tmp_path / "cp_generated.c"), "-o",
                    str(lib), "-lm"], check=True, capture_output=True)
    c = ctypes.CDLL(str(lib))
    ct = ctypes.c_float if real == "float" else ctypes.c_double
    xin = (ct * 3)(0.3, -1.2, 0.7)
    out = (ct * 3)()
    arg = (ctypes.c_void_p * max(1, fn.sz_arg()))(ctypes.cast(xin, ctypes.c_void_p))
    res = (ctypes.c_void_p * max(1, fn.sz_res()))(ctypes.cast(out, ctypes.c_void_p))
    w = (ct * max(1, fn.sz_w()))()
    iw = (ctypes.c_long * max(1, fn.sz_iw()))()
    assert c.cp_test(arg, res, iw, w, 0) == 0
    want = np.asarray(fn([0.3, -1.2, 0.7])).ravel()
    np.testing.assert_allclose(list(out), want, rtol=1e-6 if real == "float" else 1e-15)
