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


@contextlib.contextmanager
def _children_ignore_sigint() -> Iterator[None]:
    """Start processes with SIGINT ignored (it stays ignored across exec, and Python keeps it so).

    A terminal's Ctrl-C goes to the whole process group: without this each local worker would
    print its own KeyboardInterrupt traceback while the command shuts the cluster down.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


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
        try:
            with _children_ignore_sigint(), dask.config.set({"temporary-directory": scratch}):
                cluster = _local_cluster(distributed, n, processes, scratch)
            try:
                client = distributed.Client(cluster)
                client.run(quiet_third_party_warnings)
                try:
                    yield client
                finally:
                    client.close()
            finally:
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
