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
from collections.abc import Iterator
from typing import Any

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
    return "remote", text


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
    (distributed,) = require("distributed")
    kind, value = parse_address(address)
    if kind == "local":
        n = value or n_workers or os.cpu_count() or 1
        cluster = distributed.LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=processes,
            # TCP on the loopback even for thread workers: the scheduler can then be shared
            # by address (tcp://127.0.0.1:PORT) with other clients of this machine
            protocol="tcp://",
            host="127.0.0.1",
            # no dashboard: None would mean distributed's default, port 8787, and a second
            # starsense run on the same machine would then fail to start its cluster
            dashboard_address=":0",
            scheduler_kwargs={"dashboard": False},
            # CRITICAL: a worker's heartbeat racing the scheduler's shutdown logs an ERROR with
            # a traceback; task failures still reach the client as exceptions
            silence_logs=logging.CRITICAL,
        )
        try:
            client = distributed.Client(cluster)
            client.run(quiet_third_party_warnings)
            try:
                yield client
            finally:
                client.close()
        finally:
            cluster.close()
        return
    try:
        client = distributed.Client(value, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError) as exc:
        raise SchedulerUnreachableError(
            f"no Dask scheduler answers at {value} (gave up after {timeout_s:g} s): {exc}"
        ) from None
    client.run(quiet_third_party_warnings)
    try:
        yield client
    finally:
        client.close()
