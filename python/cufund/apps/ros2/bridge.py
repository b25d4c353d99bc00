"""The ROS 2 bridge component: cufund's topics out as ROS 2 messages over DDS, ROS 2 commands in, lockstep.

Each step (at ``rate_hz``, on simulated time) the bridge publishes every message that became visible on its
topics since the last step, in order, then ``/clock`` at the step's time. With ``lockstep`` and
``lockstep_nodes``, it then waits until each of those nodes has *answered* the step: published on
``/cufund/step_ack`` a ``std_msgs/msg/Header`` whose ``frame_id`` is the node's name and whose ``stamp`` is at or
after the step's ``/clock`` (a node answers after it has handled everything stamped up to then and published its
own outputs for it). Before the first step each node announces itself with an answer stamped -1 s (any answer
before the run counts), sent once its subscriptions have matched the bridge's publishers. A node silent for
``timeout_s`` of wall-clock time ends the run with :class:`Ros2Timeout` naming it, never a hang. Commands the
nodes sent before their answer are applied at that step, so a run's results do not depend on how fast the nodes
are. Without lockstep, commands are applied at the step they are found; ``realtime`` paces steps to the wall clock.

Commands go to the scenario's commander (``planner: commander``), as a ground station's do: a
``geometry_msgs/PoseStamped`` goal is a go-to (on the ground: arm, take off, fly there as a one-item mission); a
``nav_msgs/Path`` a mission through its poses; a ``trajectory_msgs/MultiDOFJointTrajectory`` offboard position
setpoints at each point's time; a ``quadrotor_msgs/PositionCommand`` an offboard position setpoint with its velocity;
PX4's ``VehicleCommand`` arms, disarms, takes off, lands and switches to offboard (``DO_SET_MODE`` with custom main
mode 6), ``TrajectorySetpoint`` (NED, as PX4 reads it) is an offboard setpoint while ``OffboardControlMode`` comes at
least every 0.5 s (PX4's ``COM_OF_LOSS_T``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.components import BusView, Component

from . import encode
from .answers import Ros2Timeout, StepAnswers
from .config import ACK_TOPIC, COMMAND_TOPICS, Ros2Params
from .dds import QOS, DdsParticipant, QosProfile

__all__ = ["Out", "Ros2Bridge", "Ros2Timeout"]

NS = 1_000_000_000
OFFBOARD_LOSS_S = 0.5
"""PX4's COM_OF_LOSS_T: offboard setpoints count only while OffboardControlMode came this recently [s]."""


@dataclass
class Out:
    """One published stream: cufund topic -> ROS 2 topics (a message may give several, e.g. odometry and /tf)."""

    topic: str
    """The cufund topic read."""
    writes: list[tuple[str, str, QosProfile]]
    """(ROS 2 name, ROS 2 type, QoS) of each ROS 2 topic written."""
    encode: Callable[[Any], list[bytes]]
    """The message -> one CDR payload per entry of ``writes``."""
    latest_only: bool = False
    """Publish the newest message at each bridge step instead of every message (the ground truth, which the
    simulator publishes at every instant a component runs)."""


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * NS + int(stamp.nanosec)


class Ros2Bridge(Component):
    """See the module doc. Built by the ``ros2`` scenario key (:mod:`cufund.apps.ros2.kinds`)."""

    name = "ros2_bridge"
    reads_truth = True  # a simulator-side component, like Gazebo's: it serves the truth topics it is told to

    def __init__(
        self,
        params: Ros2Params,
        outs: list[Out],
        static_tf: list[tuple[str, str, Any, Any]],
        commander: Any = None,
        rate_hz: float = 100.0,
    ) -> None:
        self.params = params
        self.outs = outs
        self.static_tf = static_tf
        self.commander = commander
        self.rate_hz = rate_hz
        self.optional_inputs = tuple(dict.fromkeys(o.topic for o in outs))
        self.dds: DdsParticipant | None = None
        self.stats = {"steps": 0, "messages": 0, "bytes": 0, "wait_s": 0.0, "commands": 0}

    # -- lifecycle ---------------------------------------------------------------------------------------------
    def reset(self) -> None:
        if self.dds is None:
            self._open()
        else:  # a new run on the same participant: the nodes stay matched; answers of the last run are dropped
            self._answers.new_run()
            for reader in self._readers.values():
                reader.take(N=10_000)
        self._offboard_mode_ns: int | None = None  # sim time of the last OffboardControlMode
        self._offboard_wanted = False  # VehicleCommand DO_SET_MODE offboard received
        self._scheduled: list[tuple[int, dict[str, Any]]] = []  # (sim ns, command) from trajectories
        self._wall0: float | None = None
        self._started = False
        self._last_t: dict[str, float] = {}
        self.stats = {"steps": 0, "messages": 0, "bytes": 0, "wait_s": 0.0, "commands": 0, "ready_s": 0.0}

    def _open(self) -> None:
        p = self.params
        self.dds = DdsParticipant(p.domain_id, p.expose)
        self._writers: dict[str, Any] = {}
        for o in self.outs:
            for name, rtype, qos in o.writes:
                if name not in self._writers:
                    self._writers[name] = self.dds.writer(name, rtype, qos)
        self._out_writers = [[self._writers[name] for name, _, _ in o.writes] for o in self.outs]
        self._clock = self.dds.writer("/clock", "rosgraph_msgs/msg/Clock", QOS["clock"])
        self._tf_static = self.dds.writer("/tf_static", "tf2_msgs/msg/TFMessage", QOS["tf_static"])
        self._answers = StepAnswers(self.dds, p.timeout_s)
        self._readers: dict[str, Any] = {}
        if self.commander is not None:
            names = {**{k: v[0] for k, v in COMMAND_TOPICS.items()}, **p.commands}
            for key, (_, rtype) in COMMAND_TOPICS.items():
                if names[key]:
                    self._readers[key] = self.dds.reader(names[key], rtype, QOS["default"])

    def setup(self, bus: BusView) -> None:
        self._subs = [(o, None if o.latest_only else bus.subscribe(o.topic)) for o in self.outs]

    def close(self) -> None:
        if self.dds is not None:
            self.dds.close()
            self.dds = None

    # -- the step ----------------------------------------------------------------------------------------------
    def step(self, t: float, bus: BusView) -> None:
        if self.dds is None:
            raise RuntimeError("ros2 bridge: step before reset")
        t_ns = round(t * NS)
        if not self._started:
            self._started = True
            w0 = time.perf_counter()
            self._wait_ready()
            self.stats["ready_s"] = time.perf_counter() - w0  # discovery and the nodes' start
            self._tf_static.write(encode.tf(t, self.static_tf))
            self._wall0 = time.perf_counter() - t
        if self.params.realtime and self._wall0 is not None:
            ahead = self._wall0 + t - time.perf_counter()
            if ahead > 0:
                time.sleep(ahead)
        for (o, sub), writers in zip(self._subs, self._out_writers, strict=True):
            if sub is None:
                newest = bus.latest(o.topic)
                fresh = newest is not None and newest.t > self._last_t.get(o.topic, -math.inf)
                if fresh:
                    self._last_t[o.topic] = newest.t
                messages = [newest] if fresh else []
            else:
                messages = sub.take()
            if not messages or not any(w.matched() for w in writers):
                continue  # nobody reads it: not encoded (a volatile sample reaches only the readers matched by then)
            for m in messages:
                for w, data in zip(writers, o.encode(m), strict=True):
                    w.write(data)
                    self.stats["messages"] += 1
                    self.stats["bytes"] += len(data)
        self._clock.write(encode.clock(t))
        if self.params.lockstep and self.params.lockstep_nodes:
            self._wait_answers(t_ns, t)
        self._take_commands(t_ns)
        self.stats["steps"] += 1

    def _wait(self, ok: Callable[[], bool], what: Callable[[], str]) -> None:
        self.stats["wait_s"] += self._answers.wait(ok, what)

    def _wait_ready(self) -> None:
        nodes = self.params.lockstep_nodes if self.params.lockstep else ()
        if not nodes:
            return
        announced = self._answers.announced
        self._wait(
            lambda: all(n in announced for n in nodes),
            lambda: (
                f"ros2 lockstep: node(s) {', '.join(n for n in nodes if n not in announced)} did not announce "
                f"themselves on {ACK_TOPIC} within {self.params.timeout_s:g} s (domain {self.params.domain_id}); "
                "is the node running, on the same ROS_DOMAIN_ID, and on this host?"
            ),
        )

    def _wait_answers(self, t_ns: int, t: float) -> None:
        nodes, answered = self.params.lockstep_nodes, self._answers.answered
        self._wait(
            lambda: all(answered(n, t_ns) for n in nodes),
            lambda: (
                f"ros2 lockstep: node(s) {', '.join(n for n in nodes if not answered(n, t_ns))} did not "
                f"answer the step at t = {t:.6f} s on {ACK_TOPIC} within {self.params.timeout_s:g} s"
            ),
        )

    # -- commands ----------------------------------------------------------------------------------------------
    def _submit(self, cmd: dict[str, Any]) -> None:
        assert self.commander is not None
        self.commander.submit(cmd)
        self.stats["commands"] += 1

    def _take_commands(self, t_ns: int) -> None:
        if self.commander is None:
            return
        self._take_scheduled_now(t_ns)
        for key, reader in self._readers.items():
            for s in reader.take(N=256):
                info = getattr(s, "sample_info", None)
                if info is not None and not info.valid_data:
                    continue
                try:
                    getattr(self, f"_on_{key}")(s, t_ns)
                except ValueError as e:  # a malformed command is refused (an event), as the commander refuses one
                    self.commander.events.append(t_ns / NS, "denied", f"ros2 {key}: {e}")

    def _on_ground(self) -> bool:
        return bool(self.commander.landed)

    def _on_goal(self, s: Any, t_ns: int) -> None:
        p = [s.pose.position.x, s.pose.position.y, s.pose.position.z]
        o = s.pose.orientation
        yaw = math.atan2(2 * (o.w * o.z + o.x * o.y), 1 - 2 * (o.y * o.y + o.z * o.z))
        if self._on_ground():
            self._submit({"command": "arm"})
            self._submit({"command": "mission_upload", "items": [{"p_W": p, "yaw": yaw}]})
            self._submit({"command": "mission_start"})
        else:
            self._submit({"command": "goto", "p_W": p, "yaw": yaw})

    def _on_path(self, s: Any, t_ns: int) -> None:
        items = []
        for ps in s.poses:
            o = ps.pose.orientation
            yaw = math.atan2(2 * (o.w * o.z + o.x * o.y), 1 - 2 * (o.y * o.y + o.z * o.z))
            items.append({"p_W": [ps.pose.position.x, ps.pose.position.y, ps.pose.position.z], "yaw": yaw})
        if not items:
            return
        if self._on_ground():
            self._submit({"command": "arm"})
        self._submit({"command": "mission_upload", "items": items})
        self._submit({"command": "mission_start"})

    def _on_trajectory(self, s: Any, t_ns: int) -> None:
        start = _ns(s.header.stamp) if _ns(s.header.stamp) > 0 else t_ns
        for pt in s.points:
            if not pt.transforms:
                continue
            tr = pt.transforms[0]
            q = tr.rotation
            yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
            cmd: dict[str, Any] = {
                "command": "offboard_position",
                "p_W": [tr.translation.x, tr.translation.y, tr.translation.z],
                "yaw": yaw,
            }
            if pt.velocities:
                v = pt.velocities[0].linear
                cmd["v_W"] = [v.x, v.y, v.z]
            self._scheduled.append((start + _ns(pt.time_from_start), cmd))
        self._scheduled.sort(key=lambda x: x[0])
        self._take_scheduled_now(t_ns)

    def _take_scheduled_now(self, t_ns: int) -> None:
        while self._scheduled and self._scheduled[0][0] <= t_ns:
            self._submit(self._scheduled.pop(0)[1])

    def _on_position_command(self, s: Any, t_ns: int) -> None:
        self._submit(
            {
                "command": "offboard_position",
                "p_W": [s.position.x, s.position.y, s.position.z],
                "v_W": [s.velocity.x, s.velocity.y, s.velocity.z],
                "yaw": float(s.yaw),
            }
        )

    def _on_px4_offboard_control_mode(self, s: Any, t_ns: int) -> None:
        self._offboard_mode_ns = t_ns

    def _on_px4_vehicle_command(self, s: Any, t_ns: int) -> None:
        c = int(s.command)
        if c == 400:  # VEHICLE_CMD_COMPONENT_ARM_DISARM
            self._submit({"command": "arm"} if s.param1 >= 0.5 else {"command": "disarm", "force": s.param2 == 21196})
        elif c == 176:  # VEHICLE_CMD_DO_SET_MODE: param1 custom mode flag, param2 main mode (6: offboard)
            self._offboard_wanted = int(round(s.param2)) == 6
        elif c == 22:  # VEHICLE_CMD_NAV_TAKEOFF
            self._submit({"command": "takeoff"})
        elif c == 21:  # VEHICLE_CMD_NAV_LAND
            self._submit({"command": "land"})
        elif c == 20:  # VEHICLE_CMD_NAV_RETURN_TO_LAUNCH
            self._submit({"command": "rtl"})

    def _on_px4_trajectory_setpoint(self, s: Any, t_ns: int) -> None:
        fresh = self._offboard_mode_ns is not None and t_ns - self._offboard_mode_ns <= OFFBOARD_LOSS_S * NS
        if not (self._offboard_wanted and fresh):
            return  # PX4 ignores setpoints outside offboard mode or without the offboard heartbeat
        ned = np.asarray(s.position, dtype=float)
        vel = np.asarray(s.velocity, dtype=float)
        yaw = float(s.yaw)
        enu_yaw = None if not math.isfinite(yaw) else math.atan2(math.cos(yaw), math.sin(yaw))  # pi/2 - yaw
        if np.all(np.isfinite(ned)):
            cmd: dict[str, Any] = {"command": "offboard_position", "p_W": [ned[1], ned[0], -ned[2]]}
            if np.all(np.isfinite(vel)):
                cmd["v_W"] = [vel[1], vel[0], -vel[2]]
        elif np.all(np.isfinite(vel)):
            cmd = {"command": "offboard_velocity", "v_W": [vel[1], vel[0], -vel[2]]}
        else:
            return
        if enu_yaw is not None:
            cmd["yaw"] = enu_yaw
        self._submit(cmd)
