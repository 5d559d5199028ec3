"""Library errors name Python arguments in backquotes; the command line prints the option that sets each
(:mod:`cartpole.commands._flags`), and every option it prints exists."""
import pytest

from cartpole.cli import main
from cartpole.commands._flags import FLAGS, as_flags
from test_cli_flags_named import cli_flags  # the parser's every option, read once for both tests


def test_every_mapped_option_is_an_option_of_the_command_line():
    options = cli_flags()
    missing = sorted(o for v in FLAGS.values() for o in v.split(", ") if o.split()[0] not in options)
    assert not missing, missing


@pytest.mark.parametrize("text, expected", [
    ("give `u_max` at most 1.", "give --u-max at most 1."),
    ("skip the video (`video=False`).", "skip the video (--no-video)."),
    ("pick `estimator='none'` or `period` 0.01.", "pick --estimator none or --period 0.01."),
    ("use `--method trajopt` or `unknown_name`.", "use `--method trajopt` or `unknown_name`."),  # left as raised
    ("the control period 0.01 s", "the control period 0.01 s"),  # prose is never touched
    ("give `MPCOptions(solver='ddp')` with `seed_plan=False`.", "give --mpc-solver ddp with --no-seed-plan."),
    ("at most `horizon=2.4` or a longer `period`.", "at most --horizon 2.4 or a longer --period."),
    ("the LQR (`lab_margins`, with `estimator='kf'`) or the PID (`pid=True`).",
     "the LQR (--margins, with --estimator kf) or the PID (--compare-pid)."),
])
def test_backquoted_arguments_become_options_and_nothing_else_changes(text, expected):
    assert as_flags(text) == expected


def test_the_command_line_prints_the_option_for_the_librarys_argument(capsys):
    rc = main(["linearize", "--period", "-1"])
    err = capsys.readouterr().err
    assert rc == 2 and "--period" in err and "`period`" not in err and len(err.splitlines()) == 1, err
