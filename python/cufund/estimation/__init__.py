"""LiDAR-inertial odometry on GTSAM (issue 12): :class:`LioCore` (pure: samples in, odometry out) and its
parameters :class:`LioParams`; :class:`LioEstimator`, the simulator component (registry kind ``lio``); offline flight records from the standalone sensor models in ``flight_data``."""

from .evaluation import odometry_errors, read_tum, write_tum
from .flight_data import FlatBodyMotion, FlightRecord, LidarFrame, record_flight, replay
from .lio_core import LioCore, NavEstimate, ScanDiagnostics
from .lio_estimator import LioEstimator
from .params import LioParams

__all__ = ["FlatBodyMotion", "FlightRecord", "LidarFrame", "LioCore", "LioEstimator", "LioParams", "NavEstimate", "ScanDiagnostics",
           "odometry_errors", "read_tum", "record_flight", "replay", "write_tum"]
