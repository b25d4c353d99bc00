"""The scenario key ``ros2: {...}`` (:class:`Ros2Params`): what the bridge publishes and subscribes, lockstep,
pacing and exposure. Plain validated data; nothing here opens a socket."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from cufund.core.config import ConfigError

__all__ = ["ACK_TOPIC", "Ros2Params"]

ACK_TOPIC = "/cufund/step_ack"
"""Where lockstep nodes answer (``std_msgs/msg/Header``: ``stamp`` the ``/clock`` answered, ``frame_id`` the
node's name)."""


def _name(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value.startswith("/") or value.endswith("/") or "//" in value:
        raise ConfigError(f"{where} must be an absolute ROS 2 topic name like /imu, got {value!r}")
    return value


@dataclass(frozen=True)
class Ros2Params:
    """The ROS 2 bridge of a scenario (``ros2: {...}``; ``cufund ros2 SCENARIO`` adds it with defaults)."""

    domain_id: int = 0
    """The DDS domain (ROS_DOMAIN_ID), 0..232."""
    topics: dict[str, str] = field(default_factory=dict)
    """cufund topic -> ROS 2 name, replacing the defaults (``/sensors/imu: /imu``, a LiDAR ``/livox/lidar``,
    ``/truth/odometry: /truth/odom``, ``/estimator/odometry: /estimator/odom``); an empty name leaves the topic
    out."""
    commands: dict[str, str] = field(default_factory=dict)
    """Subscribed command topics (``goal``, ``path``, ``trajectory``, ``position_command``,
    ``px4_trajectory_setpoint``, ``px4_offboard_control_mode``, ``px4_vehicle_command``) -> ROS 2 name, replacing
    the defaults (``/goal_pose``, ``/path``, ``/command/trajectory``, ``/position_cmd``, ``/fmu/in/...``); an empty
    name leaves it out. Commands need ``planner: commander``."""
    lockstep: bool = True
    """Simulated time advances only when every node of ``lockstep_nodes`` has answered each step."""
    lockstep_nodes: tuple[str, ...] = ()
    """Names of the nodes that answer each step on ``/cufund/step_ack`` (none: nothing to wait for)."""
    timeout_s: float = 10.0
    """A lockstep node that has not answered within this wall-clock time ends the run with an error [s]."""
    realtime: bool = False
    """Pace simulated time to the wall clock (otherwise as fast as the nodes answer)."""
    expose: bool = False
    """Let DDS discovery and traffic leave this host (every interface, multicast); default loopback only."""
    rate_hz: float | None = None
    """Bridge steps per simulated second (each publishes what became visible since the last and /clock); null:
    the fastest IMU's rate, else 100 Hz."""

    def __post_init__(self) -> None:
        d = self.domain_id
        if isinstance(d, bool) or not isinstance(d, int) or not 0 <= d <= 232:
            raise ConfigError(f"ros2.domain_id must be an integer in [0, 232] (ROS_DOMAIN_ID), got {d!r}")
        for key in ("lockstep", "realtime", "expose"):
            if not isinstance(getattr(self, key), bool):
                raise ConfigError(f"ros2.{key} must be true or false, got {getattr(self, key)!r}")
        for key in ("topics", "commands"):
            value = getattr(self, key)
            if not isinstance(value, dict):
                raise ConfigError(f"ros2.{key} must be a mapping of names to ROS 2 topic names, got {value!r}")
            out = {}
            for k, v in value.items():
                if not isinstance(k, str) or not k:
                    raise ConfigError(f"ros2.{key}: a key must be a non-empty name, got {k!r}")
                if key == "commands" and k not in COMMAND_TOPICS:
                    raise ConfigError(
                        f"ros2.commands: unknown command {k!r}; expected one of {', '.join(COMMAND_TOPICS)}"
                    )
                out[k] = "" if v in ("", None) else _name(v, f"ros2.{key}.{k}")
            object.__setattr__(self, key, out)
        nodes = self.lockstep_nodes
        if isinstance(nodes, str) or not all(isinstance(n, str) and n for n in nodes):
            raise ConfigError(f"ros2.lockstep_nodes must be a list of node names, got {nodes!r}")
        object.__setattr__(self, "lockstep_nodes", tuple(nodes))
        t = self.timeout_s
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) or not 0 < t <= 3600:
            raise ConfigError(f"ros2.timeout_s must be a number of seconds in (0, 3600], got {t!r}")
        object.__setattr__(self, "timeout_s", float(t))
        r = self.rate_hz
        if r is not None:
            if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r) or not 0 < r <= 10_000:
                raise ConfigError(f"ros2.rate_hz must be a rate in (0, 10000] [Hz] or null, got {r!r}")
            object.__setattr__(self, "rate_hz", float(r))


COMMAND_TOPICS = {
    "goal": ("/goal_pose", "geometry_msgs/msg/PoseStamped"),
    "path": ("/path", "nav_msgs/msg/Path"),
    "trajectory": ("/command/trajectory", "trajectory_msgs/msg/MultiDOFJointTrajectory"),
    "position_command": ("/position_cmd", "quadrotor_msgs/msg/PositionCommand"),
    "px4_trajectory_setpoint": ("/fmu/in/trajectory_setpoint", "px4_msgs/msg/TrajectorySetpoint"),
    "px4_offboard_control_mode": ("/fmu/in/offboard_control_mode", "px4_msgs/msg/OffboardControlMode"),
    "px4_vehicle_command": ("/fmu/in/vehicle_command", "px4_msgs/msg/VehicleCommand"),
}
"""The command topics the bridge subscribes to: default ROS 2 name and type (RViz's goal, a path, RotorS's
trajectory, EGO-Planner's position command, PX4's offboard topics)."""
