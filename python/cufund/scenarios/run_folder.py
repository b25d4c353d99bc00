"""Writing a run folder: metrics.json, config.yaml (reproduces the run), trajectory.png and replay.html (when the
run flew a reference); ``run.mcap`` is written while the run goes (see :func:`cufund.scenarios.build.run_scenario`'s
``logger``).

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

from .build import ScenarioRun

__all__ = ["RunInterrupted", "run_into_folder", "write_config", "write_run_folder"]


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by a signal (``signum``: SIGINT or SIGTERM); a KeyboardInterrupt, so code that lets Ctrl-C
    through lets it through."""

    received: int | None = None
    """The signal :meth:`raise_for` was called for (None: none yet). Kept because an exception raised inside a
    Python callback of compiled code may reach the caller as another type."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @classmethod
    def raise_for(cls, signum: int) -> None:
        """What a signal handler calls: records ``signum``, then raises."""
        cls.received = int(signum)
        raise cls(signum)


def _json_safe(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    return x


def write_run_folder(run: ScenarioRun, out: str | Path, plots: bool = True, replay: bool = True) -> Path:
    """Writes the run's files into ``out`` (created if needed); returns the folder."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    _write_metrics(run.metrics, out)
    write_config(run.config, out)
    params = run.config.vehicle_params()
    if plots and run.reference is not None and run.path is not None and run.metrics.get("tracking_rmse_m") is not None:
        from cufund.viz.plots import plot_tracking

        window = (float(run.path.t_knots[0]), run.path.t_end)
        title = (
            f"{run.config.name}, {run.config.controller.kind if run.config.controller else 'no controller'}: "
            f"RMSE {100 * run.metrics['tracking_rmse_m']:.2f} cm, max {100 * run.metrics['tracking_max_m']:.2f} cm"
        )
        plot_tracking(out / "trajectory.png", run.result, run.reference, window, title)
    if replay:
        from cufund.viz.replay import write_replay_html

        write_replay_html(out / "replay.html", run.result, params, run.reference)
    for hook in run.output_hooks:
        hook(run, out, plots=plots, replay=replay)
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
        signum = exc.signum if isinstance(exc, RunInterrupted) else RunInterrupted.received
        if signum is None and not isinstance(exc, KeyboardInterrupt):
            raise
        signum = signal.SIGINT if signum is None else signum  # a plain KeyboardInterrupt: Ctrl-C
        metrics: dict[str, Any] = {
            "status": "interrupted",
            "message": f"stopped by {signal.Signals(signum).name}",
            "sim_time_s": float(built.simulator.t),
        }
        if logger is not None:
            try:
                logger.close()
            except Exception as close_error:  # the folder is finished whatever the log says
                metrics["log_error"] = f"{type(close_error).__name__}: {close_error}"
            logger = None
        _write_metrics(metrics, out)
        if isinstance(exc, KeyboardInterrupt):
            raise
        raise RunInterrupted(signum) from exc  # the signal's exception came back as another type
    finally:
        if logger is not None:
            logger.close()
    write_run_folder(run, out, plots=plots, replay=replay)
    return run


def _log_context(logger: Any, built: Any) -> None:
    """The log's ``/tf_static`` (base_link -> each sensor's frame from its extrinsic) and the world's meshes."""
    from cufund.logs.codecs import sensor_frame
    from cufund.logs.run_context import write_run_context

    config = built.config
    sensors = []
    for spec in (config.sensors or {}).values():
        if spec is not None and spec.topic is not None:
            e = spec.extrinsic
            sensors.append((sensor_frame(str(spec.topic)), None if e is None else e.t, None if e is None else e.q))
    world = built.context.world
    write_run_context(logger, sensors, config.estimator is not None, world)


class _Excluding:
    """The logger without the topics of ``log.exclude``."""

    def __init__(self, logger: Any, exclude: tuple[str, ...]) -> None:
        self.logger, self.exclude = logger, frozenset(exclude)

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int) -> None:
        if str(topic) not in self.exclude:
            self.logger.write(topic, message, log_time_ns, publish_time_ns)
