"""PX4 actuator outputs -> cufund rotor-speed commands: the airframe's channel mapping and its motor order.

PX4 sends normalised motor outputs ``u`` in ``HIL_ACTUATOR_CONTROLS.controls[0..3]``; Gazebo classic's
``mavlink_interface`` turns channel ``i`` into a rotor speed ``omega = (u + input_offset) * input_scaling +
zero_position_armed`` while armed and ``zero_position_disarmed`` otherwise (``models/iris/iris.sdf``: offset 0,
scaling 1000 rad/s, armed zero 100 rad/s, disarmed zero 0). :class:`Px4Airframe` is that mapping, typed.

Motor order: PX4 numbers the motors of a geometry (``quad_x``: 1 front-right CCW, 2 rear-left CCW, 3 front-left
CW, 4 rear-right CW; ``quad_+``: 1 right CCW, 2 left CCW, 3 front CW, 4 rear CW); cufund numbers its rotors by
``QuadrotorParams.layout``. :meth:`Px4Airframe.rotor_of_output` matches them by position and spin direction from
both vehicles' geometry, so a mismatch is an error, never a silently swapped motor.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cufund.core.config import ConfigError
from cufund.vehicle.params import QuadrotorParams

__all__ = ["PX4_GEOMETRIES", "Px4Airframe"]

#: PX4 motor geometry per airframe: for motor 1..4, (x forward, y right) direction in body FRD and spin
#: (+1 counter-clockwise seen from above, -1 clockwise), as in PX4's airframe reference.
PX4_GEOMETRIES: dict[str, tuple[tuple[float, float, int], ...]] = {
    "quad_x": ((1.0, 1.0, +1), (-1.0, -1.0, +1), (1.0, -1.0, -1), (-1.0, 1.0, -1)),
    "quad_+": ((0.0, 1.0, +1), (0.0, -1.0, +1), (1.0, 0.0, -1), (-1.0, 0.0, -1)),
}


@dataclass(frozen=True)
class Px4Airframe:
    """How PX4's normalised motor outputs become rotor speeds [rad/s] (Gazebo's ``control_channels``), per
    motor output 1..4 (PX4 numbering)."""

    geometry: str = "quad_x"
    """PX4 geometry the outputs follow: ``quad_x`` or ``quad_+`` (see :data:`PX4_GEOMETRIES`)."""
    input_offset: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    """Added to each output before scaling [-]."""
    input_scaling: tuple[float, float, float, float] = (1000.0, 1000.0, 1000.0, 1000.0)
    """Rotor speed per unit output [rad/s]."""
    zero_position_armed: tuple[float, float, float, float] = (100.0, 100.0, 100.0, 100.0)
    """Rotor speed at output 0 while armed [rad/s] (idle spin)."""
    zero_position_disarmed: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    """Rotor speed while disarmed [rad/s]."""

    def __post_init__(self) -> None:
        if self.geometry not in PX4_GEOMETRIES:
            raise ConfigError(f"geometry must be one of {sorted(PX4_GEOMETRIES)}, got {self.geometry!r}")
        for name in ("input_offset", "input_scaling", "zero_position_armed", "zero_position_disarmed"):
            v = getattr(self, name)
            try:
                a = np.asarray(v, dtype=float)
            except (TypeError, ValueError):
                raise ConfigError(f"{name} must be 4 numbers, got {v!r}") from None
            if a.shape != (4,) or not np.all(np.isfinite(a)):
                raise ConfigError(f"{name} must be 4 finite numbers (one per motor output), got {v!r}")
            object.__setattr__(self, name, tuple(float(x) for x in a))

    @classmethod
    def iris(cls) -> Px4Airframe:
        """Gazebo classic's iris (``models/iris/iris.sdf``): omega = u * 1000 + 100 rad/s armed, 0 disarmed."""
        return cls()

    @classmethod
    def for_vehicle(cls, params: QuadrotorParams) -> Px4Airframe:
        """The iris mapping for the iris preset; otherwise output 0..1 spans the vehicle's rotor-speed range
        (omega = rotor_speed_min + u * (rotor_speed_max - rotor_speed_min) armed, 0 disarmed)."""
        geometry = "quad_x" if params.layout == "x" else "quad_+"
        if params.name == "iris" and params.layout == "x" and params.rotor_speed_max == 1100.0:
            return cls.iris()
        lo, hi = float(params.rotor_speed_min), float(params.rotor_speed_max)
        return cls(geometry, (0.0,) * 4, (hi - lo,) * 4, (lo,) * 4, (0.0,) * 4)

    def rotor_speeds(self, controls: np.ndarray, armed: bool) -> np.ndarray:
        """Rotor-speed commands [rad/s] per PX4 motor output (4,) from outputs ``controls[0..3]``; a
        non-finite output (PX4's "disabled") commands the disarmed speed."""
        return np.array(self.rotor_speed_list(controls, armed))

    def rotor_speed_list(
        self, controls: Sequence[float] | np.ndarray, armed: bool, outputs: Sequence[int] = (0, 1, 2, 3)
    ) -> list[float]:
        """:meth:`rotor_speeds` as a list of plain floats (four channels: no numpy overhead per call), for the
        motor ``outputs`` (0-based) in the order given: all four by default, or reordered (e.g. into cufund's
        rotor order) in the same pass."""
        if not armed:
            dis = self.zero_position_disarmed
            return [dis[i] for i in outputs]
        off, scale, zero, dis = (
            self.input_offset,
            self.input_scaling,
            self.zero_position_armed,
            self.zero_position_disarmed,
        )
        out = []
        for i in outputs:
            w = (float(controls[i]) + off[i]) * scale[i] + zero[i]
            out.append(w if math.isfinite(w) else dis[i])
        return out

    def rotor_of_output(self, params: QuadrotorParams) -> np.ndarray:
        """(4,) int: the cufund rotor index driven by PX4 motor output i (0-based), matched by direction from
        the centre and spin. Raises ConfigError when the vehicle's rotors do not fit this geometry."""
        pos_B = np.asarray(params.rotor_positions(), dtype=float)  # FLU
        spins = np.asarray(params.rotor_spins(), dtype=float)
        ang_cufund = np.arctan2(pos_B[:, 1], pos_B[:, 0])
        out = np.empty(4, dtype=int)
        for i, (x, y_right, spin) in enumerate(PX4_GEOMETRIES[self.geometry]):
            ang = math.atan2(-y_right, x)  # FRD -> FLU: y flips
            diff = np.abs((ang_cufund - ang + np.pi) % (2 * np.pi) - np.pi)
            j = int(np.argmin(diff))
            if diff[j] > np.radians(10.0) or spins[j] != spin:
                raise ConfigError(
                    f"PX4 {self.geometry} motor {i + 1} (spin {'CCW' if spin > 0 else 'CW'}) has no "
                    f"matching rotor on vehicle {params.name!r} (layout {params.layout!r})"
                )
            out[i] = j
        if len(set(out.tolist())) != 4:
            raise ConfigError(f"PX4 {self.geometry} motors do not map one-to-one onto {params.name!r}'s rotors")
        return out
