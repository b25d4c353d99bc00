"""PX4's custom flight modes (``px4_custom_mode.h``) and how the cufund commander's modes map onto them.

HEARTBEAT.custom_mode = main_mode << 16 | sub_mode << 24. A ground station shows the PX4 name of the commander's
mode; a DO_SET_MODE to a PX4 mode becomes the commander command that means the same.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink

MAIN_MANUAL, MAIN_ALTCTL, MAIN_POSCTL, MAIN_AUTO, MAIN_ACRO, MAIN_OFFBOARD, MAIN_STABILIZED = 1, 2, 3, 4, 5, 6, 7
SUB_READY, SUB_TAKEOFF, SUB_LOITER, SUB_MISSION, SUB_RTL, SUB_LAND = 1, 2, 3, 4, 5, 6

_NAMES = {
    (MAIN_MANUAL, 0): "MANUAL",
    (MAIN_ALTCTL, 0): "ALTCTL",
    (MAIN_POSCTL, 0): "POSCTL",
    (MAIN_ACRO, 0): "ACRO",
    (MAIN_OFFBOARD, 0): "OFFBOARD",
    (MAIN_STABILIZED, 0): "STABILIZED",
    (MAIN_AUTO, SUB_READY): "READY",
    (MAIN_AUTO, SUB_TAKEOFF): "TAKEOFF",
    (MAIN_AUTO, SUB_LOITER): "LOITER",
    (MAIN_AUTO, SUB_MISSION): "MISSION",
    (MAIN_AUTO, SUB_RTL): "RTL",
    (MAIN_AUTO, SUB_LAND): "LAND",
}

COMMANDER_TO_PX4: dict[str, tuple[int, int]] = {
    "idle": (MAIN_AUTO, SUB_LOITER),  # PX4 sits in Hold on the ground
    "takeoff": (MAIN_AUTO, SUB_TAKEOFF),
    "hold": (MAIN_AUTO, SUB_LOITER),
    "goto": (MAIN_AUTO, SUB_LOITER),  # PX4 flies DO_REPOSITION in Hold
    "mission": (MAIN_AUTO, SUB_MISSION),
    "external": (MAIN_AUTO, SUB_MISSION),  # a mission state machine (e.g. the tunnel mission) in command
    "offboard": (MAIN_OFFBOARD, 0),
    "land": (MAIN_AUTO, SUB_LAND),
    "rtl": (MAIN_AUTO, SUB_RTL),
}
"""cufund commander mode -> (PX4 main mode, sub mode)."""


def custom_mode(main: int, sub: int = 0) -> int:
    """HEARTBEAT.custom_mode of a PX4 (main, sub) mode."""
    return (int(main) & 0xFF) << 16 | (int(sub) & 0xFF) << 24


def split_custom_mode(value: int) -> tuple[int, int]:
    """(main, sub) of a PX4 custom_mode."""
    value = int(value)
    return (value >> 16) & 0xFF, (value >> 24) & 0xFF


def px4_name(main: int, sub: int = 0) -> str:
    """PX4's name of a mode ('LOITER', 'MISSION', ...) or 'UNKNOWN'."""
    return _NAMES.get((main, sub if main == MAIN_AUTO else 0), "UNKNOWN")


def heartbeat_mode(commander_mode: str, armed: bool) -> tuple[int, int]:
    """(base_mode, custom_mode) of a HEARTBEAT for the commander's mode."""
    main, sub = COMMANDER_TO_PX4.get(commander_mode, (MAIN_AUTO, SUB_LOITER))
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if main == MAIN_AUTO or main == MAIN_OFFBOARD:
        base |= (
            mavlink.MAV_MODE_FLAG_AUTO_ENABLED
            | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
            | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
        )
    if armed:
        base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    return base, custom_mode(main, sub)
