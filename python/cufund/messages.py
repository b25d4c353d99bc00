"""Typed messages that components exchange on named topics (the paper's ROS messages, without ROS).

Every message carries the simulated time ``t`` [s] at which it was produced. Arrays are float64 numpy arrays;
frames follow the names (``_W`` world ENU, ``_B`` body FLU), quaternions are ``[w, x, y, z]``. Messages are
frozen: a component that wants to change one publishes a new one.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ActuatorCommand", "AirPressure", "AttitudeSetpoint", "FlightMode", "FlightModeCommand", "GpsFix", "Imu",
    "MagneticField", "Odometry", "PointCloud",
    "RateSetpoint", "ThrustTorqueSetpoint", "TrajectorySetpoint", "Topics",
]


class Topics:
    """Default topic names used by the built-in components."""

    GROUND_TRUTH = "/ground_truth/odometry"
    """Exact vehicle state, published by the simulator every physics step at which any component runs."""
    ESTIMATE = "/estimator/odometry"
    TRAJECTORY_SETPOINT = "/setpoint/trajectory"
    ATTITUDE_SETPOINT = "/setpoint/attitude"
    """Attitude and thrust from the position controller (or the user in attitude mode)."""
    MANUAL_ATTITUDE_SETPOINT = "/setpoint/attitude_manual"
    """Attitude and thrust commanded by a user or planner in attitude mode."""
    RATE_SETPOINT = "/setpoint/rates"
    THRUST_TORQUE_SETPOINT = "/setpoint/thrust_torque"
    ACTUATOR_COMMAND = "/actuator/command"
    FLIGHT_MODE = "/commander/flight_mode"
    IMU = "/sensors/imu"
    MAGNETOMETER = "/sensors/magnetometer"
    BAROMETER = "/sensors/barometer"
    GPS = "/sensors/gps"
    POINT_CLOUD = "/sensors/point_cloud"


class FlightMode(enum.Enum):
    """Which references the flight controller tracks (paper §2.3)."""

    POSITION = "position"
    """Position, with velocity, acceleration and yaw-rate feed-forward."""
    VELOCITY = "velocity"
    """Velocity, with acceleration feed-forward; position is not controlled."""
    ATTITUDE = "attitude"
    """Attitude and collective thrust."""


@dataclass(frozen=True, slots=True)
class Odometry:
    """Vehicle state estimate (or ground truth)."""

    t: float
    p_W: np.ndarray
    """Position [m], (3,)."""
    v_W: np.ndarray
    """Velocity [m/s], (3,)."""
    q_WB: np.ndarray
    """Attitude, body to world, [w, x, y, z]."""
    w_B: np.ndarray
    """Body rate [rad/s], (3,)."""
    a_W: np.ndarray | None = None
    """Acceleration [m/s^2], (3,): set on ground truth (the model's true acceleration, which inertial sensors
    read); None where the source does not know it."""
    alpha_B: np.ndarray | None = None
    """Angular acceleration [rad/s^2], (3,): set on ground truth, else None."""


@dataclass(frozen=True, slots=True)
class Imu:
    """Specific force and angular rate in the IMU's own frame I (the body frame when the IMU is mounted
    without rotation; its mounting, ``q_BI`` and lever arm ``p_BI``, is the estimator's extrinsic)."""

    t: float
    f_I: np.ndarray
    """Specific force (accelerometer) [m/s^2], (3,)."""
    w_I: np.ndarray
    """Angular rate (gyroscope) [rad/s], (3,)."""


@dataclass(frozen=True, slots=True)
class MagneticField:
    """Magnetometer sample in the body frame (the magnetometer is mounted along the body axes)."""

    t: float
    m_B: np.ndarray
    """Magnetic flux density [T], (3,)."""


@dataclass(frozen=True, slots=True)
class AirPressure:
    """Barometer sample."""

    t: float
    pressure_pa: float
    """Static pressure [Pa]."""
    altitude_m: float
    """Height above the world origin from the pressure, by the standard atmosphere [m]."""
    temperature_k: float
    """Air temperature [K]."""


@dataclass(frozen=True, slots=True)
class GpsFix:
    """One GNSS receiver output (like PX4's ``sensor_gps``)."""

    t: float
    """Measurement time [s] (the message arrives the receiver's latency later)."""
    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    """WGS-84 ellipsoidal height [m]."""
    v_W: np.ndarray
    """Velocity, east-north-up [m/s], (3,)."""
    fix_type: int
    """0: no fix (position and velocity NaN), 3: 3-D fix."""
    satellites: int
    eph: float
    """Horizontal position accuracy (1 sigma) the receiver claims [m]."""
    epv: float
    """Vertical position accuracy (1 sigma) [m]."""


@dataclass(frozen=True, slots=True)
class PointCloud:
    """One LiDAR frame: the valid returns, each stamped with its own firing time (what
    :class:`cufund.sensors.LidarComponent` publishes on ``Topics.POINT_CLOUD``)."""

    t0: float
    """Frame start time [s]."""
    t: np.ndarray
    """(N,) firing time of each point [s] (absolute, t0 <= t < t0 + period)."""
    points_L: np.ndarray
    """(N, 3) float32 points in the LiDAR frame at their own firing time (what a driver reports:
    motion-distorted when the sensor moves during the frame) [m]."""
    points_W: np.ndarray
    """(N, 3) float32 noise-free hit points in the world frame (ground truth) [m]."""
    ranges: np.ndarray
    """(N,) measured ranges, noise included [m]."""
    intensity: np.ndarray
    """(N,) reflectivity × |cos(incidence angle)| in [0, 1]."""
    channel: np.ndarray
    """(N,) laser channel (ring) index."""
    object_ids: np.ndarray
    """(N,) id of the world object hit (geometry id of the scene)."""
    frame: int
    """Frame index of the pattern."""

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True, slots=True)
class TrajectorySetpoint:
    """A point of a trajectory, PX4's ``trajectory_setpoint``: position mode uses all fields, velocity mode
    ignores ``p_W``."""

    t: float
    p_W: np.ndarray
    """Position [m], (3,)."""
    v_W: np.ndarray
    """Velocity [m/s], (3,)."""
    a_W: np.ndarray
    """Acceleration feed-forward [m/s^2], (3,)."""
    j_W: np.ndarray
    """Jerk feed-forward [m/s^3], (3,); used by the geometric controller for the desired body rate."""
    yaw: float
    """Heading [rad]."""
    yaw_rate: float
    """Heading rate feed-forward [rad/s]."""


@dataclass(frozen=True, slots=True)
class AttitudeSetpoint:
    """Attitude and collective thrust, PX4's ``vehicle_attitude_setpoint``."""

    t: float
    q_WB: np.ndarray
    """Desired attitude [w, x, y, z]."""
    thrust: float
    """Collective thrust [N] along body +z."""
    yaw_rate: float = 0.0
    """Yaw-rate feed-forward [rad/s]."""


@dataclass(frozen=True, slots=True)
class RateSetpoint:
    """Body rates and collective thrust, PX4's ``vehicle_rates_setpoint``."""

    t: float
    w_B: np.ndarray
    """Desired body rate [rad/s], (3,)."""
    thrust: float
    """Collective thrust [N]."""


@dataclass(frozen=True, slots=True)
class ThrustTorqueSetpoint:
    """Collective thrust and body torque, the input of control allocation."""

    t: float
    thrust: float
    """[N] along body +z."""
    torque_B: np.ndarray
    """[N m], (3,)."""


@dataclass(frozen=True, slots=True)
class ActuatorCommand:
    """Rotor speed commands, PX4 numbering; the simulator holds the latest one over each physics step."""

    t: float
    rotor_speeds: np.ndarray
    """[rad/s], (4,)."""


@dataclass(frozen=True, slots=True)
class FlightModeCommand:
    """Switches the flight controller's mode."""

    t: float
    mode: FlightMode
