"""``ros2_external``: an estimator, mapper, planner or controller that is a ROS 2 node over DDS.

The component runs at ``rate_hz`` like any other. At each step at simulated time t it publishes to the node every
message that became visible on its ``reads`` since the last step (as the bridge encodes them), then ``/clock`` t,
then waits until the node has *answered* t (the bridge's contract: a ``std_msgs/msg/Header`` on
``/cufund/step_ack`` with ``frame_id`` the node's name and ``stamp`` >= t), and publishes on the cufund bus what
the node sent on its ``writes`` by then (with the part's ``latency_s``). The node announces itself before the first
step (an answer stamped -1 s). A node silent for ``timeout_s`` of wall-clock time ends the run with
:class:`~cufund.apps.ros2.bridge.Ros2Timeout` naming it. Like any flight software, it may not read ``/truth/`` topics
when an estimator is configured (the scenario's wiring check refuses it).

What a node may write, by the cufund topic's message: :class:`~cufund.core.messages.Odometry` from
``nav_msgs/msg/Odometry`` (pose in the world, twist in the body frame, REP 105), and
:class:`~cufund.core.messages.TrajectorySetpoint` from ``quadrotor_msgs/msg/PositionCommand``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.core.components import BusView, Component, Estimator
from cufund.core.config import ConfigError
from cufund.core.messages import Odometry, TrajectorySetpoint
from cufund.geometry import quat_to_matrix

from .config import ACK_TOPIC, _name
from .encode import encoder_for

__all__ = ["ExternalComponent", "ExternalEstimator", "ExternalParams", "decoder_for", "encoder_for"]

NS = 1_000_000_000


@dataclass(frozen=True)
class ExternalParams:
    """A ROS 2 node as a scenario part (kind ``ros2_external`` of estimator, mapper, planner or controller)."""

    node: str = ""
    """The node's name: the ``frame_id`` of its answers on ``/cufund/step_ack``."""
    reads: dict[str, str] = field(default_factory=dict)
    """cufund topic -> the ROS 2 name it is published to the node on (e.g. ``/sensors/imu: /imu``)."""
    writes: dict[str, str] = field(default_factory=dict)
    """cufund topic -> the ROS 2 name the node publishes it on (e.g. ``/estimator/odometry: /Odometry``)."""
    rate_hz: float = 100.0
    """Steps per simulated second [Hz]."""
    timeout_s: float = 10.0
    """Wall-clock time the node may take to answer a step [s]."""
    domain_id: int = 0
    """The DDS domain (ROS_DOMAIN_ID)."""
    expose: bool = False
    """Let DDS leave this host (default: loopback only)."""

    def __post_init__(self) -> None:
        if not isinstance(self.node, str):
            raise ConfigError(f"ros2_external.node must be the node's name, got {self.node!r}")
        for key in ("reads", "writes"):
            value = getattr(self, key)
            if not isinstance(value, dict) or not all(isinstance(k, str) and k.startswith("/") for k in value):
                raise ConfigError(f"ros2_external.{key} must map cufund topics to ROS 2 names (/a: /b), got {value!r}")
            for k, v in value.items():  # a name DDS would refuse only when the run starts is refused here
                _name(v, f"ros2_external.{key}.{k}")
        for key, hi in (("rate_hz", 10_000.0), ("timeout_s", 3600.0)):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v <= hi:
                raise ConfigError(f"ros2_external.{key} must be a number in (0, {hi:g}], got {v!r}")
            object.__setattr__(self, key, float(v))
        d = self.domain_id
        if isinstance(d, bool) or not isinstance(d, int) or not 0 <= d <= 232:
            raise ConfigError(f"ros2_external.domain_id must be an integer in [0, 232] (ROS_DOMAIN_ID), got {d!r}")
        if not isinstance(self.expose, bool):
            raise ConfigError(f"ros2_external.expose must be true or false, got {self.expose!r}")


def _t(stamp: Any) -> float:
    return (int(stamp.sec) * NS + int(stamp.nanosec)) / NS


def _odometry(s: Any) -> Odometry:
    o = s.pose.pose.orientation
    q = np.array([o.w, o.x, o.y, o.z], dtype=float)
    v_B = np.array([s.twist.twist.linear.x, s.twist.twist.linear.y, s.twist.twist.linear.z], dtype=float)
    return Odometry(
        t=_t(s.header.stamp),
        p_W=np.array([s.pose.pose.position.x, s.pose.pose.position.y, s.pose.pose.position.z], dtype=float),
        v_W=quat_to_matrix(q, normalize=True) @ v_B,
        q_WB=q,
        w_B=np.array([s.twist.twist.angular.x, s.twist.twist.angular.y, s.twist.twist.angular.z], dtype=float),
    )


def _setpoint(s: Any) -> TrajectorySetpoint:
    return TrajectorySetpoint(
        t=_t(s.header.stamp),
        p_W=np.array([s.position.x, s.position.y, s.position.z], dtype=float),
        v_W=np.array([s.velocity.x, s.velocity.y, s.velocity.z], dtype=float),
        a_W=np.array([s.acceleration.x, s.acceleration.y, s.acceleration.z], dtype=float),
        j_W=np.array([s.jerk.x, s.jerk.y, s.jerk.z], dtype=float),
        yaw=float(s.yaw),
        yaw_rate=float(s.yaw_dot),
    )


def decoder_for(cls: type) -> tuple[str, Callable[[Any], Any]] | None:
    """(ROS 2 type, decoder) of what a node publishes for a cufund message class, or None."""
    if cls is Odometry:
        return "nav_msgs/msg/Odometry", _odometry
    if cls is TrajectorySetpoint:
        return "quadrotor_msgs/msg/PositionCommand", _setpoint
    return None


class ExternalComponent(Component):
    """See the module doc. ``reads``: (cufund topic, ROS 2 name, ROS 2 type, encoder); ``writes``: (cufund topic,
    ROS 2 name, ROS 2 type, decoder)."""

    def __init__(
        self,
        params: ExternalParams,
        reads: list[tuple[str, str, str, Callable[[Any], bytes]]],
        writes: list[tuple[str, str, str, Callable[[Any], Any]]],
        name: str,
    ) -> None:
        self.params = params
        self.name = name
        self.rate_hz = params.rate_hz
        self._reads = reads
        self._writes = writes
        self.dds: Any = None

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(r[0] for r in self._reads)

    @property
    def outputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(w[0] for w in self._writes)

    def reset(self) -> None:
        from .answers import StepAnswers
        from .dds import QOS, DdsParticipant

        if self.dds is None:
            self.dds = DdsParticipant(self.params.domain_id, self.params.expose)
            self._writers = [self.dds.writer(name, rtype, QOS["default"]) for _, name, rtype, _ in self._reads]
            self._readers = [self.dds.reader(name, rtype, QOS["default"]) for _, name, rtype, _ in self._writes]
            self._clock = self.dds.writer("/clock", "rosgraph_msgs/msg/Clock", QOS["clock"])
            self._answers = StepAnswers(self.dds, self.params.timeout_s)
        else:  # a new run on the same participant: the node stays matched; what it sent for the last run is dropped
            self._answers.new_run()
            for reader in self._readers:
                reader.take(N=10_000)
        self._started = False

    def setup(self, bus: BusView) -> None:
        self._subs = [bus.subscribe(topic) for topic, _, _, _ in self._reads]

    def close(self) -> None:
        if self.dds is not None:
            self.dds.close()
            self.dds = None

    def _wait(self, ok: Callable[[], bool], what: str) -> None:
        p = self.params
        self._answers.wait(
            ok,
            lambda: (
                f"ros2_external {self.name}: node {p.node!r} did not {what} on {ACK_TOPIC} within {p.timeout_s:g} s "
                f"(domain {p.domain_id})"
            ),
        )

    def step(self, t: float, bus: BusView) -> None:
        from . import encode

        t_ns = round(t * NS)
        if not self._started:
            self._started = True
            self._wait(lambda: self.params.node in self._answers.announced, "announce itself")
        for (_, _, _, enc), writer, sub in zip(self._reads, self._writers, self._subs, strict=True):
            for m in sub.take():
                writer.write(enc(m))
        self._clock.write(encode.clock(t))
        self._wait(lambda: self._answers.answered(self.params.node, t_ns), f"answer the step at t = {t:.6f} s")
        for (topic, _, _, dec), reader in zip(self._writes, self._readers, strict=True):
            for s in reader.take(N=1000):
                info = getattr(s, "sample_info", None)
                if info is None or info.valid_data:
                    bus.publish(topic, dec(s))


class ExternalEstimator(ExternalComponent, Estimator):
    """A ROS 2 node as the estimator: its Odometry output is the state the controllers fly on."""

    def estimate(self, t: float, bus: BusView) -> Odometry | None:  # pragma: no cover - step does it all
        return None
