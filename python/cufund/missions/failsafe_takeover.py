"""How the failsafe supervisor takes the reference over from whatever flies the vehicle: one small adapter per kind
of reference owner, all with the same four actions (``hold``, ``land``, ``rtl``, ``disarm``) and ``landing(t)``
(the owner is landing already: a failsafe that would land has nothing to do).

- :class:`CommanderTakeover`: a :class:`~cufund.missions.commander.Commander` (``cufund serve``, the ground
  station, scripted flights): the failsafe is applied as the commander's own hold / land / rtl / forced disarm,
  as PX4's commander switches its navigation state.
- :class:`FollowerTakeover`: a :class:`~cufund.planning.trajectory_follower.TrajectoryFollower` flying a
  precomputed or replanned reference (the ``waypoints`` planner, the replanners): the failsafe's trajectory (a
  jerk-limited stop, then hold / landing / return) is stitched into the follower from now on. A takeover is final:
  the planner's reference is not resumed (PX4 does not resume a mission after a failsafe either).
- :class:`MissionTakeover`: a mission that executes failsafes itself (the tunnel mission: it lands outside the
  course, backing out of a frame's opening first); the request is handed to it.

A disarm without a commander publishes a disarmed :class:`~cufund.core.messages.VehicleStatus`, which the
controllers (made armable when the supervisor is built) obey: the rotors stop.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cufund.core.messages import FlightMode, Topics, VehicleStatus
from cufund.planning.landing import landing
from cufund.planning.point_to_point import JerkLimitedMove
from cufund.planning.sequence import Hold, TrajectorySequence

__all__ = ["CommanderTakeover", "FollowerTakeover", "MissionTakeover", "disarmed_status"]

_FOREVER = 1e6


def disarmed_status(t: float, reason: str) -> VehicleStatus:
    """The status that stops the rotors of armable controllers (see :mod:`cufund.control.arming`)."""
    nan3 = np.full(3, np.nan)
    return VehicleStatus(t, False, "idle", False, FlightMode.POSITION, "", -1, 0, nan3, nan3.copy(), reason)


class CommanderTakeover:
    """Failsafes through the commander's own modes."""

    def __init__(self, commander: Any) -> None:
        self.commander = commander

    @property
    def home_W(self) -> np.ndarray | None:
        h = np.asarray(self.commander.home_p_W, dtype=float)
        return h if np.all(np.isfinite(h)) else None

    def landing(self, t: float) -> bool:
        return self.commander.mode == "land" or not self.commander.airborne

    def _do(self, t: float, command: dict[str, Any]) -> str:
        ack = self.commander.apply(command, t)
        if ack.result != "accepted":
            return f"the commander refused {command['command']}: {ack.message}"
        self._since = len(self.commander.events)
        return ""

    _FAILSAFE_MODES = ("hold", "rtl", "land", "idle")

    def settled(self) -> bool:
        """The commander has landed and disarmed (what ends a run the failsafe took down)."""
        return not self.commander.armed

    def overridden(self) -> bool:
        """Whether the operator took over after the failsafe (a mode other than the failsafe's own followed)."""
        since = getattr(self, "_since", None)
        if since is None:
            return False
        return any(
            e["kind"] == "mode" and e.get("mode") not in self._FAILSAFE_MODES
            for e in self.commander.events.since(since)
        )

    def hold(self, t: float, reason: str, bus: Any, temporary: bool = False) -> str:
        return self._do(t, {"command": "hold"})

    def land(self, t: float, reason: str, bus: Any, urgent: bool = False) -> str:
        return self._do(t, {"command": "land"})

    def rtl(self, t: float, reason: str, bus: Any) -> str:
        if self.commander.mode in ("rtl", "land"):
            return ""
        return self._do(t, {"command": "rtl"})

    def disarm(self, t: float, reason: str, bus: Any) -> str:
        return self._do(t, {"command": "disarm", "force": True})


class FollowerTakeover:
    """Failsafes stitched into a trajectory follower's reference (``params``: the :class:`FailsafeParams`)."""

    def __init__(self, follower: Any, params: Any, a_max: float = 2.0, j_max: float = 5.0) -> None:
        self.follower, self.params = follower, params
        self.a_max, self.j_max = float(a_max), float(j_max)
        self.home_W: np.ndarray | None = None
        """Set by the supervisor (where the vehicle stood when it first had a state)."""
        ref = follower.initial_trajectory
        last: Any = ref.parts[-1] if isinstance(ref, TrajectorySequence) else None
        self._t_landing = np.inf
        if last is not None and float(last.sample(last.t_end).p_W[0][2]) < float(last.sample(last.t_start).p_W[0][2]):
            self._t_landing = float(last.t_start)  # the planned reference ends with a descent to the ground
        self.taken = ""
        """The action flown since the takeover ('' before)."""
        self._stitch = follower.stitch
        follower.stitch = self._planner_update  # a replanner's updates reach the follower only before a takeover

    def _planner_update(self, t: float, new: Any) -> None:
        if not self.taken:
            self._stitch(t, new)

    def reset(self) -> None:
        self.taken = ""

    def landing(self, t: float) -> bool:
        return self.taken in ("land", "rtl") or t >= self._t_landing

    def _stop(self, t: float) -> tuple[JerkLimitedMove | None, np.ndarray, float]:
        """A jerk-limited stop from the reference's state at ``t``: (the move or None when at rest, where it
        ends, the heading)."""
        s = self.follower.trajectory.sample(float(t))
        p, v, a, yaw = s.p_W[0], s.v_W[0], s.a_W[0], float(s.yaw[0])
        if float(np.linalg.norm(v)) < 1e-3 and float(np.linalg.norm(a)) < 1e-3:
            return None, np.array(p, float), yaw
        stop = p + v * np.abs(v) / (2.0 * self.a_max) + 0.05 * v
        vmax = max(float(np.max(np.abs(v))) + 1e-3, self.params.MPC_XY_CRUISE)
        try:
            move = JerkLimitedMove(
                p, stop, vmax, self.a_max * 1.5, self.j_max * 2, yaw, t_start=t, start_v_W=v, start_a_W=a
            )
        except ValueError:  # a state ruckig cannot start from: from rest at the reference
            move = JerkLimitedMove(p, stop, vmax, self.a_max, self.j_max, yaw, t_start=t)
        return move, stop, yaw

    def _fly(self, t: float, parts: list[Any], action: str) -> str:
        self._stitch(float(t), TrajectorySequence(parts) if len(parts) > 1 else parts[0])
        self.taken = action
        return ""

    def _ground(self) -> float:
        return float(self.home_W[2]) if self.home_W is not None else 0.0

    def hold(self, t: float, reason: str, bus: Any, temporary: bool = False) -> str:
        if temporary:  # the estimator's hold-then-land: a follower's hold could not be given back when it recovers
            return "the planned path is kept: a follower's hold cannot be resumed"
        move, p, yaw = self._stop(t)
        t0 = move.t_end if move is not None else t
        return self._fly(t, [*([move] if move else []), Hold(p, _FOREVER, yaw, t_start=t0)], "hold")

    def land(self, t: float, reason: str, bus: Any, urgent: bool = False) -> str:
        if self.taken == "land":
            return ""
        move, p, yaw = self._stop(t)
        t0 = move.t_end if move is not None else t
        pp = self.params
        down, _ = landing(
            p, self._ground(), pp.MPC_XY_CRUISE, self.a_max, self.j_max, yaw, t0, slow_speed=pp.MPC_LAND_SPEED
        )
        return self._fly(t, [*([move] if move else []), *down.parts], "land")

    def rtl(self, t: float, reason: str, bus: Any) -> str:
        if self.taken in ("rtl", "land"):
            return ""
        if self.home_W is None:
            return self.land(t, reason, bus) or "no home position: landing here"
        pp = self.params
        move, p, yaw = self._stop(t)
        t0 = move.t_end if move is not None else t
        z = max(float(p[2]), float(self.home_W[2]) + pp.RTL_RETURN_ALT)
        up = np.array([p[0], p[1], z])
        over = np.array([self.home_W[0], self.home_W[1], z])
        parts: list[Any] = [move] if move else []
        for a, b in ((p, up), (up, over)):
            if float(np.linalg.norm(b - a)) > 1e-3:
                leg = JerkLimitedMove(a, b, pp.MPC_XY_CRUISE, self.a_max, self.j_max, yaw, t_start=t0)
                parts.append(leg)
                t0 = leg.t_end
        down, _ = landing(
            over, self._ground(), pp.MPC_XY_CRUISE, self.a_max, self.j_max, yaw, t0, slow_speed=pp.MPC_LAND_SPEED
        )
        parts += down.parts
        return self._fly(t, parts, "rtl")

    def disarm(self, t: float, reason: str, bus: Any) -> str:
        bus.publish(Topics.VEHICLE_STATUS, disarmed_status(t, reason))
        self.taken = "disarm"
        return ""


class MissionTakeover:
    """Hands each failsafe to a mission that executes it itself (its ``failsafe(t, action, reason, urgent)``
    returns what it did, '' when it did as asked); disarming still goes through the controllers' status."""

    def __init__(self, mission: Any) -> None:
        self.mission = mission
        self.home_W: np.ndarray | None = None

    def landing(self, t: float) -> bool:
        return self.mission.state in ("land", "done", "aborted")

    def settled(self) -> bool:
        return bool(self.mission.finished)

    def hold(self, t: float, reason: str, bus: Any, temporary: bool = False) -> str:
        return self.mission.failsafe(t, "hold", reason, False)

    def land(self, t: float, reason: str, bus: Any, urgent: bool = False) -> str:
        return self.mission.failsafe(t, "land", reason, urgent)

    def rtl(self, t: float, reason: str, bus: Any) -> str:
        return self.mission.failsafe(t, "rtl", reason, False)

    def disarm(self, t: float, reason: str, bus: Any) -> str:
        bus.publish(Topics.VEHICLE_STATUS, disarmed_status(t, reason))
        return ""
