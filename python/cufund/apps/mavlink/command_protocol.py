"""MAVLink commands (COMMAND_LONG / COMMAND_INT) and offboard setpoints -> cufund commander commands.

Pure translation, no I/O: each function takes the decoded MAVLink fields and returns the commander's command dict
(world ENU, SI units, every frame change through :mod:`cufund.apps.mavlink.frames`) or raises :class:`Refused` with the
MAV_RESULT to answer. PX4's conventions: NAV_TAKEOFF param7 and DO_REPOSITION param7 are AMSL altitudes (NaN:
the default / keep); lat/lon in degrees (COMMAND_LONG) or degE7 (COMMAND_INT); yaw in degrees, NaN keeps it.
A NAV_TAKEOFF altitude at or below the home's AMSL altitude is taken as a height above home, the convention
MAVProxy's ``takeoff ALT`` follows (it sends ALT as is).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from . import frames
from . import px4_modes as modes


class Refused(Exception):
    """A command this vehicle answers with ``result`` (a MAV_RESULT) and does not forward."""

    def __init__(self, result: int, text: str = "") -> None:
        super().__init__(text)
        self.result = result


def _finite(x: float) -> bool:
    return x is not None and math.isfinite(float(x))


def takeoff(param7: float, home_p_W: np.ndarray, origin: frames.GeodeticOrigin) -> dict[str, Any]:
    """NAV_TAKEOFF: param7 AMSL altitude [m] (NaN: the commander's MIS_TAKEOFF_ALT)."""
    if not _finite(param7):
        return {"command": "takeoff"}
    home_amsl = float(origin.enu_to_lla(home_p_W)[2]) if np.all(np.isfinite(home_p_W)) else origin.alt_m
    height = float(param7) - home_amsl if float(param7) > home_amsl else float(param7)
    if height <= 0:
        raise Refused(mavlink.MAV_RESULT_DENIED, f"take-off altitude {param7} m is not above home")
    return {"command": "takeoff", "altitude": height}


def reposition(
    lat_deg: float,
    lon_deg: float,
    alt_m: float,
    yaw_deg: float,
    frame: int,
    current_p_W: np.ndarray,
    home_p_W: np.ndarray,
    origin: frames.GeodeticOrigin,
) -> dict[str, Any]:
    """DO_REPOSITION to (lat, lon, alt): alt AMSL, or above home in a relative frame; NaN lat/lon or alt keeps
    that part of the current position. A target below home is refused (it is in the ground)."""
    p = np.array(current_p_W, float)
    lla = origin.enu_to_lla(p)
    if _finite(alt_m):
        relative = frame in (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT)
        lla[2] = float(alt_m) + (float(origin.enu_to_lla(home_p_W)[2]) if relative else 0.0)
    if _finite(lat_deg) and _finite(lon_deg):
        lla[0], lla[1] = float(lat_deg), float(lon_deg)
    target = origin.lla_to_enu(lla)
    if np.all(np.isfinite(home_p_W)) and target[2] < home_p_W[2]:
        raise Refused(mavlink.MAV_RESULT_DENIED, f"reposition target {target[2] - home_p_W[2]:.2f} m below home")
    cmd: dict[str, Any] = {"command": "goto", "p_W": [float(c) for c in target]}
    if _finite(yaw_deg):
        cmd["yaw"] = float(frames.yaw_ned_to_enu(math.radians(yaw_deg)))
    return cmd


def set_mode(base_mode: float, main: float, sub: float, has_offboard_setpoint: bool) -> dict[str, Any] | None:
    """DO_SET_MODE with a PX4 custom mode -> a commander command (None: offboard, which the caller handles with
    the latest setpoint; PX4 refuses offboard without a setpoint stream)."""
    if not int(base_mode) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        raise Refused(mavlink.MAV_RESULT_UNSUPPORTED, "only PX4 custom modes are supported")
    main, sub = int(main), int(sub)
    if main == modes.MAIN_AUTO:
        cmd = {
            modes.SUB_LOITER: "hold",
            modes.SUB_MISSION: "mission_start",
            modes.SUB_RTL: "rtl",
            modes.SUB_LAND: "land",
            modes.SUB_TAKEOFF: "takeoff",
        }.get(sub)
        if cmd is None:
            raise Refused(mavlink.MAV_RESULT_UNSUPPORTED, f"AUTO sub-mode {sub} is not supported")
        return {"command": cmd}
    if main == modes.MAIN_OFFBOARD:
        if not has_offboard_setpoint:
            raise Refused(mavlink.MAV_RESULT_DENIED, "offboard needs a setpoint stream first")
        return None
    if main == modes.MAIN_POSCTL:
        return {"command": "hold"}  # no sticks: position control holds where it is
    raise Refused(mavlink.MAV_RESULT_DENIED, f"{modes.px4_name(main)} needs manual control input")


# SET_POSITION_TARGET_LOCAL_NED type_mask bits (POSITION_TARGET_TYPEMASK)
_POS_IGNORE = 0b111
_VEL_IGNORE = 0b111 << 3
_YAW_IGNORE = 1 << 10


def position_target(
    type_mask: int,
    frame: int,
    p_NED: np.ndarray,
    v_NED: np.ndarray,
    yaw_NED: float,
    current_p_W: np.ndarray,
    current_yaw_W: float,
) -> dict[str, Any]:
    """SET_POSITION_TARGET_LOCAL_NED -> offboard_position or offboard_velocity (world ENU)."""
    use_pos = not type_mask & _POS_IGNORE
    use_vel = not type_mask & _VEL_IGNORE
    if frame not in (mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_OFFSET_NED):
        raise Refused(mavlink.MAV_RESULT_UNSUPPORTED, f"position target frame {frame} is not supported")
    if not (use_pos or use_vel):
        raise Refused(mavlink.MAV_RESULT_UNSUPPORTED, "position target without position or velocity")
    values = [*p_NED, *v_NED] if use_pos and use_vel else (list(p_NED) if use_pos else list(v_NED))
    if not all(math.isfinite(float(x)) for x in values):
        raise Refused(mavlink.MAV_RESULT_DENIED, "non-finite setpoint")
    yaw = None
    if not type_mask & _YAW_IGNORE and math.isfinite(float(yaw_NED)):
        yaw = float(frames.yaw_ned_to_enu(float(yaw_NED)))
    elif use_pos:
        yaw = float(current_yaw_W)
    if use_pos:
        p_W = frames.ned_to_enu(np.asarray(p_NED, float))
        if frame == mavlink.MAV_FRAME_LOCAL_OFFSET_NED:
            p_W = p_W + np.asarray(current_p_W, float)
        cmd: dict[str, Any] = {"command": "offboard_position", "p_W": [float(c) for c in p_W], "yaw": yaw}
        if use_vel:
            cmd["v_W"] = [float(c) for c in frames.ned_to_enu(np.asarray(v_NED, float))]
        return cmd
    cmd = {"command": "offboard_velocity", "v_W": [float(c) for c in frames.ned_to_enu(np.asarray(v_NED, float))]}
    if yaw is not None:
        cmd["yaw"] = yaw
    return cmd


_ATTITUDE_IGNORE = 1 << 7
_THRUST_IGNORE = 1 << 6


def attitude_target(type_mask: int, q_NED_FRD: np.ndarray, thrust: float, max_thrust_N: float) -> dict[str, Any]:
    """SET_ATTITUDE_TARGET (attitude, normalised thrust 0..1) -> offboard_attitude (q_WB, thrust [N])."""
    if type_mask & _ATTITUDE_IGNORE:
        raise Refused(mavlink.MAV_RESULT_UNSUPPORTED, "body-rate-only attitude targets are not supported")
    q = np.asarray(q_NED_FRD, float)
    if not np.all(np.isfinite(q)) or float(np.linalg.norm(q)) < 1e-6:
        raise Refused(mavlink.MAV_RESULT_DENIED, "attitude target quaternion is not a rotation")
    q_WB = frames.q_ned_frd_to_enu_flu(q / np.linalg.norm(q))
    cmd: dict[str, Any] = {"command": "offboard_attitude", "q_WB": [float(c) for c in q_WB]}
    if not type_mask & _THRUST_IGNORE:
        if not math.isfinite(float(thrust)) or not 0.0 <= float(thrust) <= 1.0:
            raise Refused(mavlink.MAV_RESULT_DENIED, f"thrust must be in [0, 1], got {thrust}")
        cmd["thrust"] = float(thrust) * max_thrust_N
    return cmd
