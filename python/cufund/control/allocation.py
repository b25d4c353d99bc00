"""Control allocation with priorities: roll/pitch authority is kept when motors saturate (PX4's mixer)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cufund import _core
from cufund.vehicle.params import QuadrotorParams

__all__ = ["ControlAllocator", "AllocationSaturation"]


@dataclass(frozen=True)
class AllocationSaturation:
    """Which demands the allocator could not meet, for anti-windup: +1 demand above what was achieved, -1 below,
    0 met. ``torque`` per body axis, ``thrust`` collective."""

    torque: tuple[int, int, int]
    thrust: int


class ControlAllocator:
    """Maps collective thrust [N] and body torque [N m] to rotor speeds [rad/s] within the motor limits (C++).

    Priorities when motors saturate (PX4 multicopter mixer with air mode): roll/pitch first, then collective
    thrust, then yaw. In rotor-thrust space: (1) roll/pitch thrust differences are scaled down only if they alone
    span more than the motors' range; (2) the collective is shifted (up or down) by the least amount that puts
    every rotor in range; (3) as much of the yaw torque is added as still fits.
    """

    def __init__(self, params: QuadrotorParams) -> None:
        self.params = params
        self._core = _core.control.ControlAllocator(params.to_core())
        self.last_saturation = AllocationSaturation((0, 0, 0), 0)
        self.last_thrust_torque = np.zeros(4)
        """[f, Mx, My, Mz] actually allocated (before the motors' lag)."""

    @property
    def max_thrust(self) -> float:
        """Collective thrust with all rotors at full speed [N]."""
        return float(self._core.max_thrust)

    def rotor_speeds(self, thrust: float, torque_B: np.ndarray) -> np.ndarray:
        """Rotor speed commands (4,) [rad/s] for ``thrust`` [N] and ``torque_B`` (3,) [N m]."""
        speeds, self.last_thrust_torque, sat = self._core.allocate(thrust, torque_B)
        self.last_saturation = AllocationSaturation((sat[1], sat[2], sat[3]), sat[0])
        return speeds
