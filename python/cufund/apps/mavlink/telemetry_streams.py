"""The telemetry a PX4 vehicle streams, built from one snapshot of a live run (every frame conversion through
:mod:`cufund.apps.mavlink.frames`).

:class:`VehicleSnapshot` is what the endpoint reads from :meth:`cufund.apps.live.LiveRun.telemetry`; each ``encode_*``
function turns it into one pymavlink message for a link's codec. :data:`DEFAULT_RATES_HZ` are the stream rates
before a client changes them with SET_MESSAGE_INTERVAL (PX4's onboard-link defaults, rounded).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from cufund.geometry import euler_zyx, yaw_of

from . import frames
from .px4_modes import heartbeat_mode

SENSORS = (
    mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink.MAV_SYS_STATUS_SENSOR_GPS
    | mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | mavlink.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | mavlink.MAV_SYS_STATUS_PREARM_CHECK
)
"""SYS_STATUS sensor bits: present, enabled and healthy (MAVSDK's health checks read GPS and PREARM_CHECK)."""

CAPABILITIES = (
    mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
)
"""AUTOPILOT_VERSION capabilities: what this endpoint implements."""

FLIGHT_SW_VERSION = (1 << 24) | (15 << 16) | (0 << 8) | 255
"""Reported as PX4 v1.15.0 release: the PX4 behaviour the endpoint follows (MAVSDK reads it)."""

DEFAULT_RATES_HZ: dict[str, float] = {
    "HEARTBEAT": 1.0,
    "SYS_STATUS": 2.0,
    "EXTENDED_SYS_STATE": 2.0,
    "HOME_POSITION": 0.5,
    "ATTITUDE_QUATERNION": 20.0,
    "ATTITUDE": 20.0,
    "LOCAL_POSITION_NED": 20.0,
    "GLOBAL_POSITION_INT": 20.0,
    "ALTITUDE": 10.0,
    "GPS_RAW_INT": 2.0,
    "VFR_HUD": 4.0,
    "MISSION_CURRENT": 1.0,
    "BATTERY_STATUS": 1.0,
}

_LANDED = {"takeoff": mavlink.MAV_LANDED_STATE_TAKEOFF, "land": mavlink.MAV_LANDED_STATE_LANDING}


@dataclass(frozen=True)
class VehicleSnapshot:
    """What the endpoint reports at one instant: the flight stack's state estimate and the commander's status."""

    t: float
    """Simulated time [s] (the vehicle's time since boot)."""
    p_W: np.ndarray
    v_W: np.ndarray
    q_WB: np.ndarray
    w_B: np.ndarray
    armed: bool
    landed: bool
    mode: str
    mission_current: int
    mission_count: int
    home_p_W: np.ndarray
    message: str
    battery: dict[str, float] | None = None
    """The power module's last reading (``voltage_v``, ``current_a``, ``remaining``, ``consumed_mah``, ``cells``), or
    None when the scenario has no ``vehicle.battery`` (then a full pack is reported, as before)."""

    @staticmethod
    def from_telemetry(tel: dict[str, Any]) -> VehicleSnapshot:
        """From :meth:`cufund.apps.live.LiveRun.telemetry`. Before the commander has a home (it takes one when
        arming), home is where the vehicle is while on the ground, as PX4 sets it once its position is valid."""
        zero = np.zeros(3)

        def vec(v: Any, n: int, default: np.ndarray) -> np.ndarray:
            try:
                a = np.asarray(v if v is not None else default, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                return default
            return a if a.shape == (n,) and np.all(np.isfinite(a)) else default

        p_W = vec(tel.get("p_W"), 3, zero)
        mission = tel.get("mission") or {}
        current = mission.get("current", -1)
        return VehicleSnapshot(
            t=float(tel.get("t", 0.0) or 0.0),
            p_W=p_W,
            v_W=vec(tel.get("v_W"), 3, zero),
            q_WB=vec(tel.get("q_WB"), 4, np.array([1.0, 0, 0, 0])),
            w_B=vec(tel.get("w_B"), 3, zero),
            armed=bool(tel.get("armed", False)),
            landed=bool(tel.get("landed", True)),
            mode=str(tel.get("mode", "idle") or "idle"),
            mission_current=int(current) if isinstance(current, (int, np.integer)) else -1,
            mission_count=int(mission.get("count", 0) or 0),
            home_p_W=vec(tel.get("home_p_W"), 3, p_W),
            message=str(tel.get("message", "") or ""),
            battery=_battery(tel.get("battery")),
        )

    @property
    def time_boot_ms(self) -> int:
        return int(max(self.t, 0.0) * 1e3) & 0xFFFFFFFF

    @property
    def time_usec(self) -> int:
        return int(max(self.t, 0.0) * 1e6)


def yaw_ned(s: VehicleSnapshot) -> float:
    """NED heading [rad] of the body x axis."""
    return float(frames.yaw_enu_to_ned(yaw_of(s.q_WB)))


def landed_state(s: VehicleSnapshot) -> int:
    if s.landed:
        return mavlink.MAV_LANDED_STATE_ON_GROUND
    return _LANDED.get(s.mode, mavlink.MAV_LANDED_STATE_IN_AIR)


def encode_heartbeat(mav, s: VehicleSnapshot, link_lost: bool = False):
    base, custom = heartbeat_mode(s.mode, s.armed)
    status = mavlink.MAV_STATE_ACTIVE if s.armed else mavlink.MAV_STATE_STANDBY
    if link_lost:
        status = mavlink.MAV_STATE_CRITICAL
    return mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, base, custom, status, 3)


def _battery(value: Any) -> dict[str, float] | None:
    """The telemetry's battery reading with finite numbers, or None."""
    if not isinstance(value, dict):
        return None
    try:
        out = {k: float(value[k]) for k in ("voltage_v", "current_a", "remaining", "consumed_mah", "cells")}
    except (KeyError, TypeError, ValueError):
        return None
    return out if all(math.isfinite(v) for v in out.values()) else None


def _battery_fields(s: VehicleSnapshot) -> tuple[int, int, int]:
    """(voltage [mV], current [cA], remaining [%]) as SYS_STATUS and BATTERY_STATUS carry them."""
    b = s.battery
    if b is None:
        return 16200, -1, 100  # no battery model: a full 4S pack, current unknown
    voltage = min(max(round(b["voltage_v"] * 1e3), 0), 65534)
    current = min(max(round(b["current_a"] * 100), -1), 32767)
    return voltage, current, min(max(round(b["remaining"] * 100), 0), 100)


def encode_sys_status(mav, s: VehicleSnapshot):
    voltage, current, remaining = _battery_fields(s)
    return mav.sys_status_encode(SENSORS, SENSORS, SENSORS, 0, voltage, current, remaining, 0, 0, 0, 0, 0, 0)


def encode_battery_status(mav, s: VehicleSnapshot):
    """BATTERY_STATUS: the pack's voltage split evenly over its cells (a power module measures the pack only),
    current [cA], charge drawn [mAh] and remaining [%]; temperature unknown."""
    b = s.battery
    if b is None:
        cells, consumed = [4050] * 4 + [65535] * 6, -1
    else:
        n = max(1, int(b["cells"]))
        per_cell = min(round(b["voltage_v"] * 1e3 / n), 65534)
        cells = [per_cell] * min(n, 10) + [65535] * (10 - min(n, 10))
        consumed = min(round(b["consumed_mah"]), 2**31 - 1)
    _, current, remaining = _battery_fields(s)
    return mav.battery_status_encode(
        0,
        mavlink.MAV_BATTERY_FUNCTION_ALL,
        mavlink.MAV_BATTERY_TYPE_LIPO,
        32767 if b is not None else 2500,
        cells,
        current,
        consumed,
        -1,
        remaining,
    )


def encode_attitude_quaternion(mav, s: VehicleSnapshot):
    q = frames.q_enu_flu_to_ned_frd(s.q_WB)
    w = frames.rates_flu_to_frd(s.w_B)
    return mav.attitude_quaternion_encode(s.time_boot_ms, *(float(c) for c in q), *(float(c) for c in w))


def encode_attitude(mav, s: VehicleSnapshot):
    roll, pitch, yaw = euler_zyx(frames.q_enu_flu_to_ned_frd(s.q_WB))
    w = frames.rates_flu_to_frd(s.w_B)
    return mav.attitude_encode(s.time_boot_ms, roll, pitch, yaw, *(float(c) for c in w))


def encode_local_position_ned(mav, s: VehicleSnapshot):
    p, v = frames.enu_to_ned(s.p_W), frames.enu_to_ned(s.v_W)
    return mav.local_position_ned_encode(s.time_boot_ms, *(float(c) for c in p), *(float(c) for c in v))


def encode_global_position_int(mav, s: VehicleSnapshot, origin: frames.GeodeticOrigin):
    lat, lon, alt = origin.enu_to_lla(s.p_W)
    v = frames.enu_to_ned(s.v_W)
    hdg = round(math.degrees(yaw_ned(s)) * 100) % 36000
    return mav.global_position_int_encode(
        s.time_boot_ms,
        frames.deg_to_e7(lat),
        frames.deg_to_e7(lon),
        frames.m_to_mm(alt),
        frames.m_to_mm(s.p_W[2] - s.home_p_W[2]),
        *(int(c) for c in frames.m_s_to_cm_s(v)),
        hdg,
    )


def encode_gps_raw_int(mav, s: VehicleSnapshot, origin: frames.GeodeticOrigin):
    lat, lon, alt = origin.enu_to_lla(s.p_W)
    v = frames.enu_to_ned(s.v_W)
    return mav.gps_raw_int_encode(
        s.time_usec,
        mavlink.GPS_FIX_TYPE_3D_FIX,
        frames.deg_to_e7(lat),
        frames.deg_to_e7(lon),
        frames.m_to_mm(alt),
        80,
        120,
        frames.m_to_cm_u16(math.hypot(v[0], v[1])),
        frames.course_cdeg(v, 0.2),
        12,
    )


def encode_extended_sys_state(mav, s: VehicleSnapshot):
    return mav.extended_sys_state_encode(mavlink.MAV_VTOL_STATE_UNDEFINED, landed_state(s))


def encode_home_position(mav, s: VehicleSnapshot, origin: frames.GeodeticOrigin):
    lat, lon, alt = origin.enu_to_lla(s.home_p_W)
    h = frames.enu_to_ned(s.home_p_W)
    return mav.home_position_encode(
        frames.deg_to_e7(lat),
        frames.deg_to_e7(lon),
        frames.m_to_mm(alt),
        *(float(c) for c in h),
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        0.0,
        s.time_usec,
    )


def encode_altitude(mav, s: VehicleSnapshot, origin: frames.GeodeticOrigin):
    amsl = float(origin.enu_to_lla(s.p_W)[2])
    up = float(s.p_W[2])
    return mav.altitude_encode(s.time_usec, amsl, amsl, up, up - float(s.home_p_W[2]), math.nan, max(up, 0.0))


def encode_vfr_hud(mav, s: VehicleSnapshot, origin: frames.GeodeticOrigin):
    heading = round(math.degrees(yaw_ned(s))) % 360
    return mav.vfr_hud_encode(
        0.0,
        float(math.hypot(s.v_W[0], s.v_W[1])),
        heading,
        50 if s.armed else 0,
        float(origin.enu_to_lla(s.p_W)[2]),
        float(s.v_W[2]),
    )


def mission_state(s: VehicleSnapshot, done: bool) -> int:
    if s.mission_count == 0:
        return mavlink.MISSION_STATE_NO_MISSION
    if done:
        return mavlink.MISSION_STATE_COMPLETE
    if s.mode == "mission":
        return mavlink.MISSION_STATE_ACTIVE
    return mavlink.MISSION_STATE_NOT_STARTED if s.mission_current < 0 else mavlink.MISSION_STATE_PAUSED


def encode_mission_current(mav, s: VehicleSnapshot, seq: int, total: int, done: bool = False):
    """MISSION_CURRENT; a plan flown to its end reports seq = total (past the last item) and COMPLETE."""
    seq = total if done else max(seq, 0)
    return mav.mission_current_encode(seq, total, mission_state(s, done), 1 if s.mode == "mission" else 0)


def encode_autopilot_version(mav, system_id: int):
    return mav.autopilot_version_encode(
        CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0xC0F00D0000000000 | system_id
    )


def encode_statustext(mav, text: str, severity: int = mavlink.MAV_SEVERITY_INFO):
    return mav.statustext_encode(severity, text.encode("ascii", "replace")[:50])
