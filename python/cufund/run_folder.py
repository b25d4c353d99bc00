"""Writing a run folder: metrics.json, config.yaml (reproduces the run), trajectory.png and replay.html."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from .scenario import ScenarioRun

__all__ = ["write_run_folder"]


def write_run_folder(run: ScenarioRun, out: str | Path, plots: bool = True, replay: bool = True) -> Path:
    """Writes the run's files into ``out`` (created if needed); returns the folder."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "metrics.json").write_text(json.dumps(run.metrics, indent=2) + "\n", encoding="utf-8")
    with (out / "config.yaml").open("w", encoding="utf-8") as f:
        f.write(f"# Reproduce with: cufund run {out / 'config.yaml'}\n")
        yaml.safe_dump(run.config.to_dict(), f, sort_keys=False)
    params = run.config.vehicle_params()
    if plots:
        from .viz.plots import plot_tracking

        window = (float(run.path.t_knots[0]), run.path.t_end)
        title = (f"{run.config.name}, {run.config.controller.kind}: RMSE {100 * run.metrics['tracking_rmse_m']:.2f} cm, "
                 f"max {100 * run.metrics['tracking_max_m']:.2f} cm")
        plot_tracking(out / "trajectory.png", run.result, run.reference, window, title)
    if replay:
        from .viz.replay import write_replay_html

        write_replay_html(out / "replay.html", run.result, params, run.reference)
    return out
