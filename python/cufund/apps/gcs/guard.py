"""What every request to the ground station's servers (the page's and the Foxglove one) is checked against: the
token, the ``Host`` a browser asked for (DNS rebinding), the ``Origin`` of a websocket or a POST (another site's
page), strict JSON of a bounded depth; and log lines that never carry the token.

The token is accepted as ``?token=`` or ``Authorization: Bearer``. A request's ``Host`` must name the server by a
loopback name or by the interface it is bound to (any ``Host`` when it is bound to every interface: the token is
the guard there). An ``Origin`` must be the server's own (``http://<Host>``); requests without one (scripts,
``curl``) pass on the token alone. What is queued to a websocket client is bounded (:class:`BoundedSender`).
"""

from __future__ import annotations

import functools
import json
import logging
import math
import secrets
import sys
from typing import Any
from urllib.parse import urlsplit

import tornado.httpserver
import tornado.netutil
import tornado.web
import tornado.websocket

__all__ = [
    "LOOPBACK",
    "MAX_MESSAGE_BYTES",
    "MAX_UNSENT_BYTES",
    "MAX_UNSENT_MESSAGES",
    "WILDCARD",
    "BoundedSender",
    "Hosts",
    "authorized",
    "listen",
    "log_request",
    "loads_strict",
    "origin_host",
    "quiet_errors",
]

LOOPBACK = ("127.0.0.1", "localhost", "::1")
MAX_MESSAGE_BYTES = 64 * 1024
"""The largest websocket message or HTTP body a server accepts (a command, a mission or a subscription is a few kB):
a larger websocket message closes the socket with 1009, a larger body is a 400."""
WILDCARD = ("", "0.0.0.0", "::")
MAX_JSON_DEPTH = 64
"""Nesting of arrays and objects accepted in a message (deeper ones are refused before Python recurses)."""


def authorized(handler: tornado.web.RequestHandler, token: str) -> bool:
    given = handler.get_query_argument("token", None)
    header = handler.request.headers.get("Authorization", "")
    if given is None and header.lower().startswith("bearer "):
        given = header[7:].strip()
    return given is not None and secrets.compare_digest(given.encode(), token.encode())


class Hosts:
    """The ``Host`` values that name a server on ``host:port``."""

    def __init__(self, host: str, port: int) -> None:
        self.any = host in WILDCARD
        names = {*LOOPBACK, host}
        self.allowed = {f"{n}:{port}" for n in names if ":" not in n} | {f"[{n}]:{port}" for n in names if ":" in n}

    def __contains__(self, host: str | None) -> bool:
        return host is not None and (self.any or host.lower() in self.allowed)


def origin_host(origin: str | None) -> str | None:
    """The ``host:port`` of an http(s) ``Origin`` header, or None (``null``, another scheme, garbage)."""
    try:
        parts = urlsplit(origin or "")
    except ValueError:
        return None
    if parts.scheme not in ("http", "https") or not parts.netloc or parts.path not in ("", "/"):
        return None
    return parts.netloc.lower()


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"number {text[:20]}{'...' if len(text) > 20 else ''} is out of range")
    return value


def _depth(text: str) -> int:
    """The deepest nesting of brackets outside strings."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def loads_strict(data: str | bytes) -> Any:
    """``json.loads`` refusing what is not JSON (NaN, Infinity, numbers that overflow a float, non-UTF-8 bytes)
    and nesting deeper than :data:`MAX_JSON_DEPTH`, all as ``ValueError`` naming the problem."""
    if isinstance(data, bytes):
        try:
            data = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"the body is not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    if data.count("[") + data.count("{") > MAX_JSON_DEPTH and _depth(data) > MAX_JSON_DEPTH:
        raise ValueError(f"JSON nested deeper than {MAX_JSON_DEPTH} levels")
    try:
        return json.loads(data, parse_constant=_refuse_constant, parse_float=_finite_float)
    except RecursionError:
        raise ValueError(f"JSON nested deeper than {MAX_JSON_DEPTH} levels") from None


def log_request(handler: tornado.web.RequestHandler) -> None:
    """Tornado's access log line without the query (it may hold the token)."""
    status = handler.get_status()
    level = logging.INFO if status < 400 else logging.WARNING if status < 500 else logging.ERROR
    request = handler.request
    logging.getLogger("tornado.access").log(
        level,
        "%d %s %s (%s) %.2fms",
        status,
        request.method,
        request.path,
        request.remote_ip,
        1000.0 * request.request_time(),
    )


class quiet_errors:
    """A request handler mixin: an uncaught exception is one stderr line (path only, no query, no traceback) and
    the client gets the status with a JSON ``{"result": "failed", "message"}``, never a traceback."""

    def log_exception(self, typ: Any, value: Any, tb: Any) -> None:
        if isinstance(value, tornado.web.HTTPError):
            return  # a 4xx the handler chose: the access log has it
        request = self.request  # type: ignore[attr-defined]
        print(f"cufund gcs: {request.method} {request.path}: {typ.__name__}: {value}", file=sys.stderr, flush=True)

    def write_error(self, status_code: int, **kwargs: Any) -> None:
        reason = self._reason  # type: ignore[attr-defined]
        exc = kwargs.get("exc_info", (None, None, None))[1]
        if isinstance(exc, tornado.web.HTTPError) and exc.reason:
            reason = exc.reason
        self.set_header("Content-Type", "application/json")  # type: ignore[attr-defined]
        self.finish(json.dumps({"result": "failed", "message": reason}))  # type: ignore[attr-defined]


MAX_UNSENT_BYTES = 4 * 1024 * 1024
"""Bytes queued to one websocket client and not yet taken by its socket beyond which the client is dropped (the
largest ground station hello, the forest scenario's, is 0.8 MB plus up to about 1.2 MB of flown path and history;
one message alone is always queued)."""
MAX_UNSENT_MESSAGES = 512
"""Messages queued to one websocket client and not yet taken by its socket beyond which it is dropped."""


def _retrieve(future: Any) -> None:
    """Marks a finished write's failure (the client went away) as seen: no "Task exception was never retrieved"."""
    if not future.cancelled():
        future.exception()


class BoundedSender:
    """A websocket handler mixin: :meth:`send_bounded` queues a message unless that would leave more than
    :data:`MAX_UNSENT_BYTES` or :data:`MAX_UNSENT_MESSAGES` unsent, in which case the client is dropped at once
    (its queue discarded, no closing handshake), :meth:`count_drop` called and one line written to stderr."""

    unsent_bytes = 0
    unsent_messages = 0
    dropped = False

    def count_drop(self) -> tuple[str, int]:
        """Counts a dropped client where its server keeps the count; returns how to name the client in the log line
        and the count."""
        raise NotImplementedError

    def send_bounded(self, message: str | bytes) -> Any:
        """The write's future, or None when the client is gone or was just dropped."""
        if self.dropped:
            return None
        size = len(message)
        if self.unsent_messages and (
            self.unsent_bytes + size > MAX_UNSENT_BYTES or self.unsent_messages >= MAX_UNSENT_MESSAGES
        ):
            self._drop()
            return None
        try:
            future = self.write_message(message, binary=isinstance(message, bytes))  # type: ignore[attr-defined]
        except tornado.websocket.WebSocketClosedError:
            self.on_close()  # type: ignore[attr-defined]
            return None
        self.unsent_bytes += size
        self.unsent_messages += 1
        future.add_done_callback(functools.partial(self._written, size))
        return future

    def _written(self, size: int, future: Any) -> None:
        self.unsent_bytes -= size
        self.unsent_messages -= 1
        _retrieve(future)

    def _drop(self) -> None:
        self.dropped = True
        name, count = self.count_drop()
        print(
            f"cufund gcs: dropped a {name} that does not read ({self.unsent_messages} messages, "
            f"{self.unsent_bytes} bytes unsent; {count} dropped so far)",
            file=sys.stderr,
            flush=True,
        )
        self.on_close()  # type: ignore[attr-defined]
        stream = getattr(self.ws_connection, "stream", None)  # type: ignore[attr-defined]
        if stream is not None:
            stream.close()
        else:
            self.close(1008, "not reading")  # type: ignore[attr-defined]


def listen(handlers: list[Any], host: str, port: int) -> tuple[tornado.httpserver.HTTPServer, int, Hosts]:
    """An application of ``handlers`` served on ``host``:``port`` (0: any free port) with the bounds and the quiet
    request log every cufund server uses; returns the server, the port it got and the Host names it answers to."""
    app = tornado.web.Application(handlers, websocket_max_message_size=MAX_MESSAGE_BYTES, log_function=log_request)
    sockets = tornado.netutil.bind_sockets(port, address=host)
    port = sockets[0].getsockname()[1]
    http = tornado.httpserver.HTTPServer(app, max_body_size=MAX_MESSAGE_BYTES)
    http.add_sockets(sockets)
    return http, port, Hosts(host, port)
