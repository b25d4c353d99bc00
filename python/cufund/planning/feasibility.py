"""Dynamic feasibility of a position trajectory: peak speed, acceleration, jerk, thrust and tilt."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .trajectory import Trajectory

__all__ = ["TrajectoryFeasibility", "feasibility"]


@dataclass(frozen=True)
class TrajectoryFeasibility:
    """Peaks over a trajectory, sampled every ``dt``. Thrust is per unit mass: ``|a + g e_z|``."""

    peak_speed: float
    """[m/s]"""
    peak_acceleration: float
    """[m/s^2]"""
    peak_jerk: float
    """[m/s^3]"""
    max_thrust_acceleration: float
    """Largest collective thrust per mass [m/s^2] (multiply by the mass for newtons)."""
    min_thrust_acceleration: float
    """Smallest collective thrust per mass [m/s^2]; near 0 means free fall is asked for."""
    max_tilt_deg: float
    """Largest angle between the thrust direction and the vertical [deg]."""

    def within(
        self,
        v_max: float = math.inf,
        a_max: float = math.inf,
        thrust_max: float = math.inf,
        tilt_max_deg: float = 90.0,
        rel_tol: float = 1e-3,
    ) -> bool:
        """True when every peak is within its limit (``rel_tol`` for the sampling)."""
        k = 1.0 + rel_tol
        return (
            self.peak_speed <= v_max * k
            and self.peak_acceleration <= a_max * k
            and self.max_thrust_acceleration <= thrust_max * k
            and self.max_tilt_deg <= tilt_max_deg * k
        )


def feasibility(trajectory: Trajectory, gravity: float = 9.81, dt: float = 0.005) -> TrajectoryFeasibility:
    """Samples ``trajectory`` from its start to its end every ``dt`` [s] (ends included)."""
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"dt must be finite and > 0 [s], got {dt!r}")
    t0 = float(trajectory.t_start)
    t1 = t0 + float(trajectory.duration)
    t = np.linspace(t0, t1, max(2, int(math.ceil((t1 - t0) / dt)) + 1))
    s = trajectory.sample(t)
    f = s.a_W + np.array([0.0, 0.0, gravity])
    fn = np.linalg.norm(f, axis=1)
    tilt = np.degrees(np.arccos(np.clip(f[:, 2] / np.maximum(fn, 1e-12), -1.0, 1.0)))
    return TrajectoryFeasibility(
        peak_speed=float(np.linalg.norm(s.v_W, axis=1).max()),
        peak_acceleration=float(np.linalg.norm(s.a_W, axis=1).max()),
        peak_jerk=float(np.linalg.norm(s.j_W, axis=1).max()),
        max_thrust_acceleration=float(fn.max()),
        min_thrust_acceleration=float(fn.min()),
        max_tilt_deg=float(tilt.max()),
    )
