"""Control allocation with priorities: roll/pitch authority is kept when motors saturate (PX4's mixer)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import QuadrotorParams

__all__ = ["ControlAllocator", "AllocationSaturation"]


@dataclass(frozen=True)
class AllocationSaturation:
    """Which demands the allocator could not meet, for anti-windup: +1 demand above what was achieved, -1 below,
    0 met. ``torque`` per body axis, ``thrust`` collective."""

    torque: tuple[int, int, int]
    thrust: int


class ControlAllocator:
    """Maps collective thrust [N] and body torque [N m] to rotor speeds [rad/s] within the motor limits.

    Priorities when motors saturate (PX4 multicopter mixer with air mode): roll/pitch first, then collective
    thrust, then yaw. In rotor-thrust space: (1) roll/pitch thrust differences are scaled down only if they alone
    span more than the motors' range; (2) the collective is shifted (up or down) by the least amount that puts
    every rotor in range; (3) as much of the yaw torque is added as still fits.
    """

    def __init__(self, params: QuadrotorParams) -> None:
        self.params = params
        self.k_f = params.k_f
        self.u_min = params.k_f * params.rotor_speed_min ** 2
        self.u_max = params.k_f * params.rotor_speed_max ** 2
        Ainv = params.allocation_matrix_inverse()
        self.last_saturation = AllocationSaturation((0, 0, 0), 0)
        self.last_thrust_torque = np.zeros(4)
        """[f, Mx, My, Mz] actually allocated (before the motors' lag)."""
        self._A = params.allocation_matrix()
        self._f = Ainv[:, 0].tolist()
        self._rp = Ainv[:, 1:3].tolist()
        self._y = Ainv[:, 3].tolist()
        self._A_rows = self._A.tolist()

    @property
    def max_thrust(self) -> float:
        """Collective thrust with all rotors at full speed [N]."""
        return 4.0 * self.u_max

    def rotor_speeds(self, thrust: float, torque_B: np.ndarray) -> np.ndarray:
        """Rotor speed commands (4,) [rad/s] for ``thrust`` [N] and ``torque_B`` (3,) [N m]."""
        # four rotors: plain floats are several times faster than numpy at this size
        mx, my, mz = (float(x) for x in torque_B)
        thrust = float(thrust)
        u_min, u_max = self.u_min, self.u_max
        u_rp = [a * mx + b * my for a, b in self._rp]
        spread = max(u_rp) - min(u_rp)
        if spread > u_max - u_min:  # roll/pitch alone exceed the motors' range: scale them down
            scale = (u_max - u_min) / spread
            u_rp = [x * scale for x in u_rp]
        u = [c * thrust + x for c, x in zip(self._f, u_rp)]
        shift = min(max(0.0, u_min - min(u)), u_max - max(u))  # least collective change that fits
        u = [x + shift for x in u]
        u_y = [c * mz for c in self._y]
        k = 1.0  # the largest k in [0, 1] with u + k u_y inside [u_min, u_max]
        for ui, yi in zip(u, u_y):
            if yi > 0:
                k = min(k, (u_max - ui) / yi)
            elif yi < 0:
                k = min(k, (u_min - ui) / yi)
        k = max(k, 0.0)
        u = [min(max(x + k * y, u_min), u_max) for x, y in zip(u, u_y)]
        achieved = [sum(a * x for a, x in zip(row, u)) for row in self._A_rows]
        self.last_thrust_torque = np.array(achieved)
        tol = 1e-9 * max(1.0, u_max)
        signs = [0 if abs(d - a) <= tol else (1 if d > a else -1)
                 for d, a in zip((thrust, mx, my, mz), achieved)]
        self.last_saturation = AllocationSaturation((signs[1], signs[2], signs[3]), signs[0])
        return np.sqrt(np.array(u) / self.k_f)
