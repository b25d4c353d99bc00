"""What a fleet's run folder (:func:`cufund.scenarios.run_folder.run_into_folder`) adds to a single vehicle's: its
log's namespaces (every vehicle's messages under ``/NAME``: ``/uav1/sensors/imu``), the log's context, and the
summary ``cufund run`` prints."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from cufund.simulator.fleet import namespaced

from .fleet import Fleet, FleetRun

__all__ = ["NamespacedLogger", "fleet_summary", "write_fleet_context"]


class NamespacedLogger:
    """One vehicle's messages into the fleet's log, each topic under ``/NAME``."""

    def __init__(self, logger: Any, name: str) -> None:
        self.name = name
        self._write = logger.write
        self._topics: dict[str, str] = {}

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int) -> None:
        full = self._topics.get(topic)
        if full is None:
            full = self._topics[topic] = namespaced(self.name, str(topic))
        self._write(full, message, log_time_ns, publish_time_ns)


def write_fleet_context(logger: Any, fleet: Fleet) -> None:
    """The fleet log's ``/tf_static`` (each vehicle's frames under its name: ``world`` -> ``uav1/odom``,
    ``uav1/base_link`` -> ``uav1/imu``, ...), the world's meshes, each vehicle's reference known before the run on
    ``/NAME/planner/path``, and ``/clock`` at each of the fleet's interaction instants."""
    from cufund.logs import codecs, ros2
    from cufund.logs.run_context import static_transforms, write_run_context

    from .sensor_frames import sensor_frames

    transforms = []
    for name in fleet.names:
        config = fleet.vehicle(name).config
        transforms += static_transforms(sensor_frames(config, name), config.estimator is not None, name)
    world = fleet.simulator.members[0].world
    write_run_context(logger, (), True, world, None, transforms)
    for name in fleet.names:
        reference = fleet.vehicle(name).built.context.reference
        if reference is not None and hasattr(reference, "sample"):
            logger.write_encoded(namespaced(name, "/planner/path"), ros2.PATH, codecs.path_of(reference, 0.0), 0)

    def clock(t: float) -> None:
        ns = round(t * 1e9)
        data = ros2.CdrWriter().put("i", ns // 1_000_000_000).put("I", ns % 1_000_000_000).bytes()
        logger.write_encoded("/clock", ros2.CLOCK, data, ns)

    fleet.simulator.observers.append(clock)


def fleet_summary(run: FleetRun, out: Path) -> str:
    """A few lines for the terminal: the fleet's status and figures, one line per vehicle."""
    m = run.metrics
    sep = m.get("fleet_min_separation_m")
    lines = [
        f"{run.config.name}: {run.status} ({run.message})",
        f"  {m['fleet_size']} vehicles, min separation {'-' if sep is None else f'{sep:.3f} m'}, "
        f"collisions {m['fleet_collisions']}, {m['sim_time_s']:.2f} s simulated",
    ]
    for name, vm in m["vehicles"].items():
        rmse = vm.get("tracking_rmse_m")
        lines.append(
            f"  {name}: {vm['status']}"
            + (f", tracking RMSE {100 * rmse:.2f} cm" if rmse is not None else "")
            + (f", odometry RMSE {100 * vm['odometry_rmse_m']:.2f} cm" if vm.get("odometry_rmse_m") is not None else "")
        )
    lines.append(f"run folder: {out.resolve()}")
    return "\n".join(lines)
