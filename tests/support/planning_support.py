"""Helpers for the replanning tests: a scripted map over the bus, a probe of the trajectory updates, and the PID
gains they fly with."""

from __future__ import annotations

import numpy as np

from cufund.core.components import Mapper
from cufund.core.messages import MapUpdate, Topics
from cufund.mapping import EsdfMap, EsdfMapParams

RES = 0.1
"""The scripted map's voxel edge [m]."""
ORIGIN = np.array([-2.0, -3.0, 0.0])
"""The scripted map's lower corner [m] (it is 12 x 6 x 3 m)."""
PILLAR = (np.array([4.0, -0.4, 0.0]), np.array([4.6, 0.4, 3.0]))  # [min, max] corners, whole voxels
GAINS = {
    "position": {"xy_p": 3.0, "z_p": 3.0, "xy_vel_p": 8.0, "xy_vel_i": 2.0, "xy_vel_d": 0.3, "z_vel_p": 8.0,
                 "z_vel_i": 2.0, "xy_vel_max": 3.0},
    "attitude": {"roll_p": 10.0, "pitch_p": 10.0, "yaw_p": 2.8},
    "rate": {"roll_p": 25.0, "roll_i": 10.0, "roll_d": 0.2, "pitch_p": 25.0, "pitch_i": 10.0, "pitch_d": 0.2,
             "yaw_p": 12.0, "yaw_i": 5.0},
}  # fmt: skip


class ScriptedMap(Mapper):
    """Publishes a map (a floor) at 10 Hz; adds ``box`` ([min, max] corners) to it at ``t_appear`` (never when
    None)."""

    name = "scripted_map"
    rate_hz = 10.0
    outputs = (Topics.ESDF_MAP,)

    def __init__(self, box: tuple[np.ndarray, np.ndarray], t_appear: float | None) -> None:
        self.box, self.t_appear = box, t_appear

    def reset(self) -> None:
        self.map = EsdfMap(EsdfMapParams(resolution=RES, size=(12, 6, 3), origin_W=tuple(ORIGIN), nthreads=1))
        self.map.set_occupied(np.argwhere(np.ones((120, 60, 1), bool)))
        self.appeared = False

    def integrate(self, t: float, bus) -> None:
        if self.t_appear is not None and t >= self.t_appear and not self.appeared:
            lo = np.round((self.box[0] - ORIGIN) / RES).astype(int)
            hi = np.round((self.box[1] - ORIGIN) / RES).astype(int)
            self.map.set_occupied(np.argwhere(np.ones(hi - lo, bool)) + lo)
            self.appeared = True
        bus.publish(Topics.ESDF_MAP, MapUpdate(t, self.map, 1))


class UpdateLog(Mapper):
    """Keeps every trajectory update (a test probe)."""

    name = "update_log"
    rate_hz = 250.0
    inputs = (Topics.TRAJECTORY_UPDATE,)

    def reset(self) -> None:
        self.updates = []

    def setup(self, bus) -> None:
        self._sub = bus.subscribe(Topics.TRAJECTORY_UPDATE)

    def integrate(self, t: float, bus) -> None:
        self.updates += self._sub.take()
