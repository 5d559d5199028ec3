"""Number lists on the command line (cartpole.commands._numbers): spaces, commas or both give the same numbers, for
every option that takes a list; anything else is refused in one line with exit status 2."""
import pytest

from cartpole.cli import build_parser, main


@pytest.mark.parametrize("command, option, dest", [
    ("lqr", "--Q", "Q"), ("lqr", "--R", "R"), ("swingup", "--x0", "x0"), ("swingup", "--u-max", "u_max"),
    ("sweep", "--x0", "x0"), ("feedforward", "--x0", "x0"), ("export", "--x0", "x0"),
])
def test_spaces_and_commas_give_the_same_numbers(command, option, dest):
    parser = build_parser()
    spaced = getattr(parser.parse_args([command, option, "1", "10", "0.1", "-0.1"]), dest)
    commas = getattr(parser.parse_args([command, option, "1,10,", "0.1, -0.1"]), dest)
    assert spaced == commas == [1.0, 10.0, 0.1, -0.1]


@pytest.mark.parametrize("values, why", [(["1,x,3"], "'x' is not a number"), ([","], "needs at least one number")])
def test_a_list_that_is_not_numbers_is_refused_in_one_line(capsys, values, why):
    assert main(["lqr", "--no-video", "--Q", *values]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--Q" in err and why in err
