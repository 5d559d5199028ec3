"""errors.first_line: any exception message as the one line the toolkit's sentences embed."""
from cartpole.errors import first_line


def test_multi_line_message_is_folded_without_the_final_period():
    exc = ValueError("XML Error: Schema violation:\n   unrecognized attribute 'foo'\n\nElement 'joint', line 7.\n")
    assert first_line(exc) == "XML Error: Schema violation: unrecognized attribute 'foo' Element 'joint', line 7"


def test_mujoco_error_prefix_is_dropped_and_long_messages_are_capped():
    assert first_line(RuntimeError("mjParseXML: Error=bad file.")) == "mjParseXML: bad file"
    long = first_line(RuntimeError("x" * 500))
    assert long == "x" * 240 + "..." and "\n" not in long


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
