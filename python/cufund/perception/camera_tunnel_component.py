"""The camera-only tunnel detector as a simulator component (issue 26, item 4a): the tunnel course's frames from a
forward stereo rig and a 2-D detector, published as the LiDAR detector's :class:`TunnelEstimate`, so the tunnel
mission, planner and controllers are unchanged."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from cufund.core.components import BusView, Component, Subscription
from cufund.core.messages import CameraImage, Detections2D, Odometry, Topics, TunnelEstimate
from cufund.core.topics import is_truth
from cufund.geometry import Transform
from cufund.sensors.camera import CameraIntrinsics

from .camera_tunnel import CameraTunnelParams, FrameMeasurement, measure_frame
from .detection import FrameDetection, order_along_course
from .pose_history import pose_at

__all__ = ["CameraTunnelDetector"]

_POSES_KEPT = 400
"""Estimates kept to find the pose at an image's capture time (2 s at 200 Hz)."""
_IMAGES_KEPT = 6
"""Left and right images kept, waiting for their detections."""
_MIN_HITS = 2
"""Measurements a tracked frame needs before it is published (a one-off mismatch is not a frame)."""
_SAME_WIDTH_M = 0.25
"""A measurement within ``associate_m`` of a tracked frame whose opening's width differs from the track's by more
than this is dropped, neither joining the track nor starting one: its bars are two frames' (the rules' widths differ
by 0.5 m). Flown on seed 3, two frames' bars measured as a 1 m wide frame 18-26 cm beside a 0.5 m one joined its
track and moved it 11.5 cm across its opening. Widths only: a height is less sure (a frame measured 1.49 m tall
instead of 1 m, first, would have kept every later right measurement out) [m]."""
_PENDING_KEPT = 8
"""Detections kept waiting for an estimate at or after their capture time."""


@dataclass
class _Track:
    """One frame followed across images: the mean of its measurements weighted by 1 / depth^4 (the stereo depth's
    variance grows as depth^4; a frame does not move)."""

    weight: float
    centre_W: np.ndarray
    normal_W: np.ndarray
    size: np.ndarray
    hits: int = 1
    points_W: np.ndarray | None = None

    def add(self, m: FrameMeasurement) -> None:
        w = 1.0 / m.depth**4
        n = m.normal_W if float(m.normal_W @ self.normal_W) >= 0 else -m.normal_W
        total = self.weight + w
        self.centre_W = (self.weight * self.centre_W + w * m.centre_W) / total
        normal = self.weight * self.normal_W + w * n
        self.normal_W = normal / max(float(np.linalg.norm(normal)), 1e-12)
        self.size = (self.weight * self.size + w * np.array([m.width, m.height])) / total
        self.weight, self.hits = total, self.hits + 1
        self.points_W = m.points_W if self.points_W is None else np.concatenate([self.points_W, m.points_W])[-400:]


class CameraTunnelDetector(Component):
    """Measures the boxes of class ``class_name`` (one name or a tuple: a model may give a frame another class's
    label; every box must still be refined to a frame) in each :class:`Detections2D` on ``detections_topic`` (found in
    the left images of ``left_topic``) with the right image of the same stamp on ``right_topic``
    (:func:`~.camera_tunnel.measure_frame`: the box refined to the frame's edges, then measured), in the world frame of the estimate on ``state_topic`` interpolated to
    the images' stamp (never ground truth; a frame newer than the newest estimate waits for it). A measurement
    joins the track whose centre is nearest within ``associate_m`` horizontally, else starts one; a track is the
    weighted mean of its measurements (1 / depth^4). Each processed frame publishes a :class:`TunnelEstimate` on
    ``Topics.TUNNEL_ESTIMATE``: the tracks measured at least twice, in flying order from ``origin_W`` (the first
    estimate's position by default), with ``expected`` at most that many (those seen most often), confidence
    1 - 0.5^hits."""

    name = "camera_tunnel_detector"

    def __init__(
        self,
        intrinsics: CameraIntrinsics,
        baseline_m: float,
        T_BC: Transform,
        left_topic: str,
        right_topic: str,
        params: CameraTunnelParams | None = None,
        detections_topic: str = Topics.DETECTIONS_2D,
        state_topic: str = Topics.ESTIMATE,
        class_name: str | tuple[str, ...] = "tunnel_frame",
        min_score: float = 0.5,
        associate_m: float = 0.35,
        expected: int | None = None,
        origin_W: object = None,
    ) -> None:
        if not isinstance(intrinsics, CameraIntrinsics):
            raise ValueError(f"intrinsics must be a CameraIntrinsics, got {type(intrinsics).__name__}")
        if not isinstance(T_BC, Transform):
            raise ValueError(f"T_BC must be a cufund Transform, got {type(T_BC).__name__}")
        if isinstance(baseline_m, bool) or not (np.isfinite(baseline_m) and baseline_m > 0):
            raise ValueError(f"baseline_m must be a finite number > 0 [m], got {baseline_m!r}")
        if is_truth(str(state_topic)):
            raise ValueError(f"state_topic must be an estimate, not ground truth ({state_topic})")
        if expected is not None and (isinstance(expected, bool) or not isinstance(expected, int) or expected < 1):
            raise ValueError(f"expected must be None or an integer >= 1 (frames), got {expected!r}")
        names = (class_name,) if isinstance(class_name, str) else tuple(class_name)
        if not names or not all(isinstance(n, str) and n for n in names):
            raise ValueError(f"class_name must be a class name or a tuple of them, got {class_name!r}")
        if not 0.0 <= float(min_score) <= 1.0:
            raise ValueError(f"min_score must be in [0, 1], got {min_score!r}")
        if not (np.isfinite(associate_m) and associate_m > 0):
            raise ValueError(f"associate_m must be a finite number > 0 [m], got {associate_m!r}")
        if origin_W is not None:
            o = np.asarray(origin_W, dtype=float)
            if o.shape != (3,) or not np.all(np.isfinite(o)):
                raise ValueError(f"origin_W must be None or 3 finite numbers [m], got {origin_W!r}")
            origin_W = o
        self.K, self.baseline_m, self.T_BC = intrinsics, float(baseline_m), T_BC
        self.params = CameraTunnelParams() if params is None else params
        self.left_topic, self.right_topic, self.detections_topic = left_topic, right_topic, detections_topic
        self.state_topic, self.class_names = state_topic, names
        self.min_score, self.associate_m, self.expected = float(min_score), float(associate_m), expected
        self.inputs = (detections_topic, left_topic, right_topic)
        self.optional_inputs = (state_topic,)
        self.outputs = (Topics.TUNNEL_ESTIMATE,)
        self._origin_given = origin_W
        self.reset()

    def reset(self) -> None:
        self.tracks: list[_Track] = []
        self.frames_measured = 0
        """Boxes measured into frames so far."""
        self.mismatched = 0
        """Measurements dropped: another opening width near a tracked frame (:data:`_SAME_WIDTH_M`)."""
        self.images_processed = 0
        self.update_seconds = 0.0
        """Wall time spent measuring frames so far [s]."""
        self.origin_W = self._origin_given
        self._poses: deque[Odometry] = deque(maxlen=_POSES_KEPT)
        self._lefts: deque[CameraImage] = deque(maxlen=_IMAGES_KEPT)
        self._rights: deque[CameraImage] = deque(maxlen=_IMAGES_KEPT)
        self._pending: deque[Detections2D] = deque(maxlen=_PENDING_KEPT)
        self._last_stamp = 0.0

    def setup(self, bus: BusView) -> None:
        self._det_sub: Subscription = bus.subscribe(self.detections_topic)
        self._left_sub: Subscription = bus.subscribe(self.left_topic)
        self._right_sub: Subscription = bus.subscribe(self.right_topic)
        self._state_sub: Subscription = bus.subscribe(self.state_topic)

    def _pose_at(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        return pose_at(self._poses, t)

    def measure(
        self, det: Detections2D, left: np.ndarray, right: np.ndarray, p_WB: np.ndarray, R_WB: np.ndarray
    ) -> list[FrameMeasurement]:
        """The frames in one pair's detections (boxes of a class in ``class_name`` scoring at least ``min_score``)."""
        names = tuple(det.class_names)
        out = []
        for box, score, cid in zip(det.boxes_xyxy, det.scores, det.class_ids, strict=True):
            if (
                not 0 <= int(cid) < len(names)
                or names[int(cid)] not in self.class_names
                or float(score) < self.min_score
            ):
                continue
            m = measure_frame(box, left, right, self.K, self.baseline_m, self.T_BC, p_WB, R_WB, self.params)
            if m is not None:
                out.append(m)
        return out

    def _associate(self, found: list[FrameMeasurement]) -> None:
        for m in found:
            # horizontally: frames stand upright on the floor (no frame's centre lies above another's), and a box
            # whose top or bottom edge is off moves the measured centre up or down, not to another frame
            near = [(float(np.linalg.norm((tr.centre_W - m.centre_W)[:2])), k) for k, tr in enumerate(self.tracks)]
            dist, k = min(near, default=(np.inf, -1))
            if dist <= self.associate_m:
                if abs(m.width - float(self.tracks[k].size[0])) > _SAME_WIDTH_M:
                    self.mismatched += 1  # another width this near a tracked frame: two frames' bars, dropped
                    continue
                self.tracks[k].add(m)
            else:
                self.tracks.append(
                    _Track(
                        1.0 / m.depth**4,
                        m.centre_W.copy(),
                        m.normal_W.copy(),
                        np.array([m.width, m.height]),
                        points_W=m.points_W,
                    )
                )
            self.frames_measured += 1

    def frames(self) -> list[FrameDetection]:
        """The tracked frames measured at least twice, in flying order (``expected`` at most: those seen most
        often)."""
        tracks = [tr for tr in self.tracks if tr.hits >= _MIN_HITS]
        if self.expected is not None and len(tracks) > self.expected:
            best = sorted(range(len(tracks)), key=lambda k: (-tracks[k].hits, k))[: self.expected]
            tracks = [tracks[k] for k in sorted(best)]
        dets = [
            FrameDetection(
                tr.centre_W.copy(),
                tr.normal_W.copy(),
                float(tr.size[0]),
                float(tr.size[1]),
                tr.hits,
                np.zeros((0, 3)) if tr.points_W is None else tr.points_W,
                tr.centre_W.copy(),
            )
            for tr in tracks
        ]
        return order_along_course(dets, self.origin_W)

    def map_points_W(self) -> np.ndarray:
        """The frames' outer points measured (for the run's plots) [m]."""
        pts = [tr.points_W for tr in self.tracks if tr.points_W is not None]
        return np.concatenate(pts) if pts else np.zeros((0, 3))

    def estimate(self) -> TunnelEstimate:
        frames = self.frames()
        k = len(frames)
        return TunnelEstimate(
            t=self._last_stamp,
            centres_W=np.array([f.centre_W for f in frames]).reshape(k, 3),
            normals_W=np.array([f.normal_W for f in frames]).reshape(k, 3),
            opening_sizes=np.array([[f.width, f.height] for f in frames]).reshape(k, 2),
            confidence=np.array([1.0 - 0.5**f.support for f in frames], dtype=float).reshape(k),
            scans=self.images_processed,
        )

    def step(self, t: float, bus: BusView) -> None:
        for s in self._state_sub.take():
            if not self._poses or s.t > self._poses[-1].t:
                self._poses.append(s)
                if self.origin_W is None:
                    self.origin_W = np.asarray(s.p_W, dtype=float).copy()
        self._lefts.extend(self._left_sub.take())
        self._rights.extend(self._right_sub.take())
        self._pending.extend(self._det_sub.take())
        published = False
        while self._pending and self._poses and self._pending[0].t <= self._poses[-1].t:
            det = self._pending.popleft()
            left = next((m for m in reversed(self._lefts) if abs(m.t - det.t) < 1e-9), None)
            right = next((m for m in reversed(self._rights) if abs(m.t - det.t) < 1e-9), None)
            pose = self._pose_at(det.t)
            if left is None or right is None or pose is None:  # its pair or pose is gone: skipped
                continue
            start = time.perf_counter()
            self._associate(self.measure(det, left.image, right.image, *pose))
            self.update_seconds += time.perf_counter() - start
            self.images_processed += 1
            self._last_stamp = det.t
            published = True
        if published:
            bus.publish(Topics.TUNNEL_ESTIMATE, self.estimate())
