"""The ROS 2 standard messages of a cufund log: their ros2msg definitions (what Foxglove, ``mcap-ros2-support`` and
``rosbags`` decode the CDR bytes with), the fixed CDR layouts of the views the logger's C++ thread derives from
fixed-size cufund messages (``nav_msgs/msg/Odometry``, ``geometry_msgs/msg/PoseStamped``, ``tf2_msgs/msg/TFMessage``,
``sensor_msgs/msg/Imu``, ``rosgraph_msgs/msg/Clock``), and a small CDR writer and reader for the variable-size
ones (``sensor_msgs/msg/PointCloud2``, ``Image``, ``nav_msgs/msg/Path``, a static ``TFMessage``).

One encoding, CDR with ros2msg schemas, for every standard message: it is what a ROS 2 bag holds and what a ROS 2
bridge publishes, so a log is read by the same tools as a real robot's bag. Quaternions are converted here only:
cufund's are [w, x, y, z], ROS's x, y, z, w.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from .cdr import CdrField, CdrLayout, stamp_sec_nsec, stamp_sec_nsec_of

__all__ = [
    "CLOCK",
    "IMAGE",
    "IMU",
    "NAV_SAT_FIX",
    "ODOMETRY",
    "PATH",
    "POINT_CLOUD2",
    "POSE_STAMPED",
    "TF_MESSAGE",
    "CdrReader",
    "CdrWriter",
    "clock_layout",
    "imu_layout",
    "nav_sat_fix_layout",
    "odometry_layout",
    "path_message",
    "pose_stamped_layout",
    "tf_layout",
    "tf_message",
]

_SEPARATOR = "=" * 80
_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
_POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
_QUATERNION = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
_POSE = "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"
_TWIST = "MSG: geometry_msgs/Twist\ngeometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n"
_TRANSFORM = "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"
_TRANSFORM_STAMPED = (
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/Transform transform\n"
)


def _ros2msg(main: str, *dependencies: str) -> str:
    return "".join([main] + [f"{_SEPARATOR}\n{d}" for d in dependencies])


ODOMETRY = (
    "nav_msgs/msg/Odometry",
    _ros2msg(
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
        "geometry_msgs/TwistWithCovariance twist\n",
        _HEADER,
        _TIME,
        "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n",
        _POSE,
        _POINT,
        _QUATERNION,
        "MSG: geometry_msgs/TwistWithCovariance\ngeometry_msgs/Twist twist\nfloat64[36] covariance\n",
        _TWIST,
        _VECTOR3,
    ),
)
POSE_STAMPED = (
    "geometry_msgs/msg/PoseStamped",
    _ros2msg("std_msgs/Header header\ngeometry_msgs/Pose pose\n", _HEADER, _TIME, _POSE, _POINT, _QUATERNION),
)
TF_MESSAGE = (
    "tf2_msgs/msg/TFMessage",
    _ros2msg(
        "geometry_msgs/TransformStamped[] transforms\n",
        _TRANSFORM_STAMPED,
        _HEADER,
        _TIME,
        _TRANSFORM,
        _VECTOR3,
        _QUATERNION,
    ),
)
IMU = (
    "sensor_msgs/msg/Imu",
    _ros2msg(
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
        _HEADER,
        _TIME,
        _QUATERNION,
        _VECTOR3,
    ),
)
CLOCK = ("rosgraph_msgs/msg/Clock", _ros2msg("builtin_interfaces/Time clock\n", _TIME))
POINT_CLOUD2 = (
    "sensor_msgs/msg/PointCloud2",
    _ros2msg(
        "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\n"
        "uint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
        _HEADER,
        _TIME,
        "MSG: sensor_msgs/PointField\nuint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\n"
        "uint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\n"
        "uint32 count\n",
    ),
)
IMAGE = (
    "sensor_msgs/msg/Image",
    _ros2msg(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\n"
        "uint8[] data\n",
        _HEADER,
        _TIME,
    ),
)
NAV_SAT_FIX = (
    "sensor_msgs/msg/NavSatFix",
    _ros2msg(
        "uint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\n"
        "uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\n"
        "std_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\nfloat64 longitude\n"
        "float64 altitude\nfloat64[9] position_covariance\nuint8 position_covariance_type\n",
        _HEADER,
        _TIME,
        "MSG: sensor_msgs/NavSatStatus\nint8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\n"
        "int8 STATUS_GBAS_FIX=2\nuint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\n"
        "uint16 SERVICE_GALILEO=8\nint8 status\nuint16 service\n",
    ),
)


PATH = (
    "nav_msgs/msg/Path",
    _ros2msg(
        "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n",
        _HEADER,
        _TIME,
        "MSG: geometry_msgs/PoseStamped\nstd_msgs/Header header\ngeometry_msgs/Pose pose\n",
        _POSE,
        _POINT,
        _QUATERNION,
    ),
)


def _header(frame: str) -> list[CdrField]:
    return [
        CdrField("header.stamp.sec", "i4"),
        CdrField("header.stamp.nanosec", "u4"),
        CdrField("frame_id", "str", const=frame),
    ]


def odometry_layout(parent: str, child: str) -> CdrLayout:
    """``nav_msgs/msg/Odometry`` in ``parent`` of ``child`` (covariances zero: unknown)."""
    return CdrLayout(
        [
            *_header(parent),
            CdrField("child_frame_id", "str", const=child),
            CdrField("pose.position", "f8", 3),
            CdrField("pose.orientation", "f8", 4),
            CdrField("pose.covariance", "f8", 36),
            CdrField("twist.linear", "f8", 3),
            CdrField("twist.angular", "f8", 3),
            CdrField("twist.covariance", "f8", 36),
        ]
    )


def pose_stamped_layout(frame: str) -> CdrLayout:
    """``geometry_msgs/msg/PoseStamped`` in ``frame``."""
    return CdrLayout([*_header(frame), CdrField("pose.position", "f8", 3), CdrField("pose.orientation", "f8", 4)])


def tf_layout(parent: str, child: str) -> CdrLayout:
    """``tf2_msgs/msg/TFMessage`` of one transform ``parent`` -> ``child``."""
    return CdrLayout(
        [
            CdrField("transforms.length", "u4", value=1),
            *_header(parent),
            CdrField("child_frame_id", "str", const=child),
            CdrField("translation", "f8", 3),
            CdrField("rotation", "f8", 4),
        ]
    )


def imu_layout(frame: str) -> CdrLayout:
    """``sensor_msgs/msg/Imu`` in ``frame``: no orientation (its covariance's first element -1, as REP 145 says),
    angular velocity and specific force, covariances zero (unknown)."""
    return CdrLayout(
        [
            *_header(frame),
            CdrField("orientation", "f8", 4),
            CdrField("orientation_covariance", "f8", 9, value=-1.0),
            CdrField("angular_velocity", "f8", 3),
            CdrField("angular_velocity_covariance", "f8", 9),
            CdrField("linear_acceleration", "f8", 3),
            CdrField("linear_acceleration_covariance", "f8", 9),
        ]
    )


def nav_sat_fix_layout(frame: str) -> CdrLayout:
    """``sensor_msgs/msg/NavSatFix`` in ``frame``: status FIX, service GPS, the position (NaN without a fix),
    covariance unknown (the receiver's claimed accuracy stays on the cufund channel)."""
    return CdrLayout(
        [
            *_header(frame),
            CdrField("status.status", "i1", value=0),
            CdrField("status.service", "u2", value=1),
            CdrField("latitude", "f8"),
            CdrField("longitude", "f8"),
            CdrField("altitude", "f8"),
            CdrField("position_covariance", "f8", 9),
            CdrField("position_covariance_type", "u1", value=0),
        ]
    )


def clock_layout() -> CdrLayout:
    """``rosgraph_msgs/msg/Clock``."""
    return CdrLayout([CdrField("clock.sec", "i4"), CdrField("clock.nanosec", "u4")])


class CdrWriter:
    """Little-endian CDR of one message, field by field (alignment counted from after the 4-byte header)."""

    def __init__(self) -> None:
        self.parts: list[bytes] = [b"\x00\x01\x00\x00"]
        self.pos = 0

    def _align(self, size: int) -> None:
        pad = (-self.pos) % size
        if pad:
            self.parts.append(b"\0" * pad)
            self.pos += pad

    def put(self, code: str, *values: Any) -> CdrWriter:
        """``values`` packed with the ``struct`` code (one letter, repeated), aligned to the element size."""
        size = struct.calcsize("<" + code)
        self._align(size)
        data = struct.pack(f"<{len(values)}{code}", *values)
        self.parts.append(data)
        self.pos += len(data)
        return self

    def string(self, text: str) -> CdrWriter:
        raw = text.encode() + b"\0"
        self.put("I", len(raw))
        self.parts.append(raw)
        self.pos += len(raw)
        return self

    def blob(self, data: bytes | memoryview) -> CdrWriter:
        """A ``uint8[]``."""
        self.put("I", len(data))
        self.parts.append(bytes(data))
        self.pos += len(data)
        return self

    def header(self, t: float, frame: str) -> CdrWriter:
        sec, nsec = stamp_sec_nsec_of(t)
        return self.put("i", sec).put("I", nsec).string(frame)

    def bytes(self) -> bytes:
        return b"".join(self.parts)


class CdrReader:
    """Reads what :class:`CdrWriter` writes (little-endian CDR only; ValueError for anything else)."""

    def __init__(self, data: bytes | memoryview, what: str):
        self.data = memoryview(data)
        self.what = what
        if bytes(self.data[:2]) != b"\x00\x01":
            raise ValueError(f"{what}: not little-endian CDR (encapsulation {bytes(self.data[:4])!r})")
        self.pos = 0

    def get(self, code: str, count: int = 1) -> tuple[Any, ...]:
        size = struct.calcsize("<" + code)
        self.pos += (-self.pos) % size
        start = 4 + self.pos
        end = start + size * count
        if end > len(self.data):
            raise ValueError(f"{self.what}: the message ends early (needs {end} bytes, has {len(self.data)})")
        self.pos += size * count
        return struct.unpack(f"<{count}{code}", self.data[start:end])

    def string(self) -> str:
        (n,) = self.get("I")
        raw = self.blob_of(n)
        return bytes(raw[:-1]).decode()

    def blob_of(self, n: int) -> memoryview:
        start = 4 + self.pos
        if n < 0 or start + n > len(self.data):
            raise ValueError(f"{self.what}: a field of {n} bytes runs past the message's end")
        self.pos += n
        return self.data[start : start + n]

    def blob(self) -> memoryview:
        (n,) = self.get("I")
        return self.blob_of(n)

    def header(self) -> tuple[float, str]:
        sec, nsec = self.get("i")[0], self.get("I")[0]
        return (sec * 1_000_000_000 + nsec) / 1e9, self.string()


def path_message(t: float, frame: str, times: Any, p: Any, yaw: Any) -> bytes:
    """A ``nav_msgs/msg/Path`` at ``t`` in ``frame``: a pose at each of ``times`` [s], positions ``p`` (N, 3) and
    headings ``yaw`` (N,) [rad] (the attitude of a flat-output trajectory is its yaw; tilt is not part of it).
    The poses are packed as one numpy block (each ``PoseStamped`` has the same layout)."""
    times, p, yaw = np.asarray(times, float), np.asarray(p, float).reshape(-1, 3), np.asarray(yaw, float)
    w = CdrWriter().header(t, frame).put("I", len(times))
    raw = frame.encode() + b"\0"
    if w.pos % 8:  # the poses' doubles would not sit at one offset in every element: field by field
        for k in range(len(times)):
            w.header(float(times[k]), frame).put("d", *p[k])
            w.put("d", 0.0, 0.0, float(np.sin(yaw[k] / 2)), float(np.cos(yaw[k] / 2)))
        return w.bytes()
    at = (12 + len(raw) + 7) // 8 * 8  # the position's offset in an element (8-aligned: elements start so)
    pose = np.dtype(
        {
            "names": ["sec", "nanosec", "len", "frame", "p", "q"],
            "formats": ["<i4", "<u4", "<u4", f"V{len(raw)}", ("<f8", 3), ("<f8", 4)],
            "offsets": [0, 4, 8, 12, at, at + 24],
            "itemsize": at + 56,
        }
    )
    poses = np.zeros(len(times), pose)
    poses["sec"], poses["nanosec"] = stamp_sec_nsec(times)
    poses["len"] = len(raw)
    poses["frame"] = np.frombuffer(raw, f"V{len(raw)}")[0]
    poses["p"] = p
    poses["q"][:, 2], poses["q"][:, 3] = np.sin(yaw / 2), np.cos(yaw / 2)
    return w.bytes() + poses.tobytes()


def tf_message(t: float, transforms: list[tuple[str, str, Any, Any]]) -> bytes:
    """A ``tf2_msgs/msg/TFMessage`` of ``transforms`` (parent, child, translation (3,), q [w, x, y, z]) at ``t``."""
    w = CdrWriter().put("I", len(transforms))
    for parent, child, p, q in transforms:
        qw, qx, qy, qz = (float(v) for v in q)
        w.header(t, parent).string(child).put("d", *(float(v) for v in p)).put("d", qx, qy, qz, qw)
    return w.bytes()
