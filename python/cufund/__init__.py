"""cufund: simulation and autonomy for micro aerial vehicles, with a fast C++ core.

The package is layered (docs/architecture.md): ``core`` → ``geometry`` → ``vehicle``, ``worlds``, ``logs`` →
``simulator`` → ``sensors`` → ``estimation``, ``mapping``, ``perception`` → ``planning`` → ``control`` → ``viz``
→ ``missions`` → ``scenarios`` → ``apps``; a module imports only from layers below its own.
"""

from typing import Any

from . import control, planning, sensors, worlds
from ._core import __version__
from .core import (
    Bus,
    BusView,
    Component,
    ConfigError,
    Controller,
    Estimator,
    FlightMode,
    Mapper,
    Planner,
    Recorder,
    Sensor,
    Subscription,
    Topic,
    Topics,
    messages,
    moved,
)
from .scenarios import ScenarioConfig, ScenarioRun, available_scenarios, load_scenario, run_scenario
from .simulator import RunStatus, SimulationResult, Simulator
from .vehicle import Quadrotor, QuadrotorBatch, QuadrotorParams, QuadrotorState, presets
from .worlds import World

moved.install()

__all__ = [
    "Bus",
    "BusView",
    "Component",
    "ConfigError",
    "Controller",
    "Estimator",
    "FlightMode",
    "Mapper",
    "Planner",
    "Quadrotor",
    "QuadrotorBatch",
    "QuadrotorParams",
    "QuadrotorState",
    "Recorder",
    "RunStatus",
    "ScenarioConfig",
    "ScenarioRun",
    "Sensor",
    "SimulationResult",
    "Simulator",
    "Subscription",
    "Topic",
    "Topics",
    "World",
    "__version__",
    "available_scenarios",
    "control",
    "load_scenario",
    "messages",
    "planning",
    "presets",
    "run_scenario",
    "sensors",
    "worlds",
]


def __getattr__(name: str) -> Any:
    """``cufund.mapping`` and ``cufund.sensors`` (0.1's names for :mod:`cufund.mapping` and :mod:`cufund.sensors`)."""
    if name in ("esdf", "lidar"):
        import importlib

        return importlib.import_module(f"cufund.{name}")
    raise AttributeError(f"module 'cufund' has no attribute {name!r}")
