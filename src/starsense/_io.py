"""Atomic file output: the one way the package writes a file a user asked for.

A file is written to a temporary name in its target directory, flushed to disk, given the
permissions any file the user creates would get (``0666`` less the umask, not ``mkstemp``'s
``0600``) and renamed into place. An error, or an interrupt, leaves neither a partial file nor
the temporary one behind.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

__all__ = ["atomic_path", "atomic_write", "dir_mode", "file_mode"]


def file_mode() -> int:
    """Permissions of a new file under the current umask (``0o666 & ~umask``)."""
    return 0o666 & ~_umask()


def dir_mode() -> int:
    """Permissions of a new directory under the current umask (``0o777 & ~umask``)."""
    return 0o777 & ~_umask()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:  # some file systems refuse fsync on read-only descriptors
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike[str], suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it to ``target`` on success.

    For writers that take a file name (``fig.savefig``, ``fits.writeto``, Pillow). The
    directory of ``target`` must exist. ``suffix`` keeps the extension a writer may look at.

    Parameters
    ----------
    target : path-like
        The file to create or replace.
    suffix : str
        Ending of the temporary name.

    Yields
    ------
    pathlib.Path
        Where to write.
    """
    target = Path(target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix, dir=target.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, file_mode())
        _fsync(tmp)
        os.replace(tmp, target)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.remove(tmp)


@contextlib.contextmanager
def atomic_write(
    target: str | os.PathLike[str], mode: str = "w", *, suffix: str = ".tmp", **kwargs: Any
) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``target`` for writing; rename it into place on success.

    Parameters
    ----------
    target : path-like
        The file to create or replace.
    mode : {"w", "wb"}
        Text or binary.
    suffix : str
        Ending of the temporary name.
    **kwargs
        Passed to :func:`open` (``encoding``, ``newline``); text mode defaults to UTF-8.

    Yields
    ------
    file object
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_write mode must be 'w' or 'wb', got {mode!r}")
    if mode == "w":
        kwargs.setdefault("encoding", "utf-8")
    with atomic_path(target, suffix=suffix) as tmp, open(tmp, mode, **kwargs) as fh:
        yield fh
        fh.flush()
