"""A planner that publishes a precomputed trajectory as setpoints, PX4's offboard ``trajectory_setpoint``."""

from __future__ import annotations

import numpy as np

from cufund.core.components import BusView, Planner
from cufund.core.messages import Odometry, Topics, TrajectorySetpoint, TrajectoryUpdate

from .sequence import TrajectorySequence
from .trajectory import Trajectory, TrajectorySamples

__all__ = ["TrajectoryFollower", "stitched"]


class TrajectoryFollower(Planner):
    """Publishes ``trajectory`` sampled at the current time on ``topic`` at ``rate_hz``.

    The trajectory is sampled ahead in blocks of ``block`` ticks on the follower's own clock grid with one
    vectorised call, so each tick only looks its row up (off-grid times are sampled directly).

    With ``update_topic`` (e.g. ``Topics.TRAJECTORY_UPDATE``) it also stitches the
    :class:`~cufund.core.messages.TrajectoryUpdate` messages of a replanner: each new trajectory replaces the followed
    one from its own ``t_start`` on (what was planned after that time is dropped; what came before is kept). The
    replanner makes the join continuous by starting the new trajectory from the old one's state at ``t_start``.
    """

    name = "trajectory_follower"

    def __init__(
        self,
        trajectory: Trajectory,
        rate_hz: float = 250.0,
        topic: str = Topics.TRAJECTORY_SETPOINT,
        block: int = 1024,
        update_topic: str | None = None,
    ) -> None:
        self.writes = (topic,)
        self.update_topic = update_topic
        self.optional_reads = () if update_topic is None else (update_topic,)
        if not isinstance(trajectory, Trajectory):
            raise TypeError(f"trajectory must implement cufund.planning.Trajectory, got {type(trajectory).__name__}")
        self.initial_trajectory = trajectory
        self.trajectory: Trajectory = trajectory
        self.rate_hz = rate_hz
        self.topic = topic
        self._block = int(block)
        self.reset()

    def reset(self) -> None:
        self.trajectory = self.initial_trajectory
        self.updates = 0
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

    def setup(self, bus: BusView) -> None:
        if self.update_topic is not None:
            self._updates = bus.subscribe(self.update_topic)

    def stitch(self, t: float, new: Trajectory) -> None:
        """Follow ``new`` from its ``t_start`` on (see :func:`stitched`)."""
        self.trajectory = stitched(self.trajectory, new, t)
        self.updates += 1
        self._rows = None  # the sampled block belongs to the old trajectory

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        if self.update_topic is not None:
            msg: TrajectoryUpdate
            for msg in self._updates.take():
                self.stitch(t, msg.trajectory)
        s, i = self._lookup(t)
        if i == 0 and s is not self._rows:  # sampled off the grid: fresh arrays, checked as usual
            bus.publish(
                self.topic,
                TrajectorySetpoint(t, s.p_W[0], s.v_W[0], s.a_W[0], s.j_W[0], float(s.yaw[0]), float(s.yaw_rate[0])),
            )
            return
        # read-only views of the block (see _lookup): no copies needed
        bus.publish(
            self.topic,
            TrajectorySetpoint.trusted(
                t, s.p_W[i], s.v_W[i], s.a_W[i], s.j_W[i], float(s.yaw[i]), float(s.yaw_rate[i])
            ),
        )


def stitched(current: Trajectory, new: Trajectory, t: float) -> Trajectory:
    """``current`` until ``new.t_start``, ``new`` from then on; parts of ``current`` that start at or after
    ``new.t_start`` are dropped, and so are those that serve no time from ``t`` [s] on."""
    if not isinstance(new, Trajectory):
        raise TypeError(f"a trajectory update must carry a cufund.planning.Trajectory, got {type(new).__name__}")
    t_new = float(new.t_start)
    parts = current.parts if isinstance(current, TrajectorySequence) else [current]
    kept = [p for p in parts if float(p.t_start) < t_new]
    starts = [float(p.t_start) for p in kept] + [t_new]
    first = 0
    while first < len(kept) and starts[first + 1] <= t:  # superseded before t
        first += 1
    return TrajectorySequence([*kept[first:], new]) if first < len(kept) else new
