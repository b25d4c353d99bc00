"""The vehicle: its parameters (:class:`QuadrotorParams`), presets, and the quadrotor dynamics (single and batched)."""

from . import presets
from .battery import Battery, BatteryParams
from .motor_power import MotorPower, MotorPowerParams
from .params import QuadrotorParams
from .quadrotor import Quadrotor, QuadrotorBatch, QuadrotorState, WindField

__all__ = [
    "Battery",
    "BatteryParams",
    "MotorPower",
    "MotorPowerParams",
    "Quadrotor",
    "QuadrotorBatch",
    "QuadrotorParams",
    "QuadrotorState",
    "WindField",
    "presets",
]
