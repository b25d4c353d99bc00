"""cufund: simulation and autonomy for micro aerial vehicles, with a fast C++ core."""

from . import lidar, presets, sensors, worlds
from ._core import __version__
from .config import ConfigError
from .params import QuadrotorParams
from .quadrotor import Quadrotor, QuadrotorBatch, QuadrotorState
from .worlds import World

__all__ = [
    "ConfigError",
    "Quadrotor",
    "QuadrotorBatch",
    "QuadrotorParams",
    "QuadrotorState",
    "World",
    "__version__",
    "lidar",
    "presets",
    "sensors",
    "worlds",
]
