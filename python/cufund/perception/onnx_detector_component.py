"""The ONNX detector as a simulator component: boxes in each new camera image and, with a depth image aligned to
it, the objects' positions in the estimated world frame."""

from __future__ import annotations

from collections import deque

import numpy as np

from cufund.core.components import BusView, Component, Subscription
from cufund.core.messages import CameraImage, Detections2D, Detections3D, Topics
from cufund.core.topics import is_truth
from cufund.geometry import Transform
from cufund.sensors.camera import R_CO, CameraIntrinsics

from .onnx_detector import Detections, OnnxDetector
from .pose_history import PoseHistory
from .stereo_depth import box_disparities

__all__ = [
    "OnnxDetectorComponent",
    "box_depths",
    "boxes_to_world",
    "place_boxes",
    "stereo_box_depths",
    "stereo_boxes_to_world",
]

_POSES_KEPT = 400
"""Estimates kept to find the pose at an image's capture time (2 s at 200 Hz)."""
_PENDING_KEPT = 8
"""Frames kept waiting for an estimate at or after their capture time (older ones are dropped)."""


def boxes_to_world(
    boxes_xyxy: np.ndarray,
    depth: np.ndarray,
    image_intrinsics: CameraIntrinsics,
    depth_intrinsics: CameraIntrinsics,
    T_BC: Transform,
    p_WB: np.ndarray,
    R_WB: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each box's centre and size in the world from a depth image taken from the same camera centre.

    A box (pixel edges in the image of ``image_intrinsics``) becomes directions (x, y) = ((u - cx) / fx, (v - cy)
    / fy) of its corners and centre (distortion ignored), and so a box in the depth image of ``depth_intrinsics``;
    its depth z (along the optical axis) is the median of the valid depths in that box's middle half (width and
    height). The box is then placed at z (:func:`place_boxes`). Returns (centres_W (k, 3) [m], sizes_m (k, 2) [m],
    valid (k,)), ``valid`` False (and NaN rows) where the box has no valid depth (also where its middle half lies
    beyond the depth image)."""
    z = box_depths(boxes_xyxy, depth, image_intrinsics, depth_intrinsics)
    return place_boxes(boxes_xyxy, z, image_intrinsics, T_BC, p_WB, R_WB)


def box_depths(
    boxes_xyxy: np.ndarray, depth: np.ndarray, image_intrinsics: CameraIntrinsics, depth_intrinsics: CameraIntrinsics
) -> np.ndarray:
    """(k,) depth [m] of each box from a depth image from the same camera centre (see :func:`boxes_to_world`);
    NaN where there is none."""
    h, w = depth.shape
    Ki, Kd = image_intrinsics, depth_intrinsics
    b = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    # pixel edges -> pixel-centre coordinates (edge u is coordinate u - 0.5) -> directions
    x = (b[:, [0, 2]] - 0.5 - Ki.cx) / Ki.fx
    y = (b[:, [1, 3]] - 0.5 - Ki.cy) / Ki.fy
    ud, vd = x * Kd.fx + Kd.cx + 0.5, y * Kd.fy + Kd.cy + 0.5  # the box in the depth image, pixel edges
    z = np.full(len(b), np.nan)
    for i in range(len(b)):
        (u0, u1), (v0, v1) = ud[i], vd[i]
        du, dv = (u1 - u0) / 4, (v1 - v0) / 4
        c0, r0 = int(np.floor(u0 + du)), int(np.floor(v0 + dv))
        c1, r1 = max(int(np.ceil(u1 - du)), c0 + 1), max(int(np.ceil(v1 - dv)), r0 + 1)  # at least one pixel
        c0, c1, r0, r1 = max(c0, 0), min(c1, w), max(r0, 0), min(r1, h)
        if c1 <= c0 or r1 <= r0:
            continue  # its middle lies beyond the depth image (a narrower field of view): no depth seen for it
        patch = depth[r0:r1, c0:c1]
        z_valid = patch[np.isfinite(patch) & (patch > 0)]
        if z_valid.size:
            z[i] = float(np.median(z_valid))
    return z


def stereo_box_depths(
    boxes_xyxy: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    intrinsics: CameraIntrinsics,
    baseline_m: float,
    max_disparity: int = 96,
) -> np.ndarray:
    """(k,) depth z = fx B / d [m] of each box (pixel edges in ``left``) from its disparity d in the rectified pair
    (``left``, ``right``) of baseline B = ``baseline_m`` (:func:`~cufund.perception.stereo_depth.box_disparities`);
    NaN where no match was found."""
    d, ok = box_disparities(left, right, boxes_xyxy, max_disparity)
    return np.where(ok, intrinsics.fx * float(baseline_m) / np.where(ok, d, 1.0), np.nan)


def stereo_boxes_to_world(
    boxes_xyxy: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    intrinsics: CameraIntrinsics,
    baseline_m: float,
    T_BC: Transform,
    p_WB: np.ndarray,
    R_WB: np.ndarray,
    max_disparity: int = 96,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each box's centre and size in the world from a rectified stereo pair (the left camera mounted at ``T_BC``):
    its depth from :func:`stereo_box_depths`, then :func:`place_boxes`."""
    z = stereo_box_depths(boxes_xyxy, left, right, intrinsics, baseline_m, max_disparity)
    return place_boxes(boxes_xyxy, z, intrinsics, T_BC, p_WB, R_WB)


def place_boxes(
    boxes_xyxy: np.ndarray,
    z: np.ndarray,
    intrinsics: CameraIntrinsics,
    T_BC: Transform,
    p_WB: np.ndarray,
    R_WB: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each box (pixel edges in the image of ``intrinsics``) placed at its depth ``z`` [m] along the optical axis:
    the centre (x z, y z, z) in the optical frame of the mean direction (x, y) of its corners, moved to the world
    with the mounting ``T_BC`` and the body pose (p_WB, R_WB); the size its width and height at z. Returns
    (centres_W (k, 3) [m], sizes_m (k, 2) [m], valid (k,)), NaN rows and ``valid`` False where z is not a finite
    positive depth."""
    K = intrinsics
    b = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    z = np.asarray(z, dtype=np.float64).reshape(-1)
    x = (b[:, [0, 2]] - 0.5 - K.cx) / K.fx
    y = (b[:, [1, 3]] - 0.5 - K.cy) / K.fy
    R_WO = np.asarray(R_WB, dtype=float) @ T_BC.R @ R_CO
    p_WC = np.asarray(p_WB, dtype=float) + np.asarray(R_WB, dtype=float) @ np.asarray(T_BC.t)
    ok = np.isfinite(z) & (z > 0)
    zs = np.where(ok, z, np.nan)
    p_O = np.column_stack([x.mean(1) * zs, y.mean(1) * zs, zs])
    centres = p_WC + p_O @ R_WO.T
    sizes = np.column_stack([(x[:, 1] - x[:, 0]) * zs, (y[:, 1] - y[:, 0]) * zs])
    ok &= np.all(np.isfinite(centres), axis=1)
    centres[~ok], sizes[~ok] = np.nan, np.nan
    return centres, sizes, ok


class OnnxDetectorComponent(Component):
    """Runs ``detector`` on the newest image of ``image_topic`` at ``rate_hz`` (older images not yet processed
    are skipped) and publishes :class:`~cufund.core.messages.Detections2D` on ``Topics.DETECTIONS_2D`` with the
    frame's latency (pre-processing, inference, NMS) in ``latency_ms``.

    With ``depth_topic`` (a depth image from the same camera centre, mounted at ``T_BC``; ``image_intrinsics`` and
    ``depth_intrinsics`` the two cameras' pinholes), or with ``right_topic`` (the right image of a rectified
    stereo pair whose left image is ``image_topic``, ``baseline_m`` apart: depth from each box's disparity,
    :func:`stereo_box_depths`), it also publishes :class:`~cufund.core.messages.Detections3D` on
    ``Topics.DETECTIONS_3D``: each box's centre in the world frame from the pose on ``state_topic`` at the image's
    capture time — the estimator's output (never ground truth). A frame newer than the newest estimate (an
    estimator with latency) waits for one at or after its capture time, and is published (with its capture
    stamp) at the first step that has it. A stereo frame is placed only with the right image of the same stamp."""

    name = "onnx_detector"

    def __init__(
        self,
        detector: OnnxDetector,
        image_topic: str = Topics.RGB_IMAGE,
        depth_topic: str | None = None,
        image_intrinsics: CameraIntrinsics | None = None,
        depth_intrinsics: CameraIntrinsics | None = None,
        T_BC: Transform | None = None,
        state_topic: str = Topics.ESTIMATE,
        rate_hz: float = 10.0,
        latency_s: float = 0.0,
        right_topic: str | None = None,
        baseline_m: float | None = None,
        max_disparity: int = 96,
    ) -> None:
        if not isinstance(detector, OnnxDetector):
            raise ValueError(f"detector must be an OnnxDetector, got {type(detector).__name__}")
        if depth_topic is not None and right_topic is not None:
            raise ValueError("give depth_topic (a depth camera) or right_topic (a stereo pair), not both")
        if depth_topic is not None and (depth_intrinsics is None or image_intrinsics is None):
            raise ValueError("image_intrinsics and depth_intrinsics are needed with depth_topic (the two pinholes)")
        if right_topic is not None:
            if image_intrinsics is None:
                raise ValueError("image_intrinsics is needed with right_topic (the rectified pair's pinhole)")
            if baseline_m is None or not (np.isfinite(baseline_m) and baseline_m > 0):
                raise ValueError(f"baseline_m must be a finite number > 0 [m] with right_topic, got {baseline_m!r}")
        if isinstance(max_disparity, bool) or not isinstance(max_disparity, (int, np.integer)) or max_disparity < 2:
            raise ValueError(f"max_disparity must be an integer >= 2 [px], got {max_disparity!r}")
        if not (np.isfinite(rate_hz) and 0 < rate_hz <= 1000):
            raise ValueError(f"rate_hz must be in (0, 1000] [Hz], got {rate_hz!r}")
        if is_truth(str(state_topic)):
            raise ValueError(f"state_topic must be an estimate, not ground truth ({state_topic})")
        self.detector = detector
        self.image_topic, self.depth_topic, self.state_topic = image_topic, depth_topic, state_topic
        self.right_topic = right_topic
        self.baseline_m = None if baseline_m is None else float(baseline_m)
        self.max_disparity = int(max_disparity)
        self.image_intrinsics, self.depth_intrinsics = image_intrinsics, depth_intrinsics
        self.T_BC = T_BC or Transform()
        self.rate_hz, self.latency_s = float(rate_hz), float(latency_s)
        self.inputs = (image_topic,)
        second = depth_topic or right_topic
        self.optional_inputs = (second, state_topic) if second is not None else ()
        self.outputs = (Topics.DETECTIONS_2D, Topics.DETECTIONS_3D) if second else (Topics.DETECTIONS_2D,)
        self.frames = 0
        self.latencies_ms: list[float] = []
        """Latency of every frame processed [ms] (what each Detections2D carries)."""

    def reset(self) -> None:
        self.frames = 0
        self.latencies_ms = []
        self._poses = PoseHistory(maxlen=_POSES_KEPT)
        self._depth: CameraImage | None = None
        self._rights: deque[CameraImage] = deque(maxlen=4)
        self._pending: deque[tuple[float, Detections, np.ndarray]] = deque(maxlen=_PENDING_KEPT)
        """(capture time, detections, each box's depth [m]) of frames not yet placed in the world."""

    def setup(self, bus: BusView) -> None:
        self._images: Subscription = bus.subscribe(self.image_topic)
        second = self.depth_topic or self.right_topic
        self._seconds: Subscription | None = bus.subscribe(second) if second else None
        self._states: Subscription | None = bus.subscribe(self.state_topic) if second else None

    def _depths(self, msg: CameraImage, det: Detections) -> np.ndarray | None:
        """Each box's depth [m] in the frame ``msg``, or None when there is nothing to take it from."""
        if self.right_topic is not None:
            right = next((r for r in reversed(self._rights) if abs(r.t - msg.t) < 1e-9), None)
            if right is None:  # its right image has not come (or was dropped): no depth for this frame
                return None
            assert self.image_intrinsics is not None and self.baseline_m is not None
            return stereo_box_depths(
                det.boxes_xyxy, msg.image, right.image, self.image_intrinsics, self.baseline_m, self.max_disparity
            )
        if self._depth is None:
            return None
        assert self.depth_intrinsics is not None and self.image_intrinsics is not None
        return box_depths(det.boxes_xyxy, self._depth.image, self.image_intrinsics, self.depth_intrinsics)

    def step(self, t: float, bus: BusView) -> None:
        if self._states is not None:
            self._poses.extend(self._states.take())
        images: list[CameraImage] = self._images.take()
        seconds: list[CameraImage] = self._seconds.take() if self._seconds is not None else []
        if seconds and self.right_topic is not None:
            self._rights.extend(seconds)
        elif seconds:
            self._depth = seconds[-1]
        if images:
            msg = images[-1]
            det = self.detector.detect(msg.image)
            self.frames += 1
            self.latencies_ms.append(det.latency_ms)
            bus.publish(
                Topics.DETECTIONS_2D,
                Detections2D(msg.t, det.boxes_xyxy, det.scores, det.class_ids, self.detector.names, det.latency_ms),
            )
            z = self._depths(msg, det) if (self.depth_topic or self.right_topic) else None
            if z is not None:
                self._pending.append((msg.t, det, z))
        self._place_pending(bus)

    def _place_pending(self, bus: BusView) -> None:
        """Publishes the Detections3D of the waiting frames an estimate now covers, oldest first."""
        t_last = self._poses.t_last
        while self._pending and t_last is not None and self._pending[0][0] <= t_last:
            t, det, z = self._pending.popleft()
            pose = self._poses.at(t)
            if pose is None:  # older than every estimate kept
                continue
            assert self.image_intrinsics is not None
            centres, sizes, ok = place_boxes(det.boxes_xyxy, z, self.image_intrinsics, self.T_BC, *pose)
            bus.publish(
                Topics.DETECTIONS_3D,
                Detections3D(t, centres[ok], sizes[ok], det.scores[ok], det.class_ids[ok], self.detector.names),
            )
