"""Public ESDF module: ``cufund.esdf.edt`` and the incremental occupancy + distance map.

The implementation lives in :mod:`cufund.mapping`; this module is the name the paper's users know.
"""

from .mapping import DistanceField, EsdfMap, EsdfMapParams, EsdfMapper, ScanStats, edt

__all__ = ["DistanceField", "EsdfMap", "EsdfMapParams", "EsdfMapper", "ScanStats", "edt"]
