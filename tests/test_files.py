"""Output files are written whole or not at all, with the usual permissions."""
import os
import stat
from pathlib import Path

import pytest

import cartpole._files as files
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


# ---- CSV -----------------------------------------------------------------------------------------------------

def test_append_csv_row_writes_the_header_once_and_quotes_fields(tmp_path):
    import csv

    from cartpole._files import append_csv_row

    path = tmp_path / "metrics" / "metrics.csv"
    header = ["run_id", "value", "notes"]
    append_csv_row(path, header, ["a", 0.125, "5_ICs"])
    append_csv_row(path, header, ["b", 1.5, 'with, a comma and "quotes"'])
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows == [header, ["a", "0.125", "5_ICs"], ["b", "1.5", 'with, a comma and "quotes"']]
    assert [p.name for p in path.parent.iterdir()] == ["metrics.csv"]


def test_append_csv_row_completes_a_last_line_without_newline_and_refuses_another_header(tmp_path):
    from cartpole._files import OutputError, append_csv_row

    path = tmp_path / "m.csv"
    path.write_text("x,y\n1,2")  # written by hand, no final newline
    append_csv_row(path, ["x", "y"], [3, 4])
    assert path.read_text() == "x,y\n1,2\n3,4\n"
    with pytest.raises(OutputError, match="its header is x,y, not a,b"):
        append_csv_row(path, ["a", "b"], [1, 2])
    assert path.read_text() == "x,y\n1,2\n3,4\n"


def test_write_csv_is_whole_or_nothing(tmp_path):
    from cartpole._files import write_csv

    path = write_csv(tmp_path / "r.csv", ["a", "b"], [[1, "x"], [2, "y,z"]])
    assert path.read_text() == 'a,b\n1,x\n2,"y,z"\n'

    def rows():
        yield [3, "w"]
        raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError):
        write_csv(path, ["a", "b"], rows())
    assert path.read_text() == 'a,b\n1,x\n2,"y,z"\n' and [p.name for p in tmp_path.iterdir()] == ["r.csv"]


# ---- failures as one sentence, nothing left behind -------------------------------------------------------------

def test_an_oserror_while_writing_is_an_output_error_and_the_new_directories_go_too(tmp_path, monkeypatch):
    import errno

    import cartpole._files as files
    from cartpole._files import OutputError
    from cartpole.errors import CartPoleError

    def full(fh):
        fh.write(b"half")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OutputError, match=r"Cannot write .*out\.bin \(No space left on device\); free some space") \
            as info:
        files.atomic_write(tmp_path / "new" / "deeper" / "out.bin", full)
    assert isinstance(info.value, CartPoleError) and isinstance(info.value, OSError)
    assert info.value.errno == errno.ENOSPC
    assert list(tmp_path.iterdir()) == []  # no temporary file, no directories made for it


def test_output_transaction_removes_what_a_failed_block_created_and_keeps_what_was_there(tmp_path):
    from cartpole._files import atomic_write, output_transaction

    (tmp_path / "figures").mkdir()
    old = tmp_path / "figures" / "old.png"
    old.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with output_transaction() as created:
            atomic_write(tmp_path / "figures" / "new.png", lambda fh: fh.write(b"new"))
            atomic_write(old, lambda fh: fh.write(b"replaced"))
            atomic_write(tmp_path / "videos" / "clip.mp4", lambda fh: fh.write(b"frames"))
            assert [p.name for p in created] == ["new.png", "videos", "clip.mp4"]
            raise RuntimeError("the command failed after writing")
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == ["figures", "figures/old.png"]
    assert old.read_bytes() == b"replaced"  # replaced whole, not restored
    with output_transaction():
        atomic_write(tmp_path / "kept.txt", lambda fh: fh.write(b"ok"))
    assert (tmp_path / "kept.txt").read_bytes() == b"ok"


def test_check_out_dir_refuses_files_in_the_way_without_creating_anything(tmp_path):
    from cartpole._files import OutputError, check_out_dir

    f = tmp_path / "file"
    f.write_text("x")
    assert check_out_dir(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    with pytest.raises(OutputError, match="is a file, not a directory"):
        check_out_dir(f)
    with pytest.raises(OutputError, match="cannot be created: .*file is a file"):
        check_out_dir(f / "sub" / "dir")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


# ---- input files by kind ------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["loop", "fifo", "device", "directory", "missing"])
def test_an_input_file_of_the_wrong_kind_is_refused_by_its_kind_without_opening_it(tmp_path, kind):
    path = tmp_path / "model.xml"
    if kind == "loop":
        os.symlink(tmp_path / "other.xml", path)
        os.symlink(path, tmp_path / "other.xml")
    elif kind == "fifo":
        os.mkfifo(path)  # opening it would block: the check must not open it
    elif kind == "device":
        path = Path("/dev/zero")
    elif kind == "directory":
        path.mkdir()
    with pytest.raises(files.InputFileError) as info:
        files.check_input_file(path, what="MJCF file", flag="`plant`")
    words = {"loop": "loop of symbolic links", "fifo": "FIFO", "device": "a device", "directory": "a directory",
             "missing": "does not exist"}[kind]
    assert words in str(info.value) and "`plant`" in str(info.value)
    assert str(info.value).count(".") >= 1 and "\n" not in str(info.value)


def test_a_file_read_with_a_bound_refuses_a_larger_one_and_returns_a_smaller_whole(tmp_path):
    f = tmp_path / "rows.csv"
    f.write_bytes(b"x" * 100)
    assert files.read_bounded(f, 100) == b"x" * 100
    with pytest.raises(files.InputFileError, match="MiB limit"):
        files.read_bounded(f, 99)


def test_an_empty_out_is_refused_not_taken_as_the_current_directory():
    with pytest.raises(files.OutputError, match="`out` is empty"):
        files.check_out_dir("")


def test_an_out_that_is_a_dangling_or_looping_link_is_refused(tmp_path):
    loop = tmp_path / "a"
    os.symlink(tmp_path / "b", loop)
    os.symlink(loop, tmp_path / "b")
    with pytest.raises(files.OutputError, match="symbolic link to nothing"):
        files.check_out_dir(loop)
    dangling = tmp_path / "c"
    os.symlink(tmp_path / "missing", dangling)
    with pytest.raises(files.OutputError, match="symbolic link to nothing"):
        files.check_out_dir(dangling)
