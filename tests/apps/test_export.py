"""run_export's options: one frozen value, checked before any folder is touched."""
import pytest

from cartpole.apps.export import ExportOptions, run_export
from cartpole.export import ExportError


@pytest.mark.parametrize("duration", [0, -1.0, float("inf"), "long"])
def test_a_verification_duration_that_is_not_a_time_is_one_sentence_naming_the_argument(duration):
    with pytest.raises(ExportError, match=r"ExportOptions.duration (= .* )?must be a (finite )?number.*; give the "
                                          r"verification e.g. `duration=5`, or None for the Python path's length\.$"):
        ExportOptions(verify=True, duration=duration)


def test_options_are_read_only_and_a_per_actuator_bound_is_kept_as_a_tuple():
    opts = ExportOptions(u_max=[1.0, 0.5], cart_max=1.2)
    assert opts.u_max == (1.0, 0.5) and opts.replace(float32=True).float32 and not opts.float32
    with pytest.raises(AttributeError):
        opts.verify = True


def test_options_of_another_kind_are_refused_before_the_folder_is_made(tmp_path):
    with pytest.raises(ExportError, match="run_export's options must be an ExportOptions"):
        run_export(None, "lqr", {"verify": True}, out=tmp_path / "c")
    assert not (tmp_path / "c").exists()
