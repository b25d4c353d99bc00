"""``cufund gcs --foxglove``: the ground station's live data for Foxglove (the app or Studio) over the Foxglove
WebSocket protocol, served by tornado on ``127.0.0.1:port`` behind the ground station's token.

foxglove-sdk's own server (``foxglove.start_server``) has no authentication and no Origin check: any local process
or any web page the operator opens could read the telemetry. This server speaks the same protocol (subprotocols
``foxglove.sdk.v1`` and ``foxglove.websocket.v1``: ``serverInfo``, ``advertise``, ``subscribe``/``unsubscribe``,
binary ``messageData``) with foxglove-sdk's schemas and message encoders, and refuses a handshake (403) without
the token (``?token=``, or ``Authorization: Bearer``), with a ``Host`` that does not name it, or with an
``Origin`` that is neither local (``http(s)://`` 127.0.0.1, localhost or [::1]) nor the Foxglove web app
(:data:`FOXGLOVE_WEB_ORIGINS`). Connect Foxglove to the URL ``cufund gcs`` prints (``ws://127.0.0.1:PORT/?token=``).

Channels: ``/vehicle/pose`` (``foxglove.PoseInFrame``, frame ``world``), ``/sensors/lidar``
(``foxglove.PointCloud``, world frame, what the page draws), ``/vehicle/telemetry`` (JSON: the page's telemetry
dict) and ``/vehicle/events`` (``foxglove.Log``). A client's message data is skipped while more than
:data:`DATA_BACKLOG_BYTES` wait for its socket; a client that leaves its control replies unread is dropped
(:class:`~cufund.apps.gcs.guard.BoundedSender`).
"""

from __future__ import annotations

import base64
import dataclasses
import json
import math
import struct
import time
from typing import Any

import numpy as np
import tornado.httpserver
import tornado.netutil
import tornado.web
import tornado.websocket

from .guard import (
    LOOPBACK,
    WILDCARD,
    BoundedSender,
    Hosts,
    authorized,
    listen,
    loads_strict,
    origin_host,
    quiet_errors,
)

__all__ = ["FoxgloveBridge"]

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
FOXGLOVE_WEB_ORIGINS = ("https://app.foxglove.dev",)
"""Non-local page origins allowed to connect (with the token): the Foxglove web app."""
MAX_SUBSCRIPTIONS = 64
DATA_BACKLOG_BYTES = 2 * 1024 * 1024
"""Message data waiting for a client's socket beyond which newer data for it is skipped (a slow client gets fresh
data late rather than a growing queue)."""


def _stamp(t: Any) -> Any:
    from foxglove.messages import Timestamp

    t = float(t) if isinstance(t, (int, float)) and math.isfinite(t) and t >= 0 else 0.0
    sec = int(t)
    return Timestamp(sec, round((t - sec) * 1e9) % 1_000_000_000)


@dataclasses.dataclass(frozen=True)
class _Channel:
    id: int
    topic: str
    encoding: str
    schema_name: str
    schema_encoding: str
    schema: str

    def advertised(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "topic": self.topic,
            "encoding": self.encoding,
            "schemaName": self.schema_name,
            "schemaEncoding": self.schema_encoding,
            "schema": self.schema,
        }


def _protobuf_channel(ident: int, topic: str, message_type: Any) -> _Channel:
    schema = message_type.get_schema()
    return _Channel(ident, topic, "protobuf", schema.name, schema.encoding, base64.b64encode(schema.data).decode())


def _origin_allowed(origin: str | None) -> bool:
    if origin is None:
        return True  # not a browser page: Foxglove desktop, scripts
    host = origin_host(origin)
    if host is None:
        return False
    name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
    return name.strip("[]") in LOOPBACK or origin.rstrip("/").lower() in FOXGLOVE_WEB_ORIGINS


class FoxgloveBridge:
    """The Foxglove server on ``host:port`` (0: any free port; the bound one is :attr:`port` after :meth:`start`),
    started inside a running asyncio loop with the ground station's token."""

    def __init__(self, port: int = 8765, host: str = "127.0.0.1") -> None:
        from foxglove.messages import Log, PointCloud, PoseInFrame

        self.host = host
        self.port = int(port)
        self.token = ""
        self.url = ""
        self.clients: set[FoxgloveSocket] = set()
        self.dropped_clients = 0
        self.hosts = Hosts(host, self.port)
        self.pose = _protobuf_channel(1, "/vehicle/pose", PoseInFrame)
        self.lidar = _protobuf_channel(2, "/sensors/lidar", PointCloud)
        self.log = _protobuf_channel(3, "/vehicle/events", Log)
        self.json = _Channel(
            4, "/vehicle/telemetry", "json", "cufund.Telemetry", "jsonschema", json.dumps({"type": "object"})
        )
        self.channels = {c.id: c for c in (self.pose, self.lidar, self.log, self.json)}
        self.session_id = str(time.time_ns())
        self._http: tornado.httpserver.HTTPServer | None = None
        self._t = 0.0

    def start(self, token: str) -> str:
        """Binds the port; returns the URL to give Foxglove (with the token)."""
        self.token = token
        self._http, self.port, self.hosts = listen([(r"/", FoxgloveSocket, {"bridge": self})], self.host, self.port)
        shown = "127.0.0.1" if self.host in WILDCARD else self.host
        self.url = f"ws://{shown}:{self.port}/?token={token}"
        return self.url

    def _wanted(self, channel: _Channel) -> bool:
        return any(channel.id in c.subscriptions.values() for c in self.clients)

    def _publish(self, channel: _Channel, payload: bytes) -> None:
        now = time.time_ns()
        for c in list(self.clients):
            c.publish(channel.id, payload, now)

    def telemetry(self, tel: dict[str, Any], events: list[dict[str, Any]]) -> None:
        from foxglove.messages import Log, LogLevel, Pose, PoseInFrame, Quaternion, Vector3

        t = tel.get("t")
        if isinstance(t, (int, float)):
            self._t = float(t)
        if self._wanted(self.json):
            self._publish(self.json, json.dumps(tel).encode())
        p, q = tel.get("p_W"), tel.get("q_WB")
        if self._wanted(self.pose) and p is not None and q is not None and None not in p and None not in q:
            self._publish(
                self.pose,
                PoseInFrame(
                    timestamp=_stamp(self._t),
                    frame_id="world",
                    pose=Pose(
                        position=Vector3(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(w=q[0], x=q[1], y=q[2], z=q[3])
                    ),
                ).encode(),
            )
        if self._wanted(self.log):
            for e in events:
                level = (
                    LogLevel.Warning
                    if str(e.get("kind", "")).lower() in ("warning", "crash", "error")
                    else LogLevel.Info
                )
                self._publish(
                    self.log,
                    Log(
                        timestamp=_stamp(e.get("t", self._t)),
                        level=level,
                        name="cufund",
                        message=str(e.get("message", e)),
                    ).encode(),
                )

    def cloud(self, frame: bytes) -> None:
        """A cloud in the page's layout (float32 ``[t, n, x, y, z, ...]``, world frame)."""
        if not self._wanted(self.lidar):
            return
        from foxglove.messages import (
            PackedElementField,
            PackedElementFieldNumericType,
            PointCloud,
            Pose,
            Quaternion,
            Vector3,
        )

        head = np.frombuffer(frame[:8], dtype="<f4")
        f32 = PackedElementFieldNumericType.Float32
        self._publish(
            self.lidar,
            PointCloud(
                timestamp=_stamp(float(head[0])),
                frame_id="world",
                pose=Pose(position=Vector3(), orientation=Quaternion(w=1.0)),
                point_stride=12,
                fields=[PackedElementField(name=n, offset=4 * i, type=f32) for i, n in enumerate("xyz")],
                data=frame[8:],
            ).encode(),
        )

    def stop(self) -> None:
        for c in list(self.clients):
            c.close()
        if self._http is not None:
            self._http.stop()


class FoxgloveSocket(quiet_errors, BoundedSender, tornado.websocket.WebSocketHandler):
    """One Foxglove client (see the module docstring)."""

    def initialize(self, bridge: FoxgloveBridge) -> None:
        self.bridge = bridge
        self.subscriptions: dict[int, int] = {}
        """Subscription id -> channel id."""

    async def get(self, *args: Any, **kwargs: Any) -> None:
        why = (
            "Host does not name this server"
            if self.request.host not in self.bridge.hosts
            else "token required (?token= or Authorization: Bearer)"
            if not authorized(self, self.bridge.token)
            else "Origin not allowed"
            if not _origin_allowed(self.request.headers.get("Origin"))
            else ""
        )
        if why:
            self.set_status(403)
            self.finish(why)
            return
        await super().get(*args, **kwargs)

    def check_origin(self, origin: str) -> bool:
        return _origin_allowed(origin)

    def select_subprotocol(self, subprotocols: list[str]) -> str | None:
        return next((p for p in subprotocols if p in SUBPROTOCOLS), None)

    def open(self, *args: Any, **kwargs: Any) -> None:
        self.set_nodelay(True)
        self.bridge.clients.add(self)
        self._reply(
            {
                "op": "serverInfo",
                "name": "cufund gcs",
                "capabilities": [],
                "supportedEncodings": [],
                "metadata": {},
                "sessionId": self.bridge.session_id,
            }
        )
        self._reply({"op": "advertise", "channels": [c.advertised() for c in self.bridge.channels.values()]})

    def on_close(self) -> None:
        self.bridge.clients.discard(self)

    def count_drop(self) -> tuple[str, int]:
        self.bridge.dropped_clients += 1
        return "Foxglove client", self.bridge.dropped_clients

    def _reply(self, message: dict[str, Any]) -> None:
        self.send_bounded(json.dumps(message))

    def _status(self, text: str) -> None:
        self._reply({"op": "status", "level": 2, "message": text})

    def publish(self, channel_id: int, payload: bytes, log_time_ns: int) -> None:
        if self.dropped or self.unsent_bytes > DATA_BACKLOG_BYTES:
            return
        for sub, channel in self.subscriptions.items():
            if channel == channel_id:
                self.send_bounded(struct.pack("<BIQ", 1, sub, log_time_ns) + payload)

    def on_message(self, message: str | bytes) -> None:
        if self.dropped:
            return
        try:
            if isinstance(message, bytes):
                raise ValueError("this server accepts no client channels (binary messages)")
            data = loads_strict(message)
            op = data.get("op") if isinstance(data, dict) else None
            if op == "subscribe":
                self._subscribe(data.get("subscriptions"))
            elif op == "unsubscribe":
                ids = data.get("subscriptionIds")
                if not isinstance(ids, list):
                    raise ValueError("unsubscribe needs 'subscriptionIds', a list of subscription ids")
                for sub in ids:
                    if isinstance(sub, int):
                        self.subscriptions.pop(sub, None)
            else:
                raise ValueError("expected a JSON object with op 'subscribe' or 'unsubscribe'")
        except Exception as exc:  # every malformed message gets a status reply; the socket stays open
            self._status(f"{type(exc).__name__}: {exc}" if not isinstance(exc, ValueError) else str(exc))

    def _subscribe(self, subscriptions: Any) -> None:
        if not isinstance(subscriptions, list):
            raise ValueError("subscribe needs 'subscriptions', a list of {id, channelId}")
        for s in subscriptions:
            sub = s.get("id") if isinstance(s, dict) else None
            channel = s.get("channelId") if isinstance(s, dict) else None
            if not (
                isinstance(sub, int)
                and 0 <= sub < 2**32
                and isinstance(channel, int)
                and channel in self.bridge.channels
            ):
                raise ValueError(f"a subscription is {{id: uint32, channelId: one of {sorted(self.bridge.channels)}}}")
            if sub not in self.subscriptions and len(self.subscriptions) >= MAX_SUBSCRIPTIONS:
                raise ValueError(f"at most {MAX_SUBSCRIPTIONS} subscriptions per client")
            self.subscriptions[sub] = channel
