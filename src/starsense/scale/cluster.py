"""The Dask cluster the distributed analyses run on: in-process by default, or any scheduler.

``--dask`` takes

* ``local`` (the default) or ``local:N``: a :class:`distributed.LocalCluster` on this machine with
  N single-threaded worker processes (default: one per CPU);
* ``tcp://HOST:PORT`` (or ``HOST:PORT``, ``tls://...``): an existing scheduler, e.g. one started
  with ``dask scheduler`` / ``dask worker`` or by dask-jobqueue / dask-kubernetes. The connection
  gives up after ``timeout_s`` with :class:`SchedulerUnreachableError` instead of hanging.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing.util as mp_util  # the spawn start method starts a child here
import os
import shutil
import signal
import tempfile
import threading
import time
from collections.abc import Iterator
from typing import Any

from starsense._io import probe_tcp
from starsense.errors import InputError
from starsense.scale._deps import quiet_third_party_warnings, require
from starsense.scale.errors import SchedulerUnreachableError

#: seconds to wait for a remote scheduler before giving up
CONNECT_TIMEOUT_S = 10.0


def parse_address(address: str | None) -> tuple[str, int | None]:
    """``("local", n_workers or None)`` or ``("remote", "tcp://host:port")``."""
    text = "local" if address is None else str(address).strip()
    if text == "local" or text.startswith("local:"):
        _, _, n_text = text.partition(":")
        if not n_text:
            return "local", None
        try:
            n = int(n_text)
        except ValueError:
            n = 0
        if n < 1:
            raise InputError(f"--dask local:N needs a number of workers N >= 1, got {address!r}")
        return "local", n
    if not text:
        raise InputError("--dask needs an address: local, local:N or tcp://HOST:PORT")
    if "://" not in text:
        text = f"tcp://{text}"
    scheme, _, rest = text.partition("://")
    host, _, port = rest.rpartition(":")
    if scheme not in ("tcp", "tls", "inproc", "ucx", "ws", "wss") or not host or not port:
        raise InputError(
            f"--dask {address!r} is not a scheduler address; expected local, local:N or "
            "tcp://HOST:PORT"
        )
    if scheme != "inproc" and not (port.isdigit() and 1 <= int(port) <= 65535):
        raise InputError(f"--dask {address!r}: port {port!r} is not a number in 1-65535")
    return "remote", text


def check_scheduler(address: str | None, timeout_s: float = CONNECT_TIMEOUT_S) -> tuple:
    """Parse ``address`` and, for a TCP scheduler, check that something listens there.

    Cheap (no Dask import): commands call it before any other work, so a malformed address or
    a refused connection is reported at once.

    Parameters
    ----------
    address : str or None
        As for :func:`dask_client`.
    timeout_s : float
        How long to wait for the scheduler's port to answer, s.

    Returns
    -------
    tuple
        What :func:`parse_address` returns.

    Raises
    ------
    InputError
        A malformed address (a port outside 1-65535).
    SchedulerUnreachableError
        The connection is refused (at once) or not answered within ``timeout_s``.
    """
    kind, value = parse_address(address)
    if kind == "remote" and value.startswith(("tcp://", "tls://")):
        host, _, port = value.partition("://")[2].rpartition(":")
        try:  # a refusal is known at once, not after the timeout
            probe_tcp(
                host.strip("[]"),
                int(port),
                timeout_s=timeout_s,
                what=f"no Dask scheduler at {value}",
            )
        except InputError as exc:
            raise SchedulerUnreachableError(str(exc)) from None
    return kind, value


#: how long a signal waits for the cluster's start to finish, s (workers killed by the same
#: signal, sent to the whole process group, can leave the start waiting for them for minutes)
START_GRACE_S = 10.0


@contextlib.contextmanager
def _starting_workers() -> Iterator[list[int]]:
    """Start processes that never see SIGINT; hold this process's SIGINT and SIGTERM back.

    A terminal's Ctrl-C goes to the whole process group: each local worker would print its own
    KeyboardInterrupt traceback while the command shuts the cluster down. The workers are
    spawned (by the cluster's threads) with SIGINT blocked in the spawning thread, and a
    blocked signal stays blocked across ``exec``: they never receive it. (Ignoring SIGINT
    process-wide instead lost a Ctrl-C that came while the cluster started: the command ran
    to its end.) This process notes a SIGINT or SIGTERM arriving meanwhile and raises it again
    when the block ends, once the cluster exists and can be closed (a SIGTERM that cut the
    start short left worker processes behind, and their scratch files), or after
    :data:`START_GRACE_S` if the start has not ended by then: the processes spawned so far
    are then killed (their ids are yielded) and no more are started.
    """
    spawned: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield spawned
        return
    spawn = mp_util.spawnv_passfds
    pending: list[int] = []
    stopped: list[bool] = []

    def spawn_without_sigint(*args, **kwargs):
        if stopped:
            raise OSError("the command was interrupted: no more workers are started")
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            pid = spawn(*args, **kwargs)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        spawned.append(pid)
        return pid

    def note(signum, frame):
        if not pending:
            signal.setitimer(signal.ITIMER_REAL, START_GRACE_S)
        pending.append(signum)

    def give_up(signum, frame):  # the start outlived the grace: the signal is raised now
        restore()
        stopped.append(True)
        _kill(spawned)
        first = pending[0]
        pending.clear()
        signal.raise_signal(first)

    held = (signal.SIGINT, signal.SIGTERM)
    old = {s: signal.signal(s, note) for s in held}
    old[signal.SIGALRM] = signal.signal(signal.SIGALRM, give_up)
    mp_util.spawnv_passfds = spawn_without_sigint

    def restore():
        signal.setitimer(signal.ITIMER_REAL, 0)
        mp_util.spawnv_passfds = spawn
        for s, handler in old.items():
            signal.signal(s, handler)

    try:
        yield spawned
    finally:
        if mp_util.spawnv_passfds is spawn_without_sigint:
            restore()
        for s in dict.fromkeys(pending):
            signal.raise_signal(s)


def _kill(pids: list[int]) -> None:
    """Kill the worker processes ``pids`` (an abandoned start) and reap them."""
    for pid in pids:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    for pid in pids:
        with contextlib.suppress(OSError):
            os.waitpid(pid, 0)


def _local_cluster(distributed, n: int, processes: bool, scratch: str):
    """Start a loopback LocalCluster of ``n`` single-thread workers with scratch in ``scratch``."""
    return distributed.LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=processes,
        local_directory=scratch,
        # TCP on the loopback even for thread workers: the scheduler can then be shared
        # by address (tcp://127.0.0.1:PORT) with other clients of this machine
        protocol="tcp://",
        host="127.0.0.1",
        # no dashboard: None would mean distributed's default, port 8787, and a
        # second starsense run on the same machine would then fail to start its cluster
        dashboard_address=":0",
        scheduler_kwargs={"dashboard": False},
        # CRITICAL: a worker's heartbeat racing the scheduler's shutdown logs an ERROR with
        # a traceback; task failures still reach the client as exceptions
        silence_logs=logging.CRITICAL,
    )


@contextlib.contextmanager
def dask_client(
    address: str | None = None,
    *,
    n_workers: int | None = None,
    processes: bool = True,
    timeout_s: float = CONNECT_TIMEOUT_S,
) -> Iterator[Any]:
    """Yield a :class:`distributed.Client`, closed (with its local cluster) on exit.

    Parameters
    ----------
    address : str or None
        ``None`` / ``"local"`` / ``"local:N"`` or a scheduler address (module notes).
    n_workers : int or None
        Workers of a local cluster when the address does not say (default: CPUs).
    processes : bool
        Local workers as processes (true parallelism; default) or threads in this process
        (fast start-up; NumPy releases the GIL in the heavy kernels).
    timeout_s : float
        Connect timeout for a remote scheduler, s.

    Raises
    ------
    SchedulerUnreachableError
        Nothing answers at the address within ``timeout_s``.
    """
    kind, value = check_scheduler(address, timeout_s)
    (distributed,) = require("distributed")
    if kind == "local":
        n = value or n_workers or os.cpu_count() or 1
        # the workers' scratch space (its lock files) in a folder of this run, removed after
        # (every server, the scheduler too, keeps one: dask's temporary-directory points there)
        scratch = tempfile.mkdtemp(prefix="starsense-dask-")
        (dask,) = require("dask")
        cluster = None
        try:
            # a signal during the start is raised as the block ends, with the cluster bound
            with _starting_workers(), dask.config.set({"temporary-directory": scratch}):
                cluster = _local_cluster(distributed, n, processes, scratch)
            client = distributed.Client(cluster)
            client.run(quiet_third_party_warnings)
            try:
                yield client
            finally:
                client.close()
        finally:
            try:
                if cluster is not None:
                    cluster.close()
            finally:
                shutil.rmtree(scratch, ignore_errors=True)
        return
    t0 = time.monotonic()
    try:
        client = distributed.Client(value, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError) as exc:
        raise SchedulerUnreachableError(
            f"no Dask scheduler answers at {value} (waited {time.monotonic() - t0:.1f} s): "
            f"{' '.join(str(exc).split())}"
        ) from None
    client.run(quiet_third_party_warnings)
    try:
        yield client
    finally:
        client.close()
