"""Write output files whole or not at all; turn every file-system failure into one sentence.

* :func:`atomic_write` / :func:`atomic_path`: write beside the target, rename over it at the end; a failure part-way
  leaves no file (an existing target untouched) and removes the directories it had created.
* :func:`write_csv`, :func:`append_csv_row`: CSV through the :mod:`csv` module, atomically.
* :func:`exclusive_lock`: an ``fcntl.flock`` held for a block, refused at once when another process holds it.
* :func:`check_input_file`, :func:`read_bounded`: an input file checked by kind (a regular file, not a FIFO,
  device, directory or symbolic-link loop) and read with a size bound.
* :func:`check_out_dir`: before any work, is ``--out`` a directory that exists or can be created, and writable?
* :func:`output_transaction`: a command's outputs as a set: when the block fails, the files and directories it
  created are removed again, so a failed command leaves the ``--out`` tree as it found it (files it *replaced* keep
  their new, whole content).

Every :class:`OSError` on the way (no space left, a read-only file system, a file where a directory should be, no
permission) becomes :class:`OutputError`: one sentence naming the path, the reason and what to do.
"""
from __future__ import annotations

import csv
import errno
import io
import os
import stat
import tempfile
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import IO, Callable, Iterable, Iterator, Sequence

from cartpole.errors import CartPoleError, elide

_ADVICE = {
    errno.ENOSPC: "free some space or choose another --out",
    errno.EDQUOT: "free some space or choose another --out",
    errno.EROFS: "the file system is read-only; choose a writable --out",
    errno.EACCES: "choose a directory you may write to as --out",
    errno.EPERM: "choose a directory you may write to as --out",
    errno.ENOTDIR: "a file stands where a directory is needed; remove it or choose another --out",
    errno.EEXIST: "a file stands where a directory is needed; remove it or choose another --out",
    errno.EISDIR: "a directory stands where the file goes; remove it or choose another --out",
    errno.ENAMETOOLONG: "choose a shorter --out",
}


def short(path, width: int = 90) -> str:
    """``path`` as text, its middle elided (``/tmp/run/...long/figure.png``) past ``width`` characters, so that a
    sentence naming it stays short and its advice is never pushed off the end (:func:`cartpole.errors.elide`)."""
    return elide(str(path), width)


class InputFileError(CartPoleError, OSError):
    """An input file cannot be used: missing, a symbolic-link loop, a directory, FIFO or device, unreadable, or too
    large (one sentence: the path, why, what to do). Also an :class:`OSError`; ``reason`` holds the why alone
    (``"is a device, not a regular file"``)."""

    reason: str = ""


class OutputError(CartPoleError, OSError):
    """An output file or directory cannot be written (one sentence: the path, why, what to do).

    Also an :class:`OSError`, so code that caught the file system's own error still catches this one.
    """


def output_error(path, exc: OSError, what: str = "write") -> OutputError:
    """:class:`OutputError` for ``exc`` raised while trying to ``what`` ``path``."""
    code = getattr(exc, "errno", None)
    reason = exc.strerror or type(exc).__name__
    advice = _ADVICE.get(code, "check the path or choose another --out")
    err = OutputError(f"Cannot {what} {short(path)} ({reason}); {advice}.")
    err.errno = code
    return err


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# ---- a command's outputs as one set ---------------------------------------------------------------------------

_CREATED: ContextVar[list | None] = ContextVar("cartpole_output_transaction", default=None)


@contextmanager
def output_transaction() -> Iterator[list]:
    """Inside the block, remember every file and directory :func:`atomic_path` creates; if the block raises,
    remove them again (newest first; directories only when empty) and re-raise. Yields that list of paths."""
    created: list[Path] = []
    token = _CREATED.set(created)
    try:
        yield created
    except BaseException:
        _remove(created)
        raise
    finally:
        _CREATED.reset(token)


def _remove(paths) -> None:
    for p in reversed(list(paths)):
        try:
            if p.is_dir() and not p.is_symlink():
                p.rmdir()
            else:
                p.unlink()
        except OSError:
            pass  # not empty (something else wrote there), already gone: leave it


def _missing_parents(path: Path) -> list[Path]:
    """The ancestors of ``path`` that do not exist yet, outermost first."""
    missing = []
    for p in path.parents:
        if os.path.lexists(p):
            break
        missing.append(p)
    return missing[::-1]


def _make_parents(path: Path) -> list[Path]:
    missing = _missing_parents(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _remove(p for p in missing if p.exists())
        raise output_error(path.parent, exc, "create the directory") from None
    return missing


@contextmanager
def atomic_path(path: str | Path, *, suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed over ``path`` when the block ends without error.

    For writers that take a file name rather than a file object (an encoder in another process, say). The
    temporary file exists (empty) when the block starts, its name ends with ``suffix`` (give the target's own,
    e.g. ``".mp4"``, when the writer picks its format from the name). A failure part-way leaves no file behind
    (and an existing ``path`` untouched) and removes the parent directories this call created. The result gets
    the usual permissions (``0o666`` less the umask), not ``mkstemp``'s private ``0o600``. Parent directories are
    created.

    Raises
    ------
    OutputError
        The directory cannot be created, ``path`` is a read-only file (it is not replaced: renaming over it would
        defeat its mode), the temporary file cannot be made or renamed (errors raised inside the block itself pass
        through unchanged).
    """
    path = Path(path)
    created = _make_parents(path)
    existed = os.path.lexists(path)
    try:
        check_replaceable(path)
    except OutputError:
        _remove(created)
        raise
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    except OSError as exc:
        _remove(created)
        raise output_error(path, exc) from None
    os.close(fd)
    try:
        yield Path(tmp)
        try:
            os.chmod(tmp, 0o666 & ~_umask())
            os.replace(tmp, path)
        except OSError as exc:
            raise output_error(path, exc) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        _remove(created)
        raise
    log = _CREATED.get()
    if log is not None:
        log.extend(created)
        if not existed:
            log.append(path)


def check_replaceable(path: str | Path) -> None:
    """Refuse to replace ``path`` when it is a read-only file (no write permission, or its owner's write bit clear:
    a file made read-only on purpose, even for root); nothing when it is missing or writable.

    Raises
    ------
    OutputError
        ``path`` is read-only (one sentence: make it writable, move it away or choose another ``--out``).
    """
    try:
        st = os.stat(path)
    except OSError:
        return
    if stat.S_ISREG(st.st_mode) and (not os.access(path, os.W_OK) or not st.st_mode & stat.S_IWUSR):
        raise OutputError(f"Cannot write {short(path)}: the file is read-only; make it writable (chmod u+w), move it "
                          "away or choose another `out`.")


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Call ``write(fileobj)`` on a temporary file beside ``path``, then rename it over ``path``.

    A failure part-way leaves no file behind (and an existing ``path`` untouched). The result gets the usual
    permissions (``0o666`` less the umask), not ``mkstemp``'s private ``0o600``. Parent directories are
    created. Returns ``path``.

    Raises
    ------
    OutputError
        Any :class:`OSError` while creating, writing, flushing or renaming (a full disk, a read-only file system,
        a file where a directory should be...), as one sentence.
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        try:
            with open(tmp, "wb") as fh:
                write(fh)
        except OutputError:
            raise
        except OSError as exc:
            raise output_error(path, exc) from None
    return path


# ---- CSV ---------------------------------------------------------------------------------------------------

def _csv_text(rows: Iterable[Sequence]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def write_csv(path: str | Path, header: Sequence[str], rows: Iterable[Sequence]) -> Path:
    """Write ``header`` and ``rows`` as CSV (the :mod:`csv` module's quoting, ``\\n`` line ends), whole or not at
    all (:func:`atomic_write`). Returns ``path``."""
    text = _csv_text([list(header), *(list(r) for r in rows)])
    return atomic_write(path, lambda fh: fh.write(text.encode()))


def append_csv_row(path: str | Path, header: Sequence[str], row: Sequence) -> Path:
    """Append one CSV ``row`` to ``path``, writing ``header`` first when the file is new (or empty).

    Atomic, copy-append-rename: the old content and the new row go to a temporary file beside ``path``, which is
    renamed over it, so a reader never sees half a row and a failure leaves the old file as it was. The row is
    quoted by the :mod:`csv` module (a comma or a quote inside a field stays one field). Returns ``path``.

    Raises
    ------
    OutputError
        ``path`` exists with another header (the sentence says which), or cannot be read or written.
    """
    path = Path(path)
    header = [str(h) for h in header]
    row = list(row)
    if len(row) != len(header):
        raise ValueError(f"append_csv_row: the row has {len(row)} fields but the header {len(header)}.")
    try:
        old = path.read_bytes() if path.exists() else b""
    except OSError as exc:
        raise output_error(path, exc, "read") from None
    if old.strip():
        first = next(csv.reader(io.StringIO(old.decode(errors="replace").splitlines()[0])), [])
        if first != header:
            raise OutputError(f"Cannot append to {short(path)}: its header is {short(','.join(first), 60)}, not "
                              f"{short(','.join(header), 60)}; move it away (a new file gets the right header).")
        if not old.endswith(b"\n"):
            old += b"\n"
        new = old + _csv_text([row]).encode()
    else:
        new = _csv_text([header, row]).encode()
    return atomic_write(path, lambda fh: fh.write(new))


# ---- --out --------------------------------------------------------------------------------------------------

def check_out_dir(out: str | Path) -> Path:
    """Check, before any work and without creating anything, that ``out`` is a directory that exists or can be
    created, and that it is writable. Returns ``Path(out)``.

    Raises
    ------
    OutputError
        ``out`` (or one of its ancestors) is a file; the nearest existing ancestor cannot be written (no permission,
        a read-only file system); the name is too long.
    """
    if str(out).strip() == "":
        raise OutputError("`out` is empty; give a directory (e.g. '.' for the current one).")
    out = Path(out)
    if os.path.islink(out) and not os.path.exists(out):
        raise OutputError(f"`out` {short(out)} is a symbolic link to nothing (a missing target or a loop of links); "
                          "give a directory.")
    if os.path.lexists(out) and not out.is_dir():
        raise OutputError(f"`out` {short(out)} is a file, not a directory; give a directory (it is created if "
                          "missing).")
    probe = out
    while not os.path.lexists(probe):
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise OutputError(f"`out` {short(out)} cannot be created: {short(probe)} is a file, not a directory; give "
                          "another `out`.")
    if not os.access(probe, os.W_OK | os.X_OK):
        try:
            readonly = bool(os.statvfs(probe).f_flag & os.ST_RDONLY)
        except (OSError, AttributeError):
            readonly = False
        why = "is on a read-only file system" if readonly else "is not writable"
        raise OutputError(f"`out` {short(out)} cannot be written: {short(probe)} {why}; choose a writable `out`.")
    try:
        max_name = os.pathconf(probe, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        max_name = 255
    if any(len(part.encode()) > max_name for part in out.parts):
        raise OutputError(f"`out` {short(out)} has a name longer than {max_name} bytes; choose a shorter `out`.")
    return out


# ---- input files --------------------------------------------------------------------------------------------

def check_input_file(path: str | Path, *, what: str = "File", flag: str = "", max_bytes: int | None = None) -> Path:
    """Check, before reading it, that ``path`` names a regular file that can be read (and, with ``max_bytes``, is
    at most that large); return its absolute path (symbolic links resolved).

    ``what`` names the file in the sentence (``"MJCF file"``), ``flag`` the Python argument that gave it, between
    backquotes (``"`plant`"``; the command line prints its option, :mod:`cartpole.commands._flags`).
    Nothing is opened: a FIFO (which would block), a device such as ``/dev/zero`` (which never ends), a directory,
    a socket or a symbolic-link loop is refused by its kind.

    Raises
    ------
    InputFileError
        Missing, a loop of symbolic links, not a regular file, not readable, or larger than ``max_bytes``.
    """
    text = os.path.expanduser(str(path))
    give = f"pass {flag} with the path of a readable file" if flag else "give the path of a readable file"

    def refuse(reason):
        err = InputFileError(f"{what} '{short(text)}' {reason}; {give}.")
        err.reason = reason
        return err

    try:
        st = os.stat(text)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise refuse("is a loop of symbolic links") from None
        if exc.errno in (errno.ENOENT, errno.ENOTDIR):
            raise refuse("does not exist") from None
        raise refuse(f"cannot be read ({exc.strerror})") from None
    kind = None
    if stat.S_ISDIR(st.st_mode):
        kind = "a directory"
    elif stat.S_ISFIFO(st.st_mode):
        kind = "a FIFO (named pipe)"
    elif stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode):
        kind = "a device"
    elif stat.S_ISSOCK(st.st_mode):
        kind = "a socket"
    elif not stat.S_ISREG(st.st_mode):
        kind = "not a regular file"
    if kind is not None:
        raise refuse(f"is {kind}, not a regular file")
    if not os.access(text, os.R_OK):
        raise refuse("is not readable (permission denied)")
    if max_bytes is not None and st.st_size > max_bytes:
        raise refuse(f"is {st.st_size / 2**20:.3g} MiB, more than the {max_bytes / 2**20:.3g} MiB limit")
    return Path(os.path.realpath(text))


def read_bounded(path: str | Path, max_bytes: int, *, what: str = "File", flag: str = "") -> bytes:
    """The bytes of the regular file ``path`` (:func:`check_input_file`), read with a bound: never more than
    ``max_bytes`` + 1 bytes are read, so a file that grows (or a path swapped for a device) cannot exhaust memory.

    Raises
    ------
    InputFileError
        As :func:`check_input_file`, or the file grew past ``max_bytes`` while read.
    """
    real = check_input_file(path, what=what, flag=flag, max_bytes=max_bytes)
    try:
        with open(real, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise InputFileError(f"{what} '{short(path)}' cannot be read ({exc.strerror}); check the path.") from None
    if len(data) > max_bytes:
        err = InputFileError(f"{what} '{short(path)}' grew past the {max_bytes / 2**20:.3g} MiB limit while read; "
                             "give a smaller file.")
        err.reason = f"grew past the {max_bytes / 2**20:.3g} MiB limit while read"
        raise err
    return data


# ---- exclusive locks ------------------------------------------------------------------------------------------

class LockedError(CartPoleError):
    """Another process holds the lock (one sentence: what is locked, by which process, what to do)."""


@contextmanager
def exclusive_lock(lock_path: str | Path, what: str, advice: str) -> Iterator[Path]:
    """Hold an exclusive ``fcntl.flock`` on ``lock_path`` (created, with its directory, if missing) inside the block;
    refuse at once, without waiting, when another process holds it. The lock file keeps the holder's process id
    (for the sentence) and stays on disk (removing it would let two processes lock two files of one name); the
    kernel releases the lock when the block ends or the process dies, however it dies.

    Raises
    ------
    LockedError
        Another process holds the lock: ``"{what} is in use by process N; {advice}."``.
    OutputError
        The lock file cannot be created.
    """
    import fcntl

    lock_path = Path(lock_path)
    try:
        lock_path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o600)
    except OSError as exc:
        raise output_error(lock_path, exc, "create the lock file") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            except OSError:
                holder = "?"
            raise LockedError(f"{what} is in use by process {holder}; {advice}.") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield lock_path
    finally:
        os.close(fd)  # releases the lock
