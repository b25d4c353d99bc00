"""cufund as PX4's simulator: :class:`Px4SimulatorBridge` plays Gazebo classic's ``mavlink_interface`` for
``px4_sitl`` (TCP, lockstep) or for a flight controller in HITL (serial, lockstep off).

Each HIL_SENSOR period (250 Hz, PX4's IMU_INTEG_RATE) the bridge's component, scheduled after the sensors it
reads, sends what is new — HIL_GPS (5 Hz), HIL_STATE_QUATERNION (ground truth, only at the interval PX4 asked for
with SET_MESSAGE_INTERVAL), a HEARTBEAT every second of simulated time, and last HIL_SENSOR, stamped with the
simulated time — and then, in lockstep, waits for PX4's HIL_ACTUATOR_CONTROLS before the physics integrates the
next period with the rotor speeds they command. Until the first controls arrive the simulation runs on (paced)
without waiting, as Gazebo does, because PX4 only starts once time flows; ``wait_first_controls`` makes every
step wait (a deterministic harness). Controls older than ``stale_controls_s`` of simulated time command the
disarmed speeds.

The vehicle, world and sensor models come from a cufund scenario with its flight software removed
(:func:`px4_scenario`): PX4 is the flight stack, cufund the world.
"""

from __future__ import annotations

import math
import struct
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from cufund.core.components import BusView, Component
from cufund.core.config import ConfigError
from cufund.core.messages import ActuatorCommand, Topics
from cufund.scenarios.build import build_simulation
from cufund.scenarios.schema import ScenarioConfig
from cufund.simulator import RunStatus, SimulationResult

from .frames import GeodeticOrigin
from .hil_codec import FrameWriter, scan_frames, take_controls
from .hil_messages import HilEncoder
from .px4_airframe import Px4Airframe
from .px4_links import GcsForward, Link, LinkClosed, TcpServerLink

__all__ = [
    "PX4_MAX_INSTANCES",
    "PX4_SENSOR_RATES",
    "Px4BridgeParams",
    "Px4SimulatorBridge",
    "px4_scenario",
    "sensor_instances",
]

#: The sensor rates PX4's simulator contract uses [Hz]; px4_scenario runs the scenario's sensors at them.
PX4_SENSOR_RATES = {"imu": 250.0, "magnetometer": 100.0, "barometer": 50.0, "gps": 5.0}
#: Instances of each sensor PX4's simulator_mavlink takes (HIL_SENSOR / HIL_GPS ``id`` 0 .. n-1).
PX4_MAX_INSTANCES = {"imu": 3, "magnetometer": 4, "barometer": 4, "gps": 2}
#: Sensor kinds added when a scenario lacks one of PX4's sensors (cufund's models, with their noise).
_DEFAULT_KINDS = {"imu": "icm42688p", "magnetometer": "magnetometer", "barometer": "ms5611", "gps": "ublox_m8n"}
_FLIGHT_SOFTWARE = ("estimator", "mapper", "planner", "controller", "mission")

MAV_CMD_SET_MESSAGE_INTERVAL = 511
MSG_ID_HIL_STATE_QUATERNION = 115
MAV_MODE_FLAG_SAFETY_ARMED = 128
MAV_RESULT_ACCEPTED, MAV_RESULT_UNSUPPORTED = 0, 3
MAV_TYPE_GENERIC, MAV_AUTOPILOT_INVALID = 0, 8


@dataclass(frozen=True)
class Px4BridgeParams:
    """How the bridge talks to PX4."""

    hil_sensor_rate_hz: float = 250.0
    """HIL_SENSOR (and lockstep) rate [Hz]; PX4 integrates its IMU at 250 Hz."""
    lockstep: bool = True
    """Wait for HIL_ACTUATOR_CONTROLS after each HIL_SENSOR (SITL). HITL runs with it off."""
    wait_first_controls: bool = False
    """Wait for controls from the very first HIL_SENSOR (a harness that answers every one); PX4 itself needs
    time to flow before it sends any, so leave this off for px4_sitl."""
    speed: float | None = 1.0
    """Simulated seconds per wall second the bridge paces to (PX4_SIM_SPEED_FACTOR's role); None: as fast as
    the peer answers."""
    controls_timeout_s: float = 1.0
    """Lockstep: wall time to wait for controls before stepping on without them (Gazebo's poll timeout) [s]."""
    stale_controls_s: float = 0.2
    """Controls older than this much simulated time command the disarmed rotor speeds [s]."""
    heartbeat_period_s: float = 1.0
    """HEARTBEAT period in simulated time [s]."""
    system_id: int = 1
    component_id: int = 200
    """MAVLink source ids of the bridge's messages (Gazebo's plugin uses 1/200)."""
    record_rate_hz: float = 50.0
    """Ground-truth samples kept in the run's result [Hz] (must divide the physics rate); sensor messages are not
    kept: a PX4 session may run for hours."""

    def __post_init__(self) -> None:
        for name in (
            "hil_sensor_rate_hz",
            "controls_timeout_s",
            "stale_controls_s",
            "heartbeat_period_s",
            "record_rate_hz",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ConfigError(f"{name} must be a number > 0, got {v!r}")
        s = self.speed
        if s is not None and (isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s) or s <= 0):
            raise ConfigError(f"speed must be a real-time factor > 0 or None (as fast as possible), got {s!r}")
        for name, hi in (("system_id", 255), ("component_id", 255)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= hi:
                raise ConfigError(f"{name} must be an integer in [0, {hi}], got {v!r}")


def px4_scenario(config: ScenarioConfig) -> ScenarioConfig:
    """``config`` as PX4's world: no estimator, mapper, planner, controller or mission (PX4 flies), and an IMU,
    magnetometer, barometer and GPS at PX4's rates (:data:`PX4_SENSOR_RATES`) — the scenario's own models when it
    has them, cufund's defaults (``icm42688p``, ``magnetometer``, ``ms5611``, ``ublox_m8n``) otherwise. The physics
    node rate is the HIL_SENSOR rate (the vehicle's own integration step is unchanged)."""
    if not isinstance(config, ScenarioConfig):
        raise TypeError(f"config must be a cufund ScenarioConfig, got {type(config).__name__}")
    data = config.to_dict()
    for group in _FLIGHT_SOFTWARE:
        data[group] = None
    # one physics step per HIL_SENSOR period (PX4 holds its outputs over it); the dynamics still integrate at the
    # vehicle's max_integration_step inside the step, so accuracy is the scenario's
    data.setdefault("rates", {})["physics_hz"] = PX4_SENSOR_RATES["imu"]
    sensors = data.get("sensors") or {}
    for stype, rate in PX4_SENSOR_RATES.items():
        names = sensor_instances(config, stype)
        if not names:
            names = [stype if stype not in sensors else f"px4_{stype}"]
            sensors[names[0]] = {"kind": _DEFAULT_KINDS[stype]}
        for name in names:
            sensors[name]["rate_hz"] = rate
    data["sensors"] = sensors
    return ScenarioConfig.from_dict(data, base_dir=config.base_dir)


def sensor_instances(config: ScenarioConfig, stype: str) -> list[str]:
    """The scenario's sensors of ``stype`` in PX4 instance order (``id`` 0 first): the one named after the type
    (e.g. ``imu``) is instance 0, the others follow in the scenario's order. Raises ConfigError past PX4's count."""
    found = [n for n, s in config.sensors.items() if s.sensor_type == stype]
    found.sort(key=lambda n: n != stype)  # stable: the named one first, the rest as declared
    if len(found) > PX4_MAX_INSTANCES[stype]:
        raise ConfigError(
            f"sensors: PX4 takes at most {PX4_MAX_INSTANCES[stype]} {stype} sensors, got "
            f"{len(found)} ({', '.join(found)})"
        )
    return found


class _Px4Port(Component):
    """The bridge inside the simulator: runs at the HIL_SENSOR rate after the sensors, exchanges with PX4 and
    publishes the commanded rotor speeds. A truth reader (HIL_STATE_QUATERNION is ground truth).

    Its first exchange is at the end of the first period, as Gazebo's first update is one step in: PX4 never sees
    time 0 (a zero timestamp means "no data" to much of PX4); that period's samples go out with it."""

    name = "px4"
    reads_truth = True

    def __init__(self, bridge: Px4SimulatorBridge, topics: dict[tuple[str, int], str], rate_hz: float) -> None:
        self.bridge = bridge
        self.topics = topics
        self.rate_hz = rate_hz
        self.optional_inputs = tuple(topics.values())
        self.outputs = (Topics.ACTUATOR_COMMAND,)

    def setup(self, bus: BusView) -> None:
        self._reads = tuple(self.topics.items())
        self._seen: dict[tuple[str, int], Any] = dict.fromkeys(self.topics)  # the last sample handed over, per input
        self._started = False

    def step(self, t: float, bus: BusView) -> None:
        if not self._started:  # the run's first instant: nothing to PX4 yet
            self._started = True
            bus.publish(Topics.ACTUATOR_COMMAND, ActuatorCommand.trusted(t, self.bridge._command(t)))
            return
        # what is new since the last period: each message is its own object, so a newest message that is not the
        # one handed over last time is new (no subscription queues to fill and empty every period)
        new = {}
        seen = self._seen
        latest = bus.latest
        for k, topic in self._reads:
            msg = latest(topic)
            if msg is not seen[k]:
                new[k] = seen[k] = msg
        truth = latest(Topics.TRUTH_ODOMETRY) if self.bridge._hsq_interval_us is not None else None
        speeds = self.bridge._exchange(t, new, truth)
        bus.publish(Topics.ACTUATOR_COMMAND, ActuatorCommand.trusted(t, speeds))  # a read-only array


class Px4SimulatorBridge:
    """Serves ``config`` (a scenario, made PX4's world by :func:`px4_scenario`) to PX4 over ``link``: a
    :class:`~cufund.apps.mavlink.px4_links.TcpServerLink` (SITL; default 127.0.0.1:4560 + ``instance``) or a
    :class:`~cufund.apps.mavlink.px4_links.SerialLink` (HITL, with ``params.lockstep`` off).

    ``simulator`` is the cufund simulator (set the initial state through ``simulator.vehicle`` before
    :meth:`run`); ``stats`` counts what went over the link. ``gcs`` (HITL): a
    :class:`~cufund.apps.mavlink.px4_links.GcsForward` relaying the flight controller's MAVLink to a ground station and
    back, since the board's USB port is the simulator's. ``built``: serve this :class:`Built` (a fleet's vehicle,
    made PX4's world already) instead of building ``config``; :meth:`connect`, advancing ``simulator`` and
    :meth:`disconnect` are then the caller's (:class:`~cufund.apps.mavlink.fleet_px4.Px4FleetBridge`).
    """

    def __init__(
        self,
        config: ScenarioConfig,
        link: Link | None = None,
        params: Px4BridgeParams | None = None,
        instance: int = 0,
        host: str = "127.0.0.1",
        airframe: Px4Airframe | None = None,
        gcs: GcsForward | None = None,
        built: Any = None,
    ) -> None:
        self.params = params if params is not None else Px4BridgeParams()
        if not isinstance(self.params, Px4BridgeParams):
            raise TypeError(f"params must be a Px4BridgeParams, got {type(self.params).__name__}")
        if isinstance(instance, bool) or not isinstance(instance, int) or not 0 <= instance <= 60000:
            raise ValueError(f"instance must be an integer in [0, 60000], got {instance!r}")
        if built is None:
            self.config = px4_scenario(config)
            self.built = build_simulation(self.config, extra_components=())
        else:  # a fleet's vehicle, built already as PX4's world (apps/mavlink/fleet_px4.py)
            self.config, self.built = built.config, built
        self.simulator = sim = self.built.simulator
        nodes = sim.physics_rate_hz / self.params.record_rate_hz
        if abs(nodes - round(nodes)) > 1e-9 or nodes < 1:
            raise ConfigError(
                f"record_rate_hz must divide the physics rate {sim.physics_rate_hz:g} Hz, "
                f"got {self.params.record_rate_hz:g}"
            )
        sim.record_period, sim.record_topics = round(nodes), ()
        assert self.simulator.vehicle is not None  # a PX4 bridge flies a vehicle (checked when it was built)
        vehicle = self.simulator.vehicle.params
        self.airframe = airframe if airframe is not None else Px4Airframe.for_vehicle(vehicle)
        rotor_of_output = self.airframe.rotor_of_output(vehicle)
        self._output_of_rotor = [int(i) for i in np.argsort(rotor_of_output)]  # PX4 output driving rotor j
        self._cmd_disarmed = np.array(self.airframe.rotor_speed_list((), False, self._output_of_rotor))
        self._cmd_disarmed.setflags(write=False)
        self.link: Any = link if link is not None else TcpServerLink(host, 4560 + instance)
        self.gcs = gcs
        self.mav = mavlink.MAVLink(None, srcSystem=self.params.system_id, srcComponent=self.params.component_id)
        self.mav.robust_parsing = True
        self.writer = FrameWriter(self.mav)
        self._rx = mavlink.MAVLink(None, srcSystem=0, srcComponent=0)
        self._rx.robust_parsing = True
        topics: dict[tuple[str, int], str] = {}
        q_BI: dict[int, Any] = {}
        for stype in PX4_SENSOR_RATES:
            for sid, name in enumerate(sensor_instances(self.config, stype)):
                spec = self.config.sensors[name]
                topics[(stype, sid)] = spec.topic
                if stype == "imu":
                    q_BI[sid] = spec.extrinsic.q if spec.extrinsic is not None else spec.params.q_BI
        self.origin = GeodeticOrigin.from_geo_point(
            self.config.sensors[sensor_instances(self.config, "gps")[0]].params.home
        )
        self._ids = sorted({sid for _, sid in topics}, reverse=True)  # instance 0 last: it closes the period
        self.encoders = {
            sid: HilEncoder(self.writer, self.origin, np.asarray(q_BI.get(sid, (1.0, 0.0, 0.0, 0.0))), sid)
            for sid in self._ids
        }
        self._gps_keys = [(("gps", sid), self.encoders[sid]) for sid in self._ids]
        self._sensor_keys = [
            (sid, self.encoders[sid], ("imu", sid), ("magnetometer", sid), ("barometer", sid)) for sid in self._ids
        ]
        self.port = _Px4Port(self, topics, self.params.hil_sensor_rate_hz)
        self.simulator.add(self.port)
        self.stats = {
            "hil_sensor": 0,
            "hil_gps": 0,
            "hil_state_quaternion": 0,
            "heartbeats_sent": 0,
            "heartbeats_received": 0,
            "controls": 0,
            "controls_timeouts": 0,
            "bad_packets": 0,
            "commands": 0,
        }
        self.armed = False
        self._reset_link_state()

    def _reset_link_state(self) -> None:
        self._got_controls = False
        self._controls_t = -math.inf
        self._cmd = self._cmd_disarmed
        self._hsq_interval_us: int | None = None
        self._hsq_next_us = 0
        self._next_heartbeat = -math.inf
        self._wall0: float | None = None
        self._closed = False
        self.close_reason = ""
        self._pending = b""  # the start of a frame the next read completes

    @property
    def port_number(self) -> int | None:
        """The TCP port PX4 connects to (None for a serial link)."""
        return getattr(self.link, "port", None)

    # -- the exchange, run by the port component inside the simulator ------------------------------------------
    def _exchange(self, t: float, latest: dict[tuple[str, int], Any], truth: Any) -> np.ndarray:
        p = self.params
        if self._closed:
            return self._command(t)
        if p.speed is not None:
            self._pace(t)
        time_usec = round(t * 1e6)
        out = []
        if t >= self._next_heartbeat:
            self._next_heartbeat = t + p.heartbeat_period_s - 1e-9
            refuse = getattr(self.link, "refuse_pending", None)
            if refuse is not None:
                refuse()  # a second simulator client is told so, not left waiting in the backlog
            out.append(self.writer.heartbeat(MAV_TYPE_GENERIC, MAV_AUTOPILOT_INVALID, 0, 0, 0))
            self.stats["heartbeats_sent"] += 1
        stats = self.stats
        for key, encoder in self._gps_keys:
            fix = latest.get(key)
            if fix is not None:
                out.append(encoder.hil_gps(time_usec, fix))
                stats["hil_gps"] += 1
        if self._hsq_interval_us is not None and time_usec >= self._hsq_next_us and truth is not None:
            out.append(self.encoders[0].hil_state_quaternion(time_usec, truth))
            self._hsq_next_us += self._hsq_interval_us  # on the requested grid, never two in one period
            if self._hsq_next_us <= time_usec:
                self._hsq_next_us = time_usec + self._hsq_interval_us
            stats["hil_state_quaternion"] += 1
        get = latest.get
        for sid, encoder, imu, mag, baro in self._sensor_keys:  # further instances only when something of theirs
            frame, bits = encoder.hil_sensor(time_usec, get(imu), get(mag), get(baro))  # is new; 0 always, last
            if sid == 0 or bits:
                out.append(frame)
                stats["hil_sensor"] += 1
        try:
            self.link.send(b"".join(out))
            self._receive(t)
            if self.gcs is not None:
                from_gcs = self.gcs.poll()
                if from_gcs:
                    self.link.send(from_gcs)
        except LinkClosed as e:
            self._close(str(e), failed=True)
        return self._command(t)

    def _pace(self, t: float) -> None:
        """Holds simulated time to ``speed`` x wall time. After a stall (a slow peer, a busy machine) it does not
        race to catch up more than 0.1 s: a flight controller in HITL would get a burst of stale periods."""
        now = time.perf_counter()
        speed = self.params.speed
        assert speed is not None  # paced runs only
        if self._wall0 is None:
            self._wall0 = now - t / speed
            return
        wait = self._wall0 + t / speed - now
        if wait > 0:
            time.sleep(wait)
        elif wait < -0.1:
            self._wall0 = now - t / speed

    def _receive(self, t: float) -> None:
        """Lockstep (once controls flow, or always with wait_first_controls): blocks until HIL_ACTUATOR_CONTROLS
        (or the timeout); otherwise takes what has arrived."""
        p = self.params
        link = self.link
        if not (p.lockstep and (self._got_controls or p.wait_first_controls)):
            while True:  # take what is waiting, without waiting
                data = link.recv(0.0)
                if not data:
                    if data == b"":
                        self._close("PX4 closed the connection")
                    return
                self._handle(data, t)
        start = time.perf_counter()
        timeout = p.controls_timeout_s
        while True:
            data = link.recv(timeout)
            if data == b"":
                self._close("PX4 closed the connection")
                return
            if data is not None and self._handle(data, t):
                return  # the period's answer is in: anything after it is read next period
            if timeout == 0.0:  # that was the last look, after the deadline
                self.stats["controls_timeouts"] += 1
                return
            timeout = max(start + p.controls_timeout_s - time.perf_counter(), 0.0)

    def _handle(self, data: bytes, t: float) -> bool:
        """Takes what arrived: HIL_ACTUATOR_CONTROLS (True if any came), heartbeats, commands. Whole controls
        frames at the front take the fast path; anything else is split into CRC-valid frames, resynchronising
        past noise byte by byte (:func:`~cufund.apps.mavlink.hil_codec.scan_frames`), so garbage never costs the
        controls frame behind it."""
        got = False
        if not self._pending:
            controls, data = take_controls(data)
            for frame, u, mode in controls:
                if self.gcs is not None:
                    self.gcs.send(frame)
                self._on_controls(u, mode, t)
                got = True
            if not data:
                return got
        frames, bad, self._pending = scan_frames(self._pending + data)
        self.stats["bad_packets"] += bad
        for frame in frames:
            controls, _ = take_controls(frame)
            if controls:
                _, u, mode = controls[0]
                self._on_controls(u, mode, t)
                got = True
            else:
                try:
                    messages = self._rx.parse_buffer(frame) or ()
                except (ValueError, TypeError, IndexError, struct.error, mavlink.MAVError):
                    self.stats["bad_packets"] += 1  # a valid frame whose payload pymavlink cannot decode
                    continue
                for msg in messages:
                    got = self._on_message(msg, t) or got
                continue
            if self.gcs is not None:
                self.gcs.send(frame)
        return got

    def _on_message(self, msg: Any, t: float) -> bool:
        kind = msg.get_type()
        if self.gcs is not None and kind != "BAD_DATA":
            self.gcs.send(bytes(msg.get_msgbuf()))
        if kind == "HIL_ACTUATOR_CONTROLS":  # a signed or MAVLink 1 frame: pymavlink decoded it
            self._on_controls(msg.controls[:4], msg.mode, t)
            return True
        if kind == "HEARTBEAT":
            self.stats["heartbeats_received"] += 1
        elif (
            kind == "COMMAND_LONG"
            and msg.target_system in (0, self.params.system_id)
            and msg.target_component in (0, self.params.component_id)
        ):
            self._on_command(msg)
        elif kind in ("BAD_DATA", "UNKNOWN") or kind.startswith("UNKNOWN"):
            self.stats["bad_packets"] += 1
        return False

    def _on_controls(self, u: Any, mode: int, t: float) -> None:
        isfinite = math.isfinite
        controls = [min(max(x, -1.0), 1.0) if isfinite(x) else math.nan for x in u]
        self.armed = armed = bool(mode & MAV_MODE_FLAG_SAFETY_ARMED)
        cmd = np.array(self.airframe.rotor_speed_list(controls, armed, self._output_of_rotor))  # rotor order
        cmd.setflags(write=False)  # it goes into messages as it is
        self._cmd = cmd
        self._controls_t = t
        self._got_controls = True
        self.stats["controls"] += 1

    def _on_command(self, msg: Any) -> None:
        self.stats["commands"] += 1
        result = MAV_RESULT_UNSUPPORTED
        if msg.command == MAV_CMD_SET_MESSAGE_INTERVAL and msg.param1 == MSG_ID_HIL_STATE_QUATERNION:
            interval = float(msg.param2)
            if interval == -1.0:
                self._hsq_interval_us = None
                result = MAV_RESULT_ACCEPTED
            elif interval >= 0.0 and math.isfinite(interval):
                step_us = round(1e6 / self.params.hil_sensor_rate_hz)
                self._hsq_interval_us = int(interval) if interval > 0 else step_us  # 0: default rate, every step
                self._hsq_next_us = 0
                result = MAV_RESULT_ACCEPTED
        ack = self.mav.command_ack_encode(msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        self.link.send(self.writer.pack(ack))

    def _command(self, t: float) -> np.ndarray:
        """Rotor-speed commands in cufund's rotor order [rad/s] (disarmed speeds when the controls are stale);
        read-only."""
        return self._cmd if t - self._controls_t <= self.params.stale_controls_s + 1e-9 else self._cmd_disarmed

    def _close(self, reason: str, failed: bool = False) -> None:
        """Ends the run: COMPLETED when PX4 left in order, ABORTED (with the reason) when the link failed."""
        self._closed = True
        self.close_reason = reason
        self.simulator.stop(RunStatus.ABORTED if failed else RunStatus.COMPLETED, reason)

    # -- running -----------------------------------------------------------------------------------------------
    def run(
        self, duration: float | None = None, connect_timeout: float | None = None, progress: bool = False
    ) -> SimulationResult:
        """Waits for PX4 (TCP: up to ``connect_timeout`` [s], None forever), then simulates until PX4 closes the
        link, the vehicle crashes or ``duration`` [s] of simulated time passes. Raises TimeoutError when nobody
        connects in time."""
        if duration is not None and (
            isinstance(duration, bool)
            or not isinstance(duration, (int, float))
            or not math.isfinite(duration)
            or duration <= 0
        ):
            raise ValueError(f"duration must be a number of seconds > 0 or None, got {duration!r}")
        self.connect(connect_timeout)
        sim = self.simulator
        sim.reset()
        end = sim.t + duration if duration is not None else math.inf
        while sim.t < end:
            t_before = sim.t
            if not sim.advance_to(min(end, t_before + 1.0), progress=progress) or sim.t == t_before:
                break
        if sim.status is None:
            sim.stop(RunStatus.COMPLETED, "duration elapsed")
        self.disconnect()
        return sim.result()

    def connect(self, connect_timeout: float | None = None) -> None:
        """Waits for PX4 (TCP: up to ``connect_timeout`` [s], None forever; TimeoutError then) and starts a new
        session on the link."""
        accept = getattr(self.link, "accept", None)
        if accept is not None and not accept(connect_timeout):
            raise TimeoutError(f"PX4 did not connect to {self.link.host}:{self.link.port} within {connect_timeout} s")
        self._reset_link_state()

    def disconnect(self) -> None:
        """Ends the session: PX4 sees the simulator go away (the TCP server stays open until :meth:`close`)."""
        disconnect = getattr(self.link, "disconnect", None)
        if disconnect is not None:
            disconnect()

    def close(self) -> None:
        """Closes the link (and the TCP server, and the ground-station relay)."""
        self.link.close()
        if self.gcs is not None:
            self.gcs.close()
