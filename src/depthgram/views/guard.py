"""Who may talk to the viewer: host names, an access token, the page's origin and request sizes.

The viewer has no login. On loopback only this machine reaches it, and two checks keep other
web sites' pages out: the ``Host`` header must be one of ours (DNS rebinding: a foreign name
that resolves to 127.0.0.1 would otherwise reach the viewer with the browser's blessing), and
an ``Origin``, when a browser sends one, must be this server's own scheme, host and port. Beyond
loopback anyone on the network can send any ``Host``, so ``depthgram view`` then requires either
the names the server is reached by (``--allow-host``) or an access token, which the page's first
request carries as ``?token=`` and which is then kept in a cookie for that origin only.
"""

from __future__ import annotations

import hmac
import json
from collections.abc import Sequence
from typing import Any
from urllib.parse import parse_qs, urlsplit

from fastapi.responses import JSONResponse

__all__ = [
    "LOOPBACK_HOSTS",
    "MAX_BODY_BYTES",
    "TOKEN_COOKIE",
    "BodyTooLarge",
    "Guard",
    "JSONBodyError",
    "host_name",
    "parse_json",
    "same_origin",
]

#: Host names that reach this machine only; the default set of allowed ``Host`` headers.
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")

#: Largest request body accepted (bytes): the controls send a few dozen bytes.
MAX_BODY_BYTES = 64 * 1024

#: Cookie holding the access token once the page was opened with ``?token=``.
TOKEN_COOKIE = "depthgram_token"


class JSONBodyError(ValueError):
    """A request body or message that is not acceptable JSON; the message says why."""


def parse_json(data: bytes | str) -> Any:
    """Parse JSON from a request or a page's message; :class:`JSONBodyError` rather than a crash.

    Nesting deeper than the interpreter's recursion limit (``[[[[...]]]]`` in 64 kB) makes
    :func:`json.loads` raise ``RecursionError``: that is the sender's error, not the server's.
    """
    try:
        return json.loads(data)
    except RecursionError:
        raise JSONBodyError("JSON nested too deeply") from None
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise JSONBodyError("request body must be JSON") from None


def host_name(host_header: str) -> str:
    """``Host`` header without its port: ``[::1]:8765`` -> ``::1``, ``localhost:8765`` -> ``localhost``."""
    h = host_header.strip().lower()
    if h.startswith("["):
        return h[1:].partition("]")[0]
    return h.rpartition(":")[0] if h.count(":") == 1 else h


def _default_port(scheme: str) -> str:
    return "443" if scheme in ("https", "wss") else "80"


def same_origin(headers: Any, scheme: str) -> bool:
    """Return true when a request carries no ``Origin`` (not from a web page) or comes from this server's own page.

    Browsers let any web site open a WebSocket to 127.0.0.1 or send a simple POST there; the
    Origin they attach is the only way to tell our page from someone else's. Scheme, host and
    port must all match: ``https://host`` is another origin than ``http://host``.

    Parameters
    ----------
    headers : mapping
        The request's headers.
    scheme : str
        The request's own scheme (``http``, ``https``, ``ws`` or ``wss``).
    """
    origin = headers.get("origin")
    if origin is None:
        return True
    o = urlsplit(origin.strip().lower())
    ours = {"ws": "http", "wss": "https"}.get(scheme, scheme)
    if o.scheme != ours:
        return False
    host = str(headers.get("host", "")).strip().lower()
    want = host if ":" in host.rpartition("]")[2] else f"{host}:{_default_port(ours)}"
    got = o.netloc if o.port is not None else f"{o.netloc}:{_default_port(o.scheme)}"
    return got == want


def _json_error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


class Guard:
    """ASGI middleware: refuse unknown host names (unless the token is presented) and large bodies.

    Parameters
    ----------
    app : ASGI application
        The viewer's application.
    hosts : sequence of str or None
        Host names accepted in the ``Host`` header (any port); None accepts any.
    token : str or None
        Access token; when set, every request must carry it (query ``token``, cookie
        :data:`TOKEN_COOKIE` or ``Authorization: Bearer``), whatever its host name.
    max_body : int
        Largest request body (bytes); larger ones get 413.
    """

    def __init__(
        self, app: Any, hosts: Sequence[str] | None, token: str | None = None, max_body: int = MAX_BODY_BYTES
    ) -> None:
        self.app = app
        self.hosts = None if hosts is None else {h.lower().strip("[]") for h in hosts}
        self.token = token
        self.max_body = max_body

    def _has_token(self, scope: Any, headers: dict[bytes, bytes]) -> bool:
        assert self.token is not None
        given: list[str] = parse_qs(scope.get("query_string", b"").decode("latin-1")).get("token", [])
        auth = headers.get(b"authorization", b"").decode("latin-1")
        if auth.lower().startswith("bearer "):
            given.append(auth[7:].strip())
        for part in headers.get(b"cookie", b"").decode("latin-1").split(";"):
            k, _, v = part.strip().partition("=")
            if k == TOKEN_COOKIE:
                given.append(v)
        return any(hmac.compare_digest(g.encode(), self.token.encode()) for g in given)

    async def _refuse(self, scope: Any, receive: Any, send: Any, status: int, code: int, message: str) -> None:
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": code, "reason": message[:120]})
            return
        await _json_error(status, message)(scope, receive, send)

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        """Pass a request on to the app, or answer it with an error when the checks refuse it."""
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = dict(scope["headers"])
        host = headers.get(b"host", b"").decode("latin-1")
        if self.token is not None:
            if not self._has_token(scope, headers):
                await self._refuse(
                    scope,
                    receive,
                    send,
                    401,
                    4401,
                    "this viewer needs its access token: open the address it printed at start",
                )
                return
        elif self.hosts is not None and host_name(host) not in self.hosts:
            await self._refuse(
                scope, receive, send, 400, 4400, f"host {host!r} is not served here; use {sorted(self.hosts)[0]}"
            )
            return
        if scope["type"] == "http":
            length = headers.get(b"content-length")
            if length is not None and (not length.isdigit() or int(length) > self.max_body):
                await _json_error(413, f"request body over {self.max_body} bytes")(scope, receive, send)
                return
            receive = self._limited(receive)
        await self.app(scope, receive, send)

    def _limited(self, receive: Any) -> Any:
        """``receive`` that stops a body sent without a length (chunked) once it passes the limit."""
        seen = 0

        async def wrapped() -> Any:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.max_body:
                    raise BodyTooLarge()
            return message

        return wrapped


class BodyTooLarge(Exception):
    """A chunked request body passed :data:`MAX_BODY_BYTES`; answered with 413 by the app."""
