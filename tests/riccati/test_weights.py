"""The default weights: 1 per slide, 10 per hinge, 0.1 per rate and per input, for any chain of poles; for one pole
the lab's Q_LAB, R_LAB (the handout's)."""
from types import SimpleNamespace

import numpy as np
import pytest

import cartpole as cp
from cartpole import riccati
from cartpole.apps.lab import Q_LAB, R_LAB
from cartpole.riccati import ONE_POLE, default_weights


def test_the_labs_weights_are_the_handouts_and_read_only():
    np.testing.assert_array_equal(Q_LAB, np.diag([1.0, 10.0, 0.1, 0.1]))
    np.testing.assert_array_equal(R_LAB, [[0.1]])
    assert not Q_LAB.flags.writeable and not R_LAB.flags.writeable
    assert cp.Q_LAB is Q_LAB and cp.R_LAB is R_LAB  # the package top re-exports them
    assert cp.default_weights is default_weights


def test_the_old_names_are_gone():
    """``lab_weights``, ``riccati.Q_LAB`` and ``riccati.R_LAB`` were removed (CHANGELOG): the lab's weights live in
    the lab."""
    for name in ("lab_weights", "Q_LAB", "R_LAB"):
        assert not hasattr(riccati, name)


def test_one_pole_pattern_is_q_lab_r_lab():
    Q, R = default_weights(ONE_POLE)
    np.testing.assert_array_equal(Q, Q_LAB)
    np.testing.assert_array_equal(R, R_LAB)
    Q[0, 0] = 5.0  # fresh arrays: the caller may change them
    assert Q_LAB[0, 0] == 1.0


def test_the_symbolic_model_gives_the_default_weights():
    Q, R = default_weights(cp.build_model())  # has nx and nu
    np.testing.assert_array_equal(Q, Q_LAB)
    np.testing.assert_array_equal(R, R_LAB)


def test_chain_of_poles_default_layout():
    Q, R = default_weights(SimpleNamespace(nq=3, nu=1))  # cart, two hinges
    np.testing.assert_array_equal(np.diag(Q), [1.0, 10.0, 10.0, 0.1, 0.1, 0.1])
    assert Q.shape == (6, 6) and np.count_nonzero(Q - np.diag(np.diag(Q))) == 0
    np.testing.assert_array_equal(R, [[0.1]])


@pytest.mark.parametrize("slides, hinges, nu, q", [
    ((1,), (0, 2), 1, [10.0, 1.0, 10.0]),     # the slide is not joint 0
    ((0,), (1, 2), 2, [1.0, 10.0, 10.0]),     # a motor on a hinge too
])
def test_named_joint_indices_are_used(slides, hinges, nu, q):
    Q, R = default_weights(SimpleNamespace(nq=3, nu=nu, slides=slides, hinges=hinges))
    np.testing.assert_array_equal(np.diag(Q), [*q, 0.1, 0.1, 0.1])
    np.testing.assert_array_equal(R, 0.1 * np.eye(nu))
