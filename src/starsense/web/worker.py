"""One verification of the design page, in its own interpreter (see :mod:`starsense.web.jobs`).

Run as ``python -m starsense.web.worker``: reads one JSON line ``{"document", "catalog",
"settings", "parent"}`` on standard input, builds the datasheet of the design on rendered
frames at a lower scheduling priority, and writes JSON lines on standard output:
``["progress", label, done, total]`` as it goes, then ``["result", datasheet]`` or
``["error", one-line message]``. It ignores SIGINT (the server's Ctrl-C ends it through the
server) and, on Linux, is killed when the server dies.
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import signal
import sys

__all__ = ["NICENESS", "main"]

#: the niceness added to a verification's process: the page's predictions come first
NICENESS = 10


def _die_with(parent: int) -> None:
    """Ask Linux to kill this process when the server dies; exit if it has already.

    SIGKILL, not SIGTERM: the server may have held this process (SIGSTOP), and a stopped
    process takes no other signal; it writes nothing that could be left half done.
    """
    pr_set_pdeathsig = 1
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:
        raise SystemExit(1)


def main() -> None:
    """Read the task, build the datasheet, report (see the module docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    out = os.fdopen(os.dup(sys.stdout.fileno()), "w", encoding="utf-8", buffering=1)
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # a stray print cannot garble a report
    task = json.loads(sys.stdin.readline())
    _die_with(int(task["parent"]))
    with contextlib.suppress(OSError):
        os.nice(NICENESS)

    def report(*message) -> None:
        out.write(json.dumps(message) + "\n")

    try:
        # imported here, at the lower priority: loading them is a good part of the work
        from starsense.analysis.datasheet.sheet import (  # noqa: PLC0415
            DatasheetSettings,
            build_datasheet,
        )
        from starsense.analysis.inputs import as_catalog  # noqa: PLC0415
        from starsense.sensor.load import sensor_from_dict  # noqa: PLC0415

        sensor = sensor_from_dict(task["document"], source="design")
        settings = DatasheetSettings(**task["settings"])
        catalog = as_catalog(task["catalog"])
        sheet = build_datasheet(
            sensor,
            catalog,
            settings=settings,
            progress=lambda label, done, total: report("progress", label, done, total),
        )
        report("result", sheet.to_dict())
    except Exception as exc:  # shown to the user beside the button, on one line
        report("error", " ".join(str(exc).split())[:500] or type(exc).__name__)
    finally:
        out.close()


if __name__ == "__main__":
    main()
