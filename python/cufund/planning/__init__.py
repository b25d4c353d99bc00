"""Trajectories and planners (paper §3.1)."""

from ..components import Planner
from .minimum_snap import MinimumSnapTrajectory, allocate_segment_times, min_derivative_spline
from .point_to_point import JerkLimitedMove
from .sequence import Hold, TrajectorySequence
from .trajectory import Trajectory, TrajectorySamples
from .trajectory_follower import TrajectoryFollower

__all__ = ["Hold", "JerkLimitedMove", "MinimumSnapTrajectory", "TrajectorySequence", "Planner", "Trajectory", "TrajectoryFollower", "TrajectorySamples",
           "allocate_segment_times", "min_derivative_spline"]
