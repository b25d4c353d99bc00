"""The frames of a scenario's sensors as its log names them (shared by single-vehicle and fleet run folders)."""

from __future__ import annotations

from typing import Any


def sensor_frames(config: Any, vehicle: str = "") -> list[tuple[str, Any, Any]]:
    """(frame, translation, q_BX) of each sensor of ``config`` (its frame as the log names it: a fleet
    ``vehicle``'s under its name). A camera rig (params with ``cameras`` and ``camera_topics``, the
    ``stereo_camera``) gives one frame per camera, from its topic, at the camera's stated mounting."""
    from cufund.logs.codecs import sensor_frame
    from cufund.simulator.fleet import namespaced

    def frame(topic: Any) -> str:
        return sensor_frame(namespaced(vehicle, str(topic)) if vehicle else str(topic))

    sensors = []
    for spec in (config.sensors or {}).values():
        if spec is None or spec.topic is None:
            continue
        params = spec.params
        if callable(getattr(params, "cameras", None)) and callable(getattr(params, "camera_topics", None)):
            rig = params.cameras(getattr(config, "base_dir", None))
            for topic, camera in zip(params.camera_topics(len(rig)), rig, strict=True):
                sensors.append((frame(topic), camera.T_BC.t, camera.T_BC.q))
            continue
        e = spec.extrinsic
        sensors.append((frame(spec.topic), None if e is None else e.t, None if e is None else e.q))
    return sensors
