"""The vehicle commander: arming, take-off, hold, go-to, missions, offboard control, landing and return, as PX4's
commander and navigator do it, driven by :class:`cufund.missions.Command` s from any thread.

States (``mode``): ``idle`` (on the ground, armed or not) -> ``takeoff`` -> ``hold`` / ``goto`` / ``mission`` /
``offboard`` -> ``land`` (descend, detect touchdown, disarm) -> ``idle``; ``rtl`` climbs to a safe height, flies
home and lands. Auto modes fly jerk-limited moves (:class:`cufund.planning.JerkLimitedMove`); a hold stops with a
critically damped brake from the reference's velocity. The commander publishes the trajectory setpoint (or, in
attitude mode, the manual attitude setpoint) at its rate and a :class:`VehicleStatus` at ``status_hz`` and at
every change; the controllers read the status to stop the rotors when disarmed (:mod:`cufund.control.arming`).

What each command does (``denied`` acks say why; every refusal is also a ``denied`` event):

- ``arm``: on the ground with a healthy state estimate (fresh, finite); home = here. Armed already: accepted, a no-op. Disarms itself
  after ``auto_disarm_s`` without a take-off.
- ``disarm``: on the ground; in flight only with ``force`` (the rotors stop, the vehicle falls).
- ``takeoff``: armed and on the ground; climbs ``altitude`` (default ``takeoff_altitude``) above home, then holds.
- ``goto``, ``hold``, ``rtl``, ``flight_mode`` (velocity/attitude hold): airborne (``hold`` on the ground: a
  no-op). ``land``: airborne (on the ground: disarms). ``rtl``: up to ``rtl_altitude`` above home (or stays
  higher), home, land.
- ``mission_upload`` (not while one runs), ``mission_clear``; ``mission_start`` (from item ``seq``, default 0):
  armed (takes off first when on the ground); events ``mission_item_reached`` (``seq``) and ``mission_complete``, then it holds at the last item.
  With a scenario's own mission attached (:meth:`Commander.attach_mission`, e.g. the tunnel's) and no waypoints
  uploaded, ``mission_start`` flies that mission instead: on the ground only, arming first when disarmed; the
  commander then flies the mission's reference (mode ``mission``) until it has landed (then disarms) or the
  operator takes over (hold, land, return, go-to: the mission stops there).
- ``offboard_*``: armed; each setpoint (re)enters ``offboard``; none for ``offboard_timeout_s``: hold.
- ``controller``: ``pid``/``geometric`` if built into the simulation (else ``unsupported``), switched in flight.
- ``get_params`` / ``set_param``: :class:`CommanderParams` under PX4's names where they exist, plus the
  ``param_providers`` (a live run adds the controllers' gains, :mod:`cufund.missions.controller_params`).
"""

from __future__ import annotations

import collections
import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cufund.core.components import BusView, Planner
from cufund.core.messages import (
    AttitudeSetpoint,
    FlightMode,
    FlightModeCommand,
    Odometry,
    Topics,
    TrajectorySetpoint,
    VehicleStatus,
)
from cufund.geometry import yaw_of
from cufund.planning.point_to_point import JerkLimitedMove
from cufund.planning.sequence import Hold

from .commands import Command, CommandAck, MissionItem, parse_command
from .events import EventLog
from .inbox import CommandInbox
from .legs import Brake, Descend, Leg
from .params import CommanderParams, as_dict, field_of

__all__ = ["Commander"]

_Z3 = np.zeros(3)
_OFFBOARD_MODES = {
    "offboard_position": FlightMode.POSITION,
    "offboard_velocity": FlightMode.VELOCITY,
    "offboard_attitude": FlightMode.ATTITUDE,
}


def _ok(c: Command, message: str = "") -> CommandAck:
    return CommandAck(c.command, "accepted", message)


def _deny(c: Command, message: str) -> CommandAck:
    return CommandAck(c.command, "denied", message)


class Commander(CommandInbox, Planner):
    """The vehicle state machine (registry kind ``planner: commander``); see the module doc.

    ``submit(cmd) -> Future[CommandAck]`` from any thread (parsed at once: bad input raises ``ValueError``; applied
    in the next :meth:`step`, in simulated-time order); ``apply(cmd, t)`` applies at once (tests, scripts).
    ``events`` is the append-only :class:`EventLog`; ``link_lost()`` / ``link_regained()`` are the link-loss hook.
    """

    name = "commander"
    writes = (Topics.TRAJECTORY_SETPOINT, Topics.MANUAL_ATTITUDE_SETPOINT, Topics.FLIGHT_MODE, Topics.VEHICLE_STATUS)

    def __init__(
        self,
        params: CommanderParams | None = None,
        controller: str = "pid",
        controllers: tuple[str, ...] | None = None,
        events: EventLog | None = None,
    ) -> None:
        self.params = params or CommanderParams()
        self.rate_hz = self.params.rate_hz
        self.initial_controller = controller
        self.controllers = tuple(controllers) if controllers is not None else (controller,)
        """The controller kinds built into the simulation (what ``controller`` may switch to)."""
        self.events = events if events is not None else EventLog()
        CommandInbox.__init__(self)
        self.param_providers: list[tuple[Callable[[], dict[str, Any]], Callable[[str, Any], bool]]] = []
        """Extra parameters (e.g. controller gains): ``(get() -> {name: value}, set(name, value) -> handled)``."""
        self.scenario_mission: Any = None
        """The scenario's own mission (see :meth:`attach_mission`), or None."""
        self.reset()

    def attach_mission(self, mission: Any) -> None:
        """Lets ``mission_start`` fly a scenario's own mission (e.g. :class:`~cufund.missions.tunnel.TunnelMission`
        built to wait for its start). It offers ``start(t, pad_W)``, ``stop(t, reason)``, ``reference`` (the
        trajectory it flies, sampled by the commander), ``finished``, ``t_end`` (when its reference rests on the
        ground, or None), ``state`` and ``yaw``."""
        for name in ("start", "stop", "reference", "finished", "t_end", "state", "yaw"):
            if not hasattr(mission, name):
                raise TypeError(f"attach_mission: the mission needs '{name}', {type(mission).__name__} has none")
        self.scenario_mission = mission

    # -- run lifecycle ---------------------------------------------------------------------------------------
    def reset(self) -> None:
        self.armed = False
        self.landed = True
        self.mode = "idle"
        self.flight_mode = FlightMode.POSITION
        self.controller = self.initial_controller
        self.home_p_W = np.full(3, np.nan)
        self.target_p_W = np.full(3, np.nan)
        self.mission: tuple[MissionItem, ...] = ()
        self.mission_current = -1
        self.message = ""
        self.state: Odometry | None = None
        self.t = 0.0
        self.setpoint: TrajectorySetpoint | None = None
        self._ref: Any = None  # JerkLimitedMove / Hold / Brake
        self._ref_yaw = 0.0  # the heading to reach; the reference turns to it along _yaw_path
        self._yaw_path = (0.0, 0.0, 0.0, 0.0)  # (yaw at the start, change, start time, duration)
        self._legs: collections.deque[Leg] = collections.deque()
        self._leg: Leg | None = None
        self._leg_phase = "move"  # 'move' then 'hold' (waiting hold_s at the target)
        self._hold_until = 0.0
        self._after = "hold"  # what follows the last leg: 'hold' or 'land'
        self._hold_flight_mode: FlightMode | None = None
        self._offboard: tuple[Command, float] | None = None
        self._touchdown_since: float | None = None
        self._armed_since = 0.0
        self._link_lost_at: float | None = None
        self._script = list(self.params.script)
        self._status_dirty = True
        self._next_status = -math.inf
        self._published_mode: FlightMode | None = None
        self._last_refusal: tuple[str, float, int] | None = None  # (message, time of its event, repeats since)
        self._flying_scenario_mission = False
        self.plan_W: tuple[tuple[float, float, float], ...] = ()
        """The targets still to fly, the current one first [m] (updated at each change; safe to read from any
        thread)."""

    @property
    def script_done(self) -> bool:
        return not self._script

    # -- helpers -----------------------------------------------------------------------------------------------
    def _event(self, kind: str, message: str, **data: Any) -> None:
        self.message = message
        self._status_dirty = True
        self.events.append(self.t, kind, message, **data)

    def _set_mode(self, mode: str, why: str = "") -> None:
        if mode != self.mode:
            m = self.scenario_mission
            if self.mode == "mission" and m is not None and self._flying_scenario_mission and not m.finished:
                m.stop(self.t, f"operator took over ({mode})")  # hold, land, return, go-to: it stops here
            self._flying_scenario_mission = self._flying_scenario_mission and mode == "mission"
            self.mode = mode
            self._event("mode", f"mode {mode}" + (f": {why}" if why else ""), mode=mode)

    @property
    def airborne(self) -> bool:
        return self.armed and not self.landed

    def _ref_at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        r = self._ref
        if r is None:
            p = self.state.p_W if self.state is not None else _Z3
            return np.array(p, float), _Z3, _Z3, _Z3
        if isinstance(r, (Brake, Descend)):
            return r.at(t)
        s = r.sample(t)
        return s.p_W[0], s.v_W[0], s.a_W[0], s.j_W[0]

    def _move(self, t: float, target: np.ndarray, yaw: float, slow: bool = False) -> None:
        """A jerk-limited move to ``target`` from the reference's current state (smooth when re-targeting in
        motion)."""
        p = self.params
        if self._ref is not None:
            start, v0, a0, _ = self._ref_at(t)
        else:
            start, v0, a0 = np.array(self.state.p_W), _Z3, _Z3  # type: ignore[union-attr]
        v, a = (p.takeoff_speed if slow else p.v_max), p.a_max
        try:
            self._ref = JerkLimitedMove(
                np.array(start, float), target, v, a, p.j_max, yaw, t_start=t, start_v_W=v0, start_a_W=a0
            )
        except ValueError:  # a state ruckig cannot start from (beyond the limits): from rest at the reference
            self._ref = JerkLimitedMove(np.array(start, float), target, v, a, p.j_max, yaw, t_start=t)
        self._turn(t, yaw)
        self.target_p_W = np.array(target, float)

    def _turn(self, t: float, yaw: float, instant: bool = False) -> None:
        """Heads for ``yaw`` [rad]: a smoothstep from the current reference heading, its peak rate yaw_rate_max."""
        now, _ = self._yaw_at(t)
        d = (yaw - now + math.pi) % (2 * math.pi) - math.pi
        self._ref_yaw = now + d
        T = 0.0 if instant else 1.5 * abs(d) / self.params.yaw_rate_max
        self._yaw_path = (self._ref_yaw, 0.0, t, 0.0) if T == 0.0 else (now, d, t, T)

    def _yaw_at(self, t: float) -> tuple[float, float]:
        """The reference heading [rad] and its rate [rad/s] at ``t``."""
        y0, d, t0, T = self._yaw_path
        if T <= 0.0 or t >= t0 + T:
            return y0 + d, 0.0
        x = max(t - t0, 0.0) / T
        return y0 + d * x * x * (3 - 2 * x), d * 6 * x * (1 - x) / T

    def _brake(self, t: float, from_state: bool = False) -> None:
        if from_state or self._ref is None:
            s = self.state
            assert s is not None
            p0, v0 = s.p_W, s.v_W
            self._turn(t, yaw_of(s.q_WB), instant=True)
        else:
            p0, v0, _, _ = self._ref_at(t)
        self._ref = Brake(p0, v0, self.params.brake_tau, self._ref_yaw, t)
        self.target_p_W = self._ref.goal_W.copy()

    def _hold(self, t: float, why: str = "", from_state: bool = False) -> None:
        self._legs.clear()
        self._leg = None
        self._offboard = None
        self._brake(t, from_state)
        self._hold_flight_mode = None
        self._set_mode("hold", why)

    def _start_legs(self, t: float, legs: list[Leg], mode: str, after: str, why: str = "") -> None:
        self._offboard = None
        self._hold_flight_mode = None
        self.flight_mode = FlightMode.POSITION
        self._legs = collections.deque(legs)
        self._after = after
        self._set_mode(mode, why)
        self._next_leg(t)

    def _next_leg(self, t: float) -> None:
        if not self._legs:
            self._leg = None
            if self._after == "land":
                self._land(t)
            else:
                self._brake(t)
                self._set_mode("hold", f"{self.mode} done" if self.mode != "hold" else "")
            return
        leg = self._legs.popleft()
        self._leg, self._leg_phase = leg, "move"
        if leg.tag == "item":
            self.mission_current = leg.seq
            self._status_dirty = True
        self._move(t, leg.target, leg.yaw, leg.slow)

    def _land(self, t: float, why: str = "") -> None:
        s = self.state
        assert s is not None
        p0, _, _, _ = self._ref_at(t) if self._ref is not None else (s.p_W, 0, 0, 0)
        ground = self.home_p_W[2] if np.isfinite(self.home_p_W[2]) else 0.0
        # approach to land_alt above home's height, then descend at land_speed until the vehicle stops descending
        target = np.array([p0[0], p0[1], min(ground + self.params.land_alt, float(p0[2]))])
        self._legs = collections.deque()
        self._after = "hold"
        self._offboard = None
        self._hold_flight_mode = None
        self.flight_mode = FlightMode.POSITION
        self._leg = Leg(target, self._ref_yaw, "land")
        self._leg_phase = "move"
        self._touchdown_since = None
        self._move(t, target, self._ref_yaw)
        self._set_mode("land", why)

    def _disarm(self, why: str) -> None:
        self.armed = False
        self._legs.clear()
        self._leg = None
        self._offboard = None
        self._ref = None
        self.flight_mode = FlightMode.POSITION
        self._set_mode("idle")
        self._event("disarmed", f"disarmed: {why}")

    # -- commands ----------------------------------------------------------------------------------------------
    def apply(self, cmd: Any, t: float | None = None) -> CommandAck:
        """Applies ``cmd`` now (at simulated time ``t``, default the last step's) and returns its ack."""
        command = parse_command(cmd)
        if t is not None:
            self.t = float(t)
        try:
            ack = self._apply(command, self.t)
        except Exception as e:  # a command never takes the commander down
            ack = CommandAck(command.command, "failed", f"{type(e).__name__}: {e}")
        if ack.result != "accepted":
            kind = "denied" if ack.result == "denied" else "warning"
            text = f"{command.command} {ack.result}: {ack.message}"
            last = self._last_refusal
            if last is not None and last[0] == text and self.t - last[1] < 1.0:  # a flood: one event a second
                self._last_refusal = (text, last[1], last[2] + 1)
            else:
                if last is not None and last[2]:
                    self.events.append(self.t, kind, f"{last[0]} (x{last[2]} more)", command=command.command)
                self._event(kind, text, command=command.command)
                self._last_refusal = (text, self.t, 0)
        return ack

    # Each command: the state it needs (its gate) and its handler. Gates, checked in this order:
    #   free     - always applied
    #   state    - a vehicle state has arrived ("no vehicle state yet")
    #   hold     - state; on the ground it is a no-op (accepted); else armed
    #   armed    - state and armed ("disarmed; arm first")
    #   airborne - armed and off the ground ("on the ground; take off first")
    # Commands not in the table are unsupported, once they pass the airborne gate.
    _DISPATCH: dict[str, tuple[str, str]] = {
        "_link_lost": ("free", "_cmd_link_lost"),
        "_link_regained": ("free", "_cmd_link_regained"),
        "get_params": ("free", "_cmd_get_params"),
        "set_param": ("free", "_cmd_set_param"),
        "controller": ("free", "_cmd_controller"),
        "mission_upload": ("free", "_cmd_mission_upload"),
        "mission_clear": ("free", "_cmd_mission_clear"),
        "arm": ("state", "_cmd_arm"),
        "disarm": ("state", "_cmd_disarm"),
        "hold": ("hold", "_cmd_hold"),
        "takeoff": ("armed", "_cmd_takeoff"),
        "mission_start": ("armed", "_cmd_mission_start"),
        "land": ("armed", "_cmd_land"),
        "flight_mode": ("armed", "_cmd_flight_mode"),
        "offboard_position": ("armed", "_cmd_offboard"),
        "offboard_velocity": ("armed", "_cmd_offboard"),
        "offboard_attitude": ("armed", "_cmd_offboard"),
        "goto": ("airborne", "_cmd_goto"),
        "rtl": ("airborne", "_cmd_rtl"),
    }

    def _apply(self, c: Command, t: float) -> CommandAck:
        gate, handler = self._DISPATCH.get(c.command, ("airborne", "_cmd_unsupported"))
        if c.command == "mission_start" and self.scenario_mission is not None and not self.mission:
            gate, handler = "state", "_cmd_scenario_mission_start"  # it arms by itself
        refusal = self._gate(gate, c)
        if refusal is not None:
            return refusal
        return getattr(self, handler)(c, t)

    def _gate(self, gate: str, c: Command) -> CommandAck | None:
        """The ack of a command its gate stops (None: it passes)."""
        if gate == "free":
            return None
        if self.state is None:
            return _deny(c, "no vehicle state yet")
        if gate == "state":
            return None
        if gate == "hold" and self.landed:  # PX4 switches to Hold on the ground too: nothing to do
            return _ok(c, "on the ground")
        if not self.armed:
            return _deny(c, "disarmed; arm first")
        if gate == "airborne" and self.landed:
            return _deny(c, "on the ground; take off first")
        return None

    # -- command handlers (each after its gate) ---------------------------------------------------------------
    def _cmd_link_lost(self, c: Command, t: float) -> CommandAck:
        self._event("warning", "link lost")
        if self.airborne and self.mode not in ("land", "rtl"):
            self._hold(t, "link lost")
            self._link_lost_at = t
        return _ok(c)

    def _cmd_link_regained(self, c: Command, t: float) -> CommandAck:
        if self._link_lost_at is not None:
            self._event("info", "link regained")
        self._link_lost_at = None
        return _ok(c)

    def _cmd_get_params(self, c: Command, t: float) -> CommandAck:
        values = as_dict(self.params)
        for get, _ in self.param_providers:
            values.update(get())
        return CommandAck(c.command, "accepted", "", values)

    def _cmd_set_param(self, c: Command, t: float) -> CommandAck:
        return self._set_param(c)

    def _cmd_controller(self, c: Command, t: float) -> CommandAck:
        if c.kind not in self.controllers:
            return CommandAck(
                c.command,
                "unsupported",
                f"controller {c.kind!r} is not built into this simulation (built: {', '.join(self.controllers)})",
            )
        if c.kind != self.controller:
            self.controller = c.kind
            self._event("controller", f"controller {c.kind}", controller=c.kind)
        return _ok(c)

    def _cmd_mission_upload(self, c: Command, t: float) -> CommandAck:
        if self.mode == "mission":
            return _deny(c, "a mission is running; hold or land first")
        self.mission, self.mission_current = c.items, -1
        self._status_dirty = True
        self._event("mission", f"mission of {len(c.items)} items uploaded", count=len(c.items))
        return _ok(c)

    def _cmd_mission_clear(self, c: Command, t: float) -> CommandAck:
        if self.mode == "mission":
            self._hold(t, "mission cleared")
        self.mission, self.mission_current = (), -1
        self._status_dirty = True
        return _ok(c)

    def _cmd_arm(self, c: Command, t: float) -> CommandAck:
        s = self.state
        assert s is not None
        if self.armed:
            return _ok(c, "already armed")
        if not self.landed:
            return _deny(c, "not on the ground")
        if t - float(s.t) > 0.5 or not np.all(np.isfinite(s.p_W)):  # PX4's preflight check, in short
            return _deny(c, f"state estimate unhealthy (last at {float(s.t):.2f} s)")
        self.armed, self._armed_since = True, t
        self.home_p_W = np.array(s.p_W, float)
        self._ref = None
        self._turn(t, yaw_of(s.q_WB), instant=True)
        self._event("armed", "armed")
        return _ok(c)

    def _cmd_disarm(self, c: Command, t: float) -> CommandAck:
        if not self.armed:
            return _ok(c, "already disarmed")
        if not self.landed and not c.force:
            return _deny(c, "in flight (land first, or force)")
        self._disarm("forced in flight" if not self.landed else "command")
        if c.force:
            self.landed = False
        return _ok(c)

    def _cmd_hold(self, c: Command, t: float) -> CommandAck:
        self._hold(t)
        return _ok(c)

    def _cmd_takeoff(self, c: Command, t: float) -> CommandAck:
        s = self.state
        assert s is not None
        if not self.landed:
            return _deny(c, "already airborne")
        alt = c.altitude if c.altitude is not None else self.params.takeoff_altitude
        self._begin_flight(t)
        target = np.array([s.p_W[0], s.p_W[1], self.home_p_W[2] + alt])
        self._start_legs(t, [Leg(target, self._ref_yaw, "takeoff", slow=True)], "takeoff", "hold")
        return _ok(c)

    def _cmd_mission_start(self, c: Command, t: float) -> CommandAck:
        s = self.state
        assert s is not None
        if not self.mission:
            return _deny(c, "no mission uploaded")
        if c.seq >= len(self.mission):
            return _deny(c, f"seq {c.seq} is past the mission's {len(self.mission)} items")
        legs = []
        if self.landed:
            self._begin_flight(t)
            first = self.mission[c.seq].p_W
            legs.append(
                Leg(
                    np.array([s.p_W[0], s.p_W[1], max(first[2], self.home_p_W[2] + 0.5)]),
                    self._ref_yaw,
                    "takeoff",
                    slow=True,
                )
            )
        yaw = self._ref_yaw
        for i, it in enumerate(self.mission[c.seq :], start=c.seq):
            yaw = yaw if it.yaw is None else it.yaw
            legs.append(Leg(np.array(it.p_W), yaw, "item", it.hold_s, i))
        self._start_legs(t, legs, "mission", "hold")
        return _ok(c)

    def _cmd_scenario_mission_start(self, c: Command, t: float) -> CommandAck:
        s, m = self.state, self.scenario_mission
        assert s is not None and m is not None
        if self._flying_scenario_mission:
            return _ok(c, "already flying the mission")
        if m.finished or m.state != "initialise":
            return _deny(c, f"the scenario's mission has run ({m.state}); restart the scenario to fly it again")
        if not self.landed:
            return _deny(c, "the scenario's mission takes off from the ground: land first")
        if not self.armed:
            ack = self._cmd_arm(c, t)
            if ack.result != "accepted":
                return ack
        self._begin_flight(t)
        m.start(t, np.array(s.p_W, float))
        self._legs.clear()
        self._leg = None
        self._offboard = None
        self._hold_flight_mode = None
        self.flight_mode = FlightMode.POSITION
        self._ref = m.reference
        self._turn(t, float(m.yaw))
        self._set_mode("mission", "the scenario's mission")
        self._flying_scenario_mission = True
        return _ok(c)

    def _cmd_land(self, c: Command, t: float) -> CommandAck:
        if self.landed:
            self._disarm("land on the ground")
            return _ok(c, "on the ground: disarmed")
        if self.mode == "land":
            return _ok(c, "already landing")
        self._land(t)
        return _ok(c)

    def _cmd_flight_mode(self, c: Command, t: float) -> CommandAck:
        mode = FlightMode(c.mode)
        if self.landed:
            self.flight_mode = mode
            self._status_dirty = True
            return _ok(c, "on the ground: applies to offboard control")
        self._hold(t, f"flight mode {mode.value}")
        self.flight_mode = self._hold_flight_mode = mode
        self._status_dirty = True
        return _ok(c)

    def _cmd_offboard(self, c: Command, t: float) -> CommandAck:
        if self.landed:
            self._begin_flight(t)
        self.flight_mode = _OFFBOARD_MODES[c.command]
        self._legs.clear()
        self._leg = None
        self._offboard = (c, t)
        if c.p_W is not None:
            self.target_p_W = np.array(c.p_W)
        if c.yaw is not None:
            self._turn(t, c.yaw, instant=True)  # offboard: the client's heading as it comes
        self._set_mode("offboard")
        return _ok(c)

    def _cmd_goto(self, c: Command, t: float) -> CommandAck:
        yaw = self._ref_yaw if c.yaw is None else c.yaw
        self._start_legs(t, [Leg(np.array(c.p_W), yaw, "goto")], "goto", "hold")
        return _ok(c)

    def _cmd_rtl(self, c: Command, t: float) -> CommandAck:
        if not np.all(np.isfinite(self.home_p_W)):
            return _deny(c, "no home position")
        p0, _, _, _ = self._ref_at(t)
        z = max(float(p0[2]), self.home_p_W[2] + self.params.rtl_altitude)
        legs = [
            Leg(np.array([p0[0], p0[1], z]), self._ref_yaw, "rtl_climb"),
            Leg(np.array([self.home_p_W[0], self.home_p_W[1], z]), self._ref_yaw, "rtl_home"),
        ]
        self._start_legs(t, legs, "rtl", "land")
        return _ok(c)

    def _cmd_unsupported(self, c: Command, t: float) -> CommandAck:
        return CommandAck(c.command, "unsupported", f"{c.command} is not handled")

    def _begin_flight(self, t: float) -> None:
        s = self.state
        assert s is not None
        self.landed = False
        self._ref = Hold(np.array(s.p_W, float), 0.0, self._ref_yaw, t_start=t)
        self._status_dirty = True

    def _set_param(self, c: Command) -> CommandAck:
        assert c.name is not None
        f = field_of(c.name)
        if f is not None:
            try:
                self.params = dataclasses.replace(self.params, **{f: c.value})
            except Exception as e:  # ConfigError, TypeError: the ack names the field
                return CommandAck("set_param", "denied", str(e))
            self._event("param", f"{c.name} = {getattr(self.params, f)!r}", name=c.name)
            return CommandAck("set_param", "accepted", "", {c.name: getattr(self.params, f)})
        for _, setter in self.param_providers:
            try:
                if setter(c.name, c.value):
                    self._event("param", f"{c.name} = {c.value!r}", name=c.name)
                    return CommandAck("set_param", "accepted", "", {c.name: c.value})
            except (TypeError, ValueError) as e:
                return CommandAck("set_param", "denied", str(e))
        return CommandAck("set_param", "unsupported", f"unknown parameter {c.name!r}")

    # -- the periodic step -------------------------------------------------------------------------------------
    def step(self, t: float, bus: BusView) -> None:
        self.t = t
        state = bus.latest(self.active_state_topic)
        if state is not None:
            self.state = state
        while self._script and self._script[0][0] <= t:
            self.apply(self._script.pop(0)[1], t)
        self.process_pending(t)
        if self.state is not None:
            self._supervise(t, self.state)
            self._publish_setpoint(t, self.state, bus)
        if self._status_dirty or t >= self._next_status:
            self._publish_status(t, bus)

    def process_pending(self, t: float) -> None:
        """Applies the submitted commands at time ``t`` (in :meth:`step`; a live run also calls it from the
        simulation thread while paused, so that commands are answered)."""
        self.drain(lambda cmd: self.apply(cmd, t))
        if self._status_dirty:
            self._update_plan()

    def _update_plan(self) -> None:
        plan = [self._leg.target] if self._leg is not None else []
        plan += [leg.target for leg in self._legs]
        if plan and (self._after == "land" or self._leg is not None and self._leg.tag == "land"):
            ground = self.home_p_W[2] if np.isfinite(self.home_p_W[2]) else 0.0
            plan.append(np.array([plan[-1][0], plan[-1][1], ground]))
        self.plan_W = tuple((float(p[0]), float(p[1]), float(p[2])) for p in plan)

    def update(self, t: float, state: Odometry, bus: BusView) -> None:  # Planner's hook (step does it all)
        pass

    def _supervise(self, t: float, s: Odometry) -> None:
        p = self.params
        if not self.armed:
            self.landed = (
                self.landed
                or float(np.linalg.norm(s.v_W)) < 0.2
                and s.p_W[2] < 0.1 + (self.home_p_W[2] if np.isfinite(self.home_p_W[2]) else 0.0)
            )
            return
        if self.landed:
            if p.auto_disarm_s > 0 and t - self._armed_since > p.auto_disarm_s and self.mode == "idle":
                self._disarm(f"no take-off within {p.auto_disarm_s:g} s")
            return
        if self._link_lost_at is not None and self.mode == "hold" and t - self._link_lost_at >= p.link_loss_timeout_s:
            self._link_lost_at = None
            self._land(t, "link lost")
        if self.mode == "offboard" and self._offboard is not None and t - self._offboard[1] > p.offboard_timeout_s:
            self.flight_mode = FlightMode.POSITION
            self._hold(t, "offboard setpoints stale", from_state=True)
        if self._flying_scenario_mission:
            self._follow_scenario_mission(t, s)
            return
        leg = self._leg
        if leg is None or self._ref is None:
            return
        if leg.tag == "land":
            if self._leg_phase == "move":
                if t >= self._ref.t_end:
                    p0, _, _, _ = self._ref_at(t)
                    self._ref, self._leg_phase = Descend(p0, p.land_speed, self._ref_yaw, t), "descend"
                return
            # touchdown (PX4's land detector, simplified): commanded down, but no longer moving, for touchdown_s
            if t - self._ref.t_start >= 0.5 and float(np.linalg.norm(s.v_W)) < p.touchdown_speed:
                if self._touchdown_since is None:
                    self._touchdown_since = t
                if t - self._touchdown_since >= p.touchdown_s:
                    self.landed = True
                    self._leg = None
                    self._event("landed", "landed")
                    self._disarm("landed")
            else:
                self._touchdown_since = None
            return
        if self._leg_phase == "move":
            if t >= self._ref.t_end and float(np.linalg.norm(s.p_W - leg.target)) <= p.acceptance_radius:
                if leg.tag == "item":
                    self._event("mission_item_reached", f"mission item {leg.seq} reached", seq=leg.seq)
                    if leg.seq == len(self.mission) - 1 and not any(g.tag == "item" for g in self._legs):
                        self._event("mission_complete", "mission complete", count=len(self.mission))
                if leg.hold_s > 0:
                    self._leg_phase, self._hold_until = "hold", t + leg.hold_s
                else:
                    self._next_leg(t)
        elif t >= self._hold_until:
            self._next_leg(t)

    def _follow_scenario_mission(self, t: float, s: Odometry) -> None:
        """Flies the scenario's mission's reference; once it has landed (its reference at rest on the ground and
        the vehicle still there), landed and disarmed."""
        m = self.scenario_mission
        self._ref = m.reference
        if not m.finished:
            return
        ground = self.home_p_W[2] if np.isfinite(self.home_p_W[2]) else 0.0
        if m.t_end is None:  # ended in the air (it always lands; a safeguard): hold there
            self._hold(t, f"mission {m.state}")
        elif t >= m.t_end + 0.5 and float(np.linalg.norm(s.v_W)) < 0.2 and s.p_W[2] < ground + 0.1:
            self.landed = True
            self._event("landed", "landed")
            self._disarm(f"mission {m.state}")

    def _publish_setpoint(self, t: float, s: Odometry, bus: BusView) -> None:
        if self.flight_mode is not FlightMode.POSITION or self._published_mode is not self.flight_mode:
            # re-sent while not in position mode: a controller that was reset (disarmed, switched) picks it up
            bus.publish(Topics.FLIGHT_MODE, FlightModeCommand(t, self.flight_mode))
            self._published_mode = self.flight_mode
        yaw, yaw_rate = self._yaw_at(t)
        if self.mode == "offboard" and self._offboard is not None:
            c = self._offboard[0]
            if c.command == "offboard_attitude":
                bus.publish(
                    Topics.MANUAL_ATTITUDE_SETPOINT,
                    AttitudeSetpoint(t, np.array(c.q_WB), math.nan if c.thrust is None else c.thrust),
                )
                return
            if c.command == "offboard_velocity":
                sp = TrajectorySetpoint(t, np.array(s.p_W), np.array(c.v_W), _Z3, _Z3, yaw, 0.0)
            else:
                v = _Z3 if c.v_W is None else np.array(c.v_W)
                sp = TrajectorySetpoint(t, np.array(c.p_W), v, _Z3, _Z3, yaw, 0.0)
        elif self._hold_flight_mode is FlightMode.ATTITUDE:
            h = 0.5 * yaw
            bus.publish(
                Topics.MANUAL_ATTITUDE_SETPOINT,
                AttitudeSetpoint(t, np.array([math.cos(h), 0.0, 0.0, math.sin(h)]), math.nan),
            )
            return
        elif self._hold_flight_mode is FlightMode.VELOCITY:
            sp = TrajectorySetpoint(t, np.array(s.p_W), _Z3, _Z3, _Z3, yaw, 0.0)
        else:
            pr, vr, ar, jr = self._ref_at(t)
            if self._ref is None:  # on the ground: stay where the vehicle is
                pr = np.array(s.p_W)
            sp = TrajectorySetpoint(t, np.array(pr), np.array(vr), np.array(ar), np.array(jr), yaw, yaw_rate)
        self.setpoint = sp
        bus.publish(Topics.TRAJECTORY_SETPOINT, sp)

    def status(self, t: float | None = None) -> VehicleStatus:
        target = (
            self.target_p_W
            if np.all(np.isfinite(self.target_p_W))
            else (np.array(self.state.p_W) if self.state is not None else np.full(3, np.nan))
        )
        return VehicleStatus(
            self.t if t is None else t,
            self.armed,
            self.mode,
            self.landed,
            self.flight_mode,
            self.controller,
            self.mission_current,
            len(self.mission),
            np.array(self.home_p_W),
            np.array(target),
            self.message,
        )

    def _publish_status(self, t: float, bus: BusView) -> None:
        self._update_plan()
        bus.publish(Topics.VEHICLE_STATUS, self.status(t))
        self._status_dirty = False
        self._next_status = t + 1.0 / self.params.status_hz
