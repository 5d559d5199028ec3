"""The bench's hand-typed naive baseline: the one-pole cart-pole's 2x2 equations typed by hand are the file's
dynamics (the model's f to round-off at many states), and there is none for a chain (the generic baseline stays)."""
import numpy as np

from cartpole.apps.bench.trajopt import hand_typed_cartpole
from cartpole.models import SHIPPED_MJCF, build_model, read_params


def test_the_hand_typed_equations_are_the_files_dynamics():
    params = read_params(SHIPPED_MJCF)
    f, model = hand_typed_cartpole(params), build_model(params)
    assert f is not None and f.n_instructions() < model.f.n_instructions()
    rng = np.random.default_rng(3)
    for _ in range(200):
        x, u = rng.uniform(-4, 4, model.nx), rng.uniform(-1, 1, model.nu)
        want = np.asarray(model.f(x, u)).ravel()
        np.testing.assert_allclose(np.asarray(f(x, u)).ravel(), want, rtol=1e-12, atol=1e-12)


def test_a_chain_has_no_hand_typed_baseline():
    assert hand_typed_cartpole(read_params(SHIPPED_MJCF.parent / "cartpole_two_pole.xml")) is None
