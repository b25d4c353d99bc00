"""cufund: simulation and autonomy for micro aerial vehicles, with a fast C++ core."""

from . import esdf, presets
from ._core import __version__
from .config import ConfigError
from .params import QuadrotorParams
from .quadrotor import Quadrotor, QuadrotorBatch, QuadrotorState

__all__ = [
    "ConfigError",
    "Quadrotor",
    "QuadrotorBatch",
    "QuadrotorParams",
    "QuadrotorState",
    "__version__",
    "esdf",
    "presets",
]
