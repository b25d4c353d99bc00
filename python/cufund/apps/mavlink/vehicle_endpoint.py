"""The simulated vehicle as a PX4 vehicle on MAVLink: ground stations (QGroundControl, MAVProxy) and offboard
programs (MAVSDK) connect to a live run (:class:`cufund.apps.live.LiveRun`) through :class:`VehicleEndpoint`.

One thread serves every link: it reads datagrams (malformed ones counted and dropped), answers each request on
the link it came from, streams telemetry to each link at that link's rates (SET_MESSAGE_INTERVAL changes them for
the link it came on, as PX4's per-instance streams) and forwards commands to the run's commander, answering COMMAND_ACK when the commander has decided.
Commands, setpoints and parameters cross into the simulation thread only through ``run.submit``; nothing in the
loop raises out of it (an error in a handler is counted in ``stats['handler_errors']``).

Link loss: once a client has been heard, no message on any link for ``heartbeat_timeout_s`` (wall time) calls
the commander's ``link_lost()`` (hold, then land after its ``COM_DL_LOSS_T``); the next message calls
``link_regained()``.
"""

from __future__ import annotations

import concurrent.futures
import math
import queue
import select
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from cufund.geometry import yaw_of

from . import command_protocol as cp
from . import frames
from . import telemetry_streams as ts
from .link import UdpLink
from .mission_protocol import CommanderPlan
from .param_protocol import ParamProtocol

_RESULT = {
    "accepted": mavlink.MAV_RESULT_ACCEPTED,
    "denied": mavlink.MAV_RESULT_DENIED,
    "unsupported": mavlink.MAV_RESULT_UNSUPPORTED,
    "failed": mavlink.MAV_RESULT_FAILED,
    "in_progress": mavlink.MAV_RESULT_IN_PROGRESS,
}

_GLOBAL_FRAMES = (
    mavlink.MAV_FRAME_GLOBAL_INT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
)
_INT32_UNSET = 2**31 - 1  # COMMAND_INT's "no value" for x/y


def _msg_name(msg_id: int) -> str | None:
    cls = mavlink.mavlink_map.get(int(msg_id))
    return None if cls is None else cls.msgname


class VehicleEndpoint:
    """Serves ``run`` on MAVLink links (``udpout:HOST:PORT`` / ``udpin:HOST:PORT`` URLs).

    ``origin`` places the world origin on WGS-84 (default: the scenario's GPS home, else the GPS model's default);
    ``max_thrust_N`` converts SET_ATTITUDE_TARGET's normalised thrust to newtons (default: the vehicle's thrust at
    full rotor speed); ``rates_hz`` overrides some of the default stream rates
    (:data:`cufund.apps.mavlink.telemetry_streams.DEFAULT_RATES_HZ`). :meth:`start` runs the loop in a thread, :meth:`close`
    stops it and closes the sockets; :meth:`spin_once` runs one iteration (tests drive it directly).
    """

    def __init__(
        self,
        run: Any,
        links: Sequence[str],
        *,
        system_id: int = 1,
        component_id: int = 1,
        origin: frames.GeodeticOrigin | None = None,
        max_thrust_N: float | None = None,
        heartbeat_timeout_s: float = 3.0,
        rates_hz: dict[str, float] | None = None,
    ) -> None:
        if not isinstance(system_id, int) or not 1 <= system_id <= 255:
            raise ValueError(f"system_id must be an integer in [1, 255], got {system_id!r}")
        if not isinstance(component_id, int) or not 1 <= component_id <= 255:
            raise ValueError(f"component_id must be an integer in [1, 255], got {component_id!r}")
        for name, hz in (rates_hz or {}).items():
            if name not in ts.DEFAULT_RATES_HZ:
                raise ValueError(f"rates_hz: unknown stream {name!r}; expected one of {sorted(ts.DEFAULT_RATES_HZ)}")
            if isinstance(hz, bool) or not isinstance(hz, (int, float)) or not (math.isfinite(hz) and hz > 0):
                raise ValueError(f"rates_hz[{name!r}] must be a finite rate > 0 [Hz], got {hz!r}")
        if not links:
            raise ValueError("links must name at least one link, e.g. ['udpout:127.0.0.1:14550']")
        if not (math.isfinite(heartbeat_timeout_s) and heartbeat_timeout_s > 0):
            raise ValueError(f"heartbeat_timeout_s must be > 0 [s], got {heartbeat_timeout_s!r}")
        self.run = run
        self.system_id, self.component_id = system_id, component_id
        self.origin = origin or _origin_of(run)
        self.max_thrust_N = float(max_thrust_N) if max_thrust_N is not None else _max_thrust_of(run)
        self.heartbeat_timeout_s = float(heartbeat_timeout_s)
        self.links: list[UdpLink] = []
        try:
            for i, url in enumerate(links):
                self.links.append(UdpLink(url, system_id, component_id, name=f"link{i}"))
        except Exception:
            self.close()
            raise
        self.intervals: dict[str, float | None] = {
            k: 1.0 / v for k, v in {**ts.DEFAULT_RATES_HZ, **(rates_hz or {})}.items()
        }
        """The streams' configured intervals [s] (None: off): each link starts with them."""
        self.link_intervals: dict[UdpLink, dict[str, float | None]] = {lk: dict(self.intervals) for lk in self.links}
        """Each link's stream intervals [s] (None: off), as its client set them."""
        self._next_due: dict[UdpLink, dict[str, float]] = {lk: {} for lk in self.links}
        self._outbox: queue.SimpleQueue = queue.SimpleQueue()
        self.param_protocol = ParamProtocol(
            lambda cmd: self.run.submit(cmd), lambda fn, *a: self._outbox.put((None, (fn, *a)))
        )
        self.params = self.param_protocol.table
        self.plan = CommanderPlan(
            self._decide, lambda: self._snap or self._snapshot(), self.origin, lambda: self._due_now("MISSION_CURRENT")
        )
        self.missions = self.plan.protocol
        self._event_index = len(getattr(run, "events", ()) or ())
        self._snap: ts.VehicleSnapshot | None = None
        self._offboard: tuple[dict[str, Any], float] | None = None  # the latest offboard setpoint and its wall time
        self._last_rx: float | None = None
        self.link_lost = False
        self.stats: dict[str, int] = {
            "commands": 0,
            "handler_errors": 0,
            "link_losses": 0,
            "setpoints": 0,
            "setpoints_refused": 0,
        }
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- lifecycle --------------------------------------------------------------------------------------------
    def start(self) -> VehicleEndpoint:
        self.param_protocol.refresh()
        self._thread = threading.Thread(target=self.serve_forever, name="mavlink-endpoint", daemon=True)
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        while not self._stop.is_set():
            self.spin_once(0.01)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        for link in self.links:
            link.close()

    def __enter__(self) -> VehicleEndpoint:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # sockets never outlive a forgotten endpoint
        for link in getattr(self, "links", ()):
            link.close()

    @property
    def bad_data(self) -> int:
        return sum(link.stats.bad_data for link in self.links)

    # -- the loop ---------------------------------------------------------------------------------------------
    def spin_once(self, timeout: float = 0.0) -> None:
        """Receive and handle what arrived (waiting at most ``timeout`` s), then send what is due."""
        try:
            ready, _, _ = select.select(self.links, [], [], max(timeout, 0.0))
        except (OSError, ValueError):  # a socket closed under us
            return
        now = time.monotonic()
        for link in ready:
            for msg in link.recv():
                self._last_rx = now
                try:
                    self._handle(link, msg, now)
                except Exception:  # one bad request must not stop the vehicle's link
                    self.stats["handler_errors"] += 1
        self._guarded(self._drain_outbox)
        self._guarded(self._poll, now)

    def _guarded(self, fn: Callable, *args: Any) -> None:
        try:
            fn(*args)
        except Exception:
            self.stats["handler_errors"] += 1

    def _send(self, link: UdpLink | None, factory: Callable) -> None:
        """Send ``factory(mav)`` on ``link`` (None: on every link), each packed with its own codec."""
        for lk in [link] if link is not None else self.links:
            lk.send(factory(lk.mav))

    def _drain_outbox(self) -> None:
        while True:
            try:
                link, factory = self._outbox.get_nowait()
            except queue.Empty:
                return
            if callable(factory):
                self._send(link, factory)
            else:  # a deferred action on the loop thread
                factory[0](*factory[1:])

    def _snapshot(self) -> ts.VehicleSnapshot:
        self._snap = ts.VehicleSnapshot.from_telemetry(self.run.telemetry())
        return self._snap

    def _due_now(self, name: str) -> None:
        """Stream ``name`` goes out on every link at the next poll (a change to tell at once)."""
        for due in self._next_due.values():
            due[name] = 0.0

    def _poll(self, now: float) -> None:
        self.missions.poll(now)
        self._check_link(now)
        self._follow_events()
        s = None
        for link in self.links:
            next_due = self._next_due[link]
            intervals = self.link_intervals[link]
            for name, dt in intervals.items():
                if dt is None or now < next_due.get(name, 0.0):
                    continue
                next_due[name] = max(next_due.get(name, now) + dt, now)
                s = s or self._snapshot()
                factory = self._stream(name, s)
                if factory is not None:
                    self._send(link, factory)

    def _stream(self, name: str, s: ts.VehicleSnapshot) -> Callable | None:
        o = self.origin
        builders: dict[str, Callable] = {
            "HEARTBEAT": lambda mav: ts.encode_heartbeat(mav, s, self.link_lost),
            "SYS_STATUS": lambda mav: ts.encode_sys_status(mav, s),
            "BATTERY_STATUS": lambda mav: ts.encode_battery_status(mav, s),
            "ATTITUDE_QUATERNION": lambda mav: ts.encode_attitude_quaternion(mav, s),
            "ATTITUDE": lambda mav: ts.encode_attitude(mav, s),
            "LOCAL_POSITION_NED": lambda mav: ts.encode_local_position_ned(mav, s),
            "GLOBAL_POSITION_INT": lambda mav: ts.encode_global_position_int(mav, s, o),
            "GPS_RAW_INT": lambda mav: ts.encode_gps_raw_int(mav, s, o),
            "EXTENDED_SYS_STATE": lambda mav: ts.encode_extended_sys_state(mav, s),
            "HOME_POSITION": lambda mav: ts.encode_home_position(mav, s, o),
            "ALTITUDE": lambda mav: ts.encode_altitude(mav, s, o),
            "VFR_HUD": lambda mav: ts.encode_vfr_hud(mav, s, o),
            "MISSION_CURRENT": lambda mav: ts.encode_mission_current(
                mav, s, self.plan.seq(s), len(self.missions.items), self.plan.done
            ),
            "AUTOPILOT_VERSION": lambda mav: ts.encode_autopilot_version(mav, self.system_id),
        }
        return builders.get(name)

    def _check_link(self, now: float) -> None:
        if self._last_rx is None:
            return
        silent = now - self._last_rx > self.heartbeat_timeout_s
        commander = getattr(self.run, "commander", None)
        if silent and not self.link_lost:
            self.link_lost = True
            self.stats["link_losses"] += 1
            if commander is not None:
                commander.link_lost()
        elif not silent and self.link_lost:
            self.link_lost = False
            if commander is not None:
                commander.link_regained()

    def _follow_events(self) -> None:
        events = getattr(self.run, "events", None)
        if events is None or len(events) <= self._event_index:
            return
        for e in events.since(self._event_index):
            self._event_index = e["index"] + 1
            kind, text = e.get("kind", ""), str(e.get("message", ""))
            if kind == "mission_complete":
                self.plan.done = True
                self._due_now("MISSION_CURRENT")  # tell at once (MAVSDK's is_mission_finished reads it)
            elif kind == "mission" or (kind == "mode" and e.get("mode") == "mission"):
                self.plan.done = False  # a new plan, or the plan flown again
            if kind == "mission_item_reached" and isinstance(e.get("seq"), int):
                for seq in self.plan.reached_seqs(e["seq"]):
                    self._send(None, lambda mav, q=seq: mav.mission_item_reached_encode(q))
            severity = {
                "warning": mavlink.MAV_SEVERITY_WARNING,
                "denied": mavlink.MAV_SEVERITY_WARNING,
                "error": mavlink.MAV_SEVERITY_ERROR,
                "collision": mavlink.MAV_SEVERITY_CRITICAL,
            }.get(kind, mavlink.MAV_SEVERITY_INFO)
            if isinstance(e.get("severity"), str):  # an event that names its own (a failsafe: PX4's severities)
                severity = getattr(mavlink, f"MAV_SEVERITY_{e['severity'].upper()}", severity)
            if text:
                self._send(None, lambda mav, t=text, sv=severity: ts.encode_statustext(mav, t, sv))

    # -- dispatch ---------------------------------------------------------------------------------------------
    def _for_us(self, msg: Any) -> bool:
        ts_, tc = getattr(msg, "target_system", 0), getattr(msg, "target_component", 0)
        return ts_ in (0, self.system_id) and tc in (0, self.component_id)

    def _handle(self, link: UdpLink, msg: Any, now: float) -> None:
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            return
        if not self._for_us(msg):
            return
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._command(link, msg, now)
        elif kind.startswith("MISSION_"):
            self.missions.handle(msg, lambda factory: self._send(link, factory), now, link)
        elif kind in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"):
            self.param_protocol.handle(
                msg,
                lambda factory: self._send(link, factory),
                lambda text: self._send(
                    link, lambda mav: ts.encode_statustext(mav, text, mavlink.MAV_SEVERITY_WARNING)
                ),
            )
        elif kind in ("SET_POSITION_TARGET_LOCAL_NED", "SET_ATTITUDE_TARGET"):
            try:  # a setpoint has no ack: one that cannot be flown is counted and dropped
                if kind == "SET_ATTITUDE_TARGET":
                    cmd = cp.attitude_target(msg.type_mask, np.array(msg.q), msg.thrust, self.max_thrust_N)
                else:
                    s = self._snap or self._snapshot()
                    cmd = cp.position_target(
                        msg.type_mask,
                        msg.coordinate_frame,
                        np.array([msg.x, msg.y, msg.z]),
                        np.array([msg.vx, msg.vy, msg.vz]),
                        msg.yaw,
                        s.p_W,
                        yaw_of(s.q_WB),
                    )
            except cp.Refused:
                self.stats["setpoints_refused"] += 1
                return
            self._setpoint(cmd, now)

    def _setpoint(self, cmd: dict[str, Any], now: float) -> None:
        self.stats["setpoints"] += 1
        self._offboard = (cmd, now)
        s = self._snap
        if s is not None and s.mode == "offboard":
            self.run.submit(cmd)

    # -- commands ---------------------------------------------------------------------------------------------
    def _ack(self, link: UdpLink, msg: Any, command: int, result: int, text: str = "") -> None:
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        self._send(link, lambda mav: mav.command_ack_encode(command, result, 0, 0, src[0], src[1]))
        if text and result != mavlink.MAV_RESULT_ACCEPTED:
            self._send(link, lambda mav: ts.encode_statustext(mav, text[:50], mavlink.MAV_SEVERITY_WARNING))

    def _forward(
        self, link: UdpLink, msg: Any, command: int, cmd: dict[str, Any], then: Callable | None = None
    ) -> None:
        """Submit ``cmd``; COMMAND_ACK (and ``then(ack)`` on the loop thread) once the commander answers."""
        try:
            fut = self.run.submit(cmd)
        except ValueError as e:
            self._ack(link, msg, command, mavlink.MAV_RESULT_DENIED, str(e))
            return

        def done(f: Any) -> None:
            try:
                ack = f.result()
                result, text = _RESULT.get(ack.result, mavlink.MAV_RESULT_FAILED), ack.message
            except Exception as e:  # the run ended under the command
                ack, result, text = None, mavlink.MAV_RESULT_FAILED, str(e)
            self._outbox.put((None, (self._ack, link, msg, command, result, text)))
            if then is not None and ack is not None:
                self._outbox.put((None, (then, ack)))

        fut.add_done_callback(done)

    def _command(self, link: UdpLink, msg: Any, now: float) -> None:
        self.stats["commands"] += 1
        c = int(msg.command)
        is_int = msg.get_type() == "COMMAND_INT"
        p = [msg.param1, msg.param2, msg.param3, msg.param4]
        if is_int:
            x, y, z = msg.x, msg.y, msg.z
            lat, lon, frame = frames.e7_to_deg(x), frames.e7_to_deg(y), msg.frame
            p += [x, y, z]
        else:
            p += [msg.param5, msg.param6, msg.param7]
            lat, lon, z, frame = p[4], p[5], p[6], mavlink.MAV_FRAME_GLOBAL
        s = self._snap or self._snapshot()
        try:
            if c == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
                if p[0] not in (0.0, 1.0):
                    raise cp.Refused(mavlink.MAV_RESULT_DENIED, f"arm/disarm param1 must be 1 or 0, got {p[0]}")
                cmd = {"command": "arm"} if p[0] == 1.0 else {"command": "disarm", "force": p[1] == 21196.0}
                self._forward(link, msg, c, cmd)
            elif c == mavlink.MAV_CMD_NAV_TAKEOFF:
                self._forward(link, msg, c, cp.takeoff(z, s.home_p_W, self.origin))
            elif c == mavlink.MAV_CMD_NAV_LAND:
                self._forward(link, msg, c, {"command": "land"})
            elif c == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
                self._forward(link, msg, c, {"command": "rtl"})
            elif c == mavlink.MAV_CMD_NAV_LOITER_UNLIM or (c == mavlink.MAV_CMD_DO_PAUSE_CONTINUE and p[0] == 0):
                self._forward(link, msg, c, {"command": "hold"})
            elif c == mavlink.MAV_CMD_DO_PAUSE_CONTINUE:
                self._forward(link, msg, c, {"command": "mission_start"})
            elif c == mavlink.MAV_CMD_DO_REPOSITION:
                if is_int and frame not in _GLOBAL_FRAMES:
                    raise cp.Refused(mavlink.MAV_RESULT_UNSUPPORTED, f"reposition frame {frame} not supported")
                lat_ok = not (is_int and (x == y == 0 or x == _INT32_UNSET or y == _INT32_UNSET))
                self._forward(
                    link,
                    msg,
                    c,
                    cp.reposition(
                        lat if lat_ok else math.nan,
                        lon if lat_ok else math.nan,
                        z,
                        p[3],
                        frame,
                        s.p_W,
                        s.home_p_W,
                        self.origin,
                    ),
                )
            elif c == mavlink.MAV_CMD_DO_SET_MODE:
                fresh = self._offboard is not None and now - self._offboard[1] < 1.0
                mode_cmd = cp.set_mode(p[0], p[1], p[2], fresh)
                if mode_cmd is None:  # offboard, which set_mode allows only with a fresh setpoint: the latest one
                    assert self._offboard is not None
                    mode_cmd = self._offboard[0]
                self._forward(link, msg, c, mode_cmd)
            elif c == mavlink.MAV_CMD_MISSION_START:
                self._forward(link, msg, c, {"command": "mission_start"})
            elif c == mavlink.MAV_CMD_DO_SET_MISSION_CURRENT:
                ok = self.plan.set_current(int(p[0]))
                self._ack(link, msg, c, mavlink.MAV_RESULT_ACCEPTED if ok else mavlink.MAV_RESULT_DENIED)
            elif c == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
                self._ack(link, msg, c, self._set_interval(link, p[0], p[1]))
            elif c == mavlink.MAV_CMD_REQUEST_MESSAGE:
                self._request_message(link, msg, c, int(p[0]))
            elif c == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
                self._ack(link, msg, c, mavlink.MAV_RESULT_ACCEPTED)
                self._send(link, lambda mav: ts.encode_autopilot_version(mav, self.system_id))
            else:
                self._ack(link, msg, c, mavlink.MAV_RESULT_UNSUPPORTED)
        except cp.Refused as r:
            self._ack(link, msg, c, r.result, str(r))
        except (ValueError, TypeError, OverflowError) as e:  # NaN or absurd parameters
            self._ack(link, msg, c, mavlink.MAV_RESULT_DENIED, f"bad parameters: {e}")

    def _set_interval(self, link: UdpLink, msg_id: float, interval_us: float) -> int:
        """SET_MESSAGE_INTERVAL on ``link`` only: -1 stops the stream, 0 restores the default, > 0 is the interval
        [us] (at most 1 kHz). HEARTBEAT's interval is fixed (FAILED, as PX4's set_message_interval refuses it);
        a non-finite or negative interval other than -1 is DENIED; an unknown message UNSUPPORTED."""
        if not (math.isfinite(msg_id) and msg_id == int(msg_id)):
            return mavlink.MAV_RESULT_DENIED
        name = _msg_name(int(msg_id))
        if name is None or (name not in self.intervals and name not in ts.DEFAULT_RATES_HZ):
            return mavlink.MAV_RESULT_UNSUPPORTED
        if name == "HEARTBEAT":
            return mavlink.MAV_RESULT_FAILED
        if not math.isfinite(interval_us) or (interval_us < 0 and interval_us != -1):
            return mavlink.MAV_RESULT_DENIED
        intervals = self.link_intervals[link]
        if interval_us == 0:
            intervals[name] = self.intervals.get(name)
        elif interval_us < 0:
            intervals[name] = None
        else:
            intervals[name] = max(float(interval_us) * 1e-6, 1e-3)
        self._next_due[link][name] = 0.0
        return mavlink.MAV_RESULT_ACCEPTED

    def _request_message(self, link: UdpLink, msg: Any, command: int, msg_id: int) -> None:
        name = _msg_name(msg_id)
        s = self._snap or self._snapshot()
        factory = self._stream(name, s) if name else None
        if factory is None:
            self._ack(link, msg, command, mavlink.MAV_RESULT_UNSUPPORTED)
            return
        self._ack(link, msg, command, mavlink.MAV_RESULT_ACCEPTED)
        self._send(link, factory)

    # -- missions ---------------------------------------------------------------------------------------------
    def _decide(self, cmd: dict[str, Any], timeout: float = 2.0) -> Any:
        """The commander's ack of ``cmd``, waited for on this thread (the mission protocol answers in order); None
        when it cannot be had within ``timeout`` s: the command is then withdrawn, unapplied, so that the vehicle
        and the answer the client gets agree."""
        try:
            fut = self.run.submit(cmd)
            return fut.result(timeout=timeout)
        except concurrent.futures.TimeoutError:  # (the builtin TimeoutError from Python 3.11 on)
            if fut.cancel():
                return None
            try:  # being applied right now: its ack is a moment away
                return fut.result(timeout=timeout)
            except Exception:
                return None
        except Exception:  # a stopped run, a refused command
            return None


def _origin_of(run: Any) -> frames.GeodeticOrigin:
    """The scenario's GPS home (where its world origin sits on WGS-84), else the GPS model's default home."""
    from cufund.sensors.gps import GpsParams

    config = getattr(run, "config", None)
    for part in (getattr(config, "sensors", None) or {}).values():
        if isinstance(getattr(part, "params", None), GpsParams):
            return frames.GeodeticOrigin.from_geo_point(part.params.home)
    return frames.GeodeticOrigin.from_geo_point(GpsParams().home)


def _max_thrust_of(run: Any) -> float:
    """Collective thrust at full rotor speed [N] of the run's vehicle (SET_ATTITUDE_TARGET's thrust 1)."""
    vp = run.built.context.vehicle
    return 4.0 * float(vp.k_f) * float(vp.rotor_speed_max) ** 2
