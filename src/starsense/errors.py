"""Exceptions for bad input, and the unwind of a signal.

Every error a user can cause derives from :class:`StarsenseError`; the CLI prints its message
on one line and exits with status 2. Messages name what is wrong and where (file, line, field,
value, allowed range) so that the user can act on them.

:class:`Interrupted` and :class:`Terminated` unwind the command line after Ctrl-C or SIGTERM.
The signals received are noted here (:func:`note_signal`), below every stage, so that a stage
can refuse to go on once one has arrived (:func:`unwind_if_signalled`) even where a library
caught the unwind and carried on: an output is never committed after a signal.
"""

from __future__ import annotations

import signal

#: longest message shown: what a message quotes from a file (a line of binary garbage, a
#: library's error about it) is cut there, never megabytes on the user's terminal
MAX_MESSAGE_CHARS = 2000


def one_line(text: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    r"""Return ``text`` for a terminal: one line, control characters escaped, cut at ``limit``.

    A file's bytes quoted in a message (escape sequences that clear the screen or recolour
    it, a bell, a NUL, a newline) are shown as ``\x1b``, ``\x07``, ``\n``.
    """
    if text.isprintable() and len(text) <= limit:
        return text
    out = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    if len(out) > limit:
        out = f"{out[:limit]} ... ({len(out) - limit:,} more characters)"
    return out


class StarsenseError(Exception):
    """Base class for user-facing errors (bad input, bad configuration, impossible geometry).

    Its message is one line whatever it quotes (:func:`one_line`).
    """

    def __str__(self) -> str:
        return one_line(super().__str__())


class InputError(StarsenseError, ValueError):
    """A parameter value is invalid (out of range, NaN, wrong shape, unknown name)."""


class CatalogFormatError(StarsenseError, ValueError):
    """A catalogue file is malformed.

    Parameters
    ----------
    path : str
        The file being read.
    detail : str
        What is wrong, e.g. ``"'abc' is not a number"``.
    line : int or None
        1-based line number (or record number for binary files), if known.
    field : str or None
        The name of the field that could not be parsed, if known.
    """

    def __init__(
        self, path: str, *, detail: str, line: int | None = None, field: str | None = None
    ) -> None:
        self.path = str(path)
        self.line = line
        self.field = field
        self.detail = detail
        where = self.path
        if line is not None:
            where += f", line {line}"
        if field is not None:
            where += f", field {field}"
        super().__init__(f"{where}: {detail}")


class SingularGeometryError(StarsenseError, ValueError):
    """The star geometry does not determine the attitude.

    Too few stars, or all on one great circle: the Fisher information matrix is singular.
    """


class OutputError(StarsenseError, OSError):
    """An output cannot be written where the user asked.

    A missing or read-only directory, a directory where a file should go, a full disk. The
    message names the user's path, never a temporary one. Also an :class:`OSError`, so code that
    treats a failed optional write (a cache) as harmless still catches it.
    """


class Terminated(BaseException):
    """SIGTERM arrived: unwind like KeyboardInterrupt (a BaseException, so no handler eats it)."""


class Interrupted(BaseException):
    """Ctrl-C (SIGINT) arrived: unwind, and exit 130 with one line.

    Not :class:`KeyboardInterrupt`, which typer turns into "Aborted!" and status 1, and which
    Python prints as a traceback where nothing catches it.
    """


#: the exception each signal unwinds with
UNWIND: dict[int, type[BaseException]] = {signal.SIGINT: Interrupted, signal.SIGTERM: Terminated}

#: the signals received since :func:`forget_signals`, in order
_RECEIVED: list[int] = []


def note_signal(signum: int) -> BaseException:
    """Note that ``signum`` arrived; return the exception that unwinds it (for the handler)."""
    _RECEIVED.append(signum)
    return UNWIND[signum]()


def signal_received() -> int | None:
    """Return the first signal received since :func:`forget_signals`, or None."""
    return _RECEIVED[0] if _RECEIVED else None


def forget_signals() -> None:
    """Start afresh (a new command)."""
    _RECEIVED.clear()


def unwind_if_signalled() -> None:
    """Raise the unwind of a signal already received, if one was.

    A library that catches every exception (an import turned into an ``ImportError`` and
    passed over, a worker pool's bookkeeping) can swallow the unwind; the command then runs
    on. Called before an output is committed and where a long stage begins, this ends it
    there instead.
    """
    if _RECEIVED:
        raise UNWIND[_RECEIVED[0]]()
