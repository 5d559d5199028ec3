"""The compiled Hermite-Simpson interval functions: the same NLP as the SX formulation, and a clean fallback."""
import casadi as ca
import numpy as np
import pytest

from cartpole.models import build_model
from cartpole.ocp import compiled
from cartpole.ocp.collocation import DirectCollocation

HANGING = np.array([0.0, np.pi, 0.0, 0.0])


@pytest.fixture(scope="module")
def model():
    return build_model()


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("CARTPOLE_NO_COMPILE", raising=False)
    return tmp_path / "cache"


def test_compiled_and_sx_formulations_take_the_same_iterates_to_the_same_plan(model, empty_cache):
    ocp_c = DirectCollocation(model, N=40, T=2.0, compiled=True)
    traj_c, info_c = ocp_c.solve_once(HANGING)
    assert ocp_c.compiled_library is not None and str(empty_cache) in ocp_c.compiled_library
    ocp_s = DirectCollocation(model, N=40, T=2.0, compiled=False)
    traj_s, info_s = ocp_s.solve_once(HANGING)
    assert ocp_s.compiled_library is None
    assert info_c.success and info_s.success
    assert info_c.iterations == info_s.iterations
    np.testing.assert_allclose(traj_c.x, traj_s.x, atol=1e-9)
    np.testing.assert_allclose(traj_c.u, traj_s.u, atol=1e-9)
    assert info_c.objective == pytest.approx(info_s.objective, rel=1e-10)


def test_library_is_compiled_once_then_taken_from_the_cache(model, empty_cache):
    ocp = DirectCollocation(model, N=20, T=2.0)
    sx, su = ocp.scale[:4], ocp.scale[4]
    first = compiled.compiled_nlp(model.f, 20, sx, su, su**2 * 2.0)
    again = compiled.compiled_nlp(model.f, 20, sx, su, su**2 * 2.0)
    assert first.compiled_now and not again.compiled_now and first.library == again.library
    # N is not baked into the library (the interval is): another N reuses it
    other_n = compiled.compiled_nlp(model.f, 30, sx, su, su**2 * 2.0)
    assert not other_n.compiled_now and other_n.library == first.library


def test_nlp_derivatives_match_casadi_derivatives_of_the_same_nlp(model, empty_cache):
    N, T = 6, 1.5
    ocp = DirectCollocation(model, N=N, T=T)
    sx, su = ocp.scale[:4], ocp.scale[4]
    comp = compiled.compiled_nlp(model.f, N, sx, su, su**2 * T)
    assert comp is not None
    nlp, opt = comp.nlp, comp.options
    rng = np.random.default_rng(3)
    w = rng.normal(size=5 * (N + 1))
    lam_f, lam_g = 0.7, rng.normal(size=4 * N)
    fg = ca.Function("fg", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
    # reference derivatives: the same f and g written directly in SX (no compiled code)
    fns = compiled.interval_functions(model.f, sx, su, su**2 * T)
    hs_d, hs_e = fns[0], fns[1]
    xs, ps = ca.SX.sym("x", 5 * (N + 1)), ca.SX.sym("p")
    Z = ca.reshape(xs, 5, N + 1)
    V = ca.vertcat(Z[:, :-1], Z[:, 1:])
    g_ref = ca.vec(hs_d.map(N)(V, ps / N))
    f_ref = ca.sum2(hs_e.map(N)(V, ps / N))
    lg = ca.SX.sym("lg", 4 * N)
    ref = ca.Function("ref", [xs, ps, lg], [ca.gradient(f_ref, xs), ca.jacobian(g_ref, xs),
                                           ca.triu(ca.hessian(lam_f * f_ref + ca.dot(lg, g_ref), xs)[0])])
    gr, jr, hr = (np.asarray(ca.densify(a)) for a in ref(w, T, lam_g))
    f_val, g_val = fg(w, T)
    ref_fg = ca.Function("ref_fg", [xs, ps], [f_ref, g_ref])
    f_r, g_r = ref_fg(w, T)
    assert float(f_val) == pytest.approx(float(f_r), rel=1e-12)
    np.testing.assert_allclose(np.asarray(g_val).ravel(), np.asarray(g_r).ravel(), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.asarray(opt["grad_f"](w, T)[1]).ravel(), gr.ravel(), rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(np.asarray(ca.densify(opt["jac_g"](w, T)[1])), jr, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(np.asarray(ca.densify(opt["hess_lag"](w, T, lam_f, lam_g))), hr, rtol=1e-9,
                               atol=1e-10)


def test_a_failing_compiler_falls_back_to_sx_with_one_note(model, empty_cache, monkeypatch, capsys):
    monkeypatch.setattr(compiled, "_compiler", lambda: "false")
    ocp = DirectCollocation(model, N=20, T=2.0)
    traj, info = ocp.solve_once(HANGING)
    assert info.success and ocp.compiled_library is None
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "compiled collocation functions unavailable" in err and "SX" in err
    assert not list(empty_cache.glob("*.so"))  # nothing half-written left in the cache


def test_no_compiler_on_path_falls_back(model, empty_cache, monkeypatch, capsys):
    monkeypatch.setattr(compiled, "_compiler", lambda: None)
    assert compiled.compiled_nlp(model.f, 10, np.ones(4), 1.0, 1.0) is None
    assert "no C compiler" in capsys.readouterr().err
