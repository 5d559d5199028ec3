"""The multi-start: a deterministic set of named guesses, every attempt reported, the best converged one kept,
failures in one sentence."""
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.ocp.bounds import OCPError
from cartpole.ocp.collocation import DirectCollocation, OCPInfeasible, OCPNotSolved
from cartpole.ocp.guess import initial_guesses, named_guesses
from cartpole.planning.trajopt import minimum_time

TWO_POLE = SHIPPED_MJCF.with_name("cartpole_two_pole.xml")


@pytest.fixture(scope="module")
def two_pole():
    return build_model(TWO_POLE)


def test_the_guesses_are_deterministic_named_and_meet_both_ends(two_pole):
    m = two_pole
    a = named_guesses(m, m.x_hanging, T=2.0, N=20, count=10)
    b = named_guesses(m, m.x_hanging, T=2.0, N=20, count=10)
    names = [n for n, _ in a]
    assert names == [n for n, _ in b] and len(set(names)) == len(names) >= 4
    for (_, g), (_, h) in zip(a, b):
        np.testing.assert_array_equal(g.x, h.x)
        np.testing.assert_allclose(g.x[0], m.x_hanging)
        # each ends upright (hinge angles a whole number of turns from x_eq) at rest
        err = m.state_error(g.x[-1])
        assert np.abs(err).max() < 1e-12
    # initial_guesses is the same list without the names
    for (_, g), h in zip(a, initial_guesses(m, m.x_hanging, T=2.0, N=20, count=10)):
        np.testing.assert_array_equal(g.x, h.x)


def test_best_of_solves_every_guess_and_keeps_the_fastest(two_pole):
    m = two_pole
    ocp = DirectCollocation(m, N=24, T=None, objective="time")
    traj, info = ocp.solve(m.x_hanging, starts=4, best_of=True)
    assert len(info.attempts) == 4
    assert [a.guess for a in info.attempts] == [n for n, _ in named_guesses(m, m.x_hanging, T=2.0, N=24, count=4)]
    ok = [a for a in info.attempts if a.success]
    assert ok and info.T == min(a.T for a in ok)
    chosen = [a for a in info.attempts if a.chosen]
    assert len(chosen) == 1 and chosen[0].guess == info.guess == info.attempts[info.start].guess
    assert info.total_iterations == sum(a.iterations for a in info.attempts)
    # the same solve from the winning guess alone gives the same plan
    g = dict(named_guesses(m, m.x_hanging, T=2.0, N=24, count=4))[info.guess]
    again, info2 = DirectCollocation(m, N=24, T=None, objective="time").solve(m.x_hanging, guess=g)
    assert info2.T == pytest.approx(info.T, rel=1e-9)
    np.testing.assert_allclose(again.x, traj.x, atol=1e-8)


def test_minimum_time_refines_the_coarse_winner_to_the_fine_mesh(two_pole):
    m = two_pole
    T, traj, info = minimum_time(m, N=40)
    stages = [a.stage for a in info.attempts]
    assert stages[0] == "time N=20" and stages[-1] == "time N=40"
    assert traj.N == 40 and info.T == T and info.guess.endswith("refined")
    # the refined optimum is a local minimum of the fine problem: solving it again from itself changes nothing
    again, info2 = DirectCollocation(m, N=40, T=None, objective="time").solve(m.x_hanging, guess=traj)
    assert info2.T == pytest.approx(T, rel=1e-6)


def test_no_converging_guess_ends_in_one_sentence_naming_the_bound():
    m = build_model()
    with pytest.raises(OCPNotSolved) as exc:
        minimum_time(m, N=30, cart_max=0.03)
    msg = str(exc.value)
    assert "\n" not in msg and msg.endswith(".") and "cart bound" in msg
    assert isinstance(exc.value, OCPError) and not isinstance(exc.value, OCPInfeasible)
