"""StageOptions.number: the one check of an options field's number, whose sentence may end with what to do (its
``hint``); the options that name the fix in their sentences (export, feedforward, the closed loop) use it."""
import math
from dataclasses import dataclass

import pytest

from cartpole.apps.export import ExportOptions
from cartpole.apps.feedforward import FeedforwardError, FeedforwardOptions, check_mass_error
from cartpole.commands._flags import as_flags
from cartpole.export import ExportError
from cartpole.options import OptionsError, StageOptions
from cartpole.sim.options import LoopError, LoopOptions


@dataclass(frozen=True, eq=False)
class _Timed(StageOptions):
    hinted: float | None = 1.0
    plain: float = 1.0

    def __post_init__(self):
        self.number("hinted", low=0.0, low_open=True, optional=True, unit="s", hint="give e.g. `hinted=2`")
        self.number("plain", low=0.0, high=10.0)


@pytest.mark.parametrize("value, start", [(0.0, "_Timed.hinted = 0.0 must be a finite number > 0 s"),
                                          (math.inf, "_Timed.hinted = inf must be a finite number > 0 s"),
                                          ("soon", "_Timed.hinted must be a number; got 'soon'")])
def test_a_hint_ends_the_sentence_after_what_is_wrong(value, start):
    with pytest.raises(OptionsError) as info:
        _Timed(hinted=value)
    assert str(info.value) == f"{start}; give e.g. `hinted=2`."


@pytest.mark.parametrize("value, text", [(11.0, "_Timed.plain = 11.0 must be a finite number in [0, 10]."),
                                         ("x", "_Timed.plain must be a number; got 'x'.")])
def test_without_a_hint_the_sentence_is_what_is_wrong_alone(value, text):
    with pytest.raises(OptionsError) as info:
        _Timed(plain=value)
    assert str(info.value) == text


def test_a_checked_number_is_stored_as_a_float_and_none_passes_where_optional():
    opts = _Timed(hinted=3, plain="2.5")
    assert opts.hinted == 3.0 and isinstance(opts.hinted, float) and opts.plain == 2.5
    assert _Timed(hinted=None).hinted is None


@pytest.mark.parametrize("make, error, hint", [
    (lambda: ExportOptions(duration=0), ExportError, "give the verification e.g. `duration=5`, or None for the "
                                                     "Python path's length."),
    (lambda: FeedforwardOptions(mass_error=-0.95), FeedforwardError, "give a relative mass error such as "
                                                                     "`mass_error=0.1`"),
    (lambda: FeedforwardOptions(mass_error="ten"), FeedforwardError, "give a relative mass error such as "
                                                                     "`mass_error=0.1`"),
    (lambda: FeedforwardOptions(extra=0.5), FeedforwardError, "give the time after the plan e.g. `extra=2` (the "
                                                              "success test looks at its last 1 s)."),
    (lambda: LoopOptions(period=-0.02), LoopError, "give e.g. `period=0.02`."),
    (lambda: LoopOptions(duration=math.nan), LoopError, "give e.g. `duration=8`."),
])
def test_the_options_that_name_the_fix_say_it_through_number(make, error, hint):
    with pytest.raises(error) as info:
        make()
    text = str(info.value)
    assert "\n" not in text and text.endswith(".") and hint in text


def test_the_moved_checks_keep_their_bounds_and_store_floats():
    assert ExportOptions(duration=5).duration == 5.0 and ExportOptions().duration is None
    ff = FeedforwardOptions(mass_error=-0.9, extra=1)
    assert (ff.mass_error, ff.extra) == (-0.9, 1.0) and FeedforwardOptions(mass_error=9).mass_error == 9.0
    assert check_mass_error("0.25") == 0.25
    loop = LoopOptions(duration=3, period=0.01)
    assert (loop.duration, loop.period) == (3.0, 0.01) and LoopOptions().period is None


def test_the_command_line_reads_a_hints_argument_as_its_option():
    with pytest.raises(FeedforwardError) as info:
        check_mass_error(20)
    assert "--mass-error 0.1" in as_flags(str(info.value))
    with pytest.raises(LoopError) as info:
        LoopOptions(duration=0)
    assert as_flags(str(info.value)).endswith("give e.g. --duration 8.")
