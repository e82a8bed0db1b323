"""A line on stderr while an identification database builds, once it has taken a second.

A first solve with a new sensor (or field) builds its database, seconds to tens of seconds,
before the frame's few milliseconds: without a word the command looks hung. :class:`BuildProgress`
says what is being built and where it will be cached, from the first second on (a build that
finishes sooner prints nothing). On a terminal the line is redrawn in place with the step and
the time so far, then ends with the total; elsewhere (a log, a pipe) it is one line when the
build has taken a second and one when it is done.
"""

from __future__ import annotations

import contextlib
import shutil
import sys
import threading
import time
from typing import TextIO

__all__ = ["SHOW_AFTER_S", "BuildProgress"]

#: a build is announced once it has taken this long, s
SHOW_AFTER_S = 1.0
#: the terminal line is redrawn this often, s
_REDRAW_S = 0.5


class BuildProgress:
    """Context manager: a progress line on ``stream`` while the block runs past ``after_s``.

    Parameters
    ----------
    what : str
        What is built, e.g. "the 11.4 deg identification database (about 10 s, once; cached
        in /home/u/.cache/starsense/identify)".
    after_s : float, optional
        Say nothing for a build shorter than this, s (default :data:`SHOW_AFTER_S`).
    stream : file, optional
        Where to write (default ``sys.stderr``, looked up on entry).

    Examples
    --------
    >>> with BuildProgress("the database") as progress:  # doctest: +SKIP
    ...     progress.step("patterns")
    """

    def __init__(
        self, what: str, *, after_s: float | None = None, stream: TextIO | None = None
    ) -> None:
        self.what = what
        self.after_s = float(SHOW_AFTER_S if after_s is None else after_s)
        self._stream = stream
        self._step = ""
        self._shown = False
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._t0 = 0.0

    def __enter__(self) -> BuildProgress:
        self._stream = self._stream if self._stream is not None else sys.stderr
        self._live = _is_terminal(self._stream)
        self._t0 = time.perf_counter()
        self._thread = threading.Thread(target=self._run, name="starsense-progress", daemon=True)
        self._thread.start()
        return self

    def step(self, text: str) -> None:
        """Name the step now running (shown on a terminal's line)."""
        self._step = text

    def _line(self, width: int) -> str:
        """Return the terminal's line, at most ``width`` characters (``what`` shortened)."""
        head = "starsense: building "
        tail = f"{': ' + self._step if self._step else ''} ... "
        tail += f"{time.perf_counter() - self._t0:.0f} s"
        room = width - len(head) - len(tail)
        what = self.what
        if len(what) > room:
            what = what[: room - 3] + "..." if room > 3 else ""
        return (head + what + tail)[:width]

    def _write(self, text: str) -> None:
        with self._lock, contextlib.suppress(OSError, ValueError):  # a closed or broken stream
            self._stream.write(text)
            self._stream.flush()

    def _show(self) -> None:
        """Say that the build has taken ``after_s`` (a log gets its one line here)."""
        self._shown = True
        if not self._live:
            self._write(f"starsense: building {self.what} ...\n")

    def _draw(self) -> None:
        """Redraw the terminal's line in place."""
        self._write("\r\x1b[K" + self._line(shutil.get_terminal_size().columns - 1))

    def _run(self) -> None:
        if self._done.wait(self.after_s):
            return  # finished within the grace time: nothing said
        self._show()
        while self._live and not self._done.is_set():
            self._draw()
            self._done.wait(_REDRAW_S)

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        if self._thread is not None:
            self._thread.join()
        took = time.perf_counter() - self._t0
        if not self._shown and took >= self.after_s:  # past it before the thread could say so
            self._show()
        if self._shown:
            ended = "done" if exc[0] is None else "stopped"
            lead = "\r\x1b[K" if self._live else ""
            self._write(f"{lead}starsense: building {self.what}: {ended} in {took:.1f} s\n")


def _is_terminal(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False
