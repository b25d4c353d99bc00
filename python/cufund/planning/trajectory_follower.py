"""A planner that publishes a precomputed trajectory as setpoints, PX4's offboard ``trajectory_setpoint``."""

from __future__ import annotations

from ..components import Bus, Planner
from ..messages import Odometry, Topics, TrajectorySetpoint
from .trajectory import Trajectory

__all__ = ["TrajectoryFollower"]


class TrajectoryFollower(Planner):
    """Publishes ``trajectory`` sampled at the current time on ``topic`` at ``rate_hz``."""

    name = "trajectory_follower"

    def __init__(self, trajectory: Trajectory, rate_hz: float = 250.0, topic: str = Topics.TRAJECTORY_SETPOINT) -> None:
        if not isinstance(trajectory, Trajectory):
            raise TypeError(f"trajectory must implement cufund.planning.Trajectory, got {type(trajectory).__name__}")
        self.trajectory = trajectory
        self.rate_hz = rate_hz
        self.topic = topic

    def update(self, t: float, state: Odometry, bus: Bus) -> None:
        s = self.trajectory.sample(t)
        bus.publish(self.topic, TrajectorySetpoint(t, s.p_W[0], s.v_W[0], s.a_W[0], s.j_W[0], float(s.yaw[0]),
                                                   float(s.yaw_rate[0])))
