"""File output: the one way the package writes an output (reading: :mod:`.reading`).

Writing (:func:`atomic_path`, :func:`atomic_write`): the output's place is checked first
(:func:`check_output`: its directory exists, is a directory and may be written; the target is
a new path or a regular file, never a directory, a device, a FIFO, a socket or a symbolic link
to one of them, which the rename would replace), then the file is written to a temporary name
in that directory, flushed to disk, given the permissions any file the user creates would get
(``0666`` less the umask, not ``mkstemp``'s ``0600``) and renamed into place. An error, an
interrupt or SIGTERM leaves neither a partial file nor the temporary one behind; a write
failure is reported as :class:`~starsense.errors.OutputError` naming the user's path.
Temporaries carry the writing process's id (:func:`temp_prefix`), so those of a run killed
outright (SIGKILL, power loss) are removed by the next write into the same place
(:func:`sweep_stale`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import signal
import stat
import tempfile
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

from starsense.errors import OutputError, one_line, unwind_if_signalled

__all__ = [
    "atomic_path",
    "atomic_paths",
    "atomic_write",
    "check_output",
    "check_outputs_in",
    "deferred_signals",
    "dir_mode",
    "file_mode",
    "sweep_stale",
    "temp_prefix",
    "written",
]

#: marks a temporary name as ours: ``.{target}.starsense-{pid}-...``
_TMP_TAG = "starsense-"
_TMP_PID = re.compile(r"^(\d+)-")
#: errors of the disk, not of the program: reported against the user's path
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EPERM}


#: files and folders this process renamed into place, in order (:func:`written`)
_WRITTEN: list[Path] = []


def written(*, forget: bool = False) -> list[Path]:
    """Return the outputs this process has put in place (renamed complete), oldest first.

    The command line says after an interrupt whether anything was written before it (a signal
    held back during a commit is raised once the files are complete). Only what is still there
    counts: a file completed inside a staging folder that was then renamed into place or
    discarded is not the user's output (the folder, when renamed, is). ``forget`` clears the
    list (a new command starts).
    """
    out = [p for p in _WRITTEN if os.path.lexists(p)]
    if forget:
        _WRITTEN.clear()
    return out


def note_written(path: str | os.PathLike[str]) -> None:
    """Record an output put in place by a rename outside :func:`atomic_paths` (a folder)."""
    _WRITTEN.append(Path(path))


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


# -- writing ------------------------------------------------------------------------------------


def check_output(
    target: str | os.PathLike[str],
    what: str = "output",
    *,
    directory: bool = False,
    make_parents: bool = False,
) -> Path:
    """Check, before any work, that ``target`` can be written; return it as a Path.

    Parameters
    ----------
    target : path-like
        The file (or, with ``directory``, the directory) to create or replace.
    what : str
        What the output is, for the message ("--out").
    directory : bool
        ``target`` is a directory to create or replace (a report), not a file; missing
        directories above it will be created, so the nearest existing one is checked.
    make_parents : bool
        ``target`` is a file whose missing directories the writer creates (a figure): the
        nearest existing one is checked.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    OutputError
        An empty path, a parent that is missing, not a directory or not writable, a target
        that is a directory when a file is wanted (a file when a directory is wanted), or one
        that is neither a regular file nor a directory: a device, a FIFO, a socket, or a
        symbolic link to one of them (writing would replace it with a regular file).
    """
    text = os.fspath(target) if isinstance(target, str | os.PathLike) else None
    if not isinstance(text, str) or not text.strip():
        raise OutputError(f"{what} path is empty (got {target!r})")
    if "\0" in text:  # no file is named so (the system refuses the name: a ValueError)
        raise OutputError(f"{what} path {one_line(text, 200)} holds a NUL byte")
    p = Path(text).expanduser()
    parent = p.absolute().parent
    shown = f"cannot write {what} {p}"
    if directory or make_parents:  # missing folders on the way are created: the nearest counts
        while not parent.exists() and parent != parent.parent:
            parent = parent.parent
    if not parent.exists():
        raise OutputError(f"{shown}: directory {parent} does not exist")
    if not parent.is_dir():
        raise OutputError(f"{shown}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{shown}: directory {parent} is not writable")
    special = _special_kind(p)
    if special is not None:
        wanted = "a directory" if directory else "a regular file"
        raise OutputError(f"{shown}: it is {special}, not {wanted}")
    if not directory and p.is_dir():
        raise OutputError(f"{shown}: it is a directory")
    if directory and p.exists() and not p.is_dir():
        raise OutputError(f"{shown}: it exists and is not a directory")
    return p


def check_outputs_in(
    folder: str | os.PathLike[str], names: Sequence[str], what: str = "output"
) -> list[Path]:
    """Check, before any work, the files a command will write into ``folder``.

    ``folder`` itself is checked by ``check_output(folder, what, directory=True)`` (it may not
    exist yet); each name in it must be a new path or a regular file (:func:`check_output`).

    Parameters
    ----------
    folder : path-like
        The output folder (``--out``, ``--maps``).
    names : sequence of str
        The files the command writes there.
    what : str
        The option, for the message.

    Returns
    -------
    list of pathlib.Path
        ``folder / name`` for each name.

    Raises
    ------
    OutputError
        As :func:`check_output`, naming the file in the folder.
    """
    base = check_output(folder, what, directory=True)
    return [check_output(base / name, what, make_parents=True) for name in names]


#: what a path is, when it is neither a regular file nor a directory
_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def _special_kind(path: Path) -> str | None:
    """Say what ``path`` is if it exists and is neither a regular file nor a directory.

    A symbolic link is judged by what it points to ("a symbolic link to a FIFO"); a dangling
    link, a regular file, a directory or no file at all give None.
    """
    try:
        st = os.lstat(path)
    except OSError:  # nothing there (or the parent check already spoke)
        return None
    link = stat.S_ISLNK(st.st_mode)
    if link:
        try:
            st = os.stat(path)
        except OSError:  # a dangling link (or a loop): the rename replaces the link itself
            return None
    mode = st.st_mode
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    kind = next((name for test, name in _KINDS if test(mode)), "a special file")
    return f"a symbolic link to {kind}" if link else kind


def temp_prefix(target: str | os.PathLike[str]) -> str:
    """Return the start of the temporary names of ``target``: ``.{name}.starsense-{pid}-``."""
    return f".{Path(target).name}.{_TMP_TAG}{os.getpid()}-"


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True  # another user's process (or a number we cannot ask about): leave it
    return True


def sweep_stale(target: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporaries a killed run left beside ``target``.

    Only names this module makes (:func:`temp_prefix`) whose process no longer runs are
    removed; a concurrent run's temporaries are left alone.

    Parameters
    ----------
    target : path-like
        The output about to be written.

    Returns
    -------
    list of pathlib.Path
        What was removed.
    """
    target = Path(target)
    head = f".{target.name}.{_TMP_TAG}"
    removed = []
    try:
        entries = [e for e in os.scandir(target.parent or ".") if e.name.startswith(head)]
    except OSError:
        return removed
    for entry in entries:
        m = _TMP_PID.match(entry.name[len(head) :])
        if m is None or _alive(int(m.group(1))):
            continue
        path = Path(entry.path)
        with contextlib.suppress(OSError):
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(path)
            else:
                path.unlink()
            removed.append(path)
    return removed


def _fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:  # some file systems refuse fsync on read-only descriptors
        pass
    finally:
        os.close(fd)


def _output_error(target: Path, exc: OSError) -> OutputError:
    return OutputError(f"cannot write {target}: {exc.strerror or exc}")


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back while the block runs (the commit of an output).

    A signal arriving meanwhile is noted and raised again when the block ends, for the
    handler that was in place, so renames that belong together (an image and its truth, a
    report swapped for the old one) happen all or none. (The Python-level handlers are swapped
    rather than the thread's signal mask: a process-directed signal may land on any thread.)
    Outside the main thread, where handlers cannot be set, the block runs as is. A signal that
    arrived before the block, its unwind swallowed by a library on the way, ends it before it
    starts (:func:`~starsense.errors.unwind_if_signalled`): nothing is committed after one.
    """
    unwind_if_signalled()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM)
    old = {s: signal.signal(s, lambda signum, frame: pending.append(signum)) for s in held}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(pending):
            signal.raise_signal(s)


@contextlib.contextmanager
def atomic_paths(
    targets: Sequence[str | os.PathLike[str]],
    suffixes: Sequence[str] | None = None,
    *,
    output: bool = True,
) -> Iterator[list[Path]]:
    """Yield temporary paths beside ``targets``; rename them all into place on success.

    The renames run with SIGINT and SIGTERM held back (:func:`deferred_signals`): after an
    interrupt every target holds its old content, or every target its new one.

    Parameters
    ----------
    targets : sequence of path-like
        The files to create or replace, renamed in this order.
    suffixes : sequence of str, optional
        Ending of each temporary name (default ``.tmp``).
    output : bool
        The files are the command's output (listed by :func:`written`), not a cache of its own.

    Yields
    ------
    list of pathlib.Path
        Where to write, one per target.

    Raises
    ------
    OutputError
        A directory is missing or read-only, a target is a directory, or the disk refused
        the write (full, read-only): the message names the target.
    """
    paths = [check_output(t) for t in targets]
    suffixes = list(suffixes) if suffixes is not None else [".tmp"] * len(paths)
    tmps: list[str] = []
    try:
        for target, suffix in zip(paths, suffixes, strict=True):
            sweep_stale(target)
            try:
                fd, tmp = tempfile.mkstemp(
                    prefix=temp_prefix(target), suffix=suffix, dir=target.parent
                )
            except OSError as exc:
                raise _output_error(target, exc) from None
            os.close(fd)
            tmps.append(tmp)
        current = paths[0]
        try:
            yield [Path(t) for t in tmps]
            with deferred_signals():
                for target, tmp in zip(paths, tmps, strict=True):
                    current = target
                    os.chmod(tmp, file_mode())
                    _fsync(tmp)
                for target in paths:  # one made meanwhile (a FIFO) is refused, not replaced
                    check_output(target)
                for target, tmp in zip(paths, tmps, strict=True):
                    current = target
                    os.replace(tmp, target)
                    if output:
                        _WRITTEN.append(target)
        except OSError as exc:
            ours = exc.filename in (*tmps, *map(str, paths))
            if ours or (exc.filename is None and exc.errno in _DISK_ERRNOS):
                raise _output_error(current, exc) from None
            raise
    finally:
        for tmp in tmps:
            with contextlib.suppress(FileNotFoundError):
                os.remove(tmp)


@contextlib.contextmanager
def atomic_path(
    target: str | os.PathLike[str], suffix: str = ".tmp", *, output: bool = True
) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it to ``target`` on success.

    For writers that take a file name (``fig.savefig``, ``fits.writeto``, Pillow). The
    directory of ``target`` must exist (:func:`check_output`). ``suffix`` keeps the extension a
    writer may look at.

    Parameters
    ----------
    target : path-like
        The file to create or replace.
    suffix : str
        Ending of the temporary name.
    output : bool
        The file is the command's output (listed by :func:`written`), not a cache of its own.

    Yields
    ------
    pathlib.Path
        Where to write.

    Raises
    ------
    OutputError
        The directory is missing or read-only, ``target`` is a directory, or the disk refused
        the write (full, read-only): the message names ``target``.
    """
    with atomic_paths([target], [suffix], output=output) as (tmp,):
        yield tmp


@contextlib.contextmanager
def atomic_write(
    target: str | os.PathLike[str],
    mode: str = "w",
    *,
    suffix: str = ".tmp",
    output: bool = True,
    **kwargs: Any,
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
    output : bool
        The file is the command's output (listed by :func:`written`), not a cache of its own.
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
    with atomic_path(target, suffix=suffix, output=output) as tmp, open(tmp, mode, **kwargs) as fh:
        yield fh
        fh.flush()
