"""Reading a ROS 2 bag (rosbag2 folder, ``sqlite3`` or ``mcap`` storage) as cufund messages, so that
:class:`cufund.logs.LogPlayer` and ``cufund odometry`` run on a bag recorded on a real drone as on a cufund log.

The bag is opened with ``rosbags`` (its ROS 2 message definitions and CDR implementation; the definitions a bag
carries are used first). Each message is converted by its ROS 2 type; other types are not read:

- ``sensor_msgs/msg/Imu`` -> :class:`cufund.core.messages.Imu`: ``t`` the header stamp, ``f_I`` the
  ``linear_acceleration`` [m/s^2] (specific force, gravity included, as every IMU driver reports it), ``w_I`` the
  ``angular_velocity`` [rad/s], both in the IMU's frame (the estimator's extrinsics say where it sits).
- ``sensor_msgs/msg/PointCloud2`` -> :class:`cufund.core.messages.PointCloud`: float32 (or float64) ``x``, ``y``,
  ``z`` in the sensor's frame; per-point time from the first of ``timestamp`` (livox_ros_driver2: float64 ns, absolute;
  seconds when the values sit near the stamp in seconds, as Hesai's), ``offset_time`` (uint32 ns after the stamp),
  ``t`` (Ouster: uint32 ns after the stamp), ``time`` (Velodyne: float32 s after the stamp); without any, every
  point at the stamp (dt 0). ``intensity`` / ``reflectivity`` on Livox's 0-255 scale (/255), ``line`` / ``ring`` the
  channel. ``t`` is the header stamp, the frame's start. NaN points are dropped (an unorganised cloud's gaps).
- ``livox_ros_driver2/msg/CustomMsg`` (and ``livox_ros_driver/msg/CustomMsg``) -> ``PointCloud``: ``t`` the
  ``timebase`` [ns], each point's ``offset_time`` [ns] after it, ``reflectivity``/255, ``line``. Their ``.msg``
  definitions ship here as text (:data:`LIVOX_MSGS`) for bags that do not carry them.
- ``nav_msgs/msg/Odometry`` -> :class:`cufund.core.messages.Odometry` (pose in the parent frame, twist rotated from
  the child frame to the parent frame, covariances as ``pose_cov_W``/``twist_cov_B`` unless they say unknown: all
  zero or -1 first); ``geometry_msgs/msg/PoseStamped`` -> :class:`cufund.core.messages.Pose`.
  Quaternions become cufund's [w, x, y, z].

Records come in bag-timestamp order (a bag's timestamp is when the recorder received the message; a cufund bag's
is the log time, when the message became visible in the run).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .mcap_reader import LogRecord

__all__ = [
    "LIVOX_MSGS",
    "ROS2_TYPES",
    "BagReadError",
    "bag_custom_data",
    "bag_topics",
    "is_rosbag2",
    "pick_topic",
    "read_rosbag2",
    "rosbags_typestore",
]

LIVOX_MSGS = {
    "livox_ros_driver2/msg/CustomPoint": (
        "# Livox costom pointcloud format.\n\n"
        "uint32 offset_time      # offset time relative to the base time\n"
        "float32 x               # X axis, unit:m\n"
        "float32 y               # Y axis, unit:m\n"
        "float32 z               # Z axis, unit:m\n"
        "uint8 reflectivity      # reflectivity, 0~255\n"
        "uint8 tag               # livox tag\n"
        "uint8 line              # laser number in lidar\n"
    ),
    "livox_ros_driver2/msg/CustomMsg": (
        "# Livox publish pointcloud msg format.\n\n"
        "std_msgs/Header header    # ROS standard message header\n"
        "uint64 timebase           # The time of first point\n"
        "uint32 point_num          # Total number of pointclouds\n"
        "uint8  lidar_id           # Lidar device id number\n"
        "uint8[3]  rsvd            # Reserved use\n"
        "CustomPoint[] points      # Pointcloud data\n"
    ),
}
"""livox_ros_driver2's ``CustomMsg`` and ``CustomPoint`` (``msg/*.msg`` of the driver, as text); the ROS 1-era
``livox_ros_driver`` has the same fields and is registered under its own package name too."""

ROS2_TYPES = {
    "sensor_msgs/msg/Imu": "Imu",
    "sensor_msgs/msg/PointCloud2": "PointCloud",
    "livox_ros_driver2/msg/CustomMsg": "PointCloud",
    "livox_ros_driver/msg/CustomMsg": "PointCloud",
    "nav_msgs/msg/Odometry": "Odometry",
    "geometry_msgs/msg/PoseStamped": "Pose",
}
"""The ROS 2 types read, and the cufund message class each becomes."""


class BagReadError(ValueError):
    """The folder is not a readable ROS 2 bag, or a message of it cannot be converted."""


def rosbags_typestore() -> Any:
    """A ``rosbags`` typestore of ROS 2's standard messages (Humble) plus the Livox driver's ``CustomMsg``."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    for package in ("livox_ros_driver2", "livox_ros_driver"):
        types: dict[str, Any] = {}
        for name, text in LIVOX_MSGS.items():
            types.update(get_types_from_msg(text, name.replace("livox_ros_driver2", package)))
        store.register(types)
    return store


def is_rosbag2(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a rosbag2 folder (it holds ``metadata.yaml``)."""
    return Path(path).is_dir() and (Path(path) / "metadata.yaml").is_file()


def _open(path: Path) -> Any:
    if not is_rosbag2(path):
        raise BagReadError(f"{str(path)!r} is not a ROS 2 bag (a folder with metadata.yaml)")
    odd = sorted(p.name for p in path.iterdir() if p.exists() and not (p.is_file() or p.is_dir()))
    if odd:  # a FIFO would block its reader for ever, a device never end
        raise BagReadError(f"{str(path)!r}: {', '.join(odd)} is not a regular file")
    try:
        from rosbags.highlevel import AnyReader, AnyReaderError
    except ImportError as exc:
        raise BagReadError(f"reading a ROS 2 bag needs rosbags (pip install 'cufund[ros2]'): {exc}") from exc
    reader = AnyReader([path], default_typestore=rosbags_typestore())
    try:
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise BagReadError(f"{str(path)!r}: cannot open the ROS 2 bag: {exc}") from exc
    return reader


def bag_topics(path: str | os.PathLike[str]) -> dict[str, str]:
    """The topics of the bag at ``path`` that cufund reads, with the cufund message class each becomes."""
    reader = _open(Path(path))
    try:
        return {t: ROS2_TYPES[i.msgtype] for t, i in reader.topics.items() if i.msgtype in ROS2_TYPES}
    finally:
        reader.close()


def bag_custom_data(path: str | os.PathLike[str]) -> dict[str, str]:
    """The ``custom_data`` of the bag's metadata (a cufund bag: ``cufund.config``, the run's scenario), or {}."""
    import yaml

    try:
        meta = yaml.safe_load((Path(path) / "metadata.yaml").read_text())
        data = meta["rosbag2_bagfile_information"].get("custom_data") or {}
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError) as exc:
        raise BagReadError(f"{str(path)!r}: unreadable metadata.yaml: {exc}") from exc
    if not isinstance(data, dict):
        return {}
    # rosbag2's custom_data maps strings to strings: a list or mapping (whose aliases could make its text
    # exponentially long) is refused before anything is turned into text
    for k, v in data.items():
        if isinstance(v, (list, dict)):
            raise BagReadError(f"{str(path)!r}: metadata.yaml: custom_data {k!r} is not a string")
    return {str(k): str(v) for k, v in data.items()}


def _stamp(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _wxyz(q: Any) -> np.ndarray:
    return np.array([q.w, q.x, q.y, q.z], dtype=np.float64)


def _vec(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=np.float64)


def _covariance(c: Any) -> np.ndarray | None:
    """A ``float64[36]`` covariance as (6, 6), or None when it says unknown (all zero, or -1 first: REP 145) or is
    not finite."""
    c = np.asarray(c, dtype=np.float64)
    if c.shape != (36,) or not np.isfinite(c).all() or not c.any() or c[0] < 0:
        return None
    return c.reshape(6, 6)


_DATATYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def _cloud(msg: Any, where: str) -> Any:
    """A ``sensor_msgs/msg/PointCloud2`` as a cufund PointCloud (fields as the module says)."""
    from cufund.core.messages import PointCloud

    fields = {f.name: (int(f.offset), _DATATYPES.get(int(f.datatype))) for f in msg.fields}
    missing = [k for k in "xyz" if k not in fields]
    if missing:
        raise BagReadError(f"{where}: a PointCloud2 without the field(s) {missing} (it has {sorted(fields)})")
    n, step = int(msg.height) * int(msg.width), int(msg.point_step)
    if (
        not 0 < step <= 65536
        or n * step > len(msg.data)
        or any(kind is None or offset + np.dtype(kind).itemsize > step for offset, kind in fields.values())
    ):
        raise BagReadError(
            f"{where}: a PointCloud2 with bad sizes, offsets or datatypes (point_step {step}, {n} points, "
            f"fields {[(f.name, int(f.offset), int(f.datatype)) for f in msg.fields]})"
        )
    end = ">" if msg.is_bigendian else "<"
    names = list(fields)
    dtype = np.dtype(
        {
            "names": names,
            "formats": [end + str(fields[k][1]) for k in names],
            "offsets": [fields[k][0] for k in names],
            "itemsize": step,
        }
    )
    pts = np.frombuffer(np.asarray(msg.data, np.uint8).tobytes(), dtype, count=n)
    stamp_ns = _stamp(msg.header)
    xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float32)
    keep = np.isfinite(xyz).all(axis=1)
    if "timestamp" in fields:
        ts = pts["timestamp"].astype(np.float64)
        near_seconds = n and abs(float(np.median(ts)) - stamp_ns / 1e9) < abs(float(np.median(ts)) - stamp_ns)
        dt = ts - stamp_ns / 1e9 if near_seconds else (ts - stamp_ns) / 1e9
    elif "offset_time" in fields:
        dt = pts["offset_time"].astype(np.float64) / 1e9
    elif "t" in fields:
        dt = pts["t"].astype(np.float64) / 1e9
    elif "time" in fields:
        dt = pts["time"].astype(np.float64)
    else:
        dt = np.zeros(n)
    intensity_field = "intensity" if "intensity" in fields else "reflectivity" if "reflectivity" in fields else None
    intensity = pts[intensity_field].astype(np.float64) / 255.0 if intensity_field else np.zeros(n)
    line_field = "line" if "line" in fields else "ring" if "ring" in fields else None
    channel = pts[line_field].astype(np.int32) if line_field else np.zeros(n, np.int32)
    xyz = xyz[keep]
    return PointCloud(
        t=stamp_ns / 1e9,
        dt=dt[keep],
        points_L=xyz,
        ranges=np.linalg.norm(xyz.astype(np.float64), axis=1),
        intensity=intensity[keep],
        channel=channel[keep],
        frame=-1,
    )


_LIVOX_POINT = np.dtype(
    {
        "names": ["offset_time", "x", "y", "z", "reflectivity", "tag", "line"],
        "formats": ["<u4", "<f4", "<f4", "<f4", "u1", "u1", "u1"],
        "offsets": [0, 4, 8, 12, 16, 17, 18],
        "itemsize": 20,
    }
)
"""A ``CustomPoint`` in a CDR sequence: 19 bytes of fields, each element starting 4-aligned (its ``offset_time``)."""


def _livox(raw: bytes | memoryview, where: str) -> Any:
    """A Livox ``CustomMsg`` (CDR, little-endian) as a PointCloud, its points read as one numpy block (a Mid-360
    frame has some 20 000: decoding them one object at a time would be slower than the sensor)."""
    from cufund.core.messages import PointCloud

    from .ros2 import CdrReader

    try:
        r = CdrReader(raw, where)
        r.header()
        (timebase,) = r.get("Q")
        r.get("I")  # point_num
        r.get("B", 4)  # lidar_id, rsvd[3]
        (n,) = r.get("I")
        r.pos += (-r.pos) % 4
        # the last point's pad byte may be missing (nothing follows it)
        raw_points = r.blob_of(n * _LIVOX_POINT.itemsize - 1).tobytes() + b"\0" if n else b""
        pts = np.frombuffer(raw_points, _LIVOX_POINT)
    except ValueError as exc:
        raise BagReadError(f"{where}: a malformed livox CustomMsg: {exc}") from None
    xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float32)
    return PointCloud(
        t=int(timebase) / 1e9,
        dt=pts["offset_time"].astype(np.float64) / 1e9,
        points_L=xyz,
        ranges=np.linalg.norm(xyz.astype(np.float64), axis=1),
        intensity=pts["reflectivity"].astype(np.float64) / 255.0,
        channel=pts["line"].astype(np.int32),
        frame=-1,
    )


def _convert(msgtype: str, msg: Any, where: str) -> Any:
    from cufund.core import messages
    from cufund.geometry import quat_to_matrix

    if msgtype == "sensor_msgs/msg/Imu":
        return messages.Imu(
            t=_stamp(msg.header) / 1e9, f_I=_vec(msg.linear_acceleration), w_I=_vec(msg.angular_velocity)
        )
    if msgtype == "sensor_msgs/msg/PointCloud2":
        return _cloud(msg, where)
    if msgtype == "nav_msgs/msg/Odometry":
        q = _wxyz(msg.pose.pose.orientation)
        return messages.Odometry(
            t=_stamp(msg.header) / 1e9,
            p_W=_vec(msg.pose.pose.position),
            v_W=np.asarray(quat_to_matrix(q, normalize=True), float) @ _vec(msg.twist.twist.linear),
            q_WB=q,
            w_B=_vec(msg.twist.twist.angular),
            pose_cov_W=_covariance(msg.pose.covariance),
            twist_cov_B=_covariance(msg.twist.covariance),
        )
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return messages.Pose(t=_stamp(msg.header) / 1e9, p_W=_vec(msg.pose.position), q_WB=_wxyz(msg.pose.orientation))
    raise BagReadError(f"{where}: cufund does not read {msgtype} (it reads {', '.join(ROS2_TYPES)})")


def read_rosbag2(path: str | os.PathLike[str], topics: Iterable[str] | str | None = None) -> Iterator[LogRecord]:
    """The messages of the ROS 2 bag at ``path`` (only ``topics`` when given; else every topic of a type cufund
    reads) as cufund messages, in bag-timestamp order; ``log_time_ns`` and ``publish_time_ns`` are the bag's
    timestamp. :class:`BagReadError` at once for a folder that is not a bag, a topic it lacks or one of a type cufund
    does not read; while iterating, for a message that cannot be converted."""
    path = Path(path)
    reader = _open(path)
    try:
        present = {t: i.msgtype for t, i in reader.topics.items()}
        if topics is None:
            wanted = {t for t, ty in present.items() if ty in ROS2_TYPES}
        else:
            wanted = {str(topics)} if isinstance(topics, str) else {str(t) for t in topics}
            for t in sorted(wanted):
                if t not in present:
                    raise BagReadError(f"topic {t} is not in {str(path)!r} (it has {', '.join(sorted(present))})")
                if present[t] not in ROS2_TYPES:
                    raise BagReadError(
                        f"topic {t} of {str(path)!r} is a {present[t]}, which cufund does not read "
                        f"(it reads {', '.join(ROS2_TYPES)})"
                    )
        connections = [c for c in reader.connections if c.topic in wanted]
        _check_livox(path, reader.typestore, connections)
    except BaseException:
        reader.close()
        raise
    return _iterate(path, reader, connections)


_LIVOX_TYPES = ("livox_ros_driver2/msg/CustomMsg", "livox_ros_driver/msg/CustomMsg")


def _check_livox(path: Path, typestore: Any, connections: list[Any]) -> None:
    """:func:`_livox` reads the driver's own ``CustomMsg`` layout: a bag whose definition of it (or of its
    ``CustomPoint``) differs is refused rather than misread."""
    ours = None
    for c in connections:
        if c.msgtype in _LIVOX_TYPES:
            ours = ours or rosbags_typestore()
            for name in (c.msgtype, c.msgtype.replace("/CustomMsg", "/CustomPoint")):
                if typestore.fielddefs.get(name) != ours.fielddefs[name]:
                    raise BagReadError(
                        f"{str(path)!r}: topic {c.topic}: the bag's definition of {name} is not the Livox "
                        "driver's, the only layout cufund reads (LIVOX_MSGS)"
                    )


def _iterate(path: Path, reader: Any, connections: list[Any]) -> Iterator[LogRecord]:
    try:
        if not connections:
            return
        messages = reader.messages(connections=connections)
        while True:
            try:
                item = next(messages, None)
            except Exception as exc:  # the storage's errors: a damaged chunk or record, a failed decompression
                raise BagReadError(f"{str(path)!r}: cannot read the bag's messages: {exc}") from exc
            if item is None:
                return
            conn, timestamp, raw = item
            where = f"{str(path)!r}: topic {conn.topic} at {timestamp} ns"
            if conn.msgtype in _LIVOX_TYPES:  # Livox: read straight from the CDR (numpy)
                yield LogRecord(conn.topic, timestamp, timestamp, _livox(raw, where))
                continue
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as exc:  # rosbags raises assorted errors for a malformed CDR message
                raise BagReadError(f"{where}: cannot deserialize the {conn.msgtype}: {exc}") from exc
            yield LogRecord(conn.topic, timestamp, timestamp, _convert(conn.msgtype, msg, where))
    finally:
        reader.close()


def pick_topic(path: str | os.PathLike[str], cls: str, preferred: Iterable[str] = (), what: str = "") -> str:
    """The bag topic to read as cufund class ``cls`` (``Imu``, ``PointCloud``, ``Odometry`` or ``Pose``): the first
    of ``preferred`` the bag has with that class, else the bag's only topic of it; BagReadError naming the candidates
    otherwise (``what`` names the option that chooses it)."""
    topics = bag_topics(path)
    for t in preferred:
        if topics.get(t) == cls:
            return t
    kinds = {"Odometry", "Pose"} if cls in ("Odometry", "Pose") else {cls}
    found = sorted(t for t, c in topics.items() if c in kinds)
    if len(found) == 1:
        return found[0]
    name = f" ({what})" if what else ""
    raise BagReadError(
        f"{str(path)!r}: {'no' if not found else 'more than one'} {cls} topic{name}: "
        f"{', '.join(found) if found else 'it has ' + ', '.join(f'{t} ({c})' for t, c in sorted(topics.items()))}"
    )
