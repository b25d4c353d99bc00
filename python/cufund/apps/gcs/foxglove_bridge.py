"""``cufund gcs --foxglove``: the ground station's live data over a Foxglove WebSocket server (foxglove-sdk) on
127.0.0.1, for Foxglove Studio.

Channels (own :class:`foxglove.Context`, so nothing else logged in the process leaks into it):
``/truth/odometry`` or the run's pose as ``foxglove.PoseInFrame`` in frame ``world`` (topic ``/vehicle/pose``),
``/sensors/lidar`` as ``foxglove.PointCloud`` (world frame, what the page draws), ``/vehicle/telemetry`` as JSON
(the page's telemetry dict) and ``/vehicle/events`` as ``foxglove.Log``.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

__all__ = ["FoxgloveBridge"]


def _stamp(t: Any) -> Any:
    from foxglove.messages import Timestamp

    t = float(t) if isinstance(t, (int, float)) and math.isfinite(t) and t >= 0 else 0.0
    sec = int(t)
    return Timestamp(sec, round((t - sec) * 1e9) % 1_000_000_000)


class FoxgloveBridge:
    """Starts the server on ``127.0.0.1:port`` (0: any free port; the bound one is :attr:`port`)."""

    def __init__(self, port: int = 8765, host: str = "127.0.0.1") -> None:
        import foxglove
        from foxglove.channels import LogChannel, PointCloudChannel, PoseInFrameChannel

        self.context = foxglove.Context()
        self.server = foxglove.start_server(name="cufund gcs", host=host, port=port, context=self.context)
        self.port = self.server.port
        self.pose = PoseInFrameChannel("/vehicle/pose", context=self.context)
        self.lidar = PointCloudChannel("/sensors/lidar", context=self.context)
        self.log = LogChannel("/vehicle/events", context=self.context)
        self.json = foxglove.Channel("/vehicle/telemetry", schema={"type": "object"}, message_encoding="json",
                                     context=self.context)
        self._t = 0.0

    def telemetry(self, tel: dict[str, Any], events: list[dict[str, Any]]) -> None:
        from foxglove.messages import (
            Log,
            LogLevel,
            Pose,
            PoseInFrame,
            Quaternion,
            Vector3,
        )

        t = tel.get("t")
        if isinstance(t, (int, float)):
            self._t = float(t)
        self.json.log(json.dumps(tel).encode())
        p, q = tel.get("p_W"), tel.get("q_WB")
        if p is not None and q is not None and None not in p and None not in q:
            self.pose.log(PoseInFrame(timestamp=_stamp(self._t), frame_id="world", pose=Pose(
                position=Vector3(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(w=q[0], x=q[1], y=q[2], z=q[3]))))
        for e in events:
            level = LogLevel.Warning if str(e.get("kind", "")).lower() in ("warning", "crash", "error") else LogLevel.Info
            self.log.log(Log(timestamp=_stamp(e.get("t", self._t)), level=level, name="cufund",
                             message=str(e.get("message", e))))

    def cloud(self, frame: bytes) -> None:
        """A cloud in the page's layout (float32 ``[t, n, x, y, z, ...]``, world frame)."""
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
        self.lidar.log(PointCloud(timestamp=_stamp(float(head[0])), frame_id="world",
                                  pose=Pose(position=Vector3(), orientation=Quaternion(w=1.0)), point_stride=12,
                                  fields=[PackedElementField(name=n, offset=4 * i, type=f32)
                                          for i, n in enumerate("xyz")], data=frame[8:]))

    def stop(self) -> None:
        self.server.stop()
