"""cufund as the simulator of N PX4 SITL instances: a fleet scenario (``vehicles:``) made PX4's world vehicle by
vehicle (:func:`px4_fleet_scenario`), built as one fleet (:func:`cufund.scenarios.fleet.build_fleet`: one world,
vehicle-vehicle contacts, downwash, each vehicle's LiDAR seeing the others), each vehicle served by its own
:class:`Px4SimulatorBridge` on TCP ``4560 + i`` (PX4 instance ``i``: ``px4_sitl -i i``, MAVLink system ``i + 1``;
:mod:`.fleet_ports`).

Lockstep: the fleet advances every vehicle to each HIL_SENSOR instant (250 Hz) before any goes further, and each
vehicle's bridge waits there for its own instance's HIL_ACTUATOR_CONTROLS, so no instance ever sees another's
future. Within one period the instances are served in turn (vehicle 0's sensors out, its controls in, then
vehicle 1's, ...): the physics of each vehicle is its own simulator's step, not one batched call (see
:mod:`cufund.simulator.fleet`).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

from cufund.core.config import ConfigError
from cufund.scenarios.schema import ScenarioConfig
from cufund.simulator import RunStatus

from .fleet_ports import px4_sim_port
from .px4_links import TcpServerLink
from .px4_sim import _FLIGHT_SOFTWARE, Px4BridgeParams, Px4SimulatorBridge, px4_scenario

__all__ = ["Px4FleetBridge", "Px4FleetResult", "px4_fleet_scenario", "serve_px4_fleet"]


def px4_fleet_scenario(config: ScenarioConfig) -> ScenarioConfig:
    """The fleet ``config`` as PX4's world: :func:`px4_scenario` of the fleet's parts, and of each vehicle's own
    parts (its flight software dropped, its own sensors, if it has any, at PX4's rates)."""
    if not isinstance(config, ScenarioConfig) or not config.vehicles:
        raise ConfigError("px4_fleet_scenario needs a scenario with vehicles: (a fleet)")
    from cufund.scenarios.fleet import vehicle_scenario
    from cufund.scenarios.fleet_schema import VehicleSpec

    specs = []
    for v in config.vehicles:
        overrides = {k: val for k, val in v.overrides.items() if k not in _FLIGHT_SOFTWARE}
        if "sensors" in v.overrides:  # its own sensors: made PX4's as a single vehicle's would be
            try:
                overrides["sensors"] = px4_scenario(vehicle_scenario(config, v.name)).to_dict()["sensors"]
            except ConfigError as e:
                raise ConfigError(f"vehicles.{v.name}: {e}") from None
        specs.append(VehicleSpec(v.name, v.start_p_W, v.start_yaw, overrides))
    return px4_scenario(config.replace(vehicles=tuple(specs)))


@dataclass
class Px4FleetResult:
    """A finished PX4 fleet session: the fleet's status and message, simulated time, and each vehicle's result and
    bridge counters by name."""

    status: str
    message: str
    sim_time_s: float
    wall_time_s: float
    results: dict[str, Any]
    stats: dict[str, dict[str, int]]

    @property
    def periods_per_wall_s(self) -> float:
        """Lockstep periods served per wall second, all instances counted (HIL_SENSOR instance 0 messages)."""
        n = sum(s["hil_sensor"] for s in self.stats.values())
        return n / self.wall_time_s if self.wall_time_s > 0 else math.nan


class Px4FleetBridge:
    """Serves the fleet ``config`` to N PX4 SITL instances: vehicle ``i`` on TCP ``host:4560 + first_instance + i``
    (``links``: one link per vehicle instead, e.g. ``TcpServerLink(host, 0)`` in tests). ``bridges`` maps each
    vehicle to its :class:`Px4SimulatorBridge`; ``fleet`` is the built fleet. Ports are opened at construction
    (OSError naming the one taken, nothing left open)."""

    def __init__(
        self,
        config: ScenarioConfig,
        params: Px4BridgeParams | None = None,
        host: str = "127.0.0.1",
        first_instance: int = 0,
        links: list[Any] | None = None,
    ) -> None:
        from cufund.scenarios.fleet import build_fleet

        if isinstance(first_instance, bool) or not isinstance(first_instance, int) or first_instance < 0:
            raise ValueError(f"first_instance must be an integer >= 0, got {first_instance!r}")
        self.config = px4_fleet_scenario(config)
        n = len(self.config.vehicles)
        if links is not None and len(links) != n:
            raise ValueError(f"links must give one link per vehicle ({n}), got {len(links)}")
        if px4_sim_port(first_instance + n - 1) > 65535:
            raise ValueError(f"instances {first_instance}..{first_instance + n - 1}: TCP port 4560 + i out of range")
        self.fleet = build_fleet(self.config)
        self.params = params if params is not None else Px4BridgeParams()
        self.bridges: dict[str, Px4SimulatorBridge] = {}
        opened: list[Any] = list(links or ())
        try:
            for i, name in enumerate(self.fleet.names):
                link = links[i] if links is not None else TcpServerLink(host, px4_sim_port(first_instance + i))
                if links is None:
                    opened.append(link)
                vehicle = self.fleet.vehicle(name)
                self.bridges[name] = Px4SimulatorBridge(vehicle.config, link, self.params, built=vehicle.built)
        except Exception:
            for link in opened:
                link.close()
            raise

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.fleet.names)

    def run(self, duration: float | None = None, connect_timeout: float | None = None) -> Px4FleetResult:
        """Waits for every instance (``connect_timeout`` [s] in all; None: forever; TimeoutError naming the ones
        missing), then simulates until every instance has left, a vehicle crashes, or ``duration`` [s] of
        simulated time passes."""
        if duration is not None and (
            isinstance(duration, bool)
            or not isinstance(duration, (int, float))
            or not math.isfinite(duration)
            or duration <= 0
        ):
            raise ValueError(f"duration must be a number of seconds > 0 or None, got {duration!r}")
        deadline = None if connect_timeout is None else time.monotonic() + connect_timeout
        for name, bridge in self.bridges.items():
            left = None if deadline is None else max(deadline - time.monotonic(), 0.0)
            try:
                bridge.connect(left)
            except TimeoutError:
                missing = [n for n, b in self.bridges.items() if n == name or not b.link.connected]
                raise TimeoutError(
                    f"PX4 instances of {', '.join(missing)} did not connect within {connect_timeout} s "
                    f"(ports {', '.join(str(self.bridges[n].port_number) for n in missing)})"
                ) from None
        fleet = self.fleet
        wall0 = time.perf_counter()
        end = fleet.t + duration if duration is not None else math.inf
        try:
            while fleet.t < end:
                t_before = fleet.t
                if not fleet.advance_to(min(end, t_before + 1.0)) or fleet.t == t_before:
                    break
        finally:
            wall = time.perf_counter() - wall0
            for bridge in self.bridges.values():
                bridge.disconnect()
        sim = fleet.simulator
        status = sim.status.value if sim.status is not None else "completed"
        message = sim.message or ("duration elapsed" if sim.status is None else "")
        results = {}
        for n, b in self.bridges.items():
            if b.simulator.status is None:
                b.simulator.stop(RunStatus.COMPLETED, "duration elapsed")
            results[n] = b.simulator.result()
        return Px4FleetResult(
            status, message, float(fleet.t), wall, results, {n: dict(b.stats) for n, b in self.bridges.items()}
        )

    def close(self) -> None:
        for bridge in self.bridges.values():
            bridge.close()

    def __enter__(self) -> Px4FleetBridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def serve_px4_fleet(args: Any, config: ScenarioConfig, params: Px4BridgeParams) -> int:
    """``cufund px4-sim FLEET``: vehicle i waits for PX4 instance ``--instance`` + i; the exit code (as
    ``cufund px4-sim``: 0 ended in order, 1 a crash, a failed link or nobody connecting, 2 invalid usage)."""
    import sys

    if args.hitl:
        print("cufund: --hitl serves one flight controller; a fleet scenario runs as SITL instances", file=sys.stderr)
        return 2
    try:
        bridge = Px4FleetBridge(config, params, host=args.host, first_instance=args.instance)
    except (ConfigError, ValueError, OSError) as e:
        print(f"cufund: {e}", file=sys.stderr)
        return 2
    if args.cpu is not None:  # as a single vehicle's (px4_cli.run): before any thread starts, they inherit it
        os.sched_setaffinity(0, {args.cpu})
    for i, (name, b) in enumerate(bridge.bridges.items()):
        vehicle = b.simulator.vehicle
        print(
            f"cufund px4-sim: {config.name} {name} on {vehicle.params.name if vehicle else 'no vehicle'}, waiting for "
            f"PX4 instance {args.instance + i} (MAVLink system {args.instance + i + 1}) on "
            f"tcp://{args.host}:{b.port_number} (SITL, lockstep)",
            flush=True,
        )
    try:
        result = bridge.run(duration=args.duration, connect_timeout=args.connect_timeout)
    except TimeoutError as e:
        print(f"cufund: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("cufund px4-sim: interrupted", file=sys.stderr)
        return 0
    finally:
        bridge.close()
    print(
        f"status: {result.status} ({result.message}) after {result.sim_time_s:.3f} s simulated; "
        f"{result.periods_per_wall_s:.0f} lockstep periods per wall second (all instances)"
    )
    for name, s in result.stats.items():
        print(
            f"  {name}: HIL_SENSOR {s['hil_sensor']}, HIL_GPS {s['hil_gps']}, controls {s['controls']}, "
            f"timeouts {s['controls_timeouts']}, bad packets {s['bad_packets']}"
        )
    return 0 if result.status == "completed" else 1
