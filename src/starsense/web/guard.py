"""The design server's front door: only this machine's page may use it.

The server listens on the loopback address, but a web page the user visits elsewhere can still
reach it through the browser: by a cross-site request (a form or a ``fetch`` with a "simple"
content type, sent without asking) or by DNS rebinding (a foreign name that resolves to
127.0.0.1, so the browser treats the server as that site's). :class:`Guard`, an ASGI
middleware in front of the app, refuses

* a ``Host`` other than the address the server is bound to (and ``localhost``, ``127.0.0.1``,
  ``[::1]``) with its port: 421 (a rebound name);
* a state-changing request (any method but GET, HEAD and OPTIONS) from another origin: an
  ``Origin`` that is not this server, or a browser's ``Sec-Fetch-Site`` saying the request is
  cross-site: 403;
* a POST whose body is not ``application/json``: 415 (the browser sends JSON from another
  origin only after a CORS preflight, which this server never grants);
* a body above :data:`MAX_BODY_BYTES`: 413, before it is read (``Content-Length``) or as soon
  as a chunked body passes the limit.

Each refusal is a one-line JSON ``{"error": ...}``.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any

from starlette.responses import JSONResponse

__all__ = ["MAX_BODY_BYTES", "Guard", "allowed_hosts"]

#: the largest request body accepted, bytes (a design document is a few kB)
MAX_BODY_BYTES = 1_048_576

#: methods that only read: no Origin check
_SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]


def allowed_hosts(host: str, port: int) -> frozenset[str]:
    """Return the ``Host`` values the server answers: its address and the loopback names.

    Parameters
    ----------
    host : str
        The address the server is bound to (``127.0.0.1``, ``::1``, ``localhost``).
    port : int
        Its port; port 80 may also be left out, as browsers do.

    Returns
    -------
    frozenset of str
        Lower case, ``name:port`` (IPv6 addresses in brackets).
    """
    names = {"127.0.0.1", "localhost", "[::1]", _bracketed(host.lower())}
    out = {f"{n}:{port}" for n in names}
    if port == 80:
        out |= names
    return frozenset(out)


def _bracketed(host: str) -> str:
    return f"[{host}]" if ":" in host and not host.startswith("[") else host


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return value.decode("latin-1")
    return None


class Guard:
    """ASGI middleware: the Host, Origin, content-type and body-size checks of the module.

    Parameters
    ----------
    app : ASGI application
        The design page's app.
    host : str
        The address the server is bound to.
    port : int
        Its port.
    max_body_bytes : int
        The largest body accepted.
    """

    def __init__(
        self, app: ASGIApp, *, host: str, port: int, max_body_bytes: int = MAX_BODY_BYTES
    ) -> None:
        self.app = app
        self.hosts = allowed_hosts(host, port)
        self.origins = frozenset(f"http://{h}" for h in self.hosts)
        self.max_body_bytes = max_body_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Refuse the request (one-line JSON) or pass it on, its body read already."""
        if scope["type"] != "http":  # lifespan (websockets are not routed)
            await self.app(scope, receive, send)
            return
        refusal = self._refusal(scope)
        if refusal is not None:
            await JSONResponse({"error": refusal[1]}, status_code=refusal[0])(scope, receive, send)
            return
        if scope["method"] == "POST":
            body = await self._read_body(receive)
            if body is None:
                await _too_large(self.max_body_bytes)(scope, receive, send)
                return
            receive = _replay(body, receive)
        await self.app(scope, receive, send)

    def _refusal(self, scope: Scope) -> tuple[int, str] | None:
        """Return (status, message) of a request refused on its headers, or None."""
        host = _header(scope, b"host")
        if host is None:
            return 400, "the request has no Host header"
        if host.lower() not in self.hosts:
            return 421, f"Host {host[:100]!r} is not this server (it answers {_shown(self.hosts)})"
        method = scope["method"]
        if method not in _SAFE_METHODS:
            origin = _header(scope, b"origin")
            if origin is not None and origin.lower() not in self.origins:
                return 403, f"cross-origin request refused: Origin {origin[:100]!r}"
            site = _header(scope, b"sec-fetch-site")
            if site is not None and site.lower() not in ("same-origin", "none"):
                return 403, f"cross-origin request refused: Sec-Fetch-Site {site[:40]!r}"
        if method == "POST":
            kind = (_header(scope, b"content-type") or "").split(";")[0].strip().lower()
            if kind != "application/json":
                return 415, (
                    f"the body must be JSON (Content-Type: application/json), got "
                    f"{kind[:60] or 'no content type'!r}"
                )
        length = _header(scope, b"content-length")
        if length is not None:
            if not length.strip().isdigit():
                return 400, f"Content-Length {length[:40]!r} is not a number of bytes"
            if int(length) > self.max_body_bytes:
                return 413, _too_large_text(self.max_body_bytes, int(length))
        return None

    async def _read_body(self, receive: Receive) -> bytes | None:
        """Return the whole body, or None as soon as it passes the limit."""
        chunks, size = [], 0
        while True:
            message = await receive()
            if message["type"] != "http.request":  # the client went away
                return b"".join(chunks)
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_body_bytes:
                return None
            chunks.append(chunk)
            if not message.get("more_body", False):
                return b"".join(chunks)


def _shown(hosts: frozenset[str]) -> str:
    return ", ".join(sorted(hosts))


def _too_large_text(limit: int, size: int | None = None) -> str:
    said = f" ({size:,} bytes)" if size is not None else ""
    return f"the request body is too large{said}; at most {limit:,} bytes"


def _too_large(limit: int) -> JSONResponse:
    return JSONResponse({"error": _too_large_text(limit)}, status_code=413)


def _replay(body: bytes, receive: Receive) -> Receive:
    """Return a ``receive`` that gives the body read already, then waits on the real one."""
    sent = False

    async def replay() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return replay
