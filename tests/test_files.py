"""Output files are written whole or not at all, with the usual permissions."""
import os
import stat

import pytest

from cartpole._files import atomic_path, atomic_write


def _mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


def test_atomic_write_creates_parents_and_leaves_only_the_file(tmp_path):
    path = tmp_path / "a" / "b" / "out.txt"
    assert atomic_write(path, lambda fh: fh.write(b"hello")) == path
    assert path.read_bytes() == b"hello"
    assert [p.name for p in path.parent.iterdir()] == ["out.txt"]
    mask = os.umask(0)
    os.umask(mask)
    assert _mode(path) == 0o666 & ~mask


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "out.txt"
    path.write_text("old")

    def broken(fh):
        fh.write(b"half")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError):
        atomic_write(path, broken)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_atomic_path_keeps_the_suffix_and_renames_at_the_end(tmp_path):
    path = tmp_path / "clip.mp4"
    with atomic_path(path, suffix=".mp4") as tmp:
        assert tmp.parent == tmp_path and tmp.name.endswith(".mp4") and tmp.exists()
        tmp.write_bytes(b"frames")
        assert not path.exists()
    assert path.read_bytes() == b"frames" and [p.name for p in tmp_path.iterdir()] == ["clip.mp4"]
    with pytest.raises(ValueError):
        with atomic_path(tmp_path / "other.mp4", suffix=".mp4") as tmp:
            tmp.write_bytes(b"half")
            raise ValueError
    assert [p.name for p in tmp_path.iterdir()] == ["clip.mp4"]
