"""errors.first_line: any exception message as the one line the toolkit's sentences embed."""
from cartpole.errors import elide, first_line


def test_multi_line_message_is_folded_without_the_final_period():
    exc = ValueError("XML Error: Schema violation:\n   unrecognized attribute 'foo'\n\nElement 'joint', line 7.\n")
    assert first_line(exc) == "XML Error: Schema violation: unrecognized attribute 'foo' Element 'joint', line 7"


def test_mujoco_error_prefix_is_dropped_and_a_long_message_keeps_its_last_words():
    assert first_line(RuntimeError("mjParseXML: Error=bad file.")) == "mjParseXML: bad file"
    text = "start " + "x" * 500 + " so give --x0 inside it."
    assert first_line(RuntimeError(text)) == text.rstrip(".")  # a toolkit sentence is never cut
    long = first_line(RuntimeError(text), width=240)  # a foreign message inside one of ours loses its middle only
    assert len(long) == 240 and long.startswith("start x") and long.endswith("so give --x0 inside it")
    assert "..." in long and "\n" not in long


def test_elide_keeps_both_ends_of_a_long_path():
    path = "/very/" + "long/" * 80 + "file.xml"
    short = elide(path, 60)
    assert len(short) == 60 and short.startswith("/very/long") and short.endswith("long/file.xml")
    assert elide("short.xml", 60) == "short.xml"


def test_an_empty_message_names_the_exception_type():
    assert first_line(KeyError()) == "KeyError"
    assert first_line(OSError("   \n ")) == "OSError"


def test_sigterm_inside_the_command_lines_block_raises_terminated_and_the_handler_is_put_back():
    import os
    import signal

    import pytest

    from cartpole.cli import signals_as_interrupts
    from cartpole.errors import Terminated

    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated) as info, signals_as_interrupts():
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler runs between bytecodes of the main thread
            pass
    assert isinstance(info.value, KeyboardInterrupt) and info.value.signum == signal.SIGTERM
    assert signal.getsignal(signal.SIGTERM) is before
