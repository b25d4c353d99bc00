"""Mapping (paper §2.3): occupancy from LiDAR point clouds and exact Euclidean distance fields.

Planners depend on the :class:`DistanceField` interface; :class:`EsdfMap` is cufund's implementation.
"""

from .distance_field import DistanceField
from .edt import edt
from .esdf_map import EsdfMap, EsdfMapParams, ScanStats
from .esdf_mapper import EsdfMapper

__all__ = ["DistanceField", "EsdfMap", "EsdfMapParams", "EsdfMapper", "ScanStats", "edt"]
