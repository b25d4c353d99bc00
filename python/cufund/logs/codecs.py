"""How each message type is written to and read from a log: one codec per topic, chosen from its first message.

- Fixed-size messages (odometry, IMU, GPS, setpoints, actuator commands, any dataclass of numbers and fixed-shape
  arrays): exact CDR (``cufund_msgs/msg/<Class>``, ros2msg schema), a block at a time with numpy, with standard
  ROS 2 views on companion channels built by the writer thread from the same rows: odometry as
  ``<topic>/ros`` (``nav_msgs/msg/Odometry``, not for the truth), ``<topic>/pose`` (``PoseStamped``) and ``/tf``
  (frames: :data:`ODOMETRY_FRAMES`), the truth also ``/clock``; the IMU as ``<topic>/ros``
  (``sensor_msgs/msg/Imu``); GPS as ``<topic>/ros`` (``sensor_msgs/msg/NavSatFix``).
- LiDAR frames and the LiDAR truth: ``sensor_msgs/msg/PointCloud2`` (:class:`PointCloud2Codec`); camera images:
  ``sensor_msgs/msg/Image`` (:class:`ImageCodec`); read back from those messages.
- A planner's trajectory updates: ``nav_msgs/msg/Path`` (:class:`PathCodec`, not read back).
- Anything else (enums, strings, user dataclasses): JSON of the fields (``cufund.<Class>``, JSON Schema); the
  tunnel estimate adds ``<topic>/scene`` (``foxglove.SceneUpdate``).
- Logs of older cufund versions: ``foxglove.PointCloud``, ``foxglove.RawImage`` and ``foxglove.LocationFix`` JSON
  with a ``cufund`` field for the exact round trip; still read (their codecs below are kept for that).

The channel metadata names the codec and the message class, so :func:`codec_from_channel` rebuilds the codec.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import typing
from typing import Any

import numpy as np

from . import ros2, scene, schemas
from .cdr import CdrLayout, MessageLayout, infer_message_layout, stamp_sec_nsec
from .jsonvalue import class_path, decode_fields, encode_fields, numeric_dtype
from .message_classes import message_class, note_logged

__all__ = ["Codec", "View", "codec_for", "codec_from_channel"]

WORLD_FRAME = "world"


@dataclasses.dataclass
class View:
    """A companion channel derived from a topic's CDR rows for Foxglove (not read back): each message is the view's
    template with ``copies`` (destination field, its first element, source field, its first element, elements)
    taken from the source row, ``stamps`` (destination sec and nanosec fields, source float64 time field
    [s]) converted as :func:`cufund.logs.cdr.stamp_sec_nsec` does, and ``rotations`` (destination float64[3]
    field, source float64[3] vector field, source float64[4] quaternion field [w, x, y, z]): the vector rotated
    into the quaternion's frame, ``R(q)^T v`` (q normalised; NaN for a zero quaternion). Built by the logger's
    C++ writer thread."""

    suffix: str
    schema_name: str
    schema_text: str
    layout: CdrLayout
    copies: tuple[tuple[str, int, str, int, int], ...]
    stamps: tuple[tuple[str, str, str], ...]
    absolute: bool = False
    """``suffix`` is the channel's whole topic (``/tf``, ``/clock``: shared by every source), not a suffix."""
    rotations: tuple[tuple[str, str, str], ...] = ()

    def topic(self, source: str) -> str:
        """The view's channel topic for source topic ``source``."""
        return self.suffix if self.absolute else f"{source}{self.suffix}"

    schema_encoding = "ros2msg"
    message_encoding = "cdr"

    def spec(
        self, source: CdrLayout
    ) -> tuple[bytes, list[tuple[int, int, int]], list[tuple[int, int, int]], list[tuple[int, int, int]]]:
        """(template row, byte copies (dst, src, bytes), stamps (sec, nsec, src t offsets), rotations (dst, src
        vector, src quaternion offsets)) against ``source``."""

        def at(layout: CdrLayout, field: str, element: int) -> tuple[int, int]:
            fields = layout.dtype.fields
            assert fields is not None  # a structured dtype
            dtype, offset = fields[field][:2]
            item = dtype.base.itemsize
            return offset + element * item, item

        copies = []
        for dst_field, dst_element, src_field, src_element, count in self.copies:
            dst, item = at(self.layout, dst_field, dst_element)
            src, src_item = at(source, src_field, src_element)
            if item != src_item:
                raise ValueError(f"view {self.suffix}: {dst_field} and {src_field} have different element sizes")
            copies.append((dst, src, count * item))
        stamps = [
            (at(self.layout, sec, 0)[0], at(self.layout, nsec, 0)[0], at(source, t, 0)[0])
            for sec, nsec, t in self.stamps
        ]
        rotations = []
        for dst_field, v_field, q_field in self.rotations:
            for layout, field, count in ((self.layout, dst_field, 3), (source, v_field, 3), (source, q_field, 4)):
                fields = layout.dtype.fields
                assert fields is not None  # a structured dtype
                if fields[field][0] != np.dtype(("<f8", (count,))):
                    raise ValueError(f"view {self.suffix}: {field} is not a float64[{count}]")
            rotations.append((at(self.layout, dst_field, 0)[0], at(source, v_field, 0)[0], at(source, q_field, 0)[0]))
        return self.layout.template.tobytes(), copies, stamps, rotations


class Codec:
    """Encodes a block of one topic's messages; decodes one message."""

    name: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    fixed_size: int = 0
    """Bytes per message when every message has the same size (``encode`` then returns an (n, size) array)."""
    views: tuple[View, ...] = ()
    companions: tuple[tuple[str, tuple[str, str], str, str, Any], ...] = ()
    """Derived channels encoded in Python with the topic's blocks (not read back): (suffix, (schema name, schema
    text), schema encoding, message encoding, encode(message) -> bytes); for codecs without ``fixed_size``."""

    def __init__(self, cls: type):
        self.cls = cls
        self.where = f"message {cls.__name__}"
        """What decoding errors name (the channel, once the reader knows it)."""

    def metadata(self) -> dict[str, str]:
        return {"cufund.codec": self.name, "cufund.class": class_path(self.cls)}

    def accumulator(self) -> Any:
        """What a logger buffers a topic's messages in (``add(message, log_ns, publish_ns, sequence) -> count``,
        ``drain(topic) -> (payloads, log times, publish times, sequences)``) unless ``fixed_size`` (those are
        packed into CDR rows in C++ by :class:`cufund._core.logs.LogCore`)."""
        return MessageAccumulator(self)

    def encode(self, messages: list[Any], topic: str) -> np.ndarray | list[bytes]:
        """The encoded messages of a block."""
        raise NotImplementedError

    def decode(self, data: bytes | memoryview) -> Any:
        raise NotImplementedError


class MessageAccumulator:
    """Keeps the messages of a block (for codecs that encode one message at a time: low-rate topics)."""

    def __init__(self, codec: Codec):
        self.codec = codec
        self.items: list[tuple[Any, int, int, int]] = []

    def add(self, message: Any, log: int, publish: int, sequence: int) -> int:
        self.items.append((message, log, publish, sequence))
        return len(self.items)

    def drain(self, topic: str) -> tuple[list[bytes], list[int], list[int], list[int]]:
        items, self.items = self.items, []
        return (
            self.codec.encode([i[0] for i in items], topic),  # type: ignore[return-value]
            [i[1] for i in items],
            [i[2] for i in items],
            [i[3] for i in items],
        )


class CdrCodec(Codec):
    name = "cdr"
    schema_encoding = "ros2msg"
    message_encoding = "cdr"

    def __init__(self, layout: MessageLayout, views: tuple[View, ...] = ()):
        super().__init__(layout.cls)
        self.layout = layout
        self.schema_name = f"cufund_msgs/msg/{layout.cls.__name__}"
        self.schema_data = layout.layout.ros2msg().encode()
        self.fixed_size = layout.layout.size
        self.views = views

    def metadata(self) -> dict[str, str]:
        return {**super().metadata(), "cufund.layout": json.dumps(self.layout.describe())}

    def encode(self, messages: list[Any], topic: str) -> np.ndarray:
        return (
            self.layout._rows([self.layout._all(m) for m in messages], topic)
            .view(np.uint8)
            .reshape(len(messages), self.fixed_size)
        )

    def decode(self, data: bytes | memoryview) -> Any:
        return self.layout.decode(data)


ODOMETRY_FRAMES = {"/truth/odometry": ("world", "base_link_truth"), "/estimator/odometry": ("odom", "base_link")}
"""(parent, child) frames of the standard views of odometry topics (others: ``world`` -> ``base_link`` plus the
topic's name)."""

_QUATERNION = (("{0}", 0, "q_wb", 1, 3), ("{0}", 3, "q_wb", 0, 1))  # [w, x, y, z] -> ROS's x, y, z, w
_STAMP = (("header.stamp.sec", "header.stamp.nanosec", "t"),)


VEHICLE_TOPIC_ROOTS = ("/sensors/", "/truth/", "/estimator/")
"""Where a vehicle's sensor, truth and estimate topics start; a fleet's log has them under the vehicle's name."""


def vehicle_namespace(topic: str) -> tuple[str, str]:
    """(vehicle, topic of the vehicle) of a topic in a fleet's log, ``/uav1/sensors/imu``: ``("uav1",
    "/sensors/imu")``; a single vehicle's topic (one starting with :data:`VEHICLE_TOPIC_ROOTS`): ``("", topic)``."""
    name = str(topic)
    i = name.find("/", 1)
    if i > 1 and not name.startswith(VEHICLE_TOPIC_ROOTS) and name.startswith(VEHICLE_TOPIC_ROOTS, i):
        return name[1:i], name[i:]
    return "", name


def _in_namespace(vehicle: str, frame: str) -> str:
    return f"{vehicle}/{frame}" if vehicle and frame != WORLD_FRAME else frame


def odometry_frames(topic: str) -> tuple[str, str]:
    """(parent, child) frame of the standard views of an odometry ``topic``; a fleet vehicle's under its name
    (``/uav1/estimator/odometry``: ``uav1/odom`` -> ``uav1/base_link``)."""
    vehicle, own = vehicle_namespace(topic)
    parent, child = ODOMETRY_FRAMES.get(own, (WORLD_FRAME, "base_link" + own.replace("/", "_")))
    return _in_namespace(vehicle, parent), _in_namespace(vehicle, child)


IMAGE_TOPIC_NAMES = ("image", "image_raw")
"""A camera's image topic ends in one of these after the camera's name (``/sensors/cam0/image``)."""


def sensor_frame(topic: str) -> str:
    """The frame a sensor topic's messages are in: the topic's last name (``/sensors/lidar``: ``lidar``), which is
    the sensor's name in a scenario (its default topic is ``/sensors/<name>``), or for an image topic the camera's
    name before it (``/sensors/cam0/image``: ``cam0``, each camera of a rig its own frame); a fleet vehicle's under
    its name (``/uav1/sensors/imu``: ``uav1/imu``)."""
    vehicle, own = vehicle_namespace(topic)
    names = [n for n in own.split("/") if n]
    if len(names) >= 2 and names[-1] in IMAGE_TOPIC_NAMES and f"/{names[-2]}/" not in VEHICLE_TOPIC_ROOTS:
        names.pop()
    return _in_namespace(vehicle, names[-1] if names else "sensor")


def _odometry_views(topic: str, source: CdrLayout) -> tuple[View, ...]:
    parent, child = odometry_frames(topic)
    q = _QUATERNION
    odometry = (
        ("pose.position", 0, "p_w", 0, 3),
        *((d.format("pose.orientation"), a, b, c, e) for d, a, b, c, e in q),
        ("twist.angular", 0, "w_b", 0, 3),
    )
    # the estimator's covariances when its topic's rows hold them (row-major 6 x 6, ROS's order and frames); else,
    # or in a row without them, all zero: "covariance unknown" (REP 145's convention; -1 would say "no pose")
    names = source.dtype.names or ()
    odometry += tuple(
        (dst, 0, src, 0, 36) for dst, src in (("pose.covariance", "pose_cov_w"), ("twist.covariance", "twist_cov_b"))
        if src in names
    )  # fmt: skip
    pose = (("pose.position", 0, "p_w", 0, 3), *((d.format("pose.orientation"), a, b, c, e) for d, a, b, c, e in q))
    tf = (("translation", 0, "p_w", 0, 3), *((d.format("rotation"), a, b, c, e) for d, a, b, c, e in q))
    views = [
        View("/pose", *ros2.POSE_STAMPED, ros2.pose_stamped_layout(parent), pose, _STAMP),
        View("/tf", *ros2.TF_MESSAGE, ros2.tf_layout(parent, child), tf, _STAMP, absolute=True),
    ]
    if str(topic) == "/truth/odometry":  # at every physics instant: its pose and /tf say it all, and /clock ticks
        views.append(View("/clock", *ros2.CLOCK, ros2.clock_layout(), (), (("clock.sec", "clock.nanosec", "t"),), True))
    else:
        twist = (("twist.linear", "v_w", "q_wb"),)  # REP 105: the twist in the child (body) frame, v_B = R_WB^T v_W
        views.insert(
            0, View("/ros", *ros2.ODOMETRY, ros2.odometry_layout(parent, child), odometry, _STAMP, False, twist)
        )
    return tuple(views)


def _imu_views(topic: str) -> tuple[View, ...]:
    copies = (("angular_velocity", 0, "w_i", 0, 3), ("linear_acceleration", 0, "f_i", 0, 3))
    return (View("/ros", *ros2.IMU, ros2.imu_layout(sensor_frame(topic)), copies, _STAMP),)


class JsonCodec(Codec):
    """Every field as exact JSON (``encode_value``), under a ``cufund.<Class>`` JSON Schema."""

    name = "json"
    schema_encoding = "jsonschema"
    message_encoding = "json"

    def __init__(self, cls: type):
        super().__init__(cls)
        self.schema_name = f"cufund.{cls.__name__}"
        self.schema_data = json.dumps(_json_schema(cls)).encode()

    def encode(self, messages: list[Any], topic: str) -> list[bytes]:
        return [_dumps(encode_fields(m, f"topic {topic!r}: {self.cls.__name__}")) for m in messages]

    def decode(self, data: bytes | memoryview) -> Any:
        return self.cls(**decode_fields(json.loads(bytes(data)), self.where))


def _dumps(obj: Any) -> bytes:
    return json.dumps(obj, separators=(",", ":"), allow_nan=False).encode()


def _json_schema(cls: type) -> dict[str, Any]:
    try:
        hints = typing.get_type_hints(cls)
    except Exception:
        hints = {}
    kinds: dict[Any, dict[str, Any]] = {
        float: {"type": ["number", "object"]},
        int: {"type": "integer"},
        bool: {"type": "boolean"},
        str: {"type": "string"},
    }
    properties = {
        f.name: {**kinds.get(hints.get(f.name, object), {}), "description": f"{cls.__name__}.{f.name}"}
        for f in dataclasses.fields(cls)
    }
    return {
        "title": f"cufund.{cls.__name__}",
        "type": "object",
        "properties": properties,
        "description": "cufund message: non-finite floats, arrays, enums and nested dataclasses are objects "
        "tagged $float, $ndarray, $enum, $dataclass",
    }


class _FoxgloveJsonCodec(Codec):
    """Reads the Foxglove JSON messages of logs written before the ROS 2 messages: the bulk of a message in the
    Foxglove schema's fields, its other fields, exact, in ``cufund``. Nothing writes them any more (``encode`` is
    not defined)."""

    schema_encoding = "jsonschema"
    message_encoding = "json"

    def __init__(self, cls: type, schema: tuple[str, bytes], frame_id: str):
        super().__init__(cls)
        self.schema_name, self.schema_data = schema
        self.name = self.schema_name
        self.frame_id = frame_id

    def decode(self, data: bytes | memoryview) -> Any:
        obj = json.loads(bytes(data))
        if not isinstance(obj, dict) or not isinstance(obj.get("cufund"), dict):
            raise ValueError(f"{self.where}: a {self.schema_name} message without its 'cufund' object")
        exact = obj["cufund"]
        return self.cls(**decode_fields(exact.get("fields"), self.where), **self._decode_bulk(obj, exact))

    def _decode_bulk(self, obj: dict[str, Any], exact: dict[str, Any]) -> dict[str, Any]:
        raise NotImplementedError


class PointCloudCodec(_FoxgloveJsonCodec):
    """``foxglove.PointCloud``: x, y, z into the (N, 3) ``xyz`` field and one packed field per per-point array
    (with the exact dtypes the ``cufund`` object names)."""

    def __init__(self, cls: type, frame_id: str, xyz: str, per_point: tuple[tuple[str, str], ...]):
        self.xyz, self.per_point = xyz, per_point
        super().__init__(cls, schemas.POINT_CLOUD_SCHEMA, frame_id)

    def _decode_bulk(self, obj: dict[str, Any], exact: dict[str, Any]) -> dict[str, Any]:
        dtype = np.dtype(
            {
                "names": [f["name"] for f in obj["fields"]],
                "formats": [_NUMPY_OF_TYPE[f["type"]] for f in obj["fields"]],
                "offsets": [f["offset"] for f in obj["fields"]],
                "itemsize": obj["point_stride"],
            }
        )
        if not 0 < dtype.itemsize <= 4096:
            raise ValueError(f"{self.where}: point_stride {obj['point_stride']!r} is out of range")
        data = np.frombuffer(base64.b64decode(obj["data"], validate=True), dtype)
        dtypes = {k: numeric_dtype(v, self.where) for k, v in exact["dtypes"].items()}
        out = {self.xyz: np.stack([data[k].astype(dtypes[k]) for k in "xyz"], axis=1)}
        for attr, name in self.per_point:
            out[attr] = data[name].astype(dtypes[name])
        return out


_NUMPY_OF_TYPE = {v: "<" + np.dtype(k).str[1:] for k, v in schemas.NUMERIC_TYPES.items()}


class RawImageCodec(_FoxgloveJsonCodec):
    """``foxglove.RawImage``; the exact dtype and shape ride along in ``cufund``."""

    def _decode_bulk(self, obj: dict[str, Any], exact: dict[str, Any]) -> dict[str, Any]:
        image = np.frombuffer(
            base64.b64decode(obj["data"], validate=True), numeric_dtype(exact["dtype"], self.where)
        ).reshape(exact["shape"])
        return {"image": image.copy()}


class LocationFixCodec(_FoxgloveJsonCodec):
    """``foxglove.LocationFix``: every field is in ``cufund``."""

    def _decode_bulk(self, obj: dict[str, Any], exact: dict[str, Any]) -> dict[str, Any]:
        return {}


_FLOAT32, _FLOAT64, _UINT8, _UINT32 = 7, 8, 2, 6
_POINT_FIELD_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
LIVOX_POINT = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "tag", "line", "timestamp"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "u1", "u1", "<f8"],
        "offsets": [0, 4, 8, 12, 16, 17, 18],
        "itemsize": 26,
    }
)
"""A point of livox_ros_driver2's ``PointCloud2`` (its ``LivoxPointXyzrtlt``, packed): x, y, z [m], intensity
(Livox's reflectivity scale: whole numbers 0-255, cufund's [0, 1] intensity times 255), tag (0), line (the laser)
and timestamp (the point's own time in ns on the header's clock, float64)."""
TRUTH_POINT = np.dtype({"names": ["x", "y", "z", "object_id"], "formats": ["<f4", "<f4", "<f4", "<u4"]})
"""A point of the LiDAR truth cloud: the true hit in the world frame and the id of the object hit."""


def _point_fields(dtype: np.dtype) -> list[tuple[str, int, int]]:
    fields = dtype.fields
    assert fields is not None
    codes = {v: k for k, v in _POINT_FIELD_DTYPES.items()}
    return [(name, fields[name][1], codes[fields[name][0].str[1:]]) for name in dtype.names or ()]


class _SensorCodec(Codec):
    """A standard ROS 2 sensor message (CDR, ros2msg schema ``schema``) in the frame ``frame_id``, which the channel
    metadata keeps (``cufund.frame_id``) for reading it back."""

    schema: tuple[str, str]
    schema_encoding = "ros2msg"
    message_encoding = "cdr"

    def __init__(self, cls: type, frame_id: str):
        super().__init__(cls)
        self.schema_name, text = self.schema
        self.schema_data = text.encode()
        self.frame_id = frame_id

    def metadata(self) -> dict[str, str]:
        return {**super().metadata(), "cufund.frame_id": self.frame_id}


class PointCloud2Codec(_SensorCodec):
    """``sensor_msgs/msg/PointCloud2`` (CDR): a LiDAR frame as livox_ros_driver2 publishes it (:data:`LIVOX_POINT`,
    in the sensor's frame) or the LiDAR truth (:data:`TRUTH_POINT`, in ``world``).

    Read back as the cufund message: the points (float32) exactly, the stamp and the per-point times to the
    nanosecond, the intensity to 1/255 (what a Livox sensor reports); a
    frame's ranges are the points' norms and its pattern index ``frame`` is not kept (-1)."""

    name = "ros2.PointCloud2"
    schema = ros2.POINT_CLOUD2

    def __init__(self, cls: type, frame_id: str):
        super().__init__(cls, frame_id)
        self.truth = cls.__name__ == "LidarTruth"
        self.point = TRUTH_POINT if self.truth else LIVOX_POINT
        self.fields = _point_fields(self.point)

    def encode(self, messages: list[Any], topic: str) -> list[bytes]:
        return [self._encode_one(m, topic) for m in messages]

    def _encode_one(self, m: Any, topic: str) -> bytes:
        xyz = np.asarray(m.points_W if self.truth else m.points_L)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise ValueError(f"topic {topic!r}: {self.cls.__name__} points must have shape (N, 3), got {xyz.shape}")
        n = len(xyz)
        data = np.zeros(n, self.point)
        data["x"], data["y"], data["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        sec, nsec = stamp_sec_nsec(np.array([m.t]))
        stamp_ns = int(sec[0]) * 1_000_000_000 + int(nsec[0])
        if self.truth:
            ids = np.asarray(m.object_ids)
            if ids.shape != (n,) or (n and (int(ids.min()) < 0 or int(ids.max()) >= 2**32)):
                raise ValueError(f"topic {topic!r}: object_ids must be ({n},) ids in [0, 2**32), got {ids.shape}")
            data["object_id"] = ids
        else:
            for attr in ("dt", "intensity", "channel"):
                if np.shape(getattr(m, attr)) != (n,):
                    raise ValueError(
                        f"topic {topic!r}: per-point field {attr!r} has shape {np.shape(getattr(m, attr))}, "
                        f"expected ({n},)"
                    )
            data["intensity"] = np.round(np.clip(np.asarray(m.intensity, dtype=np.float64), 0.0, 1.0) * 255.0)
            data["line"] = m.channel
            data["timestamp"] = stamp_ns + np.round(np.asarray(m.dt, dtype=np.float64) * 1e9)  # whole ns, as Livox
        w = ros2.CdrWriter().put("i", int(sec[0])).put("I", int(nsec[0])).string(self.frame_id)
        w.put("I", 1, n).put("I", len(self.fields))
        for name, offset, datatype in self.fields:
            w.string(name).put("I", offset).put("B", datatype).put("I", 1)
        w.put("?", False).put("I", self.point.itemsize, self.point.itemsize * n)
        return w.blob(data.tobytes()).put("?", True).bytes()

    def decode(self, data: bytes | memoryview) -> Any:
        r = ros2.CdrReader(data, self.where)
        sec, nsec = r.get("i")[0], r.get("I")[0]
        r.string()
        height, width = r.get("I", 2)
        fields = {}
        for _ in range(r.get("I")[0]):
            name = r.string()
            offset, datatype, _count = r.get("I")[0], r.get("B")[0], r.get("I")[0]
            fields[name] = (offset, _POINT_FIELD_DTYPES.get(datatype, "u1"))
        r.get("?")
        point_step, _ = r.get("I", 2)
        raw = r.blob()
        n = height * width
        names = [k for k in self.point.names or () if k in fields]
        if len(names) != len(self.point.names or ()) or n * point_step > len(raw) or not 0 < point_step <= 4096:
            raise ValueError(f"{self.where}: a PointCloud2 without the fields {self.point.names} or with bad sizes")
        dtype = np.dtype(
            {
                "names": names,
                "formats": ["<" + fields[k][1] for k in names],
                "offsets": [fields[k][0] for k in names],
                "itemsize": point_step,
            }
        )
        pts = np.frombuffer(raw, dtype, count=n)
        xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float32)
        stamp_ns = sec * 1_000_000_000 + nsec
        t = stamp_ns / 1e9
        if self.truth:
            return self.cls(t=t, points_W=xyz, object_ids=pts["object_id"].astype(np.uint32))
        return self.cls(
            t=t,
            dt=(pts["timestamp"].astype(np.float64) - stamp_ns) / 1e9,
            points_L=xyz,
            ranges=np.linalg.norm(xyz.astype(np.float64), axis=1),
            intensity=pts["intensity"].astype(np.float64) / 255.0,
            channel=pts["line"].astype(np.int32),
            frame=-1,
        )


_ROS_IMAGE_ENCODINGS = {
    ("float32", 1): "32FC1",
    ("uint8", 1): "mono8",
    ("uint16", 1): "16UC1",
    ("uint8", 3): "rgb8",
    ("uint8", 4): "rgba8",
}
_IMAGE_OF_ENCODING = {v: k for k, v in _ROS_IMAGE_ENCODINGS.items()}


class ImageCodec(_SensorCodec):
    """``sensor_msgs/msg/Image`` (CDR): depth as ``32FC1`` (NaN: no return), colour as ``rgb8``; read back exactly
    (the stamp to the nanosecond)."""

    name = "ros2.Image"
    schema = ros2.IMAGE

    @staticmethod
    def encoding_of(image: Any) -> str | None:
        image = np.asarray(image)
        if image.ndim not in (2, 3):
            return None
        return _ROS_IMAGE_ENCODINGS.get((image.dtype.name, image.shape[2] if image.ndim == 3 else 1))

    def encode(self, messages: list[Any], topic: str) -> list[bytes]:
        out = []
        for m in messages:
            image = np.ascontiguousarray(m.image)
            encoding = self.encoding_of(image)
            if encoding is None:
                raise ValueError(
                    f"topic {topic!r}: an image must be (H, W) float32/uint8/uint16 or (H, W, 3|4) uint8, "
                    f"got {image.shape} {image.dtype}"
                )
            w = ros2.CdrWriter().header(m.t, self.frame_id).put("I", image.shape[0], image.shape[1])
            w.string(encoding).put("B", 0).put("I", image.strides[0])
            out.append(w.blob(image.astype(image.dtype.newbyteorder("<"), copy=False).tobytes()).bytes())
        return out

    def decode(self, data: bytes | memoryview) -> Any:
        r = ros2.CdrReader(data, self.where)
        t, _ = r.header()
        height, width = r.get("I", 2)
        encoding = r.string()
        r.get("B")
        r.get("I")
        raw = r.blob()
        if encoding not in _IMAGE_OF_ENCODING:
            raise ValueError(f"{self.where}: an image of encoding {encoding[:40]!r}, which cufund does not write")
        dtype, channels = _IMAGE_OF_ENCODING[encoding]
        shape = (height, width, channels) if channels > 1 else (height, width)
        image = np.frombuffer(raw, np.dtype(dtype).newbyteorder("<"), count=int(np.prod(shape))).reshape(shape)
        return self.cls(t=t, image=image.astype(dtype))


PATH_STEP_S = 0.1
"""Spacing of the poses of a logged planned path [s]."""


def path_of(trajectory: Any, t: float) -> bytes:
    """A trajectory (:class:`cufund.planning.Trajectory`: ``t_start``, ``duration``, ``sample``) as a
    ``nav_msgs/msg/Path`` in ``world`` stamped ``t``: a pose every :data:`PATH_STEP_S` over its span."""
    start, duration = float(trajectory.t_start), float(trajectory.duration)
    n = max(2, min(20_000, int(np.ceil(duration / PATH_STEP_S)) + 1))
    samples = trajectory.sample(np.linspace(start, start + duration, n))
    return ros2.path_message(t, WORLD_FRAME, samples.t, samples.p_W, samples.yaw)


class PathCodec(Codec):
    """A planner's trajectory updates as ``nav_msgs/msg/Path`` (for viewers): written only, never read back (a
    trajectory object is not rebuilt from its samples), so the channel names no cufund codec."""

    name = "ros2.Path"
    schema_encoding = "ros2msg"
    message_encoding = "cdr"

    def __init__(self, cls: type):
        super().__init__(cls)
        self.schema_name, text = ros2.PATH
        self.schema_data = text.encode()

    def metadata(self) -> dict[str, str]:
        return {"cufund.derived": "planned path (not read back)"}

    def encode(self, messages: list[Any], topic: str) -> list[bytes]:
        return [path_of(m.trajectory, m.t) for m in messages]


def _gps_views(topic: str) -> tuple[View, ...]:
    copies = (
        ("latitude", 0, "latitude_deg", 0, 1),
        ("longitude", 0, "longitude_deg", 0, 1),
        ("altitude", 0, "altitude_m", 0, 1),
    )
    return (View("/ros", *ros2.NAV_SAT_FIX, ros2.nav_sat_fix_layout(sensor_frame(topic)), copies, _STAMP),)


def _lidar_codec(cls: type) -> PointCloudCodec:
    return PointCloudCodec(
        cls,
        "lidar",
        "points_L",
        (("dt", "dt"), ("ranges", "range"), ("intensity", "intensity"), ("channel", "channel")),
    )


def _lidar_truth_codec(cls: type) -> PointCloudCodec:
    return PointCloudCodec(cls, WORLD_FRAME, "points_W", (("object_ids", "object_id"),))


def _has_fields(cls: type, names: tuple[str, ...]) -> bool:
    return tuple(f.name for f in dataclasses.fields(cls)) == names


def codec_for(topic: str, message: Any) -> Codec:
    """The codec of ``topic``, whose first message is ``message``."""
    cls = type(message)
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"topic {topic!r}: only dataclass messages can be logged, got {cls.__name__}")
    note_logged(cls)  # a class this process logs may be read back
    cufund = cls.__module__ == "cufund.core.messages"
    name = cls.__name__
    if (
        cufund
        and name == "PointCloud"
        and _has_fields(cls, ("t", "dt", "points_L", "ranges", "intensity", "channel", "frame"))
    ):
        return PointCloud2Codec(cls, sensor_frame(topic))
    if cufund and name == "LidarTruth" and _has_fields(cls, ("t", "points_W", "object_ids")):
        return PointCloud2Codec(cls, WORLD_FRAME)
    if cufund and name == "CameraImage" and _has_fields(cls, ("t", "image")) and ImageCodec.encoding_of(message.image):
        return ImageCodec(cls, sensor_frame(topic))
    if cufund and name == "TrajectoryUpdate" and hasattr(message.trajectory, "sample"):
        return PathCodec(cls)
    layout = infer_message_layout(cls, message)
    if layout is not None:
        views: tuple[View, ...] = ()
        if cufund and name == "Odometry":
            views = _odometry_views(topic, layout.layout)
        elif cufund and name == "Imu":
            views = _imu_views(topic)
        elif cufund and name == "GpsFix":
            views = _gps_views(topic)
        return CdrCodec(layout, views)
    codec = JsonCodec(cls)
    if cufund and name == "TunnelEstimate":
        codec.companions = (("/scene", scene.SCENE_UPDATE, "jsonschema", "json", scene.tunnel_scene_update),)
    return codec


CODECS = (
    "cdr",
    "json",
    "ros2.PointCloud2",
    "ros2.Image",
    "foxglove.PointCloud",
    "foxglove.RawImage",
    "foxglove.LocationFix",
)
"""The codecs a channel may name: today's and those of older logs (JSON clouds, images and fixes before the ROS 2
messages), all read."""


def codec_from_channel(metadata: dict[str, str], where: str = "the channel") -> Codec:
    """The codec a channel was written with, from its metadata; ValueError naming ``where`` (the channel) when
    it names none, an unknown codec or a class that is not an allowed message class
    (:func:`cufund.logs.message_classes.message_class`: nothing the file names is imported)."""
    kind, path = metadata.get("cufund.codec"), metadata.get("cufund.class")
    if kind is None or path is None:
        raise ValueError(f"{where} was not written by cufund (no cufund.codec / cufund.class metadata)")
    cls = message_class(path, where)
    if not dataclasses.is_dataclass(cls):
        raise ValueError(f"{where}: its class {path!r} is not a dataclass message")
    try:
        if kind == "cdr":
            codec: Codec = CdrCodec(MessageLayout.from_description(cls, json.loads(metadata["cufund.layout"])))
        elif kind == "json":
            codec = JsonCodec(cls)
        elif kind == "ros2.PointCloud2":
            codec = PointCloud2Codec(cls, str(metadata.get("cufund.frame_id", "")))
        elif kind == "ros2.Image":
            codec = ImageCodec(cls, str(metadata.get("cufund.frame_id", "")))
        elif kind == "foxglove.PointCloud":  # logs of cufund before the ROS 2 messages (read as they were)
            fields = tuple(f.name for f in dataclasses.fields(cls))
            codec = _lidar_codec(cls) if "points_L" in fields else _lidar_truth_codec(cls)
        elif kind == "foxglove.RawImage":
            codec = RawImageCodec(cls, schemas.RAW_IMAGE_SCHEMA, "camera")
        elif kind == "foxglove.LocationFix":
            codec = LocationFixCodec(cls, schemas.LOCATION_FIX_SCHEMA, "gps")
        else:
            raise ValueError(
                f"unknown cufund codec {str(kind)[:100]!r} (a log of a newer cufund? this one reads {', '.join(CODECS)})"
            )
    except (ValueError, TypeError, KeyError, IndexError, AttributeError, RecursionError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    codec.where = where
    return codec
