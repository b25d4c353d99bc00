"""Scenarios: the schema (YAML validated into frozen dataclasses), building the component graph, running it, its
metrics, the run folder, and the built-in scenarios (``builtin/*.yaml``)."""

from cufund.planning.kinds import build_reference

from .build import (
    BuildContext,
    Built,
    RunSummary,
    ScenarioRun,
    build_simulation,
    odometry_metrics,
    run_built,
    run_scenario,
    tracking_metrics,
)
from .run_folder import run_into_folder, write_run_folder
from .schema import (
    LogConfig,
    PartSpec,
    RatesConfig,
    ScenarioConfig,
    TrajectoryConfig,
    apply_overrides,
    available_scenarios,
    load_scenario,
    parse_overrides,
)

__all__ = [
    "BuildContext",
    "Built",
    "LogConfig",
    "PartSpec",
    "RatesConfig",
    "RunSummary",
    "ScenarioConfig",
    "ScenarioRun",
    "TrajectoryConfig",
    "apply_overrides",
    "available_scenarios",
    "build_reference",
    "build_simulation",
    "load_scenario",
    "odometry_metrics",
    "parse_overrides",
    "run_built",
    "run_into_folder",
    "run_scenario",
    "tracking_metrics",
    "write_run_folder",
]
