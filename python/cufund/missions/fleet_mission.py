"""The ``fleet`` mission kind: one plain-language request flown by every vehicle of a fleet through its own commander
(docs/guides/fleet-missions.md).

Each vehicle's scenario (``cufund.scenarios.fleet.vehicle_scenario``, named ``FLEET.NAME``) builds this kind with the
same parameters and makes the same plan: the request read by the offline grammar
(:func:`~cufund.missions.mission_request_grammar.request_to_data`; free text is refused in a scenario, a chat
endpoint's answer would not be reproducible), checked against the fleet's ``homes``, ``fields`` and ``geofence``,
each vehicle's share of the waypoints, and start delays from priority-based time-shifting
(:func:`~cufund.missions.deconfliction.time_shift`, vehicles in ``homes`` order) of the trajectories the commanders
will fly (:func:`~cufund.missions.fleet_timing.commander_trajectory`: take-off, the jerk-limited legs, the return and landing) so that they keep
``min_separation``. The vehicle then flies its
share: at its start time it arms, uploads the waypoints and starts the mission (the commander takes off first), and
once the mission completes it returns home and lands (``rtl``).

The plan models the commander's reference, not the vehicle's tracking lag (each leg ends once the vehicle is within
``acceptance_radius``): ``min_separation`` carries that margin.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.components import BusView, Component
from cufund.core.config import ConfigError
from cufund.core.registry import Kind, register

from .commands import Command, parse_command
from .deconfliction import Trajectory, min_separation, time_shift
from .fleet_context import FleetContext, MissionRequestError
from .fleet_timing import commander_trajectory
from .mission_request_grammar import GrammarMiss, request_to_data
from .mission_request_schema import Formation, Mission, mission_from_data
from .params import CommanderParams

__all__ = ["FleetMissionParams", "FleetMissionRunner", "plan_fleet_mission"]


@dataclass(frozen=True)
class FleetMissionParams:
    """A fleet's mission from one request (see the module doc)."""

    request: str = ""
    """The plain-language request, one of the grammar's phrases (e.g. "survey the field with all drones at 4 m")."""
    homes: Mapping[str, Any] = field(default_factory=dict)
    """Every vehicle of the fleet and its home ``[x, y, z]`` [m] (its start), in priority order; each vehicle's own
    entry must equal its start."""
    fields: Mapping[str, Any] = field(default_factory=dict)
    """Named areas ``{name: [[x, y], ...]}`` [m] the request may name."""
    geofence: Any = None
    """Polygon ``[[x, y], ...]`` [m] every waypoint must lie in (null: none)."""
    vehicle: str | None = None
    """This vehicle's name (null: from the scenario's name ``FLEET.NAME``)."""
    min_altitude: float = 1.0
    """Lowest waypoint height [m]."""
    max_altitude: float = 50.0
    """Highest waypoint height [m]."""
    max_waypoints: int = 500
    """Most waypoints per vehicle."""
    min_separation: float = 2.0
    """Separation the planned trajectories keep [m] (time-shifting)."""
    start_s: float = 1.0
    """When the first vehicle arms and starts [s]."""
    return_home: bool = True
    """Return and land once the mission completes (else hold at its last waypoint)."""

    def __post_init__(self) -> None:
        if not isinstance(self.request, str) or not self.request.strip():
            raise ConfigError("mission.request must be the plain-language request (a non-empty string)")
        if not isinstance(self.homes, Mapping) or not self.homes:
            raise ConfigError("mission.homes must map every vehicle of the fleet to its home [x, y, z] [m]")
        for name in ("min_separation", "start_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"mission.{name} must be a finite number >= 0, got {v!r}")
        if not isinstance(self.return_home, bool):
            raise ConfigError(f"mission.return_home must be true or false, got {self.return_home!r}")
        if self.vehicle is not None and (not isinstance(self.vehicle, str) or self.vehicle not in self.homes):
            raise ConfigError(f"mission.vehicle must be one of mission.homes ({', '.join(self.homes)}), got "
                              f"{self.vehicle!r}")  # fmt: skip
        try:
            self.context()
        except MissionRequestError as e:
            raise ConfigError(f"mission: {e}") from None

    def context(self) -> FleetContext:
        return FleetContext(
            names=tuple(self.homes),
            homes={n: tuple(p) if isinstance(p, (list, tuple)) else p for n, p in self.homes.items()},
            fields=dict(self.fields),
            geofence=self.geofence,
            min_altitude=self.min_altitude,
            max_altitude=self.max_altitude,
            max_waypoints=self.max_waypoints,
        )


@dataclass(frozen=True, eq=False)
class FleetPlan:
    """The fleet's plan: the mission, each vehicle's waypoints, planned trajectory (from its mission_start) and start
    delay [s]."""

    mission: Mission
    waypoints: dict[str, np.ndarray]
    trajectories: dict[str, Trajectory]
    delays: dict[str, float]
    commands: dict[str, list[Command]]
    """Each vehicle's commands (the waypoints with the holds the plan timed with these commander parameters)."""


def plan_fleet_mission(p: FleetMissionParams, commander: CommanderParams | None = None) -> FleetPlan:
    """The plan every vehicle makes from ``p`` with the commander parameters ``commander`` (default
    :class:`CommanderParams`; give the fleet one planner so that every vehicle makes the same plan); ``ConfigError``
    with the reason when the request is refused or cannot be deconflicted."""
    cp = commander or CommanderParams()
    ctx = dataclasses.replace(p.context(), commander=cp)
    try:
        data = request_to_data(p.request, ctx)
        mission = mission_from_data(data, ctx)
    except GrammarMiss:
        raise ConfigError(
            f"mission.request {p.request!r} is not one of the grammar's phrases; a scenario takes those only (free "
            "text would need a chat endpoint, and the run would not be reproducible)"
        ) from None
    except MissionRequestError as e:
        raise ConfigError(f"mission.request refused: {e}") from None
    wps = mission.waypoints(ctx)
    holds = mission.holds(ctx)
    trajectories = {n: commander_trajectory(ctx.home(n), wp, cp, p.return_home, holds[n]) for n, wp in wps.items()}
    order = [n for n in ctx.names if n in wps]
    if isinstance(mission, Formation):  # flown in step: a delay would break it; the plan must be apart as it is
        delays = dict.fromkeys(order, 0.0)
        for i, a in enumerate(order):
            for b in order[i + 1 :]:
                d, t = min_separation(trajectories[a], trajectories[b])
                if d < p.min_separation:
                    raise ConfigError(
                        f"mission: in the formation {a} and {b} come within {d:.2f} m (t = {t:.1f} s after the start), "
                        f"under mission.min_separation {p.min_separation:g} m: start the vehicles in the formation's "
                        "order or further apart"
                    )
    else:
        try:
            delays = time_shift(trajectories, p.min_separation, priority=order)
        except ValueError as e:
            raise ConfigError(f"mission: the planned trajectories cannot be deconflicted: {e}") from None
    return FleetPlan(mission, wps, trajectories, delays, mission.commands(ctx))


class FleetMissionRunner(Component):
    """Flies this vehicle's share through its commander: arm, upload, start at ``start_t`` [s] (once the commander
    has a state), then return home when the mission completes."""

    name = "fleet_mission"
    rate_hz = 10.0

    def __init__(self, commander: Any, commands: list[Command], start_t: float, return_home: bool) -> None:
        self.commander = commander
        self.commands = commands
        self.start_t = start_t
        self.return_home = return_home
        self.reset()

    def reset(self) -> None:
        self.phase = "wait"
        self.started_at: float | None = None
        self.done_at: float | None = None
        self._events_at_start = 0

    def finished(self, t: float) -> bool:
        """The vehicle's part is through (returned and landed, or holding at the end) for a second."""
        return self.done_at is not None and t >= self.done_at + 1.0

    def step(self, t: float, bus: BusView) -> None:
        c = self.commander
        if self.phase == "wait" and t >= self.start_t and c.state is not None:
            if c.apply(parse_command("arm"), t).result == "accepted":
                self._events_at_start = len(c.events)
                for cmd in self.commands:
                    c.apply(cmd, t)
                self.phase, self.started_at = "mission", t
        elif self.phase == "mission":
            new = c.events.since(self._events_at_start)
            if any(e["kind"] == "mission_complete" for e in new):
                if self.return_home:
                    c.apply(parse_command("rtl"), t)
                self.phase = "return" if self.return_home else "done"
                self.done_at = None if self.return_home else t
        elif self.phase == "return" and c.landed and not c.armed:
            self.phase, self.done_at = "done", t


def _vehicle_name(p: FleetMissionParams, scenario_name: str) -> str:
    if p.vehicle is not None:
        return p.vehicle
    name = scenario_name.rsplit(".", 1)[-1]
    if "." not in scenario_name or name not in p.homes:
        raise ConfigError(
            f"mission (fleet): set mission.vehicle, or run it in a fleet (vehicle scenarios are named FLEET.NAME, "
            f"with NAME one of mission.homes: {', '.join(p.homes)}); got the scenario {scenario_name!r}"
        )
    return name


def build_fleet_mission(p: FleetMissionParams, ctx: BuildContext) -> list[Any]:
    cfg = ctx.config
    commander = ctx.commander
    if commander is None:
        raise ConfigError("mission (fleet) flies through the commander: set planner: {kind: commander}")
    me = _vehicle_name(p, cfg.name)
    start = np.asarray(cfg.start_p_W if cfg.start_p_W is not None else (0.0, 0.0, 0.0), dtype=float)
    home = p.context().home(me)
    if not np.allclose(start, home, atol=1e-6):
        raise ConfigError(f"mission.homes.{me} {home.tolist()} must be the vehicle's start {start.tolist()}")
    plan = plan_fleet_mission(p, commander.params)
    ctx.add_metric_hook(
        lambda result: {
            "fleet_mission": {
                "vehicle": me,
                "request": p.request,
                "mission": plan.mission.kind,
                "waypoints": int(len(plan.waypoints.get(me, ()))),
                "start_delay_s": plan.delays.get(me),
                "planned_length_m": None
                if me not in plan.waypoints
                else float(np.linalg.norm(np.diff(plan.waypoints[me], axis=0), axis=1).sum()),
                "completed": bool(commander.events.of_kind("mission_complete")),
            }
        }
    )
    if me not in plan.waypoints:
        commander.run_done = lambda t: True  # not part of this mission: stays on the ground
        return []
    commands = plan.commands[me]
    runner = FleetMissionRunner(commander, commands, p.start_s + plan.delays[me], p.return_home)
    commander.run_done = runner.finished  # the commander kind's end condition asks it (missions/kinds.py)
    return [runner]


register(
    Kind(
        "mission",
        "fleet",
        FleetMissionParams,
        build_fleet_mission,
        None,
        "a fleet's mission from one plain-language request: zigzag, orbit, survey split between the vehicles, "
        "go home; deconflicted by start delays, flown through each vehicle's commander",
    )
)
