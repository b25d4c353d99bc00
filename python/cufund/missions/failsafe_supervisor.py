"""The failsafe supervisor: PX4-like failsafes for every flight, with or without a commander.

It watches flight data only (the state estimate, the IMU, the commanded rotor speeds, the estimator's diagnostics,
the GPS, the battery's :class:`~cufund.core.messages.BatteryStatus`) and, when a failsafe fires, takes the reference
over from whatever flies the vehicle (:mod:`.failsafe_takeover`). Failsafes, by priority (a higher one replaces a
lower one; none is ever downgraded):

========================  =========================================================================================
attitude failure          roll/pitch beyond FD_FAIL_R / FD_FAIL_P for their TTRI: disarm (flight termination)
motor failure             the rate residual (:mod:`.failsafe_motor`) beyond FD_ACT_RES_THR for FD_ACT_TTRI: land
                          at once
battery                   remaining <= BAT_LOW_THR / BAT_CRIT_THR / BAT_EMERGEN_THR: per COM_LOW_BAT_ACT
estimator                 unhealthy (LIO diagnostics, diagnostics silent, or GPS lost under a GPS-only estimate) for
                          COM_POS_FS_DELAY: hold; still unhealthy COM_FAIL_ACT_T later: land (recovered before:
                          the event says so and the hold stays, except for a mission that held by itself)
geofence                  beyond GF_MAX_HOR_DIST / GF_MAX_VER_DIST from home: GF_ACTION
GPS loss                  with a LIO/VIO or no GPS in the estimate: an info event only, the vehicle flies on
========================  =========================================================================================

Each transition is an event ``{"kind": "failsafe", "message": reason, "action": ..., "severity": ...}`` in the
supervisor's :class:`~cufund.missions.events.EventLog` (the commander's when there is one: the ground station and
the MAVLink endpoint show it, the latter as STATUSTEXT of that severity) and in :attr:`FailsafeSupervisor.records`
(``[t, name, reason]``, name the action: hold, rtl, land, disarm, warning, info or cleared; they are
``metrics.json``'s ``failsafe_events``).
"""

from __future__ import annotations

import bisect
import math
from typing import Any

import numpy as np

from cufund.core.components import BusView, Planner
from cufund.core.messages import Odometry, Topics
from cufund.geometry import quat_to_matrix

from .events import EventLog
from .failsafe_health import EstimatorHealth
from .failsafe_motor import AttitudeFailureDetector, MotorFailureDetector
from .failsafe_params import FailsafeParams

__all__ = ["ACTION_RANK", "FailsafeSupervisor"]

ACTION_RANK = {"none": 0, "warning": 0, "hold": 1, "rtl": 2, "land": 3, "disarm": 4}
"""A failsafe never replaces a more drastic one already taken."""

_SEVERITY = {"warning": "warning", "hold": "warning", "rtl": "warning", "land": "critical", "disarm": "emergency"}
"""MAVLink STATUSTEXT severity per action (PX4 reports failsafe activation as critical, warnings as warning,
flight termination as emergency)."""


class FailsafeSupervisor(Planner):
    """See the module doc. ``takeover``: the adapter of the reference owner (None: events only);
    ``vehicle``: the nominal vehicle params (for the motor failure detector); ``imu_topic`` and ``q_BI``: the
    IMU and its stated mounting (without an IMU the body rates of the state are used); ``gps_topic``: the GPS
    sensor's topic or None; ``gps_only``: the estimate's position comes from the GPS alone (GPS loss is then an
    estimator failure); ``events``: the log to append to (the commander's)."""

    name = "failsafe"

    def __init__(
        self,
        params: FailsafeParams,
        takeover: Any = None,
        vehicle: Any = None,
        imu_topic: str | None = None,
        q_BI: Any = None,
        gps_topic: str | None = None,
        gps_only: bool = False,
        estimator_diagnostics: bool = False,
        health: EstimatorHealth | None = None,
        events: EventLog | None = None,
        disarm_output: bool = False,
    ) -> None:
        self.params = params
        self.rate_hz = params.rate_hz
        self.takeover = takeover
        self.events = events if events is not None else EventLog()
        self.imu_topic, self.gps_topic, self.gps_only = imu_topic, gps_topic, bool(gps_only)
        self.R_BI = np.eye(3) if q_BI is None else quat_to_matrix(np.asarray(q_BI, dtype=float))
        self.estimator_diagnostics = bool(estimator_diagnostics)
        self._own_health = health is None
        self.health = health if health is not None else EstimatorHealth(params.EST_SILENCE_T)
        self.motor = (
            MotorFailureDetector(vehicle, params.FD_ACT_RES_THR, params.FD_ACT_TTRI, params.FD_ACT_BANDWIDTH)
            if vehicle is not None and params.FD_ACT_EN
            else None
        )
        self.attitude = AttitudeFailureDetector(
            params.FD_FAIL_R, params.FD_FAIL_P, params.FD_FAIL_R_TTRI, params.FD_FAIL_P_TTRI
        )
        reads: list[str] = [Topics.BATTERY, Topics.ACTUATOR_COMMAND]
        if imu_topic is not None:
            reads.append(imu_topic)
        if gps_topic is not None:
            reads.append(gps_topic)
        if estimator_diagnostics:
            reads.append(Topics.ESTIMATOR_DIAGNOSTICS)
        self.optional_reads = tuple(reads)
        self.writes = (Topics.VEHICLE_STATUS,) if disarm_output else ()
        if disarm_output:
            self.latency_s = (
                1e-3  # its disarm status reaches the controllers a millisecond later (no zero-latency cycle)
            )
        self.reset()

    # -- run lifecycle ---------------------------------------------------------------------------------------
    def reset(self) -> None:
        self.action = "none"
        """The most drastic action taken so far (:data:`ACTION_RANK`)."""
        self.took = ""
        """The most drastic action the reference owner flew as asked ('' before any)."""
        self.records: list[list[Any]] = []
        """``[t, action, reason]`` per transition (metrics.json's ``failsafe_events``)."""
        self.home_W: np.ndarray | None = None
        self.airborne = False
        self._feeding = False
        self._battery_level = 0  # 0 ok, 1 low, 2 critical, 3 emergency
        self._est_fired_at: float | None = None
        self._est_held = False  # the estimator failsafe's hold was taken (not one already in force)
        self._gps_t: float | None = None
        self._gps_lost = False
        self._geofence = False
        self._state: Odometry | None = None
        if self.takeover is not None and hasattr(self.takeover, "reset"):
            self.takeover.reset()
        if self.motor is not None:
            self.motor.reset()
        self.attitude.reset()

    def setup(self, bus: BusView) -> None:
        if self.motor is not None:  # every command and rate sample (without an IMU: every state, e.g. truth at 1 kHz)
            self._commands = bus.subscribe(Topics.ACTUATOR_COMMAND)
            self._rates = bus.subscribe(self.imu_topic if self.imu_topic is not None else self.active_state_topic)
        if self.gps_topic is not None:
            self._gps = bus.subscribe(self.gps_topic)
        if self._own_health and self.estimator_diagnostics:
            self.health.setup(bus)

    @property
    def ended_flight(self) -> str | None:
        """'failsafe_landed' / 'failsafe_returned' once a failsafe took the vehicle down, else None (also when the
        operator took over from the commander afterwards)."""
        if not self.took:  # (the harness asks at every physics step)
            return None
        overridden = getattr(self.takeover, "overridden", None)
        if overridden is not None and overridden():
            return None
        if self.took in ("land", "disarm"):
            return "failsafe_landed"
        if self.took == "rtl":
            return "failsafe_returned"
        return None

    # -- transitions -----------------------------------------------------------------------------------------
    def _fire(
        self, t: float, action: str, reason: str, bus: BusView, urgent: bool = False, temporary: bool = False
    ) -> bool:
        """Takes ``action`` unless one as drastic was taken; publishes the event. True when it was taken."""
        if ACTION_RANK[action] <= ACTION_RANK[self.action] and action != "warning":
            return False
        note = ""
        if self.takeover is not None and action in ("hold", "rtl", "land") and self.takeover.landing(t):
            self.action = action  # the owner lands already: nothing to take over (and no escalation to repeat)
            self._event(t, action, reason + " (landing already)")
            return True
        if self.takeover is not None and action != "warning":
            if action == "hold":
                note = self.takeover.hold(t, reason, bus, temporary)
            elif action == "rtl":
                note = self.takeover.rtl(t, reason, bus)
            elif action == "land":
                note = self.takeover.land(t, reason, bus, urgent)
            elif action == "disarm":
                note = self.takeover.disarm(t, reason, bus)
        elif self.takeover is None and action != "warning":
            note = "nothing to take the reference from"
        if action != "warning":
            self.action = action
            if self.takeover is not None and not note:
                self.took = action
        self._event(t, action, reason + (f" ({note})" if note else ""))
        return True

    def _event(self, t: float, action: str, message: str) -> None:
        text = (
            f"failsafe {action}: {message}" if action not in ("info", "warning", "cleared") else f"failsafe: {message}"
        )
        self.records.append([round(float(t), 3), action, text])
        self.events.append(t, "failsafe", text, action=action, severity=_SEVERITY.get(action, "info"))

    # -- the periodic step -----------------------------------------------------------------------------------
    def step(self, t: float, bus: BusView) -> None:
        state = bus.latest(self.active_state_topic)
        if state is not None:
            self._state = state
            if self.home_W is None:
                self.home_W = np.array(state.p_W, dtype=float)
                if self.takeover is not None and getattr(self.takeover, "home_W", None) is None:
                    try:
                        self.takeover.home_W = self.home_W.copy()
                    except AttributeError:  # the commander's home is its own
                        pass
        healthy, why = self.health.update(t) if self.estimator_diagnostics else (True, "")
        gps_ok = self._gps_check(t, bus)
        if self._state is None:
            self._feed_motor(t, False)
            return
        s = self._state
        home = self._home()
        was = self.airborne
        self.airborne = (
            bool(float(s.p_W[2]) - float(home[2]) > 0.25)
            if not was
            else bool(float(s.p_W[2]) - float(home[2]) > 0.05 or float(np.linalg.norm(s.v_W)) > 0.2)
        )
        # the motor detector watches the air between take-off and the landing (touching down, the ground's contact
        # torques are no failure, and a landing is what it would ask for); a fresh observer after each gap
        feeding = self.airborne and not (self.takeover is not None and self.takeover.landing(t))
        if feeding and not self._feeding and self.motor is not None and not self.motor.failed:
            self.motor.reset()
        self._feeding = feeding
        self._feed_motor(t, feeding)
        if not self.airborne or self.action == "disarm":
            return
        # attitude failure: terminate
        if self.attitude.update(t, s.q_WB):
            self._fire(t, "disarm", f"attitude failure: {self.attitude.reason}", bus, urgent=True)
            return
        if self.motor is not None and self.motor.failed:
            m = self.motor
            self._fire(
                t,
                "land",
                f"motor failure: motor {m.motor + 1 if m.motor is not None else '?'} "
                f"(rate residual {m.peak:.2f} of a rotor's hover torque)",
                bus,
                urgent=True,
            )
        self._battery(t, bus)
        landing = self.takeover is not None and self.takeover.landing(t)
        problem = self._estimate_problem(t, healthy, why, gps_ok)
        if problem is not None:
            t0, why = problem
            if self._est_fired_at is None:
                if not landing and t - t0 >= self.params.COM_POS_FS_DELAY:
                    self._est_fired_at = t
                    self._est_held = self._fire(t, "hold", f"estimator unhealthy ({why})", bus, temporary=True)
            elif (
                t - self._est_fired_at >= self.params.COM_FAIL_ACT_T and ACTION_RANK[self.action] < ACTION_RANK["land"]
            ):
                self._fire(t, "land", f"estimator unhealthy for {t - t0:.1f} s ({why})", bus)
        elif self._est_fired_at is not None:
            if self._est_held and self.action == "hold":  # recovered before the landing (a landing once begun goes on)
                self._event(t, "cleared", f"estimator healthy again after {t - self._est_fired_at:.1f} s")
                if self.took != "hold":  # the owner flew on by itself (a mission at its rest point, a follower's path)
                    self.action = "none"  # so the next spell holds again
            self._est_fired_at = None
            self._est_held = False
        self._geofence_check(t, s, home, bus)

    def _estimate_problem(self, t: float, healthy: bool, why: str, gps_ok: bool) -> tuple[float, str] | None:
        """(since when [s], why) the estimate is unusable, or None."""
        if not healthy:
            t0 = self.health.t_unhealthy
            return (t if t0 is None else t0), why or "unhealthy"
        if not gps_ok:
            assert self._gps_t is not None
            return self._gps_t + self.params.GPS_LOSS_T, "GPS lost and the estimate has no other position source"
        return None

    def _home(self) -> np.ndarray:
        h = getattr(self.takeover, "home_W", None) if self.takeover is not None else None
        if h is not None and np.all(np.isfinite(h)):
            return np.asarray(h, dtype=float)
        return self.home_W if self.home_W is not None else np.zeros(3)

    def _feed_motor(self, t: float, airborne: bool) -> None:
        """The motor failure detector takes the commands and rates since the last step (only in the air)."""
        m = self.motor
        if m is None:
            return
        cmds = self._commands.take()
        rates = self._rates.take()
        if not airborne:
            return
        use_imu = self.imu_topic is not None
        stride = 1  # the observer takes at most 100 Hz: skip the samples it would not take without looking at them
        if len(rates) > 1:
            dt = float(rates[1].t) - float(rates[0].t)
            stride = max(1, int(m.min_dt / dt + 0.5)) if dt > 0 else 1
        cmd_t = [float(c.t) for c in cmds]
        applied = -1
        for r in rates[::stride]:  # in time order, the command in force at each sample's stamp
            tr = float(r.t)
            if not m.due(tr):
                continue
            k = bisect.bisect_right(cmd_t, tr) - 1
            if k > applied:
                m.command(cmd_t[k], cmds[k].rotor_speeds)
                applied = k
            m.gyro(tr, self.R_BI @ np.asarray(r.w_I, dtype=float) if use_imu else r.w_B)
        if cmds and applied < len(cmds) - 1:
            m.command(cmd_t[-1], cmds[-1].rotor_speeds)

    def _battery(self, t: float, bus: BusView) -> None:
        b = bus.latest(Topics.BATTERY)
        if b is None:
            return
        pp = self.params
        r = float(b.remaining)
        level = 3 if r <= pp.BAT_EMERGEN_THR else 2 if r <= pp.BAT_CRIT_THR else 1 if r <= pp.BAT_LOW_THR else 0
        if level <= self._battery_level:
            return
        self._battery_level = level
        name = {1: "low", 2: "critical", 3: "emergency"}[level]
        reason = f"battery {name} ({100 * r:.0f} % remaining, {float(b.voltage_v):.2f} V)"
        act = pp.COM_LOW_BAT_ACT
        if act == 0:
            action = "warning"
        elif act == 1:
            action = "rtl" if level == 1 else "land"
        elif act == 2:
            action = "warning" if level == 1 else "land"
        else:
            action = "warning" if level == 1 else "rtl" if level == 2 else "land"
        if not self._fire(t, action, reason, bus):
            self._event(t, "warning", reason + f" (already in {self.action})")

    def _gps_check(self, t: float, bus: BusView) -> bool:
        """False when the GPS is lost and the estimate has nothing else (GPS-only); a loss with another source is
        an info event only."""
        if self.gps_topic is None:
            return True
        for g in self._gps.take():
            if int(getattr(g, "fix_type", 3)) >= 3:
                self._gps_t = float(t)
        if self._gps_t is None:
            return True  # no fix yet: nothing to lose
        lost = t - self._gps_t > self.params.GPS_LOSS_T
        if lost != self._gps_lost:
            self._gps_lost = lost
            if not self.gps_only:
                self.events.append(
                    t,
                    "info",
                    "GPS lost: flying on the estimator's other sources (no failsafe)" if lost else "GPS regained",
                    severity="info",
                )
        return not (lost and self.gps_only)

    def _geofence_check(self, t: float, s: Odometry, home: np.ndarray, bus: BusView) -> None:
        pp = self.params
        if self._geofence or pp.GF_ACTION == 0 or (pp.GF_MAX_HOR_DIST <= 0 and pp.GF_MAX_VER_DIST <= 0):
            return
        d = np.asarray(s.p_W, dtype=float) - home
        hor, ver = float(math.hypot(d[0], d[1])), float(d[2])
        why = ""
        if pp.GF_MAX_HOR_DIST > 0 and hor > pp.GF_MAX_HOR_DIST:
            why = f"geofence: beyond GF_MAX_HOR_DIST {pp.GF_MAX_HOR_DIST:g} m ({hor:.2f} m from home)"
        elif pp.GF_MAX_VER_DIST > 0 and ver > pp.GF_MAX_VER_DIST:
            why = f"geofence: beyond GF_MAX_VER_DIST {pp.GF_MAX_VER_DIST:g} m ({ver:.2f} m above home)"
        if not why:
            return
        self._geofence = True
        action = {1: "warning", 2: "hold", 3: "rtl", 4: "disarm", 5: "land"}[pp.GF_ACTION]
        if not self._fire(t, action, why, bus):
            self._event(t, "warning", why + f" (already in {self.action})")

    def update(self, t: float, state: Odometry, bus: BusView) -> None:  # Planner's hook (step does it all)
        pass
