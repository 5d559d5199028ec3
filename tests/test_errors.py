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
