"""The ONNX detector as a simulator component: boxes in each new camera image and, with a depth image aligned to
it, the objects' positions in the estimated world frame."""

from __future__ import annotations

from collections import deque

import numpy as np

from cufund.core.components import BusView, Component, Subscription
from cufund.core.messages import CameraImage, Detections2D, Detections3D, Odometry, Topics
from cufund.core.topics import is_truth
from cufund.geometry import Transform, interpolate_poses
from cufund.sensors.camera import R_CO, CameraIntrinsics

from .onnx_detector import Detections, OnnxDetector

__all__ = ["OnnxDetectorComponent", "boxes_to_world"]

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
    height). The centre is (x z, y z, z) in the optical frame, moved to the world with the mounting ``T_BC`` and
    the body pose (p_WB, R_WB); the size is the box's width and height at z. Returns (centres_W (k, 3) [m],
    sizes_m (k, 2) [m], valid (k,)), ``valid`` False (and NaN rows) where the box has no valid depth (also where
    its middle half lies beyond the depth image)."""
    h, w = depth.shape
    Ki, Kd = image_intrinsics, depth_intrinsics
    b = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    # pixel edges -> pixel-centre coordinates (edge u is coordinate u - 0.5) -> directions
    x = (b[:, [0, 2]] - 0.5 - Ki.cx) / Ki.fx
    y = (b[:, [1, 3]] - 0.5 - Ki.cy) / Ki.fy
    ud, vd = x * Kd.fx + Kd.cx + 0.5, y * Kd.fy + Kd.cy + 0.5  # the box in the depth image, pixel edges
    R_WO = np.asarray(R_WB, dtype=float) @ T_BC.R @ R_CO
    p_WC = np.asarray(p_WB, dtype=float) + np.asarray(R_WB, dtype=float) @ np.asarray(T_BC.t)
    centres = np.full((len(b), 3), np.nan)
    sizes = np.full((len(b), 2), np.nan)
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
        if z_valid.size == 0:
            continue
        z = float(np.median(z_valid))
        p_O = np.array([x[i].mean() * z, y[i].mean() * z, z])
        centres[i] = p_WC + R_WO @ p_O
        sizes[i] = ((x[i, 1] - x[i, 0]) * z, (y[i, 1] - y[i, 0]) * z)
    return centres, sizes, np.all(np.isfinite(centres), axis=1)


class OnnxDetectorComponent(Component):
    """Runs ``detector`` on the newest image of ``image_topic`` at ``rate_hz`` (older images not yet processed
    are skipped) and publishes :class:`~cufund.core.messages.Detections2D` on ``Topics.DETECTIONS_2D`` with the
    frame's latency (pre-processing, inference, NMS) in ``latency_ms``.

    With ``depth_topic`` (a depth image from the same camera centre, mounted at ``T_BC``; ``image_intrinsics`` and
    ``depth_intrinsics`` the two cameras' pinholes) it also publishes :class:`~cufund.core.messages.Detections3D` on ``Topics.DETECTIONS_3D``: each box's
    centre in the world frame from the pose on ``state_topic`` at the image's capture time — the estimator's
    output (never ground truth). A frame newer than the newest estimate (an estimator with latency) waits for one
    at or after its capture time, and is published (with its capture stamp) at the first step that has it."""

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
    ) -> None:
        if not isinstance(detector, OnnxDetector):
            raise ValueError(f"detector must be an OnnxDetector, got {type(detector).__name__}")
        if depth_topic is not None and (depth_intrinsics is None or image_intrinsics is None):
            raise ValueError("image_intrinsics and depth_intrinsics are needed with depth_topic (the two pinholes)")
        if not (np.isfinite(rate_hz) and 0 < rate_hz <= 1000):
            raise ValueError(f"rate_hz must be in (0, 1000] [Hz], got {rate_hz!r}")
        if is_truth(str(state_topic)):
            raise ValueError(f"state_topic must be an estimate, not ground truth ({state_topic})")
        self.detector = detector
        self.image_topic, self.depth_topic, self.state_topic = image_topic, depth_topic, state_topic
        self.image_intrinsics, self.depth_intrinsics = image_intrinsics, depth_intrinsics
        self.T_BC = T_BC or Transform()
        self.rate_hz, self.latency_s = float(rate_hz), float(latency_s)
        self.inputs = (image_topic,)
        self.optional_inputs = (depth_topic, state_topic) if depth_topic is not None else ()
        self.outputs = (Topics.DETECTIONS_2D, Topics.DETECTIONS_3D) if depth_topic else (Topics.DETECTIONS_2D,)
        self.frames = 0
        self.latencies_ms: list[float] = []
        """Latency of every frame processed [ms] (what each Detections2D carries)."""

    def reset(self) -> None:
        self.frames = 0
        self.latencies_ms = []
        self._poses: deque[Odometry] = deque(maxlen=_POSES_KEPT)
        self._depth: CameraImage | None = None
        self._pending: deque[tuple[float, Detections, np.ndarray]] = deque(maxlen=_PENDING_KEPT)
        """(capture time, detections, depth image) of frames not yet placed in the world."""

    def setup(self, bus: BusView) -> None:
        self._images: Subscription = bus.subscribe(self.image_topic)
        self._depths: Subscription | None = bus.subscribe(self.depth_topic) if self.depth_topic else None
        self._states: Subscription | None = bus.subscribe(self.state_topic) if self.depth_topic else None

    def _pose_at(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        if not self._poses or not self._poses[0].t <= t <= self._poses[-1].t:
            return None
        ts = np.array([s.t for s in self._poses])
        i = int(np.clip(np.searchsorted(ts, t), 1, len(ts) - 1)) if len(ts) > 1 else 0
        pair = list(self._poses)[max(i - 1, 0) : i + 1]  # the estimates either side of t
        p, R = interpolate_poses(
            np.array([s.t for s in pair]), np.array([s.p_W for s in pair]), np.array([s.q_WB for s in pair]), [t]
        )
        return p[0], R[0]

    def step(self, t: float, bus: BusView) -> None:
        if self._states is not None:
            self._poses.extend(self._states.take())
        images: list[CameraImage] = self._images.take()
        depths: list[CameraImage] = self._depths.take() if self._depths is not None else []
        if depths:
            self._depth = depths[-1]
        if images:
            msg = images[-1]
            det = self.detector.detect(msg.image)
            self.frames += 1
            self.latencies_ms.append(det.latency_ms)
            bus.publish(
                Topics.DETECTIONS_2D,
                Detections2D(msg.t, det.boxes_xyxy, det.scores, det.class_ids, self.detector.names, det.latency_ms),
            )
            if self._depth is not None:
                self._pending.append((msg.t, det, self._depth.image))
        self._place_pending(bus)

    def _place_pending(self, bus: BusView) -> None:
        """Publishes the Detections3D of the waiting frames an estimate now covers, oldest first."""
        while self._pending and self._poses and self._pending[0][0] <= self._poses[-1].t:
            t, det, depth = self._pending.popleft()
            pose = self._pose_at(t)
            if pose is None:  # older than every estimate kept
                continue
            assert self.depth_intrinsics is not None and self.image_intrinsics is not None
            centres, sizes, ok = boxes_to_world(
                det.boxes_xyxy, depth, self.image_intrinsics, self.depth_intrinsics, self.T_BC, *pose
            )
            bus.publish(
                Topics.DETECTIONS_3D,
                Detections3D(t, centres[ok], sizes[ok], det.scores[ok], det.class_ids[ok], self.detector.names),
            )
