"""The simulator core: configuration and limits, typed topics and messages, the bus, the event scheduler, the
component interfaces and the registry of scenario kinds. Imports nothing above it (see docs/architecture.md)."""

from . import messages
from .bus import Bus, BusView, Subscription, TopicAccessError, TruthAccessError
from .components import Component, Controller, Estimator, Mapper, Planner, Recorder, Sensor
from .errors import ConfigError
from .messages import FlightMode, Topics
from .topics import TRUTH_PREFIX, Topic, is_truth

__all__ = [
    "TRUTH_PREFIX",
    "Bus",
    "messages",
    "BusView",
    "Component",
    "ConfigError",
    "Controller",
    "Estimator",
    "FlightMode",
    "Mapper",
    "Planner",
    "Recorder",
    "Sensor",
    "Subscription",
    "Topic",
    "TopicAccessError",
    "Topics",
    "TruthAccessError",
    "is_truth",
]
