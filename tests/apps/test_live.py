"""cartpole.apps.live: the LQR the page tunes is re-designed exactly as the lab designs it, refuses bad weights in one
sentence, and keeps the gain in force when it does."""
from __future__ import annotations

import numpy as np
import pytest

from cartpole.apps.lab import run_lab
from cartpole.apps.live import LQRTuner
from cartpole.errors import CartPoleError
from cartpole.riccati import lqr


@pytest.fixture(scope="module")
def lab():
    return run_lab(None, duration=0.5)


def test_a_released_weight_redesigns_the_gain_from_the_exact_linearisation(lab):
    tuner = LQRTuner(lab)
    names = [k.name for k in tuner.knobs()]
    assert len(names) == lab.A.shape[0] + lab.B.shape[1]
    hinge = lab.params.hinges[0]
    name = [n for n in names if n.startswith("Q ")][hinge]
    changed = tuner.set(name, 100.0, t=1.25)
    Q = np.array(lab.Q, float)
    Q[hinge, hinge] = 100.0
    expect = lqr(lab.A, lab.B, Q, lab.R)
    assert np.allclose(changed["K"], expect.K, rtol=1e-10, atol=1e-12)
    assert np.allclose(tuner.controller.feedback.K, expect.K, rtol=1e-10, atol=1e-12)
    assert all(re < 0 for re, _ in changed["eigenvalues"])
    assert changed["Q"][hinge] == 100.0
    x = np.array(lab.x_eq, float)
    x[hinge] += 0.1
    u_new = tuner.controller(0.0, x)
    assert not np.allclose(u_new, lab.controller()(0.0, x))  # the law in force changed


def test_bad_weights_are_one_sentence_and_leave_the_gain(lab):
    tuner = LQRTuner(lab)
    K = tuner.K.copy()
    with pytest.raises(CartPoleError, match="positive and finite"):
        tuner.set("R u", 0.0, t=0.0)
    with pytest.raises(CartPoleError, match="no weight named"):
        tuner.set("nonsense", 1.0, t=0.0)
    assert np.array_equal(tuner.K, K)


def test_the_status_names_the_law_and_the_rig(lab):
    lines = LQRTuner(lab).status(0.0, lab.x0s[0])
    assert lines[0].startswith("LQR (lqr on the continuous (A, B))")
    assert any("closed-loop eigenvalues" in line for line in lines)
    assert any("control period" in line for line in lines)


def test_watch_returns_the_run_with_its_live_log_and_it_replays(capsys):
    import cartpole as cp

    run = cp.watch(duration=0.2, wait=False)  # nobody opens the page: the run goes on at real time
    assert capsys.readouterr().out == ""
    live = run.info["live"]
    assert live["events"] == [] and live["url"].startswith("http://localhost:")
    assert run.t[-1] == pytest.approx(0.2)
    assert cp.replays_exactly(run)
