"""LiDAR faults: a dropout (no frames) and a degradation (fewer, noisier returns)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError
from cufund.core.messages import PointCloud

from .base import FaultRun, SensorFault
from .common import active, check_duration, check_sensor, check_time

__all__ = ["LidarDegraded", "LidarDropout", "degrade"]


@dataclass(frozen=True)
class LidarDropout(SensorFault):
    """No LiDAR frames for ``duration`` seconds (a frame whose publication falls in [t_start, t_start + duration)
    is lost)."""

    t_start: float
    """Start of the outage (simulated time) [s]."""
    duration: float = 1.0
    """Length of the outage [s]."""
    sensor: str = ""
    """The LiDAR's name under ``sensors`` ('' : the only LiDAR)."""

    kind = "lidar_dropout"
    sensor_type = "lidar"

    def __post_init__(self) -> None:
        object.__setattr__(self, "t_start", check_time(f"faults.{self.kind}.t_start", self.t_start))
        object.__setattr__(self, "duration", check_time(f"faults.{self.kind}.duration", self.duration, positive=True))
        check_sensor(f"faults.{self.kind}.sensor", self.sensor)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        return None if active(now, self.t_start, self.duration) else msg


@dataclass(frozen=True)
class LidarDegraded(SensorFault):
    """Fewer and noisier LiDAR returns from ``t_start``: each frame published then keeps a random ``fraction`` of
    its points and each kept range gets Gaussian noise of ``noise_m``, the point moved along its ray."""

    t_start: float
    """Start of the degradation (simulated time) [s]."""
    fraction: float = 0.5
    """Share of each frame's points kept, in (0, 1]."""
    noise_m: float = 0.05
    """Gaussian range noise added to every kept point, 1 sigma [m]."""
    duration: float | None = None
    """Length of the degradation [s]; null: to the end of the run."""
    sensor: str = ""
    """The LiDAR's name under ``sensors`` ('' : the only LiDAR)."""

    kind = "lidar_degraded"
    sensor_type = "lidar"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        object.__setattr__(self, "duration", check_duration(f"{w}.duration", self.duration))
        f = self.fraction
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not 0 < f <= 1:
            raise ConfigError(f"{w}.fraction must be a share of points in (0, 1], got {f!r}")
        n = self.noise_m
        if isinstance(n, bool) or not isinstance(n, (int, float)) or not np.isfinite(n) or not 0 <= n <= 10:
            raise ConfigError(f"{w}.noise_m must be a range noise in [0, 10] m, got {n!r}")
        object.__setattr__(self, "fraction", float(f))
        object.__setattr__(self, "noise_m", float(n))
        check_sensor(f"{w}.sensor", self.sensor)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        if not active(now, self.t_start, self.duration):
            return msg
        return degrade(msg, self.fraction, self.noise_m, run.rng)


def degrade(cloud: PointCloud, fraction: float, noise_m: float, rng: np.random.Generator) -> PointCloud:
    """``cloud`` with round(fraction * N) of its points, chosen at random (kept in order), each range plus
    N(0, noise_m^2) and its point moved along its ray (ranges stay >= 1 mm)."""
    n = len(cloud)
    keep = int(round(fraction * n))
    idx = np.sort(rng.choice(n, size=keep, replace=False)) if keep < n else np.arange(n)
    r = cloud.ranges[idx]
    r_new = np.maximum(r + rng.normal(0.0, noise_m, keep), 1e-3) if noise_m > 0 else r.copy()
    scale = np.divide(r_new, r, out=np.ones_like(r), where=r > 0)
    pts = (cloud.points_L[idx] * scale[:, None]).astype(np.float32)
    return PointCloud(cloud.t, cloud.dt[idx], pts, r_new, cloud.intensity[idx], cloud.channel[idx], cloud.frame)
