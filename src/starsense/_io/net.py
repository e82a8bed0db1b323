"""Network reachability: fail at once when nothing listens, say how long a timeout waited."""

from __future__ import annotations

import socket
import time

from starsense.errors import InputError

__all__ = ["probe_tcp"]


def probe_tcp(host: str, port: int, *, timeout_s: float, what: str) -> None:
    """Open and close a TCP connection to ``host:port``: fail at once when nothing listens.

    A refused connection is reported immediately (not after the timeout); a silent host after
    ``timeout_s``, saying how long it waited.

    Parameters
    ----------
    host : str
        Name or address.
    port : int
        1-65535.
    timeout_s : float
        How long to wait for an answer, s.
    what : str
        What is being reached, for the message ("HATS catalogue http://...").

    Raises
    ------
    InputError
        ``refused``, ``no answer after N s``, an unknown host, or another socket error; the
        message names ``what``.
    """
    if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
        raise InputError(f"{what}: port {port!r} is not a port number (1-65535)")
    t0 = time.monotonic()
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except ConnectionRefusedError:
        raise InputError(
            f"{what}: connection refused by {host}:{port} (nothing listens there)"
        ) from None
    except TimeoutError:
        raise InputError(
            f"{what}: no answer from {host}:{port} after {time.monotonic() - t0:.1f} s"
        ) from None
    except socket.gaierror as exc:
        raise InputError(f"{what}: unknown host {host!r} ({exc.strerror or exc})") from None
    except OSError as exc:
        raise InputError(
            f"{what}: cannot connect to {host}:{port}: {exc.strerror or exc}"
        ) from None
