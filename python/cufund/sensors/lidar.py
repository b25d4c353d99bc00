"""A ray-traced LiDAR: scan pattern + range model, firing each ray from the pose at its own time."""

from __future__ import annotations

import dataclasses
from typing import Any, Union

import numpy as np

from cufund import _core
from cufund.core.messages import LidarTruth, PointCloud
from cufund.geometry import PoseFn, Transform, quat_mul, quat_to_matrix, sample_poses
from cufund.worlds.world import World

from .patterns import ScanPattern, ScanRays

Target = Union[World, "_core.lidar.RaycastScene"]


@dataclasses.dataclass(frozen=True)
class LidarParams:
    """Range model of a LiDAR; all randomness drawn from ``seed``."""

    range_min: float = 0.1
    """Blind zone: returns closer than this are dropped [m]."""
    range_max: float = 40.0
    """Returns farther than this are dropped [m]."""
    range_noise_std: float = 0.0
    """Standard deviation of additive Gaussian range noise [m]."""
    dropout: float = 0.0
    """Probability that a valid return is lost, in [0, 1)."""
    pose_samples: int = 32
    """Body poses sampled per frame (pose_fn calls); each ray's pose is interpolated between them."""
    seed: int = 0
    """Seed of the noise and dropout generator."""
    nthreads: int = 0
    """Ray casting threads, 0: all cores."""

    # Realism terms (issue 31), each off by default; with all of them off a frame is bit for bit what it was
    # before they existed (their random draws come after the ones above, and only when a term is on).
    range_noise_per_m: float = 0.0
    """Range noise growing with range: sigma(r) = range_noise_std + range_noise_per_m r [m/m]."""
    incidence_noise: float = 0.0
    """Range noise growing with incidence: sigma x (1 + incidence_noise (1 / cos theta - 1)), theta the angle
    between the ray and the surface normal, capped at 85 deg [-]."""
    max_range_at_10pct: float = float("inf")
    """Detection range on a 10 % reflective target at normal incidence [m]; past r_max = max_range_at_10pct
    sqrt(rho cos theta / 0.1) (rho: the object's reflectivity) the probability of a return falls smoothly to 0
    (reflectivity- and incidence-dependent dropouts). inf: off."""
    detection_softness: float = 0.1
    """Relative width of that fall: certain detection up to r_max, none from r_max (1 + detection_softness),
    a smoothstep between [-]."""
    mixed_pixel_probability: float = 0.0
    """Probability that a return at a depth edge (a neighbouring ray of its channel, in firing order, whose true
    range differs by more than ``mixed_pixel_edge_m``) lands between the two surfaces, at a uniform mix of the two
    ranges along its ray, in [0, 1]."""
    mixed_pixel_edge_m: float = 0.3
    """Depth jump between neighbouring rays of one channel that makes a depth edge [m]."""
    timestamp_jitter_s: float = 0.0
    """1 sigma of Gaussian noise on each point's reported time offset ``dt`` (clamped to [0, period); the points
    stay in firing order) [s]."""
    intensity_noise: float = 0.0
    """Relative 1 sigma noise on the reported intensity, growing as (1 + (r / r_max)^2) towards the detection
    range r_max when ``max_range_at_10pct`` is finite (a weaker return, a noisier amplitude) [-]."""
    time_offset_s: float = 0.0
    """The cloud's reported stamp minus the true firing time of its first ray (the LiDAR-IMU clock offset); the
    rays are still cast at their true times [s]."""

    def __post_init__(self) -> None:
        reals = (
            "range_min",
            "range_max",
            "range_noise_std",
            "dropout",
            "range_noise_per_m",
            "incidence_noise",
            "detection_softness",
            "mixed_pixel_probability",
            "mixed_pixel_edge_m",
            "timestamp_jitter_s",
            "intensity_noise",
            "time_offset_s",
        )
        for name in (*reals, "max_range_at_10pct"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or np.isnan(v):
                raise ValueError(f"LidarParams.{name} must be a real number, got {v!r}")
            if name in reals and not np.isfinite(v):
                raise ValueError(f"LidarParams.{name} must be a finite real number, got {v!r}")
        for name in ("pose_samples", "seed", "nthreads"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise ValueError(f"LidarParams.{name} must be an integer, got {v!r}")
        if not self.range_min >= 0:
            raise ValueError(f"range_min must be a finite number >= 0 [m], got {self.range_min}")
        if not self.range_max > self.range_min:
            raise ValueError(f"range_max must be finite and > range_min [m], got {self.range_max}")
        if not self.range_noise_std >= 0:
            raise ValueError(f"range_noise_std must be a finite number >= 0 [m], got {self.range_noise_std}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        if self.pose_samples < 2:
            raise ValueError(f"pose_samples must be >= 2, got {self.pose_samples}")
        if self.nthreads < 0:
            raise ValueError(f"nthreads must be >= 0, got {self.nthreads}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")
        for name, unit in (
            ("range_noise_per_m", "m/m"),
            ("incidence_noise", "-"),
            ("detection_softness", "-"),
            ("timestamp_jitter_s", "s"),
            ("intensity_noise", "-"),
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"LidarParams.{name} must be >= 0 [{unit}], got {getattr(self, name)}")
        if not self.max_range_at_10pct > 0:
            raise ValueError(
                f"LidarParams.max_range_at_10pct must be > 0 [m] (inf: every return detected), got "
                f"{self.max_range_at_10pct}"
            )
        if not 0.0 <= self.mixed_pixel_probability <= 1.0:
            raise ValueError(
                f"LidarParams.mixed_pixel_probability must be in [0, 1], got {self.mixed_pixel_probability}"
            )
        if not self.mixed_pixel_edge_m > 0:
            raise ValueError(f"LidarParams.mixed_pixel_edge_m must be > 0 [m], got {self.mixed_pixel_edge_m}")


def mid360_params(**overrides: Any) -> LidarParams:
    """Livox Mid-360 range model: 0.1–40 m, 2 cm noise (1σ, Livox spec at 10 m)."""
    return dataclasses.replace(LidarParams(range_min=0.1, range_max=40.0, range_noise_std=0.02), **overrides)


class Lidar:
    """A LiDAR mounted on a body with extrinsic ``T_BL`` (LiDAR frame L -> body frame B).

    ``scan(target, pose_fn, t0)`` casts one frame of ``pattern`` starting at time ``t0``: the ray fired
    at time t leaves from the LiDAR pose T_WB(t) T_BL, with T_WB(t) from ``pose_fn(t) -> (p_W, q_WB)``
    sampled ``params.pose_samples`` times over the frame and interpolated. Frames are counted so a
    non-repetitive pattern advances; ``scan(..., frame=k)`` picks one explicitly. A ``pose_fn`` with a
    method ``many(times) -> (p_W (K, 3), q_WB (K, 4))`` (unit quaternions, consecutive signs aligned) is
    sampled at all the knots in one call. The frame is cast and its returns made in one C++ call
    (:func:`cufund._core.lidar.scan_frame`).
    """

    def __init__(self, pattern: ScanPattern, params: LidarParams | None = None, T_BL: Transform | None = None) -> None:
        if not isinstance(pattern, ScanPattern):
            raise ValueError(f"pattern must provide period and frame(k), got {type(pattern).__name__}")
        self.pattern = pattern
        self.params = params or LidarParams()
        self.T_BL = T_BL or Transform()
        self.reset()

    def reset(self) -> None:
        """Back to frame 0 and the start of the seeded noise stream: the same scans again."""
        self._rng = np.random.default_rng(self.params.seed)
        self._frame = 0
        self._cached: tuple[ScanRays, np.ndarray] | None = None

    @property
    def period(self) -> float:
        return self.pattern.period

    def _frame_rays(self, k: int) -> tuple[ScanRays, np.ndarray]:
        """Frame k's rays and unit directions; patterns marked ``repetitive`` are computed once."""
        if getattr(self.pattern, "repetitive", False):
            if self._cached is None:
                rays = self.pattern.frame(0)
                self._cached = (rays, rays.directions())
            return self._cached
        rays = self.pattern.frame(k)
        return rays, rays.directions()

    def scan(self, target: Target, pose_fn: PoseFn, t0: float, frame: int | None = None) -> PointCloud:
        """One frame starting at ``t0`` [s] (the cloud's stamp), as the sensor reports it."""
        return self.scan_with_truth(target, pose_fn, t0, frame)[0]

    def scan_with_truth(
        self, target: Target, pose_fn: PoseFn, t0: float, frame: int | None = None
    ) -> tuple[PointCloud, LidarTruth]:
        """Like :meth:`scan`, with the frame's ground truth: noise-free world hit points and object ids."""
        if isinstance(target, World):
            scene, refl = target.raycast_scene, target.reflectivities()
        elif isinstance(target, _core.lidar.RaycastScene):
            scene, refl = target, None
        else:
            raise ValueError(
                f"target must be a cufund.World or cufund.sensors.RaycastScene, got {type(target).__name__}"
            )
        if not np.isfinite(t0):
            raise ValueError(f"t0 must be finite [s], got {t0}")
        k = self._frame if frame is None else int(frame)
        self._frame = k + 1
        rays_L, d_L = self._frame_rays(k)
        p = self.params
        knots = t0 + np.linspace(0.0, self.period, int(p.pose_samples))
        many = getattr(pose_fn, "many", None)
        if many is None:
            p_WL_k, q_WL_k = sample_poses(pose_fn, knots, self.T_BL)
        else:
            p_WB_k, q_WB_k = many(knots)
            p_WL_k, q_WL_k = _compose(p_WB_k, q_WB_k, self.T_BL)
        # Noise and dropout are drawn for every ray so a frame's draws do not depend on the scene; the realism
        # terms' draws come after, each only when its term is on (so frames without them are unchanged).
        n = len(rays_L.t)
        rng = self._rng
        keep = rng.random(n) if p.dropout > 0 else None
        noise_z = rng.standard_normal(n) if p.range_noise_std > 0 or p.range_noise_per_m > 0 else None
        detect = rng.random(n) if np.isfinite(p.max_range_at_10pct) else None
        mixed = rng.random((n, 2)) if p.mixed_pixel_probability > 0 else None
        dt_noise = rng.standard_normal(n) * p.timestamp_jitter_s if p.timestamp_jitter_s > 0 else None
        intensity_z = rng.standard_normal(n) if p.intensity_noise > 0 else None
        out = _core.lidar.scan_frame(
            scene,
            d_L,
            rays_L.t,
            rays_L.channel,
            float(t0),
            knots,
            p_WL_k,
            q_WL_k,
            p.range_min,
            p.range_max,
            None,
            keep,
            p.dropout,
            refl,
            p.nthreads,
            noise_z=noise_z,
            range_noise_std=p.range_noise_std,
            range_noise_per_m=p.range_noise_per_m,
            incidence_noise=p.incidence_noise,
            detect_draw=detect,
            max_range_at_10pct=p.max_range_at_10pct,
            detection_softness=p.detection_softness,
            mixed_draw=mixed,
            mixed_pixel_probability=p.mixed_pixel_probability,
            mixed_pixel_edge_m=p.mixed_pixel_edge_m,
            dt_noise=dt_noise,
            dt_max=float(np.nextafter(self.period, 0.0)),
            intensity_z=intensity_z,
            intensity_noise=p.intensity_noise,
        )
        cloud = PointCloud(
            t=float(t0) + p.time_offset_s if p.time_offset_s else float(t0),
            dt=out["dt"],
            points_L=out["points_L"],
            ranges=out["ranges"],
            intensity=out["intensity"],
            channel=out["channel"],
            frame=k,
        )
        truth = LidarTruth(t=float(t0), points_W=out["points_W"], object_ids=out["object_ids"])
        return cloud, truth


def _compose(p_WB: np.ndarray, q_WB: np.ndarray, T_BS: Transform) -> tuple[np.ndarray, np.ndarray]:
    """Sensor poses p_WS (K, 3), q_WS (K, 4) from body poses already unit and sign-aligned (``pose_fn.many``):
    the numbers :func:`~cufund.geometry.sample_poses` gives for the same body poses."""
    return p_WB + quat_to_matrix(q_WB) @ np.array(T_BS.t), quat_mul(q_WB, np.array(T_BS.q))
