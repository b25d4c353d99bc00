"""Controller gains as named parameters (PX4's names where PX4 has the parameter, ``GEO_*`` for the geometric
controller), read and set in flight through the commander's ``get_params`` / ``set_param``.

Values are in cufund's units (the field docs of :mod:`cufund.control`), except that angles and angular rates PX4
gives in degrees (MPC_TILTMAX_AIR, MC_*RATE_MAX) are in degrees here too. PX4's rate-loop gains act on a
normalised torque, cufund's on angular acceleration: the names match, the numbers do not carry over.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable
from typing import Any

from cufund.control import AttitudeController, GeometricController, PositionController, RateController

__all__ = ["CONTROLLER_PARAMS", "controller_param_provider"]

_DEG = math.pi / 180.0
_STAGES = {
    "position": PositionController,
    "attitude": AttitudeController,
    "rate": RateController,
    "geometric": GeometricController,
}

CONTROLLER_PARAMS: dict[str, tuple[str, str, float]] = {
    "MPC_XY_P": ("position", "xy_p", 1.0),
    "MPC_Z_P": ("position", "z_p", 1.0),
    "MPC_XY_VEL_P_ACC": ("position", "xy_vel_p", 1.0),
    "MPC_XY_VEL_I_ACC": ("position", "xy_vel_i", 1.0),
    "MPC_XY_VEL_D_ACC": ("position", "xy_vel_d", 1.0),
    "MPC_Z_VEL_P_ACC": ("position", "z_vel_p", 1.0),
    "MPC_Z_VEL_I_ACC": ("position", "z_vel_i", 1.0),
    "MPC_Z_VEL_D_ACC": ("position", "z_vel_d", 1.0),
    "MPC_XY_VEL_MAX": ("position", "xy_vel_max", 1.0),
    "MPC_Z_VEL_MAX_UP": ("position", "z_vel_max_up", 1.0),
    "MPC_Z_VEL_MAX_DN": ("position", "z_vel_max_dn", 1.0),
    "MPC_TILTMAX_AIR": ("position", "tilt_max", _DEG),
    "MPC_THR_MIN": ("position", "thr_min", 1.0),
    "MPC_THR_MAX": ("position", "thr_max", 1.0),
    "MC_ROLL_P": ("attitude", "roll_p", 1.0),
    "MC_PITCH_P": ("attitude", "pitch_p", 1.0),
    "MC_YAW_P": ("attitude", "yaw_p", 1.0),
    "MC_ROLLRATE_MAX": ("attitude", "roll_rate_max", _DEG),
    "MC_PITCHRATE_MAX": ("attitude", "pitch_rate_max", _DEG),
    "MC_YAWRATE_MAX": ("attitude", "yaw_rate_max", _DEG),
    "MC_ROLLRATE_P": ("rate", "roll_p", 1.0),
    "MC_ROLLRATE_I": ("rate", "roll_i", 1.0),
    "MC_ROLLRATE_D": ("rate", "roll_d", 1.0),
    "MC_PITCHRATE_P": ("rate", "pitch_p", 1.0),
    "MC_PITCHRATE_I": ("rate", "pitch_i", 1.0),
    "MC_PITCHRATE_D": ("rate", "pitch_d", 1.0),
    "MC_YAWRATE_P": ("rate", "yaw_p", 1.0),
    "MC_YAWRATE_I": ("rate", "yaw_i", 1.0),
    "MC_YAWRATE_D": ("rate", "yaw_d", 1.0),
    "GEO_K_X": ("geometric", "k_x", 1.0),
    "GEO_K_V": ("geometric", "k_v", 1.0),
    "GEO_K_R": ("geometric", "k_R", 1.0),
    "GEO_K_W": ("geometric", "k_W", 1.0),
    "GEO_K_R_YAW": ("geometric", "k_R_yaw", 1.0),
    "GEO_K_W_YAW": ("geometric", "k_W_yaw", 1.0),
}
"""Parameter name -> (controller stage, gains field, field units per parameter unit)."""


def controller_param_provider(
    components: Iterable[Any],
) -> tuple[Callable[[], dict[str, float]], Callable[[str, Any], bool]]:
    """``(get, set)`` over the gains of the controllers among ``components`` (for
    :attr:`cufund.missions.Commander.param_providers`). ``set`` raises ValueError for a bad value (naming it)
    and returns False for a name it does not know."""
    stages: dict[str, list[Any]] = {k: [c for c in components if isinstance(c, cls)] for k, cls in _STAGES.items()}

    def get() -> dict[str, float]:
        out = {}
        for name, (stage, field, scale) in CONTROLLER_PARAMS.items():
            if stages[stage]:
                out[name] = float(getattr(stages[stage][0].gains, field)) / scale
        return out

    def set_(name: str, value: Any) -> bool:
        entry = CONTROLLER_PARAMS.get(name)
        if entry is None or not stages[entry[0]]:
            return False
        stage, field, scale = entry
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"{name} must be a finite number, got {value!r}")
        for c in stages[stage]:
            c.set_gains(dataclasses.replace(c.gains, **{field: float(value) * scale}))  # validated by the gains
        return True

    return get, set_
