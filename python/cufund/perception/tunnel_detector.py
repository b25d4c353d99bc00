"""The tunnel detector as a simulator component: LiDAR scans in the estimated world frame, accumulated, searched
for frames at a few hertz, and the frames tracked from one detection to the next (paper §3.2)."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund import _core
from cufund.core.components import BusView, Component, Subscription
from cufund.core.messages import Odometry, PointCloud, Topics, TunnelEstimate
from cufund.geometry import Transform, interpolate_poses

from .detection import (
    COLUMN_CELL,
    FrameDetection,
    TunnelDetectorParams,
    column_keys,
    detect_in_voxels,
    order_along_course,
)
from .floor_level import FloorLevel, fit_floor
from .voxel_accumulator import VoxelAccumulator

__all__ = ["TunnelDetector"]

_KNOTS = 20
"""Poses computed per scan for deskewing (a 0.1 s scan: one every 5 ms)."""
_FLOOR_POINTS = 3000
"""Floor returns (within 6 m of the pad) gathered before the floor is fitted."""
_FLOOR_SCANS = 10
"""Scans after which the floor fit is given up (the world frame's horizontal is kept)."""
_NO_COLUMNS = np.zeros(0, dtype=np.int64)
_FLOOR_RANGE = 6.0
"""Floor returns farther than this from the LiDAR are not used for the fit [m]."""


def _member(keys: np.ndarray, sorted_set: np.ndarray) -> np.ndarray:
    """``np.isin(keys, sorted_set)`` for a sorted ``sorted_set``, by binary search."""
    if len(sorted_set) == 0:
        return np.zeros(len(keys), dtype=bool)
    i = np.minimum(np.searchsorted(sorted_set, keys), len(sorted_set) - 1)
    return sorted_set[i] == keys


def _consistent(old: FrameDetection, new: FrameDetection, tolerance: float = 0.1) -> bool:
    """``new`` agrees with ``old`` within ``tolerance`` [m]: centre and opening size."""
    return bool(
        np.linalg.norm(new.centre_W - old.centre_W) <= tolerance
        and abs(new.width - old.width) <= tolerance
        and abs(new.height - old.height) <= tolerance
    )


@dataclass
class _Track:
    """One frame followed across detections (the newest measurement of it; the map only grows)."""

    detection: FrameDetection
    hits: int = 1
    misses: int = 0
    conflicts: int = 0
    """Consecutive detections that disagreed with an established track (see ``_consistent``)."""


class TunnelDetector(Component):
    """Detects the tunnel's frames in the LiDAR scans on ``cloud_topic`` and publishes a
    :class:`~cufund.core.messages.TunnelEstimate` on ``Topics.TUNNEL_ESTIMATE`` at ``params.rate_hz``.

    Its pose is the estimator's output when one is attached (ground truth only without an estimator, or
    ``state_topic`` if given): every point, measured in the LiDAR frame at its own firing time, is moved to the
    world with the body pose at that time (interpolated between the poses received, which deskews the scan) and
    the extrinsic ``T_BL``. A scan waits until poses up to its last point have arrived. Points within
    ``params.max_range`` of the LiDAR, below ``params.ceiling_z`` and inside the region of interest are
    accumulated in a bounded voxel map (:class:`VoxelAccumulator`), on which :func:`detect_in_voxels` runs at
    every step. Detections continue the nearest track within ``params.associate_radius``; a track's confidence
    grows with the points on its bars and with repeated detections, and fades slowly while it is not found
    again (a track found three times is kept; one found fewer times goes after ten misses). A track found three
    times takes a reading that moves its centre or changes its opening by more than 10 cm only when it repeats
    three times in a row (a frame does not move; a noisy map sometimes misreads one).
    Frames are published in flying order from ``origin_W`` (default: the first pose received); with
    ``expected``, at most that many (the most confident), and once all of them are confident (>= 0.9) the map
    is searched again only at ``params.settled_rate_hz`` (scans are still accumulated at every step).
    """

    name = "tunnel_detector"

    def __init__(
        self,
        params: TunnelDetectorParams | None = None,
        T_BL: Transform | None = None,
        state_topic: str | None = None,
        cloud_topic: str = Topics.POINT_CLOUD,
        expected: int | None = None,
        origin_W: object = None,
    ) -> None:
        self.params = TunnelDetectorParams() if params is None else params
        if not isinstance(self.params, TunnelDetectorParams):
            raise TypeError(f"params must be a TunnelDetectorParams, got {type(params).__name__}")
        if T_BL is not None and not isinstance(T_BL, Transform):
            raise TypeError(f"T_BL must be a cufund Transform, got {type(T_BL).__name__}")
        if expected is not None and (isinstance(expected, bool) or not isinstance(expected, int) or expected < 1):
            raise ValueError(f"expected must be None or an integer >= 1 (frames), got {expected!r}")
        if origin_W is not None:
            o = np.asarray(origin_W, dtype=float)
            if o.shape != (3,) or not np.all(np.isfinite(o)):
                raise ValueError(f"origin_W must be None or 3 finite numbers [m], got {origin_W!r}")
            origin_W = o
        self.T_BL = T_BL or Transform()
        self._R_BL, self._t_BL = self.T_BL.R, np.asarray(self.T_BL.t)
        self.state_topic, self.cloud_topic, self.expected = state_topic, cloud_topic, expected
        self.rate_hz = self.params.rate_hz
        self.active_state_topic: str = Topics.TRUTH_ODOMETRY
        self.outputs = (Topics.TUNNEL_ESTIMATE,)
        self._origin_given = origin_W
        self.reset()

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.active_state_topic, self.cloud_topic)

    def reset(self) -> None:
        p = self.params
        self.map = VoxelAccumulator(p.voxel, p.max_voxels)
        self.tracks: list[_Track] = []
        self.scans = 0
        self.detections: list[FrameDetection] = []
        """The frames found in the map at the last step (before tracking), in flying order."""
        self.updates = 0
        self.update_seconds = 0.0
        """Wall time spent in :meth:`step` so far [s] (for benchmarks; divide by ``updates``)."""
        self.update_cpu_seconds = 0.0
        """CPU time of the process (all its threads) during :meth:`step` so far [s]."""
        self.origin_W = self._origin_given
        self._t: list[float] = []
        self._p: list[np.ndarray] = []
        self._q: list[np.ndarray] = []
        self._waiting: list[PointCloud] = []
        self._last_stamp = 0.0
        self._tall = np.zeros(0, dtype=np.int64)
        self._t_detected = -math.inf
        self._tall_changed = False
        self.level: FloorLevel | None = None
        """The floor frame the map is kept in (None until the floor is fitted, see :mod:`.floor_level`)."""
        self._floor_scans: list[PointCloud] = []
        self._floor_points: list[np.ndarray] = []

    def setup(self, bus: BusView) -> None:
        self._poses_sub: Subscription = bus.subscribe(self.active_state_topic)
        self._clouds_sub: Subscription = bus.subscribe(self.cloud_topic)

    # -- poses -------------------------------------------------------------------------------------------------
    def _poses(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body positions (N, 3) and rotations (N, 3, 3) at times t, interpolated (clamped at the ends)."""
        return interpolate_poses(np.asarray(self._t), np.asarray(self._p), np.asarray(self._q), t)

    def _lidar_poses(self, cloud: PointCloud) -> tuple[float, np.ndarray, np.ndarray]:
        """The scan's span [s] and the LiDAR's positions (K, 3) and rotations (K, 3, 3) in the estimated world
        frame at ``_KNOTS + 1`` instants over it."""
        span = max(float(np.max(cloud.dt[:: self.params.point_stride], initial=0.0)), 1e-9)
        p_WB, R_WB = self._poses(cloud.t + np.linspace(0.0, span, _KNOTS + 1))
        return span, p_WB + R_WB @ self._t_BL, R_WB @ self._R_BL

    def _deskew(
        self,
        cloud: PointCloud,
        span: float,
        p_WL: np.ndarray,
        R_WL: np.ndarray,
        max_range: float,
        floor_band: float | None,
        tall_z: float,
        tall: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`cufund._core.perception.deskew_crop` of the scan: the band floor_z +- ``floor_band`` (None: from
        the floor band's top to ``ceiling_z``), columns above ``tall_z`` dropped."""
        p = self.params
        lo, hi = (
            (p.floor_z + p.floor_band, p.ceiling_z)
            if floor_band is None
            else (p.floor_z - floor_band, p.floor_z + floor_band)
        )
        return _core.perception.deskew_crop(
            cloud.points_L, cloud.dt, p.point_stride, span, p_WL, R_WL, max_range, lo, hi, tall_z, COLUMN_CELL, tall
        )

    def _level_on_floor(self, cloud: PointCloud) -> list[PointCloud]:
        """Gathers the floor's returns of the first scans and fits the floor (:func:`fit_floor`) about the pad;
        returns the scans held meanwhile once the floor is known (or given up after ``_FLOOR_SCANS`` scans), to be
        cropped in the floor's frame, else []."""
        p = self.params
        span, p_WL, R_WL = self._lidar_poses(cloud)
        # no column is tall (1e6): walls and frames are kept out by the band
        pts, _, _ = self._deskew(cloud, span, p_WL, R_WL, min(_FLOOR_RANGE, p.max_range), 0.25, 1e6, _NO_COLUMNS)
        self._floor_scans.append(cloud)
        self._floor_points.append(pts)
        if sum(len(a) for a in self._floor_points) < _FLOOR_POINTS and len(self._floor_scans) < _FLOOR_SCANS:
            return []
        pad = self.origin_W if self.origin_W is not None else np.asarray(self._p[0])
        self.level = fit_floor(np.concatenate(self._floor_points), pad, p.floor_z) or FloorLevel()
        held, self._floor_scans, self._floor_points = self._floor_scans, [], []
        return held

    def _crop(self, cloud: PointCloud) -> tuple[np.ndarray, np.ndarray]:
        """The scan's points to accumulate (N, 3) [m] and the unit directions of their rays (N, 3), in the floor's
        frame (:attr:`level`).

        Each point is moved to the world with the LiDAR pose computed at ``_KNOTS + 1`` instants over the scan:
        with both poses around its firing time, the two results blended linearly (the pose interpolated, to
        second order). Points farther than ``max_range`` from where the LiDAR was, above ``ceiling_z`` or in the
        floor band are dropped, then those in x-y columns reaching above any frame, then those outside the region
        of interest (one C++ pass, :func:`cufund._core.perception.deskew_crop`, then the column bookkeeping here)."""
        p = self.params
        span, p_WL, R_WL = self._lidar_poses(cloud)
        assert self.level is not None  # scans are cropped once the floor is known
        p_WL, R_WL = self.level.pose_to_D(p_WL, R_WL)
        # x-y columns reaching above any frame are walls or poles: never accumulated
        points_W, rays_W, tall = self._deskew(cloud, span, p_WL, R_WL, p.max_range, None, p.max_frame_top, self._tall)
        if len(tall):
            self._tall = np.union1d(self._tall, tall)
            self._tall_changed = True
        self.scans += 1
        self._last_stamp = cloud.t
        keep_poses = max(0, int(np.searchsorted(self._t, cloud.t, side="right")) - 1)
        del self._t[:keep_poses], self._p[:keep_poses], self._q[:keep_poses]
        if p.roi_min_W is None and p.roi_max_W is None:
            return points_W, rays_W  # fresh arrays from deskew_crop: no region of interest, no copy
        keep = np.ones(len(points_W), dtype=bool)
        if p.roi_min_W is not None:
            keep &= np.all(points_W >= np.asarray(p.roi_min_W), axis=1)
        if p.roi_max_W is not None:
            keep &= np.all(points_W <= np.asarray(p.roi_max_W), axis=1)
        return points_W[keep], rays_W[keep]

    # -- tracking ----------------------------------------------------------------------------------------------
    def _associate(self, detections: list[FrameDetection]) -> None:
        r = self.params.associate_radius
        pairs = sorted(
            (float(np.linalg.norm(d.centre_W - tr.detection.centre_W)), i, j)
            for i, d in enumerate(detections)
            for j, tr in enumerate(self.tracks)
        )
        used_d: set[int] = set()
        used_t: set[int] = set()
        for dist, i, j in pairs:
            if dist > r:
                break
            if i in used_d or j in used_t:
                continue
            used_d.add(i)
            used_t.add(j)
            tr = self.tracks[j]
            if tr.hits >= 3 and not _consistent(tr.detection, detections[i]) and tr.conflicts < 2:
                tr.conflicts += 1  # a frame does not change: an odd reading is believed only the third time
                continue
            tr.detection, tr.hits, tr.misses, tr.conflicts = detections[i], tr.hits + 1, 0, 0
        for j, tr in enumerate(self.tracks):
            if j not in used_t:
                tr.misses += 1
        # a frame seen a few times stays (the course does not move); a one-off goes after 10 misses
        self.tracks = [tr for tr in self.tracks if tr.hits >= 3 or tr.misses <= 10]
        self.tracks.extend(_Track(d) for i, d in enumerate(detections) if i not in used_d)

    def confidence(self, track: _Track) -> float:
        """In [0, 1): grows with the track's points and detections, fades while it is missed."""
        support = 1.0 - math.exp(-track.detection.support / self.params.full_support * 3.0)
        return support * (1.0 - 0.5**track.hits) * 0.95**track.misses

    def estimate(self) -> TunnelEstimate:
        """The current tracks as a :class:`TunnelEstimate`, in flying order."""
        tracks = self.tracks
        if self.expected is not None and len(tracks) > self.expected:  # the most confident expected frames
            best = sorted(range(len(tracks)), key=lambda k: (-self.confidence(tracks[k]), -tracks[k].hits, k))
            tracks = [tracks[k] for k in sorted(best[: self.expected])]
        ordered = order_along_course([tr.detection for tr in tracks], self._origin_D())
        by_centre = {id(tr.detection.centre_W): tr for tr in tracks}  # ordering keeps the centre arrays
        conf = [self.confidence(by_centre[id(d.centre_W)]) for d in ordered]
        ordered = [self._to_W(d) for d in ordered]
        k = len(ordered)
        return TunnelEstimate(
            t=self._last_stamp,
            centres_W=np.array([d.centre_W for d in ordered]).reshape(k, 3),
            normals_W=np.array([d.normal_W for d in ordered]).reshape(k, 3),
            opening_sizes=np.array([[d.width, d.height] for d in ordered]).reshape(k, 2),
            confidence=np.array(conf, dtype=float).reshape(k),
            scans=self.scans,
        )

    def _settled(self) -> bool:
        """Every expected frame tracked with confidence >= 0.9 (then detection slows to settled_rate_hz)."""
        if self.expected is None or len(self.tracks) < self.expected:
            return False
        conf = sorted((self.confidence(tr) for tr in self.tracks), reverse=True)
        return conf[self.expected - 1] >= 0.9

    def frames(self) -> list[FrameDetection]:
        """The tracked frames in flying order (their newest detections)."""
        return [self._to_W(d) for d in order_along_course([tr.detection for tr in self.tracks], self._origin_D())]

    def _origin_D(self) -> np.ndarray | None:
        """Where frames are ordered from, in the floor's frame."""
        if self.origin_W is None or self.level is None:
            return self.origin_W
        return self.level.pose_to_D(self.origin_W, np.eye(3))[0]

    def _to_W(self, d: FrameDetection) -> FrameDetection:
        """A detection made in the floor's frame, in the estimated world frame."""
        lv = self.level
        if lv is None:
            return d
        return dataclasses.replace(
            d,
            centre_W=lv.point_to_W(d.centre_W),
            normal_W=lv.vector_to_W(d.normal_W),
            points_W=lv.point_to_W(d.points_W),
            cluster_mean_W=lv.point_to_W(d.cluster_mean_W),
        )

    def plot(self, path: Any = None, truth: Any = None) -> Any:
        """:func:`~cufund.perception.plot.plot_detection` of the accumulated map and the tracked frames."""
        from .plot import plot_detection

        return plot_detection(self.map_points_W(), self.frames(), truth, path)

    def map_points_W(self) -> np.ndarray:
        """The accumulated map's voxel means in the estimated world frame (M, 3) [m]."""
        cloud = self.map.means()[0]
        return cloud if self.level is None else self.level.point_to_W(cloud)

    # -- the step ----------------------------------------------------------------------------------------------
    def step(self, t: float, bus: BusView) -> None:
        start, cpu = time.perf_counter(), time.process_time()
        state: Odometry
        for state in self._poses_sub.take():
            if not self._t or state.t > self._t[-1]:
                self._t.append(state.t)
                self._p.append(np.asarray(state.p_W, dtype=float))
                self._q.append(np.asarray(state.q_WB, dtype=float))
                if self.origin_W is None:
                    self.origin_W = np.asarray(state.p_W, dtype=float).copy()
        self._waiting.extend(self._clouds_sub.take())
        batch = []
        while (
            self._waiting
            and self._t
            and self._t[-1] >= self._waiting[0].t + float(np.max(self._waiting[0].dt, initial=0.0))
        ):
            scan = self._waiting.pop(0)
            if self.level is None:
                batch += [self._crop(c) for c in self._level_on_floor(scan)]
            else:
                batch.append(self._crop(scan))
        if batch:
            if self._tall_changed and len(self.map):
                self.map.drop(_member(column_keys(self.map.means()[0]), self._tall))
            self._tall_changed = False
            self.map.insert(np.concatenate([b[0] for b in batch]), np.concatenate([b[1] for b in batch]))
            if not self._settled() or t >= self._t_detected + 1.0 / self.params.settled_rate_hz - 1e-9:
                cloud, rays = self.map.means()
                found = detect_in_voxels(cloud, rays, self.params, self.expected, self._origin_D())
                self._associate(found)
                self.detections = [self._to_W(d) for d in found]
                self._t_detected = t
                bus.publish(Topics.TUNNEL_ESTIMATE, self.estimate())
        self.updates += 1
        self.update_seconds += time.perf_counter() - start
        self.update_cpu_seconds += time.process_time() - cpu
