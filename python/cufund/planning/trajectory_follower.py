"""A planner that publishes a precomputed trajectory as setpoints, PX4's offboard ``trajectory_setpoint``."""

from __future__ import annotations

import numpy as np

from ..components import Bus, Planner
from ..messages import Odometry, Topics, TrajectorySetpoint
from .trajectory import Trajectory, TrajectorySamples

__all__ = ["TrajectoryFollower"]


class TrajectoryFollower(Planner):
    """Publishes ``trajectory`` sampled at the current time on ``topic`` at ``rate_hz``.

    The trajectory is sampled ahead in blocks of ``block`` ticks on the follower's own clock grid with one
    vectorised call, so each tick only looks its row up (off-grid times are sampled directly).
    """

    name = "trajectory_follower"

    def __init__(self, trajectory: Trajectory, rate_hz: float = 250.0, topic: str = Topics.TRAJECTORY_SETPOINT,
                 block: int = 1024) -> None:
        self.writes = (topic,)
        if not isinstance(trajectory, Trajectory):
            raise TypeError(f"trajectory must implement cufund.planning.Trajectory, got {type(trajectory).__name__}")
        self.trajectory = trajectory
        self.rate_hz = rate_hz
        self.topic = topic
        self._block = int(block)
        self.reset()

    def reset(self) -> None:
        self._t_first: float | None = None
        self._j0 = 0
        self._rows: TrajectorySamples | None = None

    def _lookup(self, t: float) -> tuple[TrajectorySamples, int]:
        if self._t_first is None:
            self._t_first = t
        j = round((t - self._t_first) * self.rate_hz)
        t_grid = self._t_first + j / self.rate_hz
        if j < 0 or abs(t_grid - t) > 1e-9:
            return self.trajectory.sample(float(t)), 0
        if self._rows is None or not (self._j0 <= j < self._j0 + self._block):
            self._j0 = j
            rows = self.trajectory.sample(self._t_first + (j + np.arange(self._block)) / self.rate_hz)
            for a in (rows.p_W, rows.v_W, rows.a_W, rows.j_W):
                a.setflags(write=False)  # rows are published as views: never written again
            self._rows = rows
        return self._rows, j - self._j0

    def update(self, t: float, state: Odometry, bus: Bus) -> None:
        s, i = self._lookup(t)
        if i == 0 and s is not self._rows:  # sampled off the grid: fresh arrays, checked as usual
            bus.publish(self.topic, TrajectorySetpoint(t, s.p_W[0], s.v_W[0], s.a_W[0], s.j_W[0], float(s.yaw[0]),
                                                       float(s.yaw_rate[0])))
            return
        # read-only views of the block (see _lookup): no copies needed
        bus.publish(self.topic, TrajectorySetpoint.trusted(t, s.p_W[i], s.v_W[i], s.a_W[i], s.j_W[i], float(s.yaw[i]),
                                                           float(s.yaw_rate[i])))
