"""The frames of a scenario's sensors as its log names them (shared by single-vehicle and fleet run folders)."""

from __future__ import annotations

from typing import Any


def sensor_frames(config: Any, vehicle: str = "") -> list[tuple[str, Any, Any]]:
    """(frame, translation, q_BX) of each sensor of ``config`` (its frame as the log names it: a fleet
    ``vehicle``'s under its name)."""
    from cufund.logs.codecs import sensor_frame
    from cufund.simulator.fleet import namespaced

    sensors = []
    for spec in (config.sensors or {}).values():
        if spec is not None and spec.topic is not None:
            e = spec.extrinsic
            topic = namespaced(vehicle, str(spec.topic)) if vehicle else str(spec.topic)
            sensors.append((sensor_frame(topic), None if e is None else e.t, None if e is None else e.q))
    return sensors
