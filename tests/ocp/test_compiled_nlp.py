"""The compiled Hermite-Simpson interval functions: the same NLP as the SX formulation, and a clean fallback."""
import casadi as ca
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole import codegen
from cartpole.ocp import compiled_nlp
from cartpole.ocp.collocation import CollocationOptions, DirectCollocation

HANGING = np.array([0.0, np.pi, 0.0, 0.0])
TWO_POLE = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")


@pytest.fixture(scope="module")
def model():
    return build_model()


@pytest.fixture(scope="module")
def two_pole():
    return build_model(TWO_POLE)


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("CARTPOLE_NO_COMPILE", raising=False)
    monkeypatch.delenv("CARTPOLE_CFLAGS", raising=False)
    return tmp_path / "cache"


def _scales(ocp):
    """(state scales (nx,), ctrl scales (nu,), effort scale) of a DirectCollocation at its T."""
    sx, su = ocp.scale[:ocp.nx], ocp.scale[ocp.nx:]
    return sx, su, float(np.sum(su**2)) * ocp.T


def _tilted(model, angle=0.3):
    x0 = np.array(model.x_eq, dtype=float)
    x0[model.hinges[0]] += angle
    return x0


def _same_plan(model, x0, N):
    ocp_c = DirectCollocation(model, N=N, T=2.0, options=CollocationOptions(compiled=True))
    traj_c, info_c = ocp_c.solve_once(x0)
    ocp_s = DirectCollocation(model, N=N, T=2.0, options=CollocationOptions(compiled=False))
    traj_s, info_s = ocp_s.solve_once(x0)
    assert ocp_c.compiled_library is not None and ocp_s.compiled_library is None
    assert info_c.success and info_s.success
    assert info_c.iterations == info_s.iterations
    np.testing.assert_allclose(traj_c.x, traj_s.x, atol=1e-9)
    np.testing.assert_allclose(traj_c.u, traj_s.u, atol=1e-9)
    assert info_c.objective == pytest.approx(info_s.objective, rel=1e-10)
    return ocp_c


def test_compiled_and_sx_formulations_take_the_same_iterates_to_the_same_plan(model, empty_cache):
    ocp_c = _same_plan(model, HANGING, 40)
    assert str(empty_cache) in ocp_c.compiled_library


def test_compiled_and_sx_give_the_same_plan_for_a_two_pole_cart(two_pole, empty_cache):
    _same_plan(two_pole, _tilted(two_pole), 20)


def test_library_is_compiled_once_then_taken_from_the_cache(model, empty_cache):
    ocp = DirectCollocation(model, N=20, T=2.0)
    sx, su, eff = _scales(ocp)
    first = compiled_nlp.compiled_nlp(model, 20, sx, su, eff)
    again = compiled_nlp.compiled_nlp(model, 20, sx, su, eff)
    assert first.compiled_now and not again.compiled_now and first.library == again.library
    # N is not baked into the library (the interval is): another N reuses it
    other_n = compiled_nlp.compiled_nlp(model, 30, sx, su, eff)
    assert not other_n.compiled_now and other_n.library == first.library


def test_different_models_never_share_a_library(model, two_pole, empty_cache):
    # two carts that differ by one part in 1e9 in the pole masses, with the very same scaling
    nearly = build_model(two_pole.params.scaled_pole(1.0 + 1e-9, 1.0))
    scales = _scales(DirectCollocation(two_pole, N=10, T=2.0))
    first = compiled_nlp.compiled_nlp(two_pole, 10, *scales)
    other = compiled_nlp.compiled_nlp(nearly, 10, *scales)
    assert first.compiled_now and other.compiled_now and first.library != other.library
    assert codegen.model_key(nearly) != codegen.model_key(two_pole) != codegen.model_key(model)
    # the key is of the model's physics, not of where its file lives; a bare f is keyed on its own graph
    assert codegen.model_key(build_model(model.params.replace(mjcf="/elsewhere/cartpole.xml"))) == \
        codegen.model_key(model)
    assert codegen.model_key(model) != codegen.model_key(model.f)


@pytest.mark.parametrize("which", ["one_pole", "two_pole"])
def test_nlp_derivatives_match_casadi_derivatives_of_the_same_nlp(model, two_pole, which, empty_cache):
    m = model if which == "one_pole" else two_pole
    N, T = 6, 1.5
    nz = m.nx + m.nu
    ocp = DirectCollocation(m, N=N, T=T)
    sx, su, _ = _scales(ocp)
    eff = float(np.sum(su**2)) * T
    comp = compiled_nlp.compiled_nlp(m, N, sx, su, eff)
    assert comp is not None
    nlp, opt = comp.nlp, comp.options
    rng = np.random.default_rng(3)
    w = rng.normal(size=nz * (N + 1))
    lam_f, lam_g = 0.7, rng.normal(size=m.nx * N)
    fg = ca.Function("fg", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
    # reference derivatives: the same f and g written directly in SX (no compiled code)
    fns = compiled_nlp.interval_functions(m.f, sx, su, eff)
    hs_d, hs_e = fns[0], fns[1]
    xs, ps = ca.SX.sym("x", nz * (N + 1)), ca.SX.sym("p")
    Z = ca.reshape(xs, nz, N + 1)
    V = ca.vertcat(Z[:, :-1], Z[:, 1:])
    g_ref = ca.vec(hs_d.map(N)(V, ps / N))
    f_ref = ca.sum2(hs_e.map(N)(V, ps / N))
    lg = ca.SX.sym("lg", m.nx * N)
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
    monkeypatch.setattr(codegen, "compiler", lambda: "false")
    ocp = DirectCollocation(model, N=20, T=2.0)
    traj, info = ocp.solve_once(HANGING)
    assert info.success and ocp.compiled_library is None
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "compiled collocation functions unavailable" in err and "SX" in err
    assert not list(empty_cache.glob("*.so"))  # nothing half-written left in the cache


def test_no_compiler_on_path_falls_back(model, empty_cache, monkeypatch, capsys):
    monkeypatch.setattr(codegen, "compiler", lambda: None)
    assert compiled_nlp.compiled_nlp(model, 10, np.ones(model.nx), np.ones(model.nu), 1.0) is None
    assert "no C compiler" in capsys.readouterr().err


@pytest.mark.parametrize("objective,T", [("time", None), ("tracking", 2.5)])
def test_free_time_and_running_cost_nlps_compiled_take_the_sx_iterates(model, two_pole, objective, T, empty_cache):
    # the free final time couples every interval (a dense column in the Jacobian and the Hessian); a running cost
    # is integrated inside the compiled interval: both give the SX formulation's iterates and solution
    for m, x0, N in ((model, HANGING, 30), (two_pole, two_pole.x_hanging, 20)):
        ocp_c = DirectCollocation(m, N=N, T=T, objective=objective, options=CollocationOptions(compiled=True))
        ocp_s = DirectCollocation(m, N=N, T=T, objective=objective, options=CollocationOptions(compiled=False))
        traj_c, info_c = ocp_c.solve_once(x0)
        traj_s, info_s = ocp_s.solve_once(x0)
        assert ocp_c.compiled_library is not None and ocp_s.compiled_library is None
        assert info_c.success and info_s.success and info_c.iterations == info_s.iterations
        assert info_c.T == pytest.approx(info_s.T, rel=1e-9)
        np.testing.assert_allclose(traj_c.x, traj_s.x, atol=1e-7)
        assert info_c.objective == pytest.approx(info_s.objective, rel=1e-9)


def test_free_time_nlp_derivatives_match_casadi_derivatives(two_pole, empty_cache):
    m, N = two_pole, 5
    nz = m.nx + m.nu
    ocp = DirectCollocation(m, N=N, T=None, objective="time")
    sx, su = ocp.scale[:m.nx], ocp.scale[m.nx:]
    weight = 1e-3
    comp = compiled_nlp.compiled_nlp(m, N, sx, su, 1.0 / weight, free_time=True, time_weight=1.0)
    nlp, opt = comp.nlp, comp.options
    n = nz * (N + 1) + 1
    rng = np.random.default_rng(5)
    w = np.r_[rng.normal(size=n - 1), 1.7]
    lam_f, lam_g = 0.6, rng.normal(size=m.nx * N)
    # reference: the same NLP written in SX, T the last variable, derivatives by CasADi
    fns = compiled_nlp.interval_functions(m.f, sx, su, 1.0 / weight)
    xs = ca.SX.sym("x", n)
    Z = ca.reshape(xs[:-1], nz, N + 1)
    V = ca.vertcat(Z[:, :-1], Z[:, 1:])
    g_ref = ca.vec(fns[0].map(N)(V, xs[-1] / N))
    f_ref = xs[-1] + ca.sum2(fns[1].map(N)(V, xs[-1] / N))
    lg = ca.SX.sym("lg", m.nx * N)
    ref = ca.Function("ref", [xs, lg], [f_ref, g_ref, ca.gradient(f_ref, xs), ca.jacobian(g_ref, xs),
                                        ca.triu(ca.hessian(lam_f * f_ref + ca.dot(lg, g_ref), xs)[0])])
    f_r, g_r, gr, jr, hr = (np.asarray(ca.densify(a)) for a in ref(w, lam_g))
    fg = ca.Function("fg", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
    f_val, g_val = fg(w, [])
    assert float(f_val) == pytest.approx(float(f_r.ravel()[0]), rel=1e-12)
    np.testing.assert_allclose(np.asarray(g_val).ravel(), g_r.ravel(), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.asarray(opt["grad_f"](w, [])[1]).ravel(), gr.ravel(), rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(np.asarray(ca.densify(opt["jac_g"](w, [])[1])), jr, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(np.asarray(ca.densify(opt["hess_lag"](w, [], lam_f, lam_g))), hr, rtol=1e-9,
                               atol=1e-10)


def test_one_library_serves_fixed_and_free_time_and_any_T(model, empty_cache):
    ocp = DirectCollocation(model, N=20, T=2.0)
    sx, su, eff = _scales(ocp)
    first = compiled_nlp.compiled_nlp(model, 20, sx, su, eff)
    free = compiled_nlp.compiled_nlp(model, 20, sx, su, 1e3, free_time=True)
    other_T = compiled_nlp.compiled_nlp(model, 20, sx, su, eff * 1.7)
    assert first.compiled_now and not free.compiled_now and not other_T.compiled_now
    assert first.library == free.library == other_T.library


def _knot_shared(fns, Z, h, lam, sigma):
    """hs_kf, hs_mid1, hs_mid2, hs_kh evaluated as the SQP evaluates them: D (N, nx), J (N, nx, nv), E (N,),
    G (N, nv) and the full Hessian of the Lagrangian in all knots ((N+1) nz square)."""
    byname = {fn.name(): fn for fn in fns}
    N1, nz = Z.shape
    N = N1 - 1
    kf = [byname["hs_kf"](z) for z in Z]
    F = [np.asarray(a).ravel() for a, _ in kf]
    JF = [np.asarray(b) for _, b in kf]
    D, J, E, G = [], [], [], []
    H = np.zeros((N1 * nz, N1 * nz))
    W = np.zeros((N1, len(F[0])))
    for k in range(N):
        args = (Z[k], Z[k + 1], F[k], F[k + 1], JF[k], JF[k + 1], h)
        d, jd, e, ge = (np.asarray(a) for a in byname["hs_mid1"](*args))
        D.append(d.ravel()), J.append(jd), E.append(float(e.ravel()[0])), G.append(ge.ravel())
        hm, wk, wk1 = (np.asarray(a) for a in byname["hs_mid2"](*args, lam[k], sigma))
        H[k * nz:(k + 2) * nz, k * nz:(k + 2) * nz] += hm
        W[k] += wk.ravel()
        W[k + 1] += wk1.ravel()
    for k in range(N1):
        H[k * nz:(k + 1) * nz, k * nz:(k + 1) * nz] += np.asarray(byname["hs_kh"](Z[k], W[k]))
    return np.array(D), np.array(J), np.array(E), np.array(G), H


@pytest.mark.parametrize("objective", ["effort", "tracking"])
def test_knot_shared_derivatives_equal_the_interval_functions(objective):
    """The SQP's knot-shared evaluation (each knot's f and curvature once) gives the interval functions' defects,
    Jacobians, cost, gradient and, summed over the intervals, the same Lagrangian Hessian."""
    from cartpole.ocp.objectives import make_objective

    m = build_model()
    nx, nu = m.nx, m.nu
    nz, nv = nx + nu, 2 * (nx + nu)
    sx, su = np.array([1.4, np.pi, 5.0, 20.0]), np.array([1.0])
    run = make_objective(m, objective).running
    fns = compiled_nlp.knot_functions(m.f, sx, su, running=run)
    byname = {fn.name(): fn for fn in compiled_nlp.interval_functions(m.f, sx, su, 1.0, running=run)}
    rng = np.random.default_rng(7)
    N, h, sigma = 6, 0.02, 0.8
    Z = rng.normal(size=(N + 1, nz))
    lam = rng.normal(size=(N, nx))
    D, J, E, G, H = _knot_shared(fns, Z, h, lam, sigma)
    Href = np.zeros_like(H)
    for k in range(N):
        v = np.r_[Z[k], Z[k + 1]]
        d, jd = (np.asarray(a) for a in byname["hs_dj"](v, h))
        e, ge = (np.asarray(a) for a in byname["hs_eg"](v, h))
        np.testing.assert_allclose(D[k], d.ravel(), rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(J[k], jd[:, :nv], rtol=1e-11, atol=1e-12)
        assert E[k] == pytest.approx(float(e.ravel()[0]), rel=1e-12, abs=1e-14)
        np.testing.assert_allclose(G[k], ge.ravel()[:nv], rtol=1e-11, atol=1e-12)
        tri = np.asarray(byname["hs_hl"](v, h, lam[k], sigma)).ravel()  # upper triangle of (v, h), column-major
        full = np.zeros((nv + 1, nv + 1))
        rows, cols = np.triu_indices(nv + 1)
        order = np.lexsort((rows, cols))  # column-major order of the upper triangle
        full[rows[order], cols[order]] = tri
        full = full + np.triu(full, 1).T
        Href[k * nz:(k + 2) * nz, k * nz:(k + 2) * nz] += full[:nv, :nv]
    np.testing.assert_allclose(H, Href, rtol=1e-10, atol=1e-10 * np.abs(Href).max())
