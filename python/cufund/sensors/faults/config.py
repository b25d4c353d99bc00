"""The ``faults:`` section of a scenario: every fault kind, parsed from a map or a list, and back."""

from __future__ import annotations

from typing import Any

from cufund.core.config import ConfigError, from_dict, to_dict

from .barometer import BaroStep
from .gps import GpsDrift, GpsDropout, GpsJump
from .imu import ImuBiasStep
from .lidar import LidarDegraded, LidarDropout
from .magnetometer import MagDisturbance
from .plant import MotorEfficiency, MotorFailure, PropImbalance

__all__ = ["FAULT_KINDS", "Fault", "fault_summary", "faults_to_data", "parse_faults"]

FAULT_KINDS: dict[str, type] = {
    c.kind: c
    for c in (
        LidarDropout,
        ImuBiasStep,
        LidarDegraded,
        GpsDropout,
        GpsJump,
        GpsDrift,
        MagDisturbance,
        BaroStep,
        MotorFailure,
        MotorEfficiency,
        PropImbalance,
    )
}
"""Fault kind name -> its params dataclass."""

Fault = (
    LidarDropout
    | ImuBiasStep
    | LidarDegraded
    | GpsDropout
    | GpsJump
    | GpsDrift
    | MagDisturbance
    | BaroStep
    | MotorFailure
    | MotorEfficiency
    | PropImbalance
)


def _one(kind: Any, params: Any, where: str) -> Any:
    if isinstance(params, tuple(FAULT_KINDS.values())):
        return params
    cls = FAULT_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise ConfigError(f"{where}: unknown fault kind {kind!r}; expected one of: {', '.join(FAULT_KINDS)}")
    return from_dict(cls, params, f"{where}")


def parse_faults(value: Any) -> tuple[Any, ...]:
    """The faults of a scenario's ``faults:`` value (null, a map ``{kind: params or [params, ...]}`` or a list
    of ``{kind: ..., ...params}``), validated (:class:`cufund.ConfigError` naming the key otherwise)."""
    if value is None:
        return ()
    out = []
    if isinstance(value, dict):
        for kind, params in value.items():
            for i, p in enumerate(params if isinstance(params, (list, tuple)) else [params]):
                out.append(_one(kind, p, f"faults.{kind}" + (f"[{i}]" if isinstance(params, (list, tuple)) else "")))
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            if isinstance(item, tuple(FAULT_KINDS.values())):
                out.append(item)
                continue
            if not isinstance(item, dict) or "kind" not in item:
                raise ConfigError(
                    f"faults[{i}] must be a mapping with a 'kind' key ({', '.join(FAULT_KINDS)}), got {item!r}"
                )
            params = dict(item)
            out.append(_one(params.pop("kind"), params, f"faults[{i}]"))
    else:
        raise ConfigError(
            "faults must be a map {kind: {t_start: ..., ...}} or a list of {kind: ..., t_start: ...}, "
            f"got {type(value).__name__}"
        )
    return tuple(out)


def faults_to_data(faults: tuple[Any, ...]) -> Any:
    """Plain data :func:`parse_faults` turns back into equal faults: a map when each kind occurs once (so dotted
    overrides reach it), else a list; None for no faults."""
    if not faults:
        return None
    kinds = [f.kind for f in faults]
    if len(set(kinds)) == len(kinds):
        return {f.kind: _plain(f) for f in faults}
    return [{"kind": f.kind, **_plain(f)} for f in faults]


def _plain(fault: Any) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in to_dict(fault).items()}


def fault_summary(faults: tuple[Any, ...]) -> list[dict[str, Any]]:
    """The faults as plain records for ``metrics.json``."""
    return [{"kind": f.kind, **_plain(f)} for f in faults]
