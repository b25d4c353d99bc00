"""cufund messages as the bytes of their ROS 2 messages, through :mod:`cufund.logs` (the one CDR serialisation a
run log, a bag and the bridge share): the logs' layouts and codecs, filled here with what the bridge adds (the
truth's body-frame twist, a camera's ``camera_info``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from cufund.core.messages import CameraImage, Imu, Odometry, PointCloud, Pose, TrajectoryUpdate
from cufund.geometry import quat_to_matrix
from cufund.logs import ros2
from cufund.logs.cdr import stamp_sec_nsec_of
from cufund.logs.codecs import ImageCodec, PointCloud2Codec, path_of

__all__ = [
    "camera_info",
    "clock",
    "encoder_for",
    "image_encoder",
    "imu_encoder",
    "odometry_encoder",
    "point_cloud_encoder",
    "pose_encoder",
    "tf",
    "xyzw",
]


def xyzw(q_wxyz: Any) -> list[float]:
    """cufund's [w, x, y, z] as ROS's x, y, z, w."""
    w, x, y, z = (float(v) for v in q_wxyz)
    return [x, y, z, w]


def _stamp(row: np.ndarray, t: float, sec: str = "header.stamp.sec", nsec: str = "header.stamp.nanosec") -> None:
    row[sec], row[nsec] = stamp_sec_nsec_of(t)


_CLOCK = ros2.clock_layout()


def clock(t: float) -> bytes:
    """``rosgraph_msgs/msg/Clock`` at ``t`` [s]."""
    row = _CLOCK.empty(1)
    _stamp(row, t, "clock.sec", "clock.nanosec")
    return row.tobytes()


def imu_encoder(frame: str) -> Callable[[Any], bytes]:
    """``sensor_msgs/msg/Imu`` of a cufund :class:`~cufund.core.messages.Imu` in ``frame`` (no orientation)."""
    layout = ros2.imu_layout(frame)

    def encode(m: Any) -> bytes:
        row = layout.empty(1)
        _stamp(row, m.t)
        row["angular_velocity"] = m.w_I
        row["linear_acceleration"] = m.f_I
        return row.tobytes()

    return encode


def odometry_encoder(parent: str, child: str) -> Callable[[Any], bytes]:
    """``nav_msgs/msg/Odometry`` of a cufund odometry: pose in ``parent``, twist in ``child`` (the body: REP 105),
    covariances zero (unknown)."""
    layout = ros2.odometry_layout(parent, child)

    def encode(m: Any) -> bytes:
        row = layout.empty(1)
        _stamp(row, m.t)
        row["pose.position"] = m.p_W
        row["pose.orientation"] = xyzw(m.q_WB)
        row["twist.linear"] = quat_to_matrix(m.q_WB, normalize=True).T @ np.asarray(m.v_W, float)
        row["twist.angular"] = m.w_B
        return row.tobytes()

    return encode


def tf(t: float, transforms: list[tuple[str, str, Any, Any]]) -> bytes:
    """``tf2_msgs/msg/TFMessage`` of (parent, child, translation, q [w, x, y, z]) at ``t``."""
    return ros2.tf_message(t, transforms)


def point_cloud_encoder(frame: str) -> Callable[[Any], bytes]:
    """``sensor_msgs/msg/PointCloud2`` in livox_ros_driver2's layout (per-point ``timestamp``)."""
    codec = PointCloud2Codec(PointCloud, frame)
    return lambda m: codec.encode([m], frame)[0]


def image_encoder(frame: str) -> Callable[[Any], bytes]:
    """``sensor_msgs/msg/Image`` (depth ``32FC1``, colour ``rgb8``)."""
    codec = ImageCodec(CameraImage, frame)
    return lambda m: codec.encode([m], frame)[0]


def camera_info(t: float, frame: str, width: int, height: int, fx: float, fy: float, cx: float, cy: float) -> bytes:
    """``sensor_msgs/msg/CameraInfo`` of an ideal pinhole (``plumb_bob``, no distortion)."""
    w = ros2.CdrWriter().header(t, frame).put("I", int(height), int(width)).string("plumb_bob")
    w.put("I", 5).put("d", 0.0, 0.0, 0.0, 0.0, 0.0)
    w.put("d", fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0)
    w.put("d", 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    w.put("d", fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0)
    w.put("I", 0, 0).put("I", 0, 0, 0, 0).put("?", False)
    return w.bytes()


def pose_encoder(frame: str) -> Callable[[Any], bytes]:
    """``geometry_msgs/msg/PoseStamped`` of a cufund :class:`~cufund.core.messages.Pose` (motion capture) in
    ``frame``."""
    layout = ros2.pose_stamped_layout(frame)

    def encode(m: Any) -> bytes:
        row = layout.empty(1)
        _stamp(row, m.t)
        row["pose.position"] = m.p_W
        row["pose.orientation"] = xyzw(m.q_WB)
        return row.tobytes()

    return encode


def encoder_for(cls: type, frame: str) -> tuple[str, Callable[[Any], bytes]] | None:
    """(ROS 2 type, encoder) of a cufund message class, or None when there is no standard ROS 2 message for it:
    an IMU sample, a LiDAR frame, an image, odometry (in ``world``), a motion-capture pose, a planner's trajectory
    (``nav_msgs/msg/Path`` of its samples, as a log keeps it)."""
    if cls is Imu:
        return "sensor_msgs/msg/Imu", imu_encoder(frame)
    if cls is PointCloud:
        return "sensor_msgs/msg/PointCloud2", point_cloud_encoder(frame)
    if cls is CameraImage:
        return "sensor_msgs/msg/Image", image_encoder(frame)
    if cls is Odometry:
        return "nav_msgs/msg/Odometry", odometry_encoder("world", "base_link")
    if cls is Pose:
        return "geometry_msgs/msg/PoseStamped", pose_encoder("world")
    if cls is TrajectoryUpdate:
        return "nav_msgs/msg/Path", lambda m: path_of(m.trajectory, m.t)
    return None
