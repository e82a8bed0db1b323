"""Input and output: the one way the package reads a user's file and writes an output.

* :mod:`starsense._io.reading` — reading with errors that name the path;
* :mod:`starsense._io.files` — atomic writing (output checked first: never a device, a FIFO
  or a socket; temporaries swept, renames held against signals);
* :mod:`starsense._io.jsonout` — JSON that is always valid (``null`` for NaN and infinity);
* :mod:`starsense._io.net` — a refused connection known at once, a timeout that says how long.
"""

from starsense._io.files import (
    atomic_path,
    atomic_paths,
    atomic_write,
    check_output,
    check_outputs_in,
    deferred_signals,
    dir_mode,
    file_mode,
    note_written,
    sweep_stale,
    temp_prefix,
    written,
)
from starsense._io.jsonout import json_text, jsonable
from starsense._io.reading import read_bytes, read_text, readable_file

__all__ = [
    "atomic_path",
    "atomic_paths",
    "atomic_write",
    "check_output",
    "check_outputs_in",
    "deferred_signals",
    "dir_mode",
    "file_mode",
    "json_text",
    "jsonable",
    "note_written",
    "probe_tcp",
    "read_bytes",
    "read_text",
    "readable_file",
    "sweep_stale",
    "temp_prefix",
    "written",
]


def __getattr__(name: str):
    """Return ``probe_tcp``, imported on first use (its socket module is not a solve's)."""
    if name == "probe_tcp":
        from starsense._io.net import probe_tcp  # noqa: PLC0415

        globals()[name] = probe_tcp
        return probe_tcp
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
