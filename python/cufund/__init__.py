"""cufund: simulation and autonomy for micro aerial vehicles, with a fast C++ core."""

from . import control, esdf, lidar, messages, planning, presets, sensors, worlds
from ._core import __version__
from .bus import Bus, BusView, Subscription
from .components import Component, Controller, Estimator, Mapper, Planner, Recorder, Sensor
from .config import ConfigError
from .messages import FlightMode, Topics
from .topics import Topic
from .params import QuadrotorParams
from .quadrotor import Quadrotor, QuadrotorBatch, QuadrotorState
from .scenario import ScenarioConfig, ScenarioRun, available_scenarios, load_scenario, run_scenario
from .simulator import RunStatus, SimulationResult, Simulator
from .worlds import World

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
    "esdf",
    "lidar",
    "load_scenario",
    "messages",
    "planning",
    "presets",
    "run_scenario",
    "sensors",
    "worlds",
]
