"""The vehicle: its parameters (:class:`QuadrotorParams`), presets, and the quadrotor dynamics (single and batched)."""

from . import presets
from .params import QuadrotorParams
from .quadrotor import Quadrotor, QuadrotorBatch, QuadrotorState, WindField

__all__ = ["Quadrotor", "QuadrotorBatch", "QuadrotorParams", "QuadrotorState", "WindField", "presets"]
