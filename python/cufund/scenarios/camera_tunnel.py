"""``perception: camera`` (``--set perception=camera``): the vehicle flies with a forward stereo rig and no LiDAR
(issue 26, item 4a). Applied while a scenario is validated, so every consumer of the scenario (the build, the
log's sensor frames, the run folder) sees the same sensors."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from cufund.core.config import ConfigError

__all__ = ["CAMERA_RIG", "camera_only"]

CAMERA_RIG = {"kind": "stereo_camera", "color": "rgb", "hw_sync": True}
"""The rig added as ``sensors.stereo`` when the scenario has none: the stereo_camera kind's default pair (640 x
480, 11 cm baseline, looking along body x), in colour for the frames model, triggered on the IMU's samples (as the
VIO wants it)."""


def camera_only(config: Any, parse_part: Callable[..., Any]) -> None:
    """With ``perception.kind == camera``: the scenario's LiDARs and the ESDF mapper that reads them are removed,
    and ``sensors.stereo`` (:data:`CAMERA_RIG`) is added unless a stereo_camera is there (a ConfigError for an
    estimator that needs a LiDAR), and a tunnel mission flies ``through: stepwise``. Any other scenario is left
    as it is. ``config`` is a ScenarioConfig being validated (its parts already parsed), ``parse_part`` the
    schema's (which imports this module)."""
    spec = getattr(config, "perception", None)
    if spec is None or spec.kind != "camera":
        return
    est = config.estimator
    if est is not None and est.kind == "lio":
        raise ConfigError(
            "perception: camera flies the vehicle with no LiDAR, and estimator lio needs one; set "
            "estimator.kind=vio (stereo VIO on the same rig)"
        )
    sensors = {name: s for name, s in config.sensors.items() if s.sensor_type != "lidar"}
    if not any(s.sensor_type == "stereo_camera" for s in sensors.values()):
        if "stereo" in sensors:
            raise ConfigError("perception: camera adds the stereo rig as sensors.stereo, a name already taken")
        sensors["stereo"] = parse_part("sensor", dict(CAMERA_RIG), "sensors.stereo", sensor_name="stereo")
    object.__setattr__(config, "sensors", sensors)
    if config.mapper is not None and config.mapper.kind == "esdf":  # it maps LiDAR clouds
        object.__setattr__(config, "mapper", None)
    m = config.mission
    # the camera sees the frames one by one. An explicit through: all is overridden too, not refused: the parsed
    # params cannot tell it from the default, and the scenario's own round trips write every key (with_overrides,
    # a sweep over perception, a vehicle's scenario and a run's config.yaml all carry through: all).
    if m is not None and m.kind == "tunnel" and m.params.through == "all":
        object.__setattr__(config, "mission", replace(m, params=replace(m.params, through="stepwise")))
