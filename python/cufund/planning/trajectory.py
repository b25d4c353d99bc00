"""The trajectory interface: what a planner hands to a controller, sampled at any times."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Trajectory", "TrajectorySamples"]


@dataclass(frozen=True)
class TrajectorySamples:
    """Flat outputs at ``N`` times, world ENU. Arrays of shape (N, 3) except yaw and yaw_rate (N,)."""

    t: np.ndarray
    """Times [s], (N,)."""
    p_W: np.ndarray
    """Position [m]."""
    v_W: np.ndarray
    """Velocity [m/s]."""
    a_W: np.ndarray
    """Acceleration [m/s^2]."""
    j_W: np.ndarray
    """Jerk [m/s^3]."""
    yaw: np.ndarray
    """Yaw (heading about world z from east) [rad]."""
    yaw_rate: np.ndarray
    """Yaw rate [rad/s]."""


@runtime_checkable
class Trajectory(Protocol):
    """A time-parameterised reference from ``t_start`` for ``duration``. Before and after that span a trajectory
    holds its end points at rest."""

    t_start: float
    """Start time [s]."""

    @property
    def duration(self) -> float:
        """Length in time [s]."""
        ...

    def sample(self, t: np.ndarray | float) -> TrajectorySamples:
        """Flat outputs at the times ``t`` [s] (scalar or (N,)); vectorised."""
        ...
