"""Write output files whole or not at all."""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Callable, Iterator


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: str | Path, *, suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed over ``path`` when the block ends without error.

    For writers that take a file name rather than a file object (an encoder in another process, say). The
    temporary file exists (empty) when the block starts, its name ends with ``suffix`` (give the target's own,
    e.g. ``".mp4"``, when the writer picks its format from the name). A failure part-way leaves no file behind
    (and an existing ``path`` untouched). The result gets the usual permissions (``0o666`` less the umask), not
    ``mkstemp``'s private ``0o600``. Parent directories are created.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Call ``write(fileobj)`` on a temporary file beside ``path``, then rename it over ``path``.

    A failure part-way leaves no file behind (and an existing ``path`` untouched). The result gets the usual
    permissions (``0o666`` less the umask), not ``mkstemp``'s private ``0o600``. Parent directories are
    created. Returns ``path``.
    """
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        write(fh)
    return path
