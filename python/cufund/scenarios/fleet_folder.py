"""A fleet's run folder: ``config.yaml`` (the fleet scenario, written before the run), ``metrics.json`` (the fleet's
figures and each vehicle's under ``vehicles``), ``run.mcap`` (every vehicle's messages under its namespace,
``/uav1/sensors/imu``), and one sub-folder per vehicle with its own metrics, config (its scenario: ``cufund run``
on it flies that vehicle alone), figures and replay."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from cufund.simulator.fleet import namespaced

from .fleet import Fleet, FleetRun, build_fleet
from .run_folder import _json_safe, write_config, write_run_folder
from .schema import ScenarioConfig

__all__ = ["NamespacedLogger", "fleet_summary", "run_fleet_into_folder"]


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


def run_fleet_into_folder(
    config: ScenarioConfig | Fleet, out: str | Path, *, log: bool = True, plots: bool = True, replay: bool = True
) -> FleetRun:
    """Builds (unless given a :class:`Fleet`) and runs a fleet into the folder ``out``; returns the run."""
    import json

    fleet = config if isinstance(config, Fleet) else build_fleet(config)
    cfg = fleet.config
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_config(cfg, out)
    logger = None
    if log and cfg.log.mcap:
        from cufund.logs import McapLogger

        logger = McapLogger(
            out / "run.mcap",
            metadata={
                "scenario": cfg.name,
                "seed": str(cfg.seed),
                "config": yaml.safe_dump(cfg.to_dict(), sort_keys=False),
            },
            compression="zstd",
        )
        exclude = set(cfg.log.exclude) | ({"/truth/point_cloud"} if not cfg.log.truth_cloud else set())
        for name in fleet.names:
            sim = fleet.vehicle(name).simulator
            sim.logger = _Excluding(NamespacedLogger(logger, name), exclude)
    try:
        run = fleet.run()
    finally:
        if logger is not None:
            logger.close()
    (out / "metrics.json").write_text(json.dumps(_json_safe(run.metrics), indent=2) + "\n", encoding="utf-8")
    for name, vrun in run.runs.items():
        write_run_folder(vrun, out / name, plots=plots, replay=replay)
    return run


class _Excluding:
    def __init__(self, logger: Any, exclude: set[str]) -> None:
        self._write, self.exclude = logger.write, frozenset(exclude)

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int) -> None:
        if topic not in self.exclude:
            self._write(topic, message, log_time_ns, publish_time_ns)


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
