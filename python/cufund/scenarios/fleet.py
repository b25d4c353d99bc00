"""A fleet scenario (``vehicles:``) built and run: each vehicle its own scenario, all in one world
(docs/guides/fleets.md).

Each vehicle's scenario is the fleet's with the vehicle's overrides, start pose and seed
(:func:`vehicle_scenario`); it is built as any single-vehicle scenario (:func:`build_simulation`) and run by one
:class:`~cufund.simulator.fleet.FleetSimulator` with the others. **Seeds:** vehicle ``name``'s scenario seed is
:func:`vehicle_seed` ``(seed, name)`` (a ``numpy.random.SeedSequence`` of the fleet's seed and the CRC-32 of
``"vehicles." + name``), and all its random streams derive from that seed as a single vehicle's do from its own; so
``cufund run`` of ``vehicle_scenario(config, name)`` (or of a scenario with ``seed: vehicle_seed(seed, name)`` and
that vehicle's parts) repeats that vehicle's streams, and its whole run bit for bit when no other vehicle came
near it. Adding, removing or renaming another vehicle does not change a vehicle's streams.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError
from cufund.missions.formation_link import connect_formation_links
from cufund.simulator import RunStatus
from cufund.simulator.fleet import FleetMember, FleetSimulator, namespaced

from .build import Built, ScenarioRun, build_simulation, done_condition, measure_run
from .fleet_schema import VehicleSpec
from .schema import ScenarioConfig, apply_overrides

__all__ = [
    "Fleet",
    "FleetRun",
    "FleetVehicle",
    "build_fleet",
    "fleet_metrics",
    "run_fleet",
    "vehicle_scenario",
    "vehicle_seed",
]


def vehicle_seed(seed: int, name: str) -> int:
    """The scenario seed of vehicle ``name`` in a fleet of scenario seed ``seed`` (see the module's docstring)."""
    return int(np.random.SeedSequence([int(seed), zlib.crc32(f"vehicles.{name}".encode())]).generate_state(1)[0])


def _spec(config: ScenarioConfig, name: str) -> VehicleSpec:
    if not config.vehicles:
        raise ConfigError(f"scenario {config.name!r} has no vehicles: list; it is a single-vehicle scenario")
    for v in config.vehicles:
        if v.name == name:
            return v
    raise ConfigError(
        f"no vehicle named {name!r} in vehicles; the fleet has {', '.join(v.name for v in config.vehicles)}"
    )


def vehicle_scenario(config: ScenarioConfig, name: str) -> ScenarioConfig:
    """Vehicle ``name``'s own scenario: the fleet's top-level parts with the vehicle's overrides (each replacing the
    part of its key), its start pose, and its seed :func:`vehicle_seed` ``(config.seed, name)``; named
    ``FLEET.NAME``. Run alone, it is that vehicle without the others."""
    v = _spec(config, name)
    data = config.to_dict()
    data.pop("vehicles", None)
    data.pop("downwash", None)  # a lone vehicle: no other's downwash
    data.update(v.overrides)
    data["name"] = f"{config.name}.{name}"
    data["seed"] = vehicle_seed(config.seed, name)
    if v.start_p_W is not None:
        data["start_p_W"] = list(v.start_p_W)
    data["start_yaw"] = v.start_yaw
    try:
        return ScenarioConfig.from_dict(apply_overrides(data, {}), config.base_dir)
    except ConfigError as e:
        raise ConfigError(f"vehicles.{name}: {e}") from None


@dataclass
class FleetVehicle:
    """One vehicle of a built fleet, as a single-vehicle :class:`Built` is driven: its simulator (and bus), its
    commander (None without one), its scenario; ``namespace`` prefixes its topics outside its own bus."""

    name: str
    built: Built

    @property
    def simulator(self) -> Any:
        return self.built.simulator

    @property
    def bus(self) -> Any:
        """Its simulator's bus (topics without the namespace: each vehicle has its own bus); None until the run
        starts (the fleet's first ``advance_to`` or ``run``)."""
        return getattr(self.built.simulator, "bus", None)

    @property
    def commander(self) -> Any:
        return self.built.context.commander

    @property
    def config(self) -> ScenarioConfig:
        return self.built.config

    @property
    def namespace(self) -> str:
        return f"/{self.name}"

    def topic(self, topic: str) -> str:
        """``topic`` of this vehicle in the fleet's namespace (``/uav1/sensors/imu``)."""
        return namespaced(self.name, topic)


@dataclass
class FleetRun:
    """A finished fleet run: each vehicle's :class:`ScenarioRun` and the fleet's metrics."""

    config: ScenarioConfig
    runs: dict[str, ScenarioRun]
    metrics: dict[str, Any]
    status: str
    message: str


class Fleet:
    """Vehicles in one world, built from a scenario with ``vehicles:`` (:func:`build_fleet`)."""

    def __init__(self, config: ScenarioConfig, vehicles: list[FleetVehicle], simulator: FleetSimulator) -> None:
        self.config = config
        self.vehicles = {v.name: v for v in vehicles}
        self.names = tuple(v.name for v in vehicles)
        self.simulator = simulator

    def vehicle(self, name: str) -> FleetVehicle:
        """The vehicle ``name`` (its simulator, bus, commander)."""
        try:
            return self.vehicles[name]
        except KeyError:
            raise KeyError(f"no vehicle named {name!r}; the fleet has {', '.join(self.names)}") from None

    @property
    def t(self) -> float:
        return self.simulator.t

    def advance_to(self, t: float) -> bool:
        """Every vehicle up to time ``t`` [s]; False once the fleet's run has ended."""
        return self.simulator.advance_to(t)

    def run(self, duration: float | None = None) -> FleetRun:
        """A new run of ``duration`` [s] (default the scenario's), measured."""
        self.simulator.run(self.config.duration if duration is None else duration)
        return self.measure()

    def measure(self) -> FleetRun:
        """Each vehicle's metrics (a single run's keys) under ``vehicles`` and the fleet's."""
        results = self.simulator.results()
        runs = {n: measure_run(self.vehicles[n].built, results[n]) for n in self.names}
        sim = self.simulator
        status = (sim.status or RunStatus.COMPLETED).value
        metrics = fleet_metrics(sim, runs)
        return FleetRun(self.config, runs, metrics, status, sim.message)


def fleet_metrics(sim: FleetSimulator, runs: dict[str, ScenarioRun]) -> dict[str, Any]:
    """``status``, ``message``, timing, ``fleet_min_separation_m`` (closest centre-to-centre distance of two
    vehicles, checked at the interaction rate), ``fleet_collisions`` (vehicle-vehicle contacts) and each vehicle's
    metrics under ``vehicles``."""
    sim_time = max((r.result.sim_time_s for r in runs.values()), default=0.0)
    wall = sim.wall_time_s
    out: dict[str, Any] = {
        "status": (sim.status or RunStatus.COMPLETED).value,
        "message": sim.message,
        "sim_time_s": sim_time,
        "wall_time_s": wall,
        "real_time_factor": sim_time / wall if wall > 0 else None,
        "fleet_size": len(runs),
        "fleet_min_separation_m": None if not np.isfinite(sim.min_separation_m) else sim.min_separation_m,
        "fleet_min_separation_at": None
        if sim.min_separation_at is None
        else {"t": sim.min_separation_at[0], "vehicles": list(sim.min_separation_at[1:])},
        "fleet_collisions": len(sim.collisions),
        "fleet_collision_events": [
            {"t": c.t, "vehicles": [c.a, c.b], "point_W": list(c.point_W), "depth_m": c.depth_m} for c in sim.collisions
        ],
        "vehicles": {n: r.metrics for n, r in runs.items()},
    }
    return out


IMAGE_CAMERA_RANGE_M = 100.0
"""How far an image camera (no depth limit) sees other vehicles in a fleet [m] (a 0.2 m box is a few pixels there)."""


def sensing_range(component: Any) -> float:
    """How far a ray-cast sensor component sees [m]: a LiDAR's ``range_max``, a depth camera's ``depth_max``,
    else :data:`IMAGE_CAMERA_RANGE_M`."""
    lidar = getattr(component, "lidar", None)
    if lidar is not None and hasattr(lidar, "params"):
        return float(lidar.params.range_max)
    cameras = getattr(component, "cameras", None) or [getattr(component, "camera", None)]
    depths = [float(d) for d in (getattr(c, "depth_max", None) for c in cameras) if d is not None]
    if depths and len(depths) == len(cameras):
        return max(depths)
    return IMAGE_CAMERA_RANGE_M


def build_fleet(config: ScenarioConfig, until_done: bool = True) -> Fleet:
    """The fleet of ``config`` (a scenario with ``vehicles:``): each vehicle built as a single-vehicle scenario
    (:func:`vehicle_scenario`, validated as any), in the fleet's world. With ``until_done`` each vehicle's run ends
    as a single run's does (landed after its reference, or its mission's end condition); without, it goes on until
    the fleet is stopped (as ``Simulator.advance_to`` without ``done``: for a vehicle flown from outside, e.g. over
    MAVLink, which may take off again after landing)."""
    if not config.vehicles:
        raise ConfigError(f"scenario {config.name!r} lists no vehicles; build it with build_simulation")
    vehicles: list[FleetVehicle] = []
    members: list[FleetMember] = []
    world = None
    for spec in config.vehicles:
        vconfig = vehicle_scenario(config, spec.name)
        try:
            built = build_simulation(vconfig)
        except ConfigError as e:
            raise ConfigError(f"vehicles.{spec.name}: {e}") from None
        base = built.context.truth_world_for_metrics()
        if world is None:
            world = base
        viewers = [c for c in built.simulator.components if base is not None and getattr(c, "world", None) is base]
        reach = max((sensing_range(c) for c in viewers), default=None)
        radius = config.downwash.radius(vconfig.vehicle_params().arm_length) if config.downwash else 0.0
        members.append(
            FleetMember(
                spec.name,
                built.simulator,
                done_condition(built) if until_done else None,
                vconfig.collision_box,
                radius,
                viewers,
                base,
                reach,
            )
        )
        vehicles.append(FleetVehicle(spec.name, built))
    sim = FleetSimulator(members, world, config.downwash)
    return connect_formation_links(Fleet(config, vehicles, sim))  # followers hear their leaders' estimates


def run_fleet(config: ScenarioConfig, duration: float | None = None) -> FleetRun:
    """Builds and runs the fleet of ``config``."""
    return build_fleet(config).run(duration)
