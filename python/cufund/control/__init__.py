"""Flight control (paper §2.3): PX4-style cascaded PID, the SE(3) geometric controller, control allocation."""

from cufund.core.components import Controller
from .allocation import AllocationSaturation, ControlAllocator
from .attitude_control import AttitudeControlParams, AttitudeController
from .flight_mode import BumplessTransfer, ModeReferences
from .geometric_controller import GeometricControlParams, GeometricController
from .position_control import PositionControlParams, PositionController
from .rate_control import RateControlParams, RateController

__all__ = [
    "AllocationSaturation", "AttitudeControlParams", "AttitudeController", "BumplessTransfer", "ControlAllocator",
    "Controller", "GeometricControlParams", "GeometricController", "ModeReferences",
    "PositionControlParams", "PositionController", "RateControlParams", "RateController",
]
