"""Writing a run folder: metrics.json, config.yaml (reproduces the run), the figures (trajectory and errors, PNG
and SVG) and replay.html (when the run flew); ``run.mcap`` is written while the run goes (see
:func:`cufund.scenarios.build.run_scenario`'s ``logger``).

``config.yaml`` is written before the run starts, so a killed run's folder still says what it ran. A run stopped by
:class:`RunInterrupted` (``cufund run`` raises it on SIGINT and SIGTERM) closes its log (complete, with its
summary) and writes ``metrics.json`` with status ``interrupted``."""

from __future__ import annotations

import json
import math
import signal
from pathlib import Path
from typing import Any

import yaml

from .build import RunInterrupted, ScenarioRun

__all__ = ["RunInterrupted", "run_fleet_into_folder", "run_into_folder", "world_of", "write_config", "write_run_folder"]


def _json_safe(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    return x


def world_of(config: Any) -> Any:
    """The scenario's world built again from its description (the same kind and parameters, so the same meshes
    as the run's), for figures and replays; None without a world."""
    if getattr(config, "world", None) is None:
        return None
    from .build import ScenarioBuildContext

    return ScenarioBuildContext(config).build("world", config.world, "world")


def _phases(run: ScenarioRun, t0: float, t1: float) -> list[Any]:
    """A reference's parts: the min-snap path (``run.path``) between take-off and landing."""
    from cufund.viz.flight import Phase

    if run.path is None:
        return []
    a, b = float(run.path.t_knots[0]), float(run.path.t_end)
    spans = [(t0, a, "take-off and hover"), (a, b, "path"), (b, t1, "landing")]
    return [Phase(max(t0, x), min(t1, y), name) for x, y, name in spans if min(t1, y) > max(t0, x)]


def _title(run: ScenarioRun) -> str:
    m = run.metrics
    parts = [f"{run.config.name}: {m.get('status', run.result.status.value)}"]
    if m.get("tracking_rmse_m") is not None:
        parts.append(f"tracking RMSE {100 * m['tracking_rmse_m']:.2f} cm")
    if m.get("odometry_rmse_m") is not None:
        parts.append(f"odometry RMSE {100 * m['odometry_rmse_m']:.2f} cm")
    return ", ".join(parts)


def write_run_folder(run: ScenarioRun, out: str | Path, plots: bool = True, replay: bool = True) -> Path:
    """Writes the run's files into ``out`` (created if needed): metrics.json, config.yaml, then, for a run that
    flew, ``trajectory`` and ``errors`` (PNG and SVG, :mod:`cufund.viz.plots`) and ``replay.html``
    (:mod:`cufund.viz.replay`) of the world and the flight. The parts' output hooks run first, with
    ``flight=`` the :class:`cufund.viz.flight.Flight` they may add to (gates, phases, markers); returns the
    folder."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    _write_metrics(run.metrics, out)
    write_config(run.config, out)
    flight = None
    if (plots or replay) and len(run.result.states["t"]) >= 2:
        from cufund.viz.flight import Flight

        trajectory = getattr(run.config, "trajectory", None)  # its waypoints, when the run flew through them
        waypoints = trajectory.waypoints if trajectory is not None and run.path is not None else None
        goal = getattr(getattr(getattr(run.config, "planner", None), "params", None), "goal", None)
        flight = Flight.from_result(run.result, run.reference, goal if waypoints is None else waypoints)
        if waypoints is None and goal is not None:
            flight.waypoints_label = "goal"
        flight.phases, flight.phases_title = _phases(run, float(flight.t[0]), float(flight.t[-1])), "reference"
        if not flight.phases:  # a part may name its own (the tunnel's mission states)
            flight.phases, flight.phases_title = flight.airborne_phases(), "phases (from the true height)"
        flight.title = _title(run)
    for hook in run.output_hooks:
        hook(run, out, plots=plots, replay=replay, flight=flight)
    if flight is None:
        return out
    world = world_of(run.config)
    if plots:
        from cufund.viz.plots import plot_errors, plot_trajectory

        plot_trajectory(out / "trajectory", flight, world)
        plot_errors(out / "errors", flight)
    if replay:
        from cufund.viz.replay import write_replay_html

        write_replay_html(out / "replay.html", flight, run.config.vehicle_params(), world)
    return out


def write_config(config: Any, out: Path) -> None:
    """``out/config.yaml``: the scenario as run (``cufund run`` on it reproduces the run)."""
    text = f"# Reproduce with: cufund run {out / 'config.yaml'}\n" + yaml.safe_dump(config.to_dict(), sort_keys=False)
    (out / "config.yaml").write_text(text, encoding="utf-8")


def _write_metrics(metrics: dict[str, Any], out: Path) -> None:
    (out / "metrics.json").write_text(json.dumps(_json_safe(metrics), indent=2) + "\n", encoding="utf-8")


def run_into_folder(
    config: Any,
    out: str | Path,
    *,
    log: bool = True,
    plots: bool = True,
    replay: bool = True,
    progress: bool = False,
    extra_components: tuple = (),
) -> ScenarioRun:
    """Runs ``config`` (a :class:`cufund.ScenarioConfig`, or a scenario already made by
    :func:`cufund.scenarios.build.build_simulation`) into the run folder ``out``: ``run.mcap`` while it goes (when
    ``log`` and the scenario's ``log.mcap``; its metadata holds the scenario's config), then
    :func:`write_run_folder`; ``config.yaml`` first, before the run starts. Interrupted (a KeyboardInterrupt, e.g.
    :class:`RunInterrupted`): the log is closed, ``metrics.json`` says status ``interrupted`` (with the simulated
    time reached) and the exception goes on. Returns the run."""
    from .build import Built, build_simulation, run_built

    if getattr(config, "vehicles", None) and not extra_components:  # a fleet (docs/guides/fleets.md)
        return run_fleet_into_folder(config, out, log=log, plots=plots, replay=replay)
    built = config if isinstance(config, Built) else build_simulation(config, extra_components)
    config = built.config
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_config(config, out)
    logger = None
    if log and config.log.mcap:
        from cufund.logs import McapLogger

        logger = McapLogger(
            out / "run.mcap",
            metadata={
                "scenario": config.name,
                "seed": str(config.seed),
                "config": yaml.safe_dump(config.to_dict(), sort_keys=False),
            },
            compression="zstd",  # binary point clouds: about 20 % smaller than lz4 for a few % of a core
        )
        _log_context(logger, built)
        exclude = (*config.log.exclude, *(() if config.log.truth_cloud else ("/truth/point_cloud",)))
        built.simulator.logger = _Excluding(logger, exclude) if exclude else logger
    RunInterrupted.received = None  # only a signal during this run makes its failure an interruption
    try:
        run = run_built(built, progress=progress)
    except BaseException as exc:
        _finish_interrupted(exc, built.simulator.t, out, logger)
        raise
    finally:
        if logger is not None:
            logger.close()  # idempotent
    write_run_folder(run, out, plots=plots, replay=replay)
    return run


def _finish_interrupted(exc: BaseException, sim_time_s: float, out: Path, logger: Any) -> None:
    """Called with the exception that ended a run into ``out``: when a signal stopped it (``exc`` a
    KeyboardInterrupt, or another type the signal's exception came back as), closes the log and writes
    ``metrics.json`` with status ``interrupted`` and the simulated time reached, and for another type raises
    :class:`RunInterrupted` from it; otherwise does nothing (the caller re-raises ``exc``)."""
    signum = exc.signum if isinstance(exc, RunInterrupted) else RunInterrupted.received
    if signum is None and not isinstance(exc, KeyboardInterrupt):
        return
    signum = signal.SIGINT if signum is None else signum  # a plain KeyboardInterrupt: Ctrl-C
    metrics: dict[str, Any] = {
        "status": "interrupted",
        "message": f"stopped by {signal.Signals(signum).name}",
        "sim_time_s": float(sim_time_s),
    }
    if logger is not None:
        try:
            logger.close()
        except Exception as close_error:  # the folder is finished whatever the log says
            metrics["log_error"] = f"{type(close_error).__name__}: {close_error}"
    _write_metrics(metrics, out)
    if not isinstance(exc, KeyboardInterrupt):
        raise RunInterrupted(signum) from exc  # the signal's exception came back as another type


def run_fleet_into_folder(
    config: Any, out: str | Path, *, log: bool = True, plots: bool = True, replay: bool = True
) -> Any:
    """Builds (unless given a :class:`cufund.scenarios.fleet.Fleet`) and runs a fleet into ``out``: ``config.yaml``
    (the fleet scenario, before the run), ``run.mcap`` (each vehicle's messages under ``/NAME``), ``metrics.json``
    (the fleet's figures, each vehicle's under ``vehicles``) and one folder per vehicle (:func:`write_run_folder`:
    its metrics, its own scenario as ``config.yaml``, figures, replay). Interrupted: ``metrics.json`` says
    ``interrupted``. Returns the :class:`cufund.scenarios.fleet.FleetRun`."""
    from .fleet import Fleet, build_fleet
    from .fleet_folder import NamespacedLogger, write_fleet_context

    fleet = config if isinstance(config, Fleet) else build_fleet(config)
    cfg = fleet.config
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_config(cfg, out)
    logger = None
    if log and cfg.log.mcap:
        from cufund.logs import McapLogger

        meta = {"scenario": cfg.name, "seed": str(cfg.seed), "config": yaml.safe_dump(cfg.to_dict(), sort_keys=False)}
        logger = McapLogger(out / "run.mcap", metadata=meta, compression="zstd")
        write_fleet_context(logger, fleet)
        exclude = (*cfg.log.exclude, *(() if cfg.log.truth_cloud else ("/truth/point_cloud",)))
        for name in fleet.names:
            fleet.vehicle(name).simulator.logger = _Excluding(NamespacedLogger(logger, name), exclude)
    RunInterrupted.received = None
    try:
        run = fleet.run()
    except BaseException as exc:
        _finish_interrupted(exc, fleet.t, out, logger)
        raise
    finally:
        if logger is not None:
            logger.close()
    _write_metrics(run.metrics, out)
    if plots:  # fleet.png: every vehicle in one top view, and the separations over time
        from cufund.viz.fleet_plot import write_fleet_figure

        write_fleet_figure(run, out)
    for name, vrun in run.runs.items():
        write_run_folder(vrun, out / name, plots=plots, replay=replay)
    return run


def _log_context(logger: Any, built: Any) -> None:
    """The log's ``/tf_static`` (base_link -> each sensor's frame from its extrinsic) and the world's meshes."""
    from cufund.logs.run_context import write_run_context

    from .sensor_frames import sensor_frames

    config, ctx = built.config, built.context
    write_run_context(logger, sensor_frames(config), config.estimator is not None, ctx.world, ctx.reference)


class _Excluding:
    """The logger without the topics of ``log.exclude``."""

    def __init__(self, logger: Any, exclude: tuple[str, ...]) -> None:
        self.logger, self.exclude = logger, frozenset(exclude)
        self._write = logger.write  # the logger's compiled write, looked up once

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int) -> None:
        if topic not in self.exclude:  # a Topic hashes and compares as its name
            self._write(topic, message, log_time_ns, publish_time_ns)
