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
        self._col_f = Ainv[:, 0]
        self._cols_rp = Ainv[:, 1:3]
        self._col_y = Ainv[:, 3]
        self.last_saturation = AllocationSaturation((0, 0, 0), 0)
        self.last_thrust_torque = np.zeros(4)
        """[f, Mx, My, Mz] actually allocated (before the motors' lag)."""
        self._A = params.allocation_matrix()

    @property
    def max_thrust(self) -> float:
        """Collective thrust with all rotors at full speed [N]."""
        return 4.0 * self.u_max

    def rotor_speeds(self, thrust: float, torque_B: np.ndarray) -> np.ndarray:
        """Rotor speed commands (4,) [rad/s] for ``thrust`` [N] and ``torque_B`` (3,) [N m]."""
        u_rp = self._cols_rp @ torque_B[:2]
        spread = float(u_rp.max() - u_rp.min())
        span = self.u_max - self.u_min
        if spread > span:
            u_rp *= span / spread
        u = self._col_f * thrust + u_rp
        lo_shift = self.u_min - u.min()
        hi_shift = self.u_max - u.max()
        shift = min(max(0.0, lo_shift), hi_shift)
        u += shift
        u_y = self._col_y * torque_B[2]
        # the largest k in [0, 1] with u + k u_y inside [u_min, u_max]
        k = 1.0
        for ui, yi in zip(u.tolist(), u_y.tolist()):
            if yi > 0:
                k = min(k, (self.u_max - ui) / yi)
            elif yi < 0:
                k = min(k, (self.u_min - ui) / yi)
        k = max(k, 0.0)
        u += k * u_y
        u = np.minimum(np.maximum(u, self.u_min), self.u_max)
        achieved = self._A @ u
        self.last_thrust_torque = achieved
        demanded = (thrust, torque_B[0], torque_B[1], torque_B[2])
        tol = 1e-9 * max(1.0, self.u_max)
        signs = [0 if abs(d - a) <= tol else (1 if d > a else -1) for d, a in zip(demanded, achieved.tolist())]
        self.last_saturation = AllocationSaturation((signs[1], signs[2], signs[3]), signs[0])
        return np.sqrt(u / self.k_f)
