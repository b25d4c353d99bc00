"""A landing that ends where the ground is, not where the estimate says the pad's height is.

A vehicle's estimated world frame is its estimator's: levelled by the accelerometer on the pad, so tilted by the
residual bias over gravity (3 mg: 0.17 deg, 3 cm of height over 10 m from the pad), and the ground away from the
pad is not at the pad's height anyway. Like PX4's land mode, the landing descends quickly to ``slow_above`` over
the expected ground, then at ``slow_speed`` on to ``overshoot`` below it: the vehicle stops where it meets the
ground (the position loop then asks for descent that the ground refuses, and the thrust falls away), and the
reference rests below the ground afterwards.
"""

from __future__ import annotations

import numpy as np

from .point_to_point import JerkLimitedMove
from .sequence import Hold, TrajectorySequence

__all__ = ["landing"]

_FOREVER = 1e6


def landing(
    p_W: np.ndarray,
    ground_z: float,
    v_max: float,
    a_max: float,
    j_max: float,
    yaw: float,
    t_start: float,
    slow_above: float = 0.15,
    slow_speed: float = 0.15,
    overshoot: float = 0.3,
) -> tuple[TrajectorySequence, float]:
    """The landing from rest at ``p_W`` [m] over ground expected at ``ground_z`` [m], starting at ``t_start`` [s]:
    (the trajectory, ending with a hold below the ground; the time its descent ends [s]). Speeds [m/s], acceleration
    [m/s^2], jerk [m/s^3], lengths [m]."""
    p = np.asarray(p_W, dtype=float)
    approach = np.array([p[0], p[1], min(float(p[2]), ground_z + slow_above)])
    below = np.array([p[0], p[1], ground_z - overshoot])
    fast = JerkLimitedMove(p, approach, v_max, a_max, j_max, yaw, t_start=t_start)
    slow = JerkLimitedMove(approach, below, min(slow_speed, v_max), a_max, j_max, yaw, t_start=fast.t_end)
    return TrajectorySequence([fast, slow, Hold(below, _FOREVER, yaw, t_start=slow.t_end)]), slow.t_end
