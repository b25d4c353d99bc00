"""Touchdown detection and disarm at the end of a landing, as PX4's multicopter land detector does it, for flights
whose reference a trajectory follower flies (``square``, ``square_lio``: the ``waypoints`` planner; ``tunnel``: the
mission's), with or without the failsafe supervisor.

The planned reference ends at rest on the ground *as the estimate sees it*: with an estimate that reads the vehicle
lower than it is, the vehicle would hover above the ground for ever (and the run end in ``timeout``). So, once the
reference has ended (``t_end``) and ``grace_s`` later the vehicle has not been seen landed, the landing goes on:
straight down at ``descend_speed`` [m/s] below the reference's end (PX4's land mode descends until the land
detector says landed, whatever the estimate's height). Touchdown (:class:`LandDetector`, flight data only: the
estimate's vertical speed and the commanded collective thrust) is: thrust below ``low_thrust_fraction`` of the
hover thrust, |v_z| below ``z_vel_max``, no climb, all held for ``trigger_s``; then the detector publishes a
disarmed :class:`~cufund.core.messages.VehicleStatus` (the rotors stop, :mod:`cufund.control.arming`) and the run's
end condition (:func:`cufund.scenarios.build.done_condition`) ends the run once the vehicle rests.

A nominal flight ends before the detector acts (its run ends when it rests on the ground at ``t_end``), so its
figures are unchanged.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cufund.core.components import BusView, Planner
from cufund.core.messages import Topics
from cufund.planning.point_to_point import JerkLimitedMove

from .failsafe_takeover import disarmed_status

__all__ = ["LandDetector", "LandDetectorComponent", "land_detector_components", "land_detector_done"]


class LandDetector:
    """The touchdown test on flight data (PX4's ``MulticopterLandDetector``, simplified): ``update`` returns True
    once the vehicle has looked landed for ``trigger_s`` [s]: commanded thrust below ``low_thrust_fraction`` of
    ``hover_thrust_N``, |v_z| < ``z_vel_max`` [m/s] and not climbing (v_z < ``z_vel_max`` / 2)."""

    def __init__(
        self,
        hover_thrust_N: float,
        low_thrust_fraction: float = 0.5,
        z_vel_max: float = 0.25,
        trigger_s: float = 0.5,
    ) -> None:
        if not (math.isfinite(hover_thrust_N) and hover_thrust_N > 0):
            raise ValueError(f"LandDetector: hover_thrust_N must be a positive number of newtons, got {hover_thrust_N}")
        if not 0 < low_thrust_fraction < 1:
            raise ValueError(f"LandDetector: low_thrust_fraction must be in (0, 1), got {low_thrust_fraction}")
        if not z_vel_max > 0 or not trigger_s >= 0:
            raise ValueError(f"LandDetector: z_vel_max > 0 and trigger_s >= 0 expected, got {z_vel_max}, {trigger_s}")
        self.hover_thrust_N = float(hover_thrust_N)
        self.low_thrust_fraction, self.z_vel_max, self.trigger_s = low_thrust_fraction, z_vel_max, trigger_s
        self.reset()

    def reset(self) -> None:
        self.since: float | None = None
        self.landed = False

    def maybe_landed(self, v_z: float, thrust_N: float) -> bool:
        """The instantaneous test (no time filter)."""
        return (
            math.isfinite(v_z)
            and math.isfinite(thrust_N)
            and thrust_N < self.low_thrust_fraction * self.hover_thrust_N
            and abs(v_z) < self.z_vel_max
            and v_z < 0.5 * self.z_vel_max
        )

    def update(self, t: float, v_z: float, thrust_N: float) -> bool:
        if self.landed:
            return True
        if self.maybe_landed(v_z, thrust_N):
            self.since = t if self.since is None else self.since
            self.landed = t - self.since >= self.trigger_s
        else:
            self.since = None
        return self.landed


class LandDetectorComponent(Planner):
    """Continues a follower's landing below its reference's end until touchdown, then disarms (see the module
    doc). ``follower``: the :class:`~cufund.planning.trajectory_follower.TrajectoryFollower` flying the reference
    (its ``initial_trajectory`` ends on the ground at ``t_end``); ``hover_thrust_N``: mass x g."""

    name = "land_detector"
    writes = (Topics.VEHICLE_STATUS,)
    latency_s = 1e-3  # its disarm reaches the controllers a millisecond later (no zero-latency cycle)

    def __init__(
        self,
        follower: Any,
        hover_thrust_N: float,
        grace_s: float = 1.0,
        descend_speed: float = 0.3,
        rate_hz: float = 50.0,
    ) -> None:
        self.follower = follower
        self.detector = LandDetector(hover_thrust_N)
        self.grace_s, self.descend_speed, self.rate_hz = float(grace_s), float(descend_speed), float(rate_hz)
        self.optional_reads = (Topics.ATTITUDE_SETPOINT,)
        first = follower.initial_trajectory
        self.ground_z = float(first.sample(float(first.t_start)).p_W[0][2])
        """The height the reference starts from (the pad, in the estimate's frame) [m]."""
        self.ground_tol = 0.1
        self.reset()

    def reset(self) -> None:
        self.detector.reset()
        self.descending = False
        self.disarmed_at: float | None = None

    @property
    def t_end(self) -> float:
        """When the follower's current reference ends [s] (a failsafe's or a replanner's stitched one included;
        inf for a hold that nobody ends)."""
        tr = self.follower.trajectory
        return float(tr.t_start) + float(tr.duration)

    def _landing_ended(self, t: float) -> float | None:
        """The end time of the current reference when it has ended on the ground it started from (within
        ``ground_tol`` [m]), else None: a reference resting in the air (a replanner between plans, a hold) is
        no landing."""
        t_end = self.t_end
        if not math.isfinite(t_end) or t < t_end:
            return None
        z_end = float(self.follower.trajectory.sample(t_end).p_W[0][2])
        return t_end if z_end <= self.ground_z + self.ground_tol else None

    def step(self, t: float, bus: BusView) -> None:
        if self.disarmed_at is not None:
            return
        t_end = -math.inf if self.descending else self._landing_ended(t)
        if t_end is None:
            return
        state = bus.latest(self.active_state_topic)
        sp = bus.latest(Topics.ATTITUDE_SETPOINT)
        if state is None or sp is None:
            return
        if self.detector.update(t, float(state.v_W[2]), float(sp.thrust)):
            self.disarmed_at = t
            bus.publish(Topics.VEHICLE_STATUS, disarmed_status(t, "landed (land detector)"))
            return
        if not self.descending and t >= t_end + self.grace_s:
            self._descend(t)

    def update(self, t: float, state: Any, bus: BusView) -> None:  # Planner's hook (step does it all)
        pass

    def _descend(self, t: float) -> None:
        """Straight down at descend_speed from the reference's state (a jerk-limited move far below it)."""
        s = self.follower.trajectory.sample(float(t))
        p, yaw = np.array(s.p_W[0], float), float(s.yaw[0])
        target = p - np.array([0.0, 0.0, 100.0])
        move = JerkLimitedMove(p, target, self.descend_speed, 1.0, 2.0, yaw, t_start=t)
        # the follower's own stitch (a failsafe takeover stops a planner's updates there, not this landing's)
        type(self.follower).stitch(self.follower, float(t), move)
        self.descending = True


def land_detector_components(ctx: Any, components: list[Any]) -> list[Any]:
    """The detector for a scenario whose reference a trajectory follower flies (the ``waypoints`` planner's, the
    replanners', the tunnel mission's); none under a commander, which descends until its own touchdown test."""
    from cufund.control.arming import make_armable
    from cufund.planning.trajectory_follower import TrajectoryFollower

    if ctx.commander is not None:
        return []
    follower = next(
        (
            c
            for c in components
            if isinstance(c, TrajectoryFollower) and str(Topics.TRAJECTORY_SETPOINT) in map(str, c.writes)
        ),
        None,
    )
    if follower is None:
        return []
    make_armable(components)  # its disarm stops the rotors (nothing is published before: the controllers fly as ever)
    return [LandDetectorComponent(follower, ctx.vehicle.mass * 9.81)]


def land_detector_done(components: Any, done: Any) -> Any:
    """The run's end condition ``done(t, truth)`` (a harness check) extended: once the land detector has disarmed,
    the run ends when the vehicle rests (|v| < 0.05 m/s)."""
    detector = next((c for c in components if isinstance(c, LandDetectorComponent)), None)
    if detector is None:
        return done

    def ended(t: float, truth: Any) -> bool:
        if done is not None and done(t, truth):
            return True
        return detector.disarmed_at is not None and float(np.linalg.norm(truth.v_W)) < 0.05

    return ended
