"""The energy-shaping guess: a rollout of the symbolic model's own step, sampled on the grid, within ctrlrange."""
import numpy as np
import pytest

import cartpole as cp
from cartpole.ocp.guess import energy_guess

def test_energy_guess_follows_the_models_own_step():
    model = cp.build_model()
    t, x, u = energy_guess(model, (0, np.pi, 0, 0), T=3.0, N=60)
    assert t.shape == (61,) and x.shape == (61, 4) and u.shape == (60, 1)
    assert np.allclose(x[0], [0, np.pi, 0, 0])
    assert np.all(np.abs(u) <= model.params.u_max)
    assert t[-1] == pytest.approx(3.0)
