"""The built-in mapper kinds of scenarios: ``esdf`` (occupancy + Euclidean signed distance field from a LiDAR)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, check_at_most, vector3
from cufund.core.registry import Kind, register

from .esdf_map import EsdfMapParams
from .esdf_mapper import EsdfMapper


@dataclass(frozen=True)
class EsdfMapperParams:
    """The map's box and resolution, the sensor model's main knobs and the LiDAR it integrates."""

    resolution: float = 0.1
    """Voxel edge [m]."""
    size: tuple[float, float, float] = (20.0, 20.0, 5.0)
    """Extent of the mapped box [m]."""
    origin_W: tuple[float, float, float] = (-10.0, -10.0, -0.5)
    """World position of the box's minimum corner [m]."""
    max_range: float = 10.0
    """Beams are cut at this range and mark only free space beyond [m]."""
    rate_hz: float = 20.0
    """How often the mapper integrates the frames that arrived [Hz]."""
    lidar: str = ""
    """Name of the LiDAR in ``sensors`` (empty: the only one)."""
    merge_beams: bool = True
    """One beam per distinct end voxel and frame (see :attr:`EsdfMapParams.merge_beams`): the same hits, the
    free space of the kept beams; ``false`` casts every point."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", vector3("mapper.size", self.size, " [m]", finite=True))
        object.__setattr__(self, "origin_W", vector3("mapper.origin_W", self.origin_W, " [m]", finite=True))
        for name in ("resolution", "max_range", "rate_hz"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ConfigError(f"mapper.{name} must be a finite number > 0, got {v!r}")
        check_at_most(self, "mapper", rate_hz=1e3, max_range=1e3)
        if not isinstance(self.merge_beams, bool):
            raise ConfigError(f"mapper.merge_beams must be true or false, got {self.merge_beams!r}")


def _esdf(p: EsdfMapperParams, ctx: BuildContext) -> list[Any]:
    name, spec = ctx.sensor_of_type("lidar", p.lidar, "mapper.lidar")
    try:
        map_params = EsdfMapParams(
            resolution=p.resolution, size=p.size, origin_W=p.origin_W, max_range=p.max_range, merge_beams=p.merge_beams
        )
    except ValueError as e:
        raise ConfigError(f"mapper: {e}") from None
    return [EsdfMapper(map_params, spec.extrinsic, rate_hz=p.rate_hz, cloud_topic=spec.topic)]


register(
    Kind(
        "mapper",
        "esdf",
        EsdfMapperParams,
        _esdf,
        None,
        "occupancy (log-odds) and exact signed distance field from every LiDAR frame, on the estimated pose",
    )
)

__all__ = ["EsdfMapperParams"]
