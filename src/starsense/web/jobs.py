"""The design page's verifications: datasheets on rendered frames, each in its own process.

A verification renders and solves tens to hundreds of frames (seconds each). Run in the
server's process it would hold the interpreter against the page's predictions and could not
be stopped; here each runs in a child interpreter (``python -m starsense.web.worker``) at a
lower scheduling priority, so

* at most :data:`MAX_RUNNING` run at once; another request is refused (:class:`Busy`, the
  server's 429) rather than queued without end;
* a prediction of the page is answered meanwhile: the children are held (SIGSTOP) while it
  runs (:meth:`Verifications.paused`) and go on after it (SIGCONT). A lower priority alone
  was not enough: a niced child still takes the other core, the memory bandwidth and the
  disk while it starts, and a prediction beside two took 3 to 4 times as long as alone;
* :meth:`Verifications.close` (the server stopping, SIGTERM) ends every child at once, and a
  child whose server died ends too (Linux: the parent-death signal, SIGKILL, which a held
  child gets too).

The child reads its task as one JSON line on its standard input and reports JSON lines on its
standard output (:mod:`starsense.web.worker`), read by one thread per job.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import json
import os
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from typing import Any

__all__ = ["MAX_FRAMES", "MAX_RUNNING", "Busy", "Verifications"]

#: verifications running at once (the machine's other work, and the page's predictions, need
#: the processor too)
MAX_RUNNING = 2
#: most rendered frames per rate of one verification (at about a second a frame, minutes)
MAX_FRAMES = 200
#: finished verifications whose results are kept for the page to read (the oldest go first)
KEEP_FINISHED = 64
#: how long a child may take to end after SIGTERM before it is killed, s
STOP_WAIT_S = 0.5


class Busy(Exception):
    """No verification can start now: :data:`MAX_RUNNING` run (status 429), or the server is
    stopping (503)."""  # noqa: D205, D209

    def __init__(self, message: str, status: int = 429) -> None:
        super().__init__(message)
        self.status = status


@dataclass
class _Job:
    process: Any
    total: int = 6
    done: int = 0
    label: str = "starting"
    result: dict | None = None
    error: str | None = None
    cancelled: bool = False
    watcher: threading.Thread | None = None
    lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def finished(self) -> bool:
        return self.result is not None or self.error is not None

    def status(self) -> dict:
        with self.lock:
            return {
                "done": self.done,
                "total": self.total,
                "label": self.label,
                "error": self.error,
                "result": self.result,
            }


class Verifications:
    """The running and recent verifications of one server.

    Parameters
    ----------
    catalog : str or None
        The catalogue specification each child loads (None: the bundled Hipparcos).
    max_running : int
        Verifications at once.
    """

    def __init__(self, catalog: str | None, max_running: int = MAX_RUNNING) -> None:
        self.catalog = catalog
        self.max_running = max_running
        self._jobs: dict[str, _Job] = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._closed = False
        self._holds = 0  # predictions running: the children are stopped while > 0

    def running(self) -> int:
        """Return how many verifications run now."""
        with self._lock:
            return sum(not j.finished for j in self._jobs.values())

    def start(self, document: dict, settings) -> str:
        """Start verifying ``document`` with ``settings``; return the job's id.

        Raises
        ------
        Busy
            :attr:`max_running` verifications run already (429), or the server is stopping or
            cannot start a process (503).
        """
        with self._lock:
            if self._closed:
                raise Busy("the server is stopping", 503)
            running = sum(not j.finished for j in self._jobs.values())
            if running >= self.max_running:
                raise Busy(
                    f"{running} verifications are running (at most {self.max_running} at once); "
                    "try again when one has finished"
                )
            task = json.dumps(
                {
                    "document": document,
                    "catalog": self.catalog,
                    "settings": dataclasses.asdict(settings),
                    "parent": os.getpid(),
                }
            )
            try:
                process = subprocess.Popen(
                    [sys.executable, "-m", "starsense.web.worker"],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.DEVNULL,
                    text=True,
                    encoding="utf-8",
                )
            except OSError as exc:  # no process to be had (limits, memory)
                raise Busy(f"cannot start a verification: {exc.strerror or exc}", 503) from None
            if self._holds:
                _signal(process, signal.SIGSTOP)
            job_id, job = str(next(self._ids)), _Job(process)
            job.watcher = threading.Thread(target=_watch, args=(job, task), daemon=True)
            self._jobs[job_id] = job
            self._prune()
            job.watcher.start()
        return job_id

    def status(self, job_id: str) -> dict | None:
        """Return a job's progress and, when done, its datasheet (None: no such job)."""
        job = self._jobs.get(job_id)
        return None if job is None else job.status()

    @contextlib.contextmanager
    def paused(self):
        """Hold the running verifications (SIGSTOP) while the block runs, then let them go on."""
        with self._lock:
            self._holds += 1
            if self._holds == 1:
                for job in self._jobs.values():
                    _signal(job.process, signal.SIGSTOP)
        try:
            yield
        finally:
            with self._lock:
                self._holds -= 1
                if self._holds == 0:
                    for job in self._jobs.values():
                        _signal(job.process, signal.SIGCONT)

    def close(self) -> None:
        """Refuse new verifications and end the running ones (their processes) now."""
        with self._lock:
            self._closed = True
            jobs = [j for j in self._jobs.values() if not j.finished]
        for job in jobs:
            job.cancelled = True
            _signal(job.process, signal.SIGTERM)
            _signal(job.process, signal.SIGCONT)  # a held child must run to take the SIGTERM
        for job in jobs:
            try:
                job.process.wait(STOP_WAIT_S)
            except subprocess.TimeoutExpired:
                job.process.kill()
                job.process.wait()
            job.watcher.join(STOP_WAIT_S)  # its last word: "cancelled"

    def _prune(self) -> None:
        finished = [k for k, j in self._jobs.items() if j.finished]
        for key in finished[: max(0, len(finished) - KEEP_FINISHED)]:
            del self._jobs[key]


def _signal(process: subprocess.Popen, signum: int) -> None:
    """Send ``signum`` to a child still running (one that has ended, and been waited for, not)."""
    if process.returncode is None:
        with contextlib.suppress(OSError):
            process.send_signal(signum)


def _watch(job: _Job, task: str) -> None:
    """Send a child its task, then read its reports into its job until it is gone."""
    process = job.process
    try:
        process.stdin.write(task + "\n")
        process.stdin.close()
        for line in process.stdout:
            message = json.loads(line)
            with job.lock:
                if message[0] == "progress":
                    job.label, job.done, job.total = message[1:]
                elif message[0] == "result":
                    job.result = message[1]
                else:
                    job.error = message[1]
    except (OSError, ValueError):  # the child went away mid-line (killed)
        pass
    finally:
        with contextlib.suppress(OSError):
            process.stdout.close()
        process.wait()
        with job.lock:
            if job.result is None and job.error is None:
                job.error = (
                    "cancelled: the server is stopping"
                    if job.cancelled
                    else f"the verification ended without a result (exit {process.returncode})"
                )
