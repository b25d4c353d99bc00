"""Flight control (paper §2.3): PX4-style cascaded PID, the SE(3) geometric controller, control allocation."""

from cufund.core.components import Controller

from .allocation import AllocationSaturation, ControlAllocator
from .attitude_control import AttitudeController, AttitudeControlParams
from .flight_mode import BumplessTransfer, ModeReferences
from .geometric_controller import GeometricController, GeometricControlParams
from .position_control import PositionController, PositionControlParams
from .rate_control import RateController, RateControlParams

__all__ = [
    "AllocationSaturation",
    "AttitudeControlParams",
    "AttitudeController",
    "BumplessTransfer",
    "ControlAllocator",
    "Controller",
    "GeometricControlParams",
    "GeometricController",
    "ModeReferences",
    "PositionControlParams",
    "PositionController",
    "RateControlParams",
    "RateController",
]
