"""Wiring the failsafe supervisor into a scenario (called by :func:`cufund.scenarios.build.build_simulation` once
every part is built): which reference owner it takes over from, which sensors it watches, and the metrics it adds
(``failsafe_events``, and ``status`` ``failsafe_landed`` / ``failsafe_returned`` when a failsafe ended the flight)."""

from __future__ import annotations

from typing import Any

import numpy as np

from cufund.control.arming import make_armable
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.planning.trajectory_follower import TrajectoryFollower

from .failsafe_params import FailsafeParams
from .failsafe_supervisor import FailsafeSupervisor
from .failsafe_takeover import CommanderTakeover, FollowerTakeover, MissionTakeover

__all__ = ["failsafe_components", "failsafe_done", "failsafe_metrics"]

_OTHER_POSITION_SOURCES = ("lidar", "pose", "camera", "depth", "rgb")


def _sensor(ctx: Any, sensor_type: str) -> tuple[str, Any] | None:
    try:
        return ctx.sensor_of_type(sensor_type, "", "failsafe")
    except ConfigError:
        return None


def failsafe_components(params: FailsafeParams | None, ctx: Any, components: list[Any]) -> list[Any]:
    """The supervisor for the built ``components`` (none when ``params`` is None: ``failsafe: off``)."""
    if params is None:
        return []
    commander = ctx.commander
    mission = next((c for c in components if callable(getattr(c, "failsafe", None))), None)
    follower = next(
        (
            c
            for c in components
            if isinstance(c, TrajectoryFollower) and str(Topics.TRAJECTORY_SETPOINT) in map(str, c.writes)
        ),
        None,
    )
    takeover: Any = None
    if commander is not None:
        takeover = CommanderTakeover(commander)
    elif mission is not None:
        takeover = MissionTakeover(mission)
    elif follower is not None:
        takeover = FollowerTakeover(
            follower, params, ctx.config.trajectory.move_a_max, ctx.config.trajectory.move_j_max
        )
    imu = _sensor(ctx, "imu")
    gps = _sensor(ctx, "gps")
    gps_topic = str(gps[1].topic) if gps is not None else None
    estimators = [c for c in components if str(Topics.ESTIMATE) in map(str, getattr(c, "outputs", ()))]
    reads = {str(t) for c in estimators for t in getattr(c, "inputs", ())}
    others = {str(s.topic) for s in ctx.config.sensors.values() if s.sensor_type in _OTHER_POSITION_SOURCES}
    gps_only = gps_topic is not None and gps_topic in reads and not (reads & others)
    diagnostics = any(str(Topics.ESTIMATOR_DIAGNOSTICS) in map(str, getattr(c, "outputs", ())) for c in components)
    supervisor = FailsafeSupervisor(
        params,
        takeover,
        vehicle=ctx.vehicle,
        imu_topic=str(imu[1].topic) if imu is not None else None,
        q_BI=ctx.imu_params().q_BI if imu is not None else None,
        gps_topic=gps_topic,
        gps_only=gps_only,
        estimator_diagnostics=diagnostics,
        health=getattr(mission, "health", None),  # the tunnel mission waits on the same monitor
        events=commander.events if commander is not None else None,
        disarm_output=commander is None,
    )
    if commander is None:
        make_armable(components)  # a disarm stops the rotors (with no status published the controllers fly as ever)
    ctx.add_metric_hook(lambda result: failsafe_metrics(result, supervisor))
    return [supervisor]


def failsafe_metrics(result: Any, supervisor: FailsafeSupervisor | None) -> dict[str, Any]:
    """``failsafe_events`` ([t, action, reason] list, [] when none) and the ``status`` a failsafe ended with."""
    if supervisor is None:
        return {"failsafe_events": []}
    out: dict[str, Any] = {"failsafe_events": [list(r) for r in supervisor.records]}
    ended = supervisor.ended_flight
    if ended is not None and result.status.value == "completed":
        out["status"] = ended
    return out


def failsafe_done(components: Any, done: Any) -> Any:
    """The run's end condition ``done(t, truth)`` (a harness check, like the others) extended: a flight that a
    failsafe took down ends once the vehicle rests on the ground it started from."""
    supervisor = next((c for c in components if isinstance(c, FailsafeSupervisor)), None)
    if supervisor is None:
        return done
    ground: float | None = None

    def ended(t: float, truth: Any) -> bool:
        nonlocal ground
        if ground is None:
            ground = float(truth.p_W[2])  # where it started (the first check, at t = 0)
        if done is not None and done(t, truth):
            return True
        if not supervisor.took:  # the common case, cheap: the harness asks at every physics step
            return False
        settled = getattr(supervisor.takeover, "settled", None)
        return (
            supervisor.ended_flight is not None
            and (settled is None or settled())
            and float(truth.p_W[2]) < ground + 0.03
            and float(np.linalg.norm(truth.v_W)) < 0.05
        )

    return ended
