"""File input: the one way the package reads a user's file.

A missing file, an empty path, a directory, a file the user may not read or text that is not
UTF-8 raise :class:`~starsense.errors.InputError` naming the path, never an ``OSError`` or
``UnicodeDecodeError``.
"""

from __future__ import annotations

import os
from pathlib import Path

from starsense.errors import InputError, one_line

__all__ = ["read_bytes", "read_text", "readable_file"]


def readable_file(path: str | os.PathLike[str], what: str = "file") -> Path:
    """Return ``path`` as a :class:`~pathlib.Path` after checking it names a readable file.

    Parameters
    ----------
    path : path-like
        What the user gave (``~`` is expanded).
    what : str
        What the file is, for the message ("sensor file", "image").

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        An empty path, no such file, a directory, not a regular file, or not readable; the
        message names ``what`` and the path.
    """
    text = os.fspath(path) if isinstance(path, str | os.PathLike) else None
    if not isinstance(text, str) or not text.strip():
        raise InputError(f"{what} path is empty (got {path!r})")
    if "\0" in text:  # no file is named so (the system refuses the name: a ValueError)
        raise InputError(f"{what} path {one_line(text, 200)} holds a NUL byte")
    p = Path(text).expanduser()
    try:
        p.stat()
    except FileNotFoundError:
        raise InputError(f"{what} not found: {p}") from None
    except OSError as exc:  # permission on a parent, name too long, a loop of links
        raise InputError(f"cannot read {what} {p}: {exc.strerror or exc}") from None
    if p.is_dir():
        raise InputError(f"{what} {p} is a directory, not a file")
    if not p.is_file():
        raise InputError(f"{what} {p} is not a regular file")
    if not os.access(p, os.R_OK):
        raise InputError(f"cannot read {what} {p}: permission denied")
    return p


def read_bytes(path: str | os.PathLike[str], what: str = "file") -> bytes:
    """Return the bytes of a file, with OS errors as :class:`InputError` naming the path.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file is, for the message.

    Returns
    -------
    bytes
    """
    p = readable_file(path, what)
    try:
        return p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {what} {p}: {exc.strerror or exc}") from None


def read_text(path: str | os.PathLike[str], what: str = "file") -> str:
    """Return a UTF-8 text file's content; OS and decoding errors raise :class:`InputError`.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file is, for the message.

    Returns
    -------
    str
    """
    raw = read_bytes(path, what)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError(
            f"{what} {Path(path).expanduser()} is not UTF-8 text: byte 0x{raw[exc.start]:02x} "
            f"at line {line}"
        ) from None
