"""cufund messages as the bytes of their ROS 2 messages, through :mod:`cufund.logs` (the one CDR serialisation a
run log, a bag and the bridge share): the logs' layouts and codecs, filled here with what the bridge adds (the
truth's body-frame twist, a camera's ``camera_info``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.messages import CameraImage, Imu, Odometry, PointCloud, Pose, TrajectoryUpdate
from cufund.geometry import quat_to_matrix
from cufund.logs import ros2
from cufund.logs.cdr import stamp_sec_nsec_of
from cufund.logs.codecs import ImageCodec, PointCloud2Codec, path_of

__all__ = [
    "CameraInfo",
    "camera_info",
    "camera_info_of",
    "clock",
    "encoder_for",
    "image_encoder",
    "imu_encoder",
    "odometry_encoder",
    "point_cloud_encoder",
    "pose_encoder",
    "stereo_camera_infos",
    "tf",
    "unrectified_camera_info",
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
    K = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    P = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return camera_info_of(t, frame, CameraInfo(int(width), int(height), "plumb_bob", (0.0,) * 5, K, _EYE3, P))


_EYE3 = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]


@dataclass(frozen=True)
class CameraInfo:
    """The calibration fields of a ``sensor_msgs/msg/CameraInfo`` (row-major K, R, P)."""

    width: int
    height: int
    distortion_model: str
    D: tuple[float, ...]
    K: list[float]
    R: list[float]
    P: list[float]


def camera_info_of(t: float, frame: str, info: CameraInfo) -> bytes:
    """``sensor_msgs/msg/CameraInfo`` of ``info`` at ``t`` in ``frame`` (no binning, full-image ROI)."""
    w = ros2.CdrWriter().header(t, frame).put("I", info.height, info.width).string(info.distortion_model)
    w.put("I", len(info.D))
    if info.D:
        w.put("d", *info.D)
    w.put("d", *info.K).put("d", *info.R).put("d", *info.P)
    w.put("I", 0, 0).put("I", 0, 0, 0, 0).put("?", False)
    return w.bytes()


def unrectified_camera_info(intrinsics: Any) -> CameraInfo:
    """The ``camera_info`` of one camera (:class:`cufund.sensors.camera_models.CameraIntrinsics`) on its own: its
    K and D, R identity, P = [K | 0]."""
    info = intrinsics.camera_info()
    K = info["K"]
    P = [*K[0:3], 0.0, *K[3:6], 0.0, *K[6:9], 0.0]
    return CameraInfo(intrinsics.width, intrinsics.height, info["distortion_model"], tuple(info["D"]), K, _EYE3, P)


def stereo_camera_infos(left: Any, right: Any) -> tuple[CameraInfo, CameraInfo]:
    """The ``camera_info`` of a calibrated stereo pair (:class:`cufund.sensors.camera_models.CameraCalibration`
    of the left and the right camera, mounted ``T_BC`` on the body), as ROS's stereo drivers and
    ``camera_calibration`` give them: each camera's raw K and D, R its rectification rotation and P the rectified
    projection (OpenCV's ``stereoRectify``, zero disparity at infinity), the right one's ``P[3] = -fx' B`` with the
    baseline B [m] (a point in the left rectified optical frame projects with P into each rectified image)."""
    import cv2

    from cufund.geometry import homogeneous
    from cufund.sensors.camera_models import R_CO

    cams = (left, right)
    T_BO = []
    for cam in cams:
        T = homogeneous(cam.T_BC)
        T[:3, :3] = T[:3, :3] @ R_CO
        T_BO.append(T)
    T_O1O0 = np.linalg.inv(T_BO[1]) @ T_BO[0]  # left optical -> right optical
    i0, i1 = left.intrinsics, right.intrinsics
    if (i0.width, i0.height) != (i1.width, i1.height):
        raise ValueError(
            f"stereo camera_info: the cameras' image sizes differ ({i0.width}x{i0.height}, {i1.width}x{i1.height})"
        )
    if np.linalg.norm(T_O1O0[:3, 3]) < 1e-6:
        raise ValueError("stereo camera_info: the two cameras are at the same place (no baseline)")
    size = (i0.width, i0.height)
    D0, D1 = np.asarray(i0.distortion, float), np.asarray(i1.distortion, float)
    R, T = T_O1O0[:3, :3].copy(), T_O1O0[:3, 3:].copy()
    if i0.distortion_model == i1.distortion_model == "equidistant":
        R1, R2, P1, P2, _ = cv2.fisheye.stereoRectify(
            i0.K, D0, i1.K, D1, size, R, T, flags=cv2.CALIB_ZERO_DISPARITY, balance=0.0
        )
    elif i0.distortion_model == i1.distortion_model == "radtan":
        R1, R2, P1, P2, *_ = cv2.stereoRectify(i0.K, D0, i1.K, D1, size, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    else:
        raise ValueError(
            f"stereo camera_info: both cameras need the same distortion model, got {i0.distortion_model} and "
            f"{i1.distortion_model}"
        )
    out = []
    for intr, Rr, Pp in ((i0, R1, P1), (i1, R2, P2)):
        info = intr.camera_info()
        out.append(
            CameraInfo(
                intr.width,
                intr.height,
                info["distortion_model"],
                tuple(info["D"]),
                info["K"],
                [float(x) for x in np.asarray(Rr).ravel()],
                [float(x) for x in np.asarray(Pp).ravel()],
            )
        )
    return out[0], out[1]


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
